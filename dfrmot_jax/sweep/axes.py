"""The axis kinds of a sweep's config table, as one idea (:class:`AxisKind`).

A sweep's configs are its parameters, options and variants (the rows ``config_hash`` always hashes
in full, :func:`dfrmot_jax.sweep.table.expand`) crossed with each of the sweep's further axis kinds
in turn (``SweepSpec.axes``: the LiDAR settings of ``[lift]`` / ``[simulate]``, then the
distortion lanes of ``[distortion]``). The table expands them, the plan splits and names chunks
by them, without knowing any of them: a new kind is one module implementing the protocol (and its
table of the sweep file, parsed into a ``SweepSpec`` field listed in ``SweepSpec.axes``).
"""

from __future__ import annotations

from typing import Any, Hashable, Mapping, Protocol, Sequence

__all__ = ["AxisKind", "cross_rows", "hash_settings", "split_keys", "split_key"]


class AxisKind(Protocol):
    """One kind of axis of the config table: the columns it adds, how it crosses with the table,
    what it adds to a config's hash, the data it needs.

    ``columns``: the columns it adds, in table order, each to its default; a column at its default
    is left out of ``config_hash``, so a config at every default hashes as without the kind.
    """

    columns: Mapping[str, Any]

    def values(self, baseline: bool) -> list[dict]:
        """The values (``{column: value}``) every config is crossed with, innermost, in table order;
        for the baseline row (``baseline``) the first is the one the baseline runs on."""

    def size(self, configs: int) -> tuple[int, str, list[tuple[int, str]]]:
        """Before expanding: (at most how many configs ``configs`` become crossed with this kind,
        the factor as text for messages, its (count, sweep-file key) factors)."""

    def hash_settings(self, row: Mapping) -> dict:
        """Sweep-wide settings off their defaults that change ``row`` (its ``config_hash`` settings; {}: none)."""

    def split_key(self, row: Mapping) -> Hashable | None:
        """The data ``row``'s config needs beyond its class's split: configs of different keys run on
        different splits (``plan.DataSettings.lidar``); None: the class's split. A key is hashable,
        with ``identity()``: its part of the split's data identity (in every chunk id of the split)."""

    def chunk_identity(self) -> dict:
        """What this kind adds to every chunk's identity (part of the chunk ids; {}: nothing)."""


def cross_rows(rows: Sequence[Mapping], kind: AxisKind) -> list[dict]:
    """Every row x the kind's values (innermost); the baseline flag stays on the baseline row's first
    value (the baseline row comes first, so it still does)."""
    values = {False: kind.values(False), True: kind.values(True)}
    return [{**r, **v, "baseline": bool(r["baseline"]) and i == 0}
            for r in rows for i, v in enumerate(values[bool(r["baseline"])])]


def hash_settings(kinds: Sequence[AxisKind], row: Mapping) -> dict:
    """The ``config_hash`` settings of ``row`` from every kind (:meth:`AxisKind.hash_settings`)."""
    return {k: v for kind in kinds for k, v in kind.hash_settings(row).items()}


def split_keys(kinds: Sequence[AxisKind]) -> list:
    """The distinct split keys of the kinds' values (:meth:`AxisKind.split_key`, None among them for
    the class's own split; [] when no kind needs data of its own). One kind at most may need data: a
    split has one key."""
    keys = [list(dict.fromkeys(kind.split_key(v) for v in kind.values(False))) for kind in kinds]
    keys = [k for k in keys if any(x is not None for x in k)]
    if len(keys) > 1:
        raise ValueError("more than one axis kind needs data of its own: a split has one key")
    return keys[0] if keys else []


def split_key(kinds: Sequence[AxisKind], row: Mapping) -> Hashable | None:
    """``row``'s split key among the kinds' (:meth:`AxisKind.split_key`; None: its class's split)."""
    return next((k for k in (kind.split_key(row) for kind in kinds) if k is not None), None)
