"""The columns of a sweep's stored tables, as the sweep writes them and the report reads them.

Row keys: ``sequence`` (a sequence's name, or :data:`COMBINED` for the row combined over them),
``class`` (a class, or :data:`AVERAGE` for the class-average rows); the per-alpha HOTA fields
(:data:`RAW_COLUMN`); the configs' columns: every parameter (:data:`PARAM_NAMES`, per class
``<class>.<parameter>``: :func:`class_columns`) and option (:data:`OPTION_NAMES`), the per-lane axes
beyond them with their defaults (:func:`extra_axes`: the LiDAR settings, :data:`LIDAR_AXES`, and
the distortion lanes, :data:`DISTORTION_AXES`) and the defaults of the settings added later
(:data:`LATE_OPTIONS`, :data:`LATE_PARAMS`). The report's :class:`Contrast` of two groups of an
axis's values (``[report] contrast``, ``dfrmot report --contrast``; :func:`parse_contrast`).

Moved here from ``sweep.spec``, ``sweep.table`` and ``sweep.lidar_axes`` (which import them from
here) so that the report (:mod:`dfrmot_jax.report`) reads stored tables without importing JAX.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..checks import Table, config_error, is_scalar, type_name
import numpy as np
import pandas as pd

from ..family_configs import family_config
from ..lidar_settings import LIFT_SETTINGS, LiftSettings, SimSettings

__all__ = ["COMBINED", "RAW_COLUMN", "AVERAGE", "TABLE_FAMILY", "PARAM_NAMES", "OPTION_NAMES", "CLASSES", "INT_PARAMS",
           "LATE_OPTIONS", "LATE_PARAMS",
           "split_class_column", "class_columns", "SIM_INT", "CROP", "crop_text", "lift_value", "LIFT_COLUMNS",
           "SIM_COLUMNS", "LIDAR_AXES", "EXTRA_AXES", "DISTORTION_AXES", "extra_axes", "CONTRAST_KEYS", "Contrast",
           "parse_contrast", "contrast_doc", "param_key", "canonical_params"]

COMBINED = "COMBINED"
#: the per-alpha HOTA fields of a row (``RAW_FIELDS``, flattened, 7 x 19), so that any subset of
#: sequences can be re-combined exactly as TrackEval combines sequences (cross-validation).
RAW_COLUMN = "_hota_alpha"
#: The ``class`` of the class-average rows of a sweep over several classes (one per config,
#: ``sequence = COMBINED``) and the report's name for ranking on them.
AVERAGE = "average"

#: the family of the stored tables' configs: every table is one family's, and every table written so far
#: is DFR-FastMOT's (``family = "dfr"``, the default); its settings are the tables' parameter and option columns
TABLE_FAMILY = family_config()
PARAM_NAMES: tuple[str, ...] = TABLE_FAMILY.Params._fields
OPTION_NAMES: tuple[str, ...] = TABLE_FAMILY.Options._fields
#: the classes a table's per-class columns (``<class>.<parameter>``) may name
CLASSES: tuple[str, ...] = TABLE_FAMILY.classes
INT_PARAMS = TABLE_FAMILY.int_params
#: Options added after config hashes were first written -> their default (the family's
#: ``late_options``). At its default such an option is left out of the hash (a row without its column
#: has the default), so every earlier config keeps its hash and chunk ids; result rows written before
#: it existed get the default.
LATE_OPTIONS: dict[str, Any] = dict(TABLE_FAMILY.late_options)
#: Parameters added after config hashes were first written -> their default, kept likewise (the
#: family's ``late_params``).
LATE_PARAMS: dict[str, Any] = dict(TABLE_FAMILY.late_params)


def split_class_column(name: str) -> tuple[str, str] | None:
    """``"pedestrian.a_l"`` -> ("pedestrian", "a_l"); None for any other column."""
    if not isinstance(name, str) or "." not in name:
        return None
    cls, param = name.split(".", 1)
    return (cls, param) if cls in CLASSES and param in PARAM_NAMES else None


def class_columns(columns) -> list[str]:
    """The per-class parameter columns (``<class>.<parameter>``) among ``columns``, in their order."""
    return [c for c in columns if split_class_column(c) is not None]


def param_key(name: str, v):
    """The identity of a parameter's value, as ``sweep.table.config_hash`` hashes it: an integer
    parameter's int, any other's float32 value (its repr). Two values with one key are one setting."""
    return int(v) if name in INT_PARAMS else repr(float(np.float32(v)))


def canonical_params(df: pd.DataFrame) -> pd.DataFrame:
    """``df`` with one value per setting in each float parameter column (plain and per class): values
    one setting by :func:`param_key` (e.g. the C++'s float32 gain 0.89999997615814209 of a preset and
    a sweep file's 0.9, which hash alike) replaced by the most frequent of them (the first met on a
    tie), so that the report counts, ranks and draws them as one value. The same table when no column
    holds two values of one setting; the stored tables are not changed."""
    out = df
    for col in [c for c in list(PARAM_NAMES) + class_columns(df.columns) if c in df.columns]:
        name = split_class_column(col)[1] if split_class_column(col) else col
        if name in INT_PARAMS or not pd.api.types.is_float_dtype(df[col]):
            continue
        counts = df[col].value_counts(sort=False, dropna=True)          # in order of appearance
        if len(counts) < 2:
            continue
        keys = counts.index.to_numpy(np.float64).astype(np.float32)
        if len(np.unique(keys)) == len(keys):
            continue
        chosen: dict = {}
        for v, k, n in zip(counts.index, keys, counts.to_numpy()):
            if k not in chosen or n > chosen[k][1]:
                chosen[k] = (v, n)
        mapping = {v: chosen[k][0] for v, k in zip(counts.index, keys) if chosen[k][0] != v}
        if out is df:
            out = df.copy()
        out[col] = df[col].replace(mapping)
    return out


# ---------------------------------------------------------------------------------------------
# The per-lane axes beyond parameters and options

#: the simulation settings whose columns hold integers
SIM_INT = ("beams", "seed")
#: the lifting settings held as text (``"x,y,z"``: :func:`crop_text`)
CROP = ("crop_lo", "crop_hi")


def crop_text(v) -> str:
    """A crop corner as the table holds it: ``"x,y,z"`` (each the shortest text of its double)."""
    return ",".join(repr(float(x)) for x in v)


def lift_value(name: str, v):
    """A lifting setting's table value (crop corners as text, ``min_cluster`` int, others float)."""
    if name in CROP:
        return crop_text(v)
    return int(v) if name == "min_cluster" else float(v)


