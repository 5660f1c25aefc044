"""The value checks every table of a sweep file shares: :class:`SweepConfigError` (a bad file, naming
the key) and the small validators the parsers of :mod:`.spec` and :mod:`.distortion` build on."""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

#: Most values one count in a sweep file may ask for (a linspace / logspace count, distortion
#: seeds): checked while parsing, before anything is allocated. The configs of the whole sweep are
#: limited separately (``table.MAX_CONFIGS``, overridable).
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


def check_keys(d: Mapping, allowed: Sequence[str], prefix: str, source) -> None:
    if not isinstance(d, Mapping):
        raise config_error(prefix.rstrip("."), f"expected a table, got {type(d).__name__}", source)
    for k in d:
        if k not in allowed:
            raise config_error(f"{prefix}{k}", f"unknown key; expected one of {list(allowed)}", source)


def is_number(v) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))


def clean_float(v: float) -> float:
    """Round a computed grid value to 12 significant digits (0.6000000000000001 -> 0.6)."""
    return float(f"{float(v):.12g}")


def check_count(n: int, key: str, source) -> None:
    """Refuse a count above :data:`MAX_AXIS_VALUES` (before anything of that size is allocated)."""
    if n > MAX_AXIS_VALUES:
        raise config_error(key, f"count {n:,} is above the limit of {MAX_AXIS_VALUES:,} values per axis "
                                f"(dfrmot_jax.sweep.checks.MAX_AXIS_VALUES)", source)


def positive_int(doc, key, default, source, minimum=1, prefix=""):
    v = doc.get(key, default)
    if v is None:
        return None
    if not isinstance(v, int) or isinstance(v, bool) or v < minimum:
        raise config_error(prefix + key, f"{v!r}: expected an integer >= {minimum}", source)
    return v
