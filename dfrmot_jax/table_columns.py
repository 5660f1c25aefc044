"""The columns of a sweep's stored tables, as the sweep writes them and the report reads them.

Row keys: ``sequence`` (a sequence's name, or :data:`COMBINED` for the row combined over them),
``class`` (a class, or :data:`AVERAGE` for the class-average rows); the per-alpha HOTA fields
(:data:`RAW_COLUMN`); the configs' columns, those of the table's tracker family (every table is one
family's: :func:`table_family`): every parameter (:func:`param_names`, per class
``<class>.<parameter>``: :func:`class_columns`) and option (:func:`option_names`), the per-lane axes
beyond them with their defaults (:func:`extra_axes`: the LiDAR settings, :data:`LIDAR_AXES`, and
the distortion lanes, :data:`DISTORTION_AXES`) and the defaults of the settings added later
(:func:`late_options`, :func:`late_params`). The report's :class:`Contrast` of two groups of an
axis's values (``[report] contrast``, ``dfrmot report --contrast``; :func:`parse_contrast`).

Moved here from ``sweep.spec``, ``sweep.table`` and ``sweep.lidar_axes`` (which import them from
here) so that the report (:mod:`dfrmot_jax.report`) reads stored tables without importing JAX.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from .checks import Table, config_error, is_scalar, type_name
import numpy as np
import pandas as pd

from .trackers import protocol
from .trackers.protocol import DEFAULT_FAMILY, FamilyConfig
from .trackers.registry import family_config, family_names
from .lidar_settings import LIFT_SETTINGS, LiftSettings, SimSettings

__all__ = ["COMBINED", "RAW_COLUMN", "AVERAGE", "PARAM_NAMES", "OPTION_NAMES", "CLASSES", "INT_PARAMS",
           "LATE_OPTIONS", "LATE_PARAMS", "settings_of", "param_names", "option_names", "setting_names", "table_classes",
           "int_params", "late_options", "late_params", "table_family",
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

#: DFR-FastMOT's (the default family's) parameter and option columns, classes, integer parameters and
#: late settings, as every table written before tables named their family holds them; kept for the
#: public API (``dfrmot_jax.sweep.PARAM_NAMES`` ...). A table's own are its family's:
#: :func:`param_names`, :func:`option_names`, :func:`table_classes`, :func:`int_params`,
#: :func:`late_options`, :func:`late_params` of the family of the table (:func:`table_family`).
PARAM_NAMES: tuple[str, ...] = family_config().Params._fields
OPTION_NAMES: tuple[str, ...] = family_config().Options._fields
CLASSES: tuple[str, ...] = family_config().classes
INT_PARAMS = family_config().int_params
#: Options added after config hashes were first written -> their default (the family's
#: ``late_options``). At its default such an option is left out of the hash (a row without its column
#: has the default), so every earlier config keeps its hash and chunk ids; result rows written before
#: it existed get the default. DFR-FastMOT's: :func:`late_options` gives a family's.
LATE_OPTIONS: dict[str, Any] = dict(family_config().late_options)
#: Parameters added after config hashes were first written -> their default, kept likewise (DFR-FastMOT's;
#: :func:`late_params`).
LATE_PARAMS: dict[str, Any] = dict(family_config().late_params)

def settings_of(family: "str | FamilyConfig" = DEFAULT_FAMILY) -> FamilyConfig:
    """The settings (:class:`~dfrmot_jax.trackers.protocol.FamilyConfig`) of ``family``, a name (ValueError
    naming the registered ones when unknown) or the settings themselves."""
    return family if isinstance(family, FamilyConfig) else family_config(family)


def param_names(family: "str | FamilyConfig" = DEFAULT_FAMILY) -> tuple[str, ...]:
    """The parameter columns of a table of ``family`` (its ``Params`` fields, in order)."""
    return tuple(settings_of(family).Params._fields)


def option_names(family: "str | FamilyConfig" = DEFAULT_FAMILY) -> tuple[str, ...]:
    """The option columns of a table of ``family`` (its ``Options`` fields, in order)."""
    return tuple(settings_of(family).Options._fields)


def setting_names(family: "str | FamilyConfig" = DEFAULT_FAMILY) -> tuple[str, ...]:
    """Its parameter columns, then its option columns."""
    return param_names(family) + option_names(family)


def table_classes(family: "str | FamilyConfig" = DEFAULT_FAMILY) -> tuple[str, ...]:
    """The classes a table of ``family``'s per-class columns (``<class>.<parameter>``) may name."""
    return tuple(settings_of(family).classes)


