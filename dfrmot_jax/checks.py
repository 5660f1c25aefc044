"""The value checks every table of a sweep file shares: :class:`SweepConfigError` (a bad file, naming
the key), :class:`Table` (the one rule by which keys are named: every value is read through its
table, which names the full key, ``report.folds``, in every error) and the small validators the
parsers of :mod:`dfrmot_jax.sweep.spec`, :mod:`dfrmot_jax.sweep.distortion`,
:mod:`dfrmot_jax.tuning.settings` and the report's contrast (:mod:`dfrmot_jax.table_columns`)
build on. A module of the package root (NumPy only), so that the report, which imports no JAX, and
the sweep share it."""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

#: Most values one count in a sweep file may ask for (a linspace / logspace count, distortion
#: seeds): checked while parsing, before anything is allocated. The configs of the whole sweep are
#: limited separately (``sweep.table.MAX_CONFIGS``, overridable).
MAX_AXIS_VALUES = 1_000_000
GRID_KINDS = ("grid", "linspace", "logspace")


class SweepConfigError(ValueError):
    """A bad sweep file: ``key`` is the offending key path (``params.a_c``, ``data.det2d``, ...)."""

    def __init__(self, key: str, message: str, source: str | None = None):
        self.key = key
        self.message = message
        self.source = source
        super().__init__(f"{source + ': ' if source else ''}{key}: {message}")


def config_error(key, msg, source):
    return SweepConfigError(key, msg, source)


def type_name(v) -> str:
    """What a TOML value is, for messages: 'a table', 'a list', 'a boolean', 'a string', ..."""
    if isinstance(v, Mapping):
        return "a table"
    if isinstance(v, list):
        return "a list"
    if isinstance(v, (bool, np.bool_)):
        return "a boolean"
    if isinstance(v, str):
        return "a string"
    return "a number" if is_number(v) else f"a {type(v).__name__}"


class Table:
    """One table of a sweep or tune file at its key path ``path`` ("" for the file itself,
    ``report``, ``tune.refine``, ``variants[1].params``): the one rule by which the parsers name
    keys. Every value is read through its table, and every error about it names the full key
    (``report.folds``, ``tune.refine.steps``), never the leaf alone.

    ``allowed``: the keys the table may have (others are refused by name)."""

    def __init__(self, doc, path: str, source, allowed: Sequence[str] | None = None):
        if not isinstance(doc, Mapping):
            raise SweepConfigError(path or "(file)", f"expected a table, got {type_name(doc)}: {doc!r}", source)
        self.doc, self.path, self.source = doc, path, source
        for k in doc if allowed is not None else ():
            if k not in allowed:
                raise self.error(k, f"unknown key; expected one of {list(allowed)}")

    def key(self, k) -> str:
        """The full key of ``k`` in this table."""
        return f"{self.path}.{k}" if self.path else str(k)

    def error(self, k, message: str) -> SweepConfigError:
        return SweepConfigError(self.key(k), message, self.source)

    def get(self, k, default=None):
        return self.doc.get(k, default)

    def __contains__(self, k) -> bool:
        return k in self.doc

    def table(self, k, allowed: Sequence[str] | None = None) -> "Table":
        """The sub-table ``k`` (absent: an empty one)."""
        return Table(self.doc.get(k, {}), self.key(k), self.source, allowed)

    def integer(self, k, default, minimum: int = 1):
        """An integer >= ``minimum`` (booleans are not integers); ``default`` when absent."""
        v = self.doc.get(k, default)
        if v is None:
            return None
        if not isinstance(v, int) or isinstance(v, bool) or v < minimum:
            raise self.error(k, f"{v!r}: expected an integer >= {minimum}")
        return v

    def string(self, k, default, empty: bool = False):
        """A string (non-empty unless ``empty``); ``default`` when absent."""
        v = self.doc.get(k, default)
        if v is not None and (not isinstance(v, str) or not (v or empty)):
            raise self.error(k, f"{v!r}: expected a {'' if empty else 'non-empty '}string")
        return v

    def choice(self, k, default, choices: Sequence[str], what: str = ""):
        """One of ``choices`` (strings); ``default`` when absent."""
        v = self.doc.get(k, default)
        if not isinstance(v, str) or v not in choices:
            raise self.error(k, f"{v!r}: {what + ': ' if what else ''}expected one of {list(choices)}")
        return v


def is_scalar(v) -> bool:
    """A number, a boolean or a string: a value an axis can take (not a list, table or date)."""
    return isinstance(v, (str, bool, np.bool_)) or is_number(v)


def is_number(v) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))


def clean_float(v: float) -> float:
    """Round a computed grid value to 12 significant digits (0.6000000000000001 -> 0.6)."""
    return float(f"{float(v):.12g}")


def check_count(n: int, key: str, source) -> None:
    """Refuse a count above :data:`MAX_AXIS_VALUES` (before anything of that size is allocated)."""
    if n > MAX_AXIS_VALUES:
        raise config_error(key, f"count {n:,} is above the limit of {MAX_AXIS_VALUES:,} values per axis "
                                f"(dfrmot_jax.checks.MAX_AXIS_VALUES)", source)