_LIFT_DEFAULTS = LiftSettings()
#: table column -> default value of every lifting setting (``lift.<name>``)
LIFT_COLUMNS: dict[str, Any] = {f"lift.{n}": lift_value(n, getattr(_LIFT_DEFAULTS, n)) for n in LIFT_SETTINGS}
#: table column -> default value of every simulation setting (``simulate.<name>``; the seed 0)
SIM_COLUMNS: dict[str, Any] = {f"simulate.{n}": (int(d) if n in SIM_INT else float(d))
                               for n, d in {**SimSettings()._asdict(), "seed": 0}.items()}
#: every LiDAR column of a config table -> its default (the sweep's extra axes)
LIDAR_AXES: dict[str, Any] = {**LIFT_COLUMNS, **SIM_COLUMNS}
#: Further per-lane axes (columns of the config table, part of the config hash): name -> default
#: value. A column equal to its default is left out of the hash, so adding an axis keeps existing
#: hashes. An axis kind (:class:`dfrmot_jax.sweep.axes.AxisKind`) registers its columns here (the
#: LiDAR settings of ``sweep.lidar_axes.LidarAxes``) or, the distortion axes, in ``DISTORTION_AXES``.
EXTRA_AXES: dict[str, Any] = {**LIDAR_AXES}
#: The per-lane distortion axes of a sweep with a [distortion] table (columns of its config table
#: and of every result row; part of the config hash when off their default): the kind (one of
#: ``distort.KINDS``; "none" = undistorted, level 0 of every kind), the level, the seed.
DISTORTION_AXES: dict[str, Any] = {"distortion.kind": "none", "distortion.level": 0.0, "distortion.seed": 0}


def extra_axes() -> dict[str, Any]:
    return {**DISTORTION_AXES, **EXTRA_AXES}


# ---------------------------------------------------------------------------------------------
# The report's contrast

CONTRAST_KEYS = ("axis", "high", "low", "by")


@dataclass(frozen=True)
class Contrast:
    """Two groups of values of one axis compared level by level (``robustness_contrast``), e.g.
    long memory (epsilon 30, 60) against short memory (epsilon 1, 2, 3), per value of ``by``."""

    axis: str
    high: tuple
    low: tuple
    by: tuple[str, ...] = ()


def parse_contrast(c, source) -> Contrast | None:
    if c is None:
        return None
    t = Table(c, "report.contrast", source, CONTRAST_KEYS)
    axis = t.get("axis")
    if axis not in PARAM_NAMES + OPTION_NAMES:
        raise t.error("axis", f"{axis!r}: expected a parameter or option name")
    groups = []
    for k in ("high", "low"):
        v = t.get(k)
        if v is None:
            raise t.error(k, "missing: the axis values of this group")
        items = [(f"{k}[{i}]", x) for i, x in enumerate(v)] if isinstance(v, list) else [(k, v)]
        if not items:
            raise t.error(k, "empty list")
        for key, x in items:
            if not is_scalar(x):
                raise t.error(key, f"{x!r}: expected a value of {axis}, got {type_name(x)}")
        groups.append(tuple(x for _, x in items))
    if set(groups[0]) & set(groups[1]):
        raise config_error("report.contrast", f"a value is in both groups: {sorted(set(groups[0]) & set(groups[1]), key=str)}",
                   source)
    by = t.get("by", [])
    by = [by] if isinstance(by, str) else by
    if not isinstance(by, list) or any(b not in PARAM_NAMES + OPTION_NAMES or b == axis for b in by):
        raise t.error("by", f"{by!r}: expected a list of other parameter / option names")
    return Contrast(axis, groups[0], groups[1], tuple(by))


def contrast_doc(c: Contrast) -> dict:
    return {"axis": c.axis, "high": list(c.high), "low": list(c.low), "by": list(c.by)}