def int_params(family: "str | FamilyConfig" = DEFAULT_FAMILY) -> frozenset:
    """The parameters of ``family`` that take integers."""
    return frozenset(settings_of(family).int_params)


def late_options(family: "str | FamilyConfig" = DEFAULT_FAMILY) -> dict[str, Any]:
    """The options of ``family`` added after its config hashes were first written -> their default."""
    return dict(settings_of(family).late_options)


def late_params(family: "str | FamilyConfig" = DEFAULT_FAMILY) -> dict[str, Any]:
    """The parameters of ``family`` added after its config hashes were first written -> their default."""
    return dict(settings_of(family).late_params)


def table_family(columns, family: "str | FamilyConfig | None" = None) -> FamilyConfig:
    """The settings of the family a table's columns are of: ``family`` when given (a stored sweep's
    manifest's ``family``, a sweep's ``SweepSpec.family``), else read from the ``columns`` (a table
    given bare): the registered family every one of whose parameters and options is a column, the
    default family first; the default family when none is."""
    if family is not None:
        return settings_of(family)
    cols = set(columns)
    for name in family_names():
        fc = family_config(name)
        if set(fc.Params._fields) <= cols and set(fc.Options._fields) <= cols:
            return fc
    return family_config()


def split_class_column(name: str, family: "str | FamilyConfig" = DEFAULT_FAMILY) -> tuple[str, str] | None:
    """``"pedestrian.a_l"`` -> ("pedestrian", "a_l"): a per-class column of a table of ``family``;
    None for any other column."""
    return protocol.split_class_column(name, settings_of(family))


def class_columns(columns, family: "str | FamilyConfig" = DEFAULT_FAMILY) -> list[str]:
    """The per-class parameter columns (``<class>.<parameter>``) of ``family`` among ``columns``, in their order."""
    return protocol.class_columns(columns, settings_of(family))


def param_key(name: str, v, family: "str | FamilyConfig" = DEFAULT_FAMILY):
    """The identity of a parameter's value, as ``sweep.table.config_hash`` hashes it: an integer
    parameter's int (of ``family``), any other's float32 value (its repr). Two values with one key
    are one setting."""
    return int(v) if name in settings_of(family).int_params else repr(float(np.float32(v)))


def canonical_params(df: pd.DataFrame, family: "str | FamilyConfig | None" = None) -> pd.DataFrame:
    """``df`` with one value per setting in each float parameter column (plain and per class): values
    one setting by :func:`param_key` (e.g. the C++'s float32 gain 0.89999997615814209 of a preset and
    a sweep file's 0.9, which hash alike) replaced by the most frequent of them (the first met on a
    tie), so that the report counts, ranks and draws them as one value. The same table when no column
    holds two values of one setting; the stored tables are not changed. ``family``: the table's (None:
    read from its columns, :func:`table_family`)."""
    fc = table_family(df.columns, family)
    out = df
    for col in [c for c in list(fc.Params._fields) + class_columns(df.columns, fc) if c in df.columns]:
        name = split_class_column(col, fc)[1] if split_class_column(col, fc) else col
        if name in fc.int_params or not pd.api.types.is_float_dtype(df[col]):
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


def parse_contrast(c, source, family: "str | FamilyConfig" = DEFAULT_FAMILY) -> Contrast | None:
    """The ``[report] contrast`` table ``c`` (None: none), its axes among ``family``'s parameters and options."""
    if c is None:
        return None
    names = setting_names(family)
    t = Table(c, "report.contrast", source, CONTRAST_KEYS)
    axis = t.get("axis")
    if axis not in names:
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
    if not isinstance(by, list) or any(b not in names or b == axis for b in by):
        raise t.error("by", f"{by!r}: expected a list of other parameter / option names")
    return Contrast(axis, groups[0], groups[1], tuple(by))


def contrast_doc(c: Contrast) -> dict:
    return {"axis": c.axis, "high": list(c.high), "low": list(c.low), "by": list(c.by)}
