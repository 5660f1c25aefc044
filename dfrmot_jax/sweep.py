"""Declarative parameter sweeps: a TOML file -> a config table -> chunked, resumable, batched runs
(track + metrics in-process) -> one tidy ``pandas.DataFrame``; reports with honest cross-validation.

The pipeline::

    load_spec(FILE) ─▶ SweepSpec ─▶ expand() ─▶ config table (one row per config: every parameter,
        every static option, config_hash; with a [distortion] table also the per-lane columns
        distortion.kind, distortion.level, distortion.seed: configs x levels x seeds)
    plan() ─▶ groups of rows with equal static Options (one compilation each) ─▶ chunks of
        ``chunk`` configs; chunk id = hash(data settings + the chunk's config hashes
        [+ the distortion settings])
    run ─▶ per chunk: dfrmot_jax.track (one [B] batch; distortion lanes vmapped with the parameter
        lanes, one DistortSpec per option group) ─▶ metrics on the padded arrays (prepared
        ground truth reused, identical tracker outputs scored once) ─▶ DIR/chunks/<id>.parquet
        written atomically (tmp file + os.replace); a rerun skips chunks whose file exists
    table ─▶ one row per (config, sequence) + one ``COMBINED`` row per config
    several classes (data.class = ["car", "pedestrian"]) ─▶ every config run per class, each class
        on its own split (its chunks, its compilation); per-class axes ``pedestrian.a_l`` are
        columns of the config table (in config_hash only where they differ from the plain value);
        rows carry ``class``, plus one class-average row per config (class "average")
    report() ─▶ best configs by an objective, the baseline beside them, sensitivity per axis,
        k-fold cross-validation over sequences (best chosen on training folds, scored held out);
        with distortion: the objective per level and kind (mean ± SE over seeds) per setting, and
        an optional contrast of two groups of an axis (e.g. long vs short memory) paired by seed

See ``sweeps/README.md`` for the file format. Python use::

    import dfrmot_jax as dm
    df = dm.sweep("sweeps/kitti_dfr_grid.toml", out="results/grid")     # or a dict spec
    rep = dm.sweep_report(df, objective="HOTA", folds=5); print(rep.text)
    rep = dm.sweep_report(df, cls="pedestrian")          # several classes: one class or "average"
    from dfrmot_jax.sweep import robustness_contrast, robustness_curves     # distortion sweeps
    curves = robustness_curves(df, ("HOTA", "AssA", "IDSW"))                # per setting, kind, level
    gaps = robustness_contrast(df, "epsilon", high=[30, 60], low=[1, 2, 3], by=["filter"])
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import multiprocessing as mp
import os
import sys
import time
import tomllib
import warnings
from collections import deque
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
import pandas as pd

from . import distort
from .config import CLASSES, INT_PARAMS, PRESETS, Options, Params, option_problem, param_problem, preset

__all__ = [
    "SweepConfigError", "SweepSpec", "DataSettings", "Axis", "load_spec", "parse_spec", "expand", "config_hash",
    "resolve_data", "plan", "sweep", "load_results", "sweep_report", "SweepReport", "cross_validate",
    "make_folds", "sensitivity", "combine_sequences", "PARAM_NAMES", "OPTION_NAMES", "EXTRA_AXES",
    "OBJECTIVES", "MINIMISE", "DISTORTION_AXES", "DistortionAxes", "robustness_curves", "robustness_contrast",
    "robustness_summary", "Contrast", "n_settings", "setting_axes", "resolve_data_all", "class_view",
    "class_columns", "AVERAGE",
]

PARAM_NAMES: tuple[str, ...] = Params._fields
OPTION_NAMES: tuple[str, ...] = Options._fields
#: Further per-lane axes (columns of the config table, part of the config hash): name -> default
#: value. A column equal to its default is left out of the hash, so adding an axis keeps existing
#: hashes. The distortion axes are registered separately (``DISTORTION_AXES``).
EXTRA_AXES: dict[str, Any] = {}
#: The per-lane distortion axes of a sweep with a [distortion] table (columns of its config table
#: and of every result row; part of the config hash when off their default): the kind (one of
#: ``distort.KINDS``; "none" = undistorted, level 0 of every kind), the level, the seed.
DISTORTION_AXES: dict[str, Any] = {"distortion.kind": "none", "distortion.level": 0.0, "distortion.seed": 0}
DISTORTION_KEYS = ("kind", "level", "levels", "seeds", "clutter_slots", "burst_dist", "burst_max", "burst_rate",
                   "burst_len")
#: Kinds whose level is a probability (<= 1).
PROBABILITY_KINDS = ("drop", "drop_2d", "drop_3d", "burst_rate")
CONTRAST_KEYS = ("axis", "high", "low", "by")


def _extra_axes() -> dict[str, Any]:
    return {**DISTORTION_AXES, **EXTRA_AXES}

GRID_KINDS = ("grid", "linspace", "logspace")
RANDOM_KINDS = ("uniform", "loguniform", "randint", "choice")
#: Objectives the report knows by name (any metric column works); these are minimised.
MINIMISE = frozenset({"IDSW", "Frag", "ML", "CLR_FN", "CLR_FP", "IDFN", "IDFP", "PT", "MLR", "FP_per_frame"})
OBJECTIVES = ("HOTA", "MOTA", "IDF1", "AssA", "DetA", "IDSW")

COMBINED = "COMBINED"
RAW_COLUMN = "_hota_alpha"
#: per-alpha HOTA fields kept (flattened, 7 x 19) in ``RAW_COLUMN`` so that any subset of sequences
#: can be re-combined exactly as TrackEval combines sequences (cross-validation).
RAW_FIELDS = ("HOTA_TP", "HOTA_FN", "HOTA_FP", "AssA", "AssRe", "AssPr", "LocA")
TOP_KEYS = ("name", "description", "chunk", "seed", "samples", "data", "baseline", "params", "options", "variants",
            "distortion", "report")
DATA_KEYS = ("root", "det2d", "det3d", "class", "sequences")
BASELINE_KEYS = ("preset", "class")
REPORT_KEYS = ("objective", "folds", "top", "contrast", "class")
#: The ``class`` of the class-average rows of a sweep over several classes (one per config,
#: ``sequence = COMBINED``) and the report's name for ranking on them.
AVERAGE = "average"
VARIANT_KEYS = ("name", "params", "options")


class SweepConfigError(ValueError):
    """A bad sweep file: ``key`` is the offending key path (``params.a_c``, ``data.det2d``, ...)."""

    def __init__(self, key: str, message: str, source: str | None = None):
        self.key = key
        self.message = message
        self.source = source
        super().__init__(f"{source + ': ' if source else ''}{key}: {message}")


# ---------------------------------------------------------------------------------------------
# The sweep file


@dataclass(frozen=True)
class Axis:
    """One swept name: ``kind`` 'grid' (``values`` crossed with the other grid axes) or a random
    distribution 'uniform' | 'loguniform' | 'randint' (``values`` = (low, high)) | 'choice'.

    ``cls``: a per-class parameter axis (``[params] pedestrian.a_l = [...]``): ``name`` is then
    ``"pedestrian.a_l"`` (its column in the config table) and the axis moves that class only."""

    name: str
    kind: str
    values: tuple
    key: str
    cls: str | None = None

    @property
    def is_grid(self) -> bool:
        return self.kind == "grid"

    @property
    def param(self) -> str:
        """The parameter or option name (without the class)."""
        return self.name.split(".", 1)[1] if self.cls else self.name


@dataclass(frozen=True)
class Variant:
    name: str
    params: tuple[Axis, ...]
    options: tuple[Axis, ...]


@dataclass(frozen=True)
class DataSettings:
    """Resolved data settings of a sweep (part of every chunk's identity)."""

    root: str
    det2d: str
    det3d: str
    cls: str
    sequences: tuple[str, ...]
    lengths: tuple[int, ...] = ()

    def identity(self) -> dict:
        return {"root": self.root, "det2d": self.det2d, "det3d": self.det3d, "class": self.cls,
                "sequences": list(self.sequences)}


@dataclass(frozen=True)
class DistortionAxes:
    """The resolved [distortion] table: per-lane axes crossed with every config of the sweep.

    ``kinds``: ((kind, levels), ...) in file order (levels ascending, distinct, 0 included when
    listed); ``seeds``: the seeds of every nonzero level. Level 0 is the identity for every kind
    and seed: its lane is the undistorted config (kind "none", seed 0: the same ``config_hash`` as
    without distortion) and starts every kind's curve. ``clutter_slots``, ``burst_dist`` and
    ``burst_max`` are the static ``DistortSpec`` fields; ``burst_rate`` is the start rate of kind
    "burst" (whose level is the mean length) and ``burst_len`` the mean length of kind
    "burst_rate" (whose level is the start rate).
    """

    kinds: tuple[tuple[str, tuple[float, ...]], ...]
    seeds: tuple[int, ...]
    clutter_slots: int = 0
    burst_dist: str = "fixed"
    burst_max: int = 30
    burst_rate: float = distort.BURST_RATE
    burst_len: float = distort.BURST_LEN

    def lane(self, kind: str, level: float, seed: int) -> distort.DistortParams:
        """The ``DistortParams`` of one lane (kind "none" / level 0: all zero)."""
        if kind == "none" or float(level) == 0.0:
            return distort.level_params("none", 0.0, seed=0)
        kw = {}
        if kind == "burst":
            kw["burst_rate"] = self.burst_rate
        elif kind == "burst_rate":
            kw["burst_len"] = self.burst_len
        return distort.level_params(kind, float(level), seed=int(seed), **kw)

    def hash_extra(self, kind: str) -> dict:
        """Settings off the module's defaults that change a lane of ``kind`` (part of its hash)."""
        if kind == "none":
            return {}
        out = {}
        if kind == "burst" and self.burst_rate != distort.BURST_RATE:
            out["burst_rate"] = repr(float(self.burst_rate))
        if kind == "burst_rate" and self.burst_len != distort.BURST_LEN:
            out["burst_len"] = repr(float(self.burst_len))
        if kind in ("burst", "burst_rate"):
            if self.burst_dist != "fixed":
                out["burst_dist"] = self.burst_dist
            if self.burst_max != 30:
                out["burst_max"] = int(self.burst_max)
        if kind.startswith("clutter"):
            out["clutter_slots"] = int(self.clutter_slots)
        return out

    def identity(self) -> dict:
        """The settings that can change any result (part of every chunk's identity)."""
        return {"clutter_slots": int(self.clutter_slots), "burst_dist": self.burst_dist,
                "burst_max": int(self.burst_max), "burst_rate": float(self.burst_rate),
                "burst_len": float(self.burst_len)}

    def make_spec(self, options: Options, frames=None, dps=None) -> distort.DistortSpec:
        return distort.make_spec(options, clutter_slots=self.clutter_slots, burst_max=self.burst_max,
                                 burst_dist=self.burst_dist, frames=frames, dps=dps)

    @property
    def n_lanes(self) -> int:
        """Lanes per config (level 0 counted once)."""
        zero = any(0.0 in lv for _, lv in self.kinds)
        return int(zero) + sum(sum(1 for v in lv if v != 0.0) for _, lv in self.kinds) * len(self.seeds)


@dataclass(frozen=True)
class Contrast:
    """Two groups of values of one axis compared level by level (``robustness_contrast``), e.g.
    long memory (epsilon 30, 60) against short memory (epsilon 1, 2, 3), per value of ``by``."""

    axis: str
    high: tuple
    low: tuple
    by: tuple[str, ...] = ()


@dataclass(frozen=True)
class SweepSpec:
    """A parsed sweep file. ``data_root`` None = ``$DFRMOT_DATA`` / the default root.

    ``classes``: the classes every config is run for (``data.class``, a name or a list; ``cls``
    is the first). The baseline of class ``k`` is ``params.preset(baseline, baseline_class or k)``.
    """

    def __post_init__(self):
        if not self.classes:
            object.__setattr__(self, "classes", (self.cls,))

    name: str
    description: str = ""
    chunk: int = 64
    seed: int = 0
    samples: int = 1
    data_root: str | None = None
    det2d: str = "rrc"
    det3d: str = "pointrcnn"
    cls: str = "car"
    sequences: tuple[str, ...] | None = None
    baseline: str = "dfr2023"
    variants: tuple[Variant, ...] = ()
    classes: tuple[str, ...] = ()               # data.class as a tuple (``cls`` is the first); () = (cls,)
    baseline_class: str | None = None           # [baseline] class: every class's baseline is preset(baseline, it)
    report_class: str | None = None             # report.class: a class or "average" (None: see report_class_of)
    objective: str = "HOTA"
    folds: int | None = None
    top: int = 10
    distortion: DistortionAxes | None = None
    contrast: Contrast | None = None
    source: str | None = None
    raw: Mapping | None = field(default=None, compare=False, repr=False)


def load_spec(path) -> SweepSpec:
    """Read and validate a sweep TOML file (see ``sweeps/README.md``)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"sweep file {path} not found")
    try:
        with open(path, "rb") as f:
            doc = tomllib.load(f)
    except tomllib.TOMLDecodeError as e:
        raise SweepConfigError("(file)", f"not valid TOML: {e}", str(path)) from None
    return parse_spec(doc, source=str(path))


def _err(key, msg, source):
    return SweepConfigError(key, msg, source)


def _check_keys(d: Mapping, allowed: Sequence[str], prefix: str, source) -> None:
    if not isinstance(d, Mapping):
        raise _err(prefix.rstrip("."), f"expected a table, got {type(d).__name__}", source)
    for k in d:
        if k not in allowed:
            raise _err(f"{prefix}{k}", f"unknown key; expected one of {list(allowed)}", source)


def _is_number(v) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))


def _clean_float(v: float) -> float:
    """Round a computed grid value to 12 significant digits (0.6000000000000001 -> 0.6)."""
    return float(f"{float(v):.12g}")


def _check_param_value(name: str, v, key: str, source) -> int | float:
    problem = param_problem(name, v)
    if problem:
        raise _err(key, f"{v!r}: parameter {name}: {problem}", source)
    return int(round(float(v))) if name in INT_PARAMS else float(v)


def _param_axis(name: str, spec, key: str, source) -> Axis:
    if name not in PARAM_NAMES:
        hint = " (a static option: put it under [options])" if name in OPTION_NAMES else ""
        raise _err(key, f"unknown parameter{hint}; parameters are {list(PARAM_NAMES)}", source)
    if isinstance(spec, Mapping):
        if len(spec) != 1:
            raise _err(key, f"a distribution table has exactly one key among {list(GRID_KINDS + RANDOM_KINDS)}, "
                            f"got {sorted(spec)}", source)
        kind, arg = next(iter(spec.items()))
        k2 = f"{key}.{kind}"
        if kind not in GRID_KINDS + RANDOM_KINDS:
            raise _err(k2, f"unknown distribution; expected one of {list(GRID_KINDS + RANDOM_KINDS)}", source)
        if not isinstance(arg, list):
            raise _err(k2, f"expected a list, got {arg!r}", source)
        if kind in ("grid", "choice"):
            if not arg:
                raise _err(k2, "empty list: nothing to sweep", source)
            vals = tuple(_check_param_value(name, v, f"{k2}[{i}]", source) for i, v in enumerate(arg))
            return Axis(name, "grid" if kind == "grid" else "choice", vals, key)
        if kind in ("linspace", "logspace"):
            if len(arg) != 3 or not all(_is_number(a) for a in arg) or isinstance(arg[2], float) and \
                    not float(arg[2]).is_integer():
                raise _err(k2, f"expected [low, high, count], got {arg!r}", source)
            lo, hi, n = float(arg[0]), float(arg[1]), int(arg[2])
            if n < 1:
                raise _err(k2, f"count {n} < 1: empty grid", source)
            _check_param_value(name, lo, k2, source)
            _check_param_value(name, hi, k2, source) if name not in INT_PARAMS else None
            if kind == "logspace":
                if lo <= 0 or hi <= 0:
                    raise _err(k2, f"logspace needs positive ends, got {arg!r}", source)
                raw = np.geomspace(lo, hi, n)
            else:
                raw = np.linspace(lo, hi, n)
            if name in INT_PARAMS:
                rounded = np.round(raw)
                if np.any(np.abs(raw - rounded) > 1e-9):
                    raise _err(k2, f"gives non-integer values {raw.tolist()} for integer parameter {name}", source)
                raw = rounded
            vals = tuple(dict.fromkeys(_check_param_value(name, _clean_float(v), k2, source) for v in raw))
            return Axis(name, "grid", vals, key)
        # uniform / loguniform / randint: [low, high]
        if len(arg) != 2 or not all(_is_number(a) for a in arg):
            raise _err(k2, f"expected [low, high], got {arg!r}", source)
        lo, hi = arg
        if not float(lo) < float(hi):
            raise _err(k2, f"low {lo!r} must be below high {hi!r}", source)
        if kind == "randint":
            if not all(float(a).is_integer() for a in arg):
                raise _err(k2, f"randint takes integers, got {arg!r}", source)
            lo, hi = int(lo), int(hi)
            _check_param_value(name, lo, k2, source)
            _check_param_value(name, hi - 1, k2, source)
            return Axis(name, kind, (lo, hi), key)
        if name in INT_PARAMS:
            raise _err(k2, f"parameter {name} takes integers: use randint", source)
        if kind == "loguniform" and float(lo) <= 0:
            raise _err(k2, f"loguniform needs low > 0, got {lo!r}", source)
        _check_param_value(name, lo, k2, source)
        _check_param_value(name, hi, k2, source)
        return Axis(name, kind, (float(lo), float(hi)), key)
    if isinstance(spec, list):
        if not spec:
            raise _err(key, "empty list: nothing to sweep", source)
        vals = tuple(_check_param_value(name, v, f"{key}[{i}]", source) for i, v in enumerate(spec))
        return Axis(name, "grid", vals, key)
    return Axis(name, "grid", (_check_param_value(name, spec, key, source),), key)


def _check_option_value(name: str, v, key: str, source):
    problem = option_problem(name, v)
    if problem:
        raise _err(key, f"{v!r}: {problem}", source)
    return v


def _option_axis(name: str, spec, key: str, source) -> Axis:
    if name not in OPTION_NAMES:
        hint = " (a dynamic parameter: put it under [params])" if name in PARAM_NAMES else ""
        raise _err(key, f"unknown option{hint}; options are {list(OPTION_NAMES)}", source)
    if isinstance(spec, Mapping):
        if list(spec) != ["grid"]:
            raise _err(key, "static options take a value, a list or {grid = [...]} (each value is its own "
                            "compilation; random distributions are for parameters)", source)
        spec = spec["grid"]
        key = f"{key}.grid"
    vals = spec if isinstance(spec, list) else [spec]
    if not vals:
        raise _err(key, "empty list: nothing to sweep", source)
    vals = tuple(dict.fromkeys(_check_option_value(name, v, f"{key}[{i}]" if isinstance(spec, list) else key, source)
                               for i, v in enumerate(vals)))
    return Axis(name, "grid", vals, key)


def _class_axis(cls: str, name: str, spec, key: str, source, classes: Sequence[str]) -> Axis:
    """A per-class parameter axis ``<cls>.<name>`` (``key`` names it in errors)."""
    if cls not in CLASSES:
        raise _err(key.rsplit(".", 1)[0] if "." in key else key,
                   f"{cls!r} is neither a parameter nor a class; parameters are {list(PARAM_NAMES)}, "
                   f"classes {list(CLASSES)} (per-class axes: <class>.<parameter>)", source)
    if cls not in classes:
        raise _err(key, f"class {cls!r} is not swept (data.class = {list(classes)})", source)
    if name in OPTION_NAMES and name not in PARAM_NAMES:
        raise _err(key, "static options apply to every class; per-class axes are for parameters", source)
    axis = _param_axis(name, spec, key, source)
    return replace(axis, name=f"{cls}.{name}", cls=cls)


def _axes(table, kind: str, prefix: str, source, classes: Sequence[str] = ("car",)) -> tuple[Axis, ...]:
    if table is None:
        return ()
    if not isinstance(table, Mapping):
        raise _err(prefix, f"expected a table, got {type(table).__name__}", source)
    if kind != "params":
        for k in table:
            if k in CLASSES or "." in k:
                raise _err(f"{prefix}.{k}", "static options apply to every class: per-class axes "
                                            "(<class>.<name>) are for [params]", source)
        return tuple(_option_axis(k, v, f"{prefix}.{k}", source) for k, v in table.items())
    out = []
    for k, v in table.items():
        if "." in k:                                   # a quoted key "pedestrian.a_l"
            cls, name = k.split(".", 1)
            out.append(_class_axis(cls, name, v, f"{prefix}.{k}", source, classes))
        elif k not in PARAM_NAMES and k not in OPTION_NAMES and isinstance(v, Mapping) and \
                not set(v) & set(GRID_KINDS + RANDOM_KINDS):      # pedestrian.a_l = ... / [params.pedestrian]
            if k not in CLASSES:
                raise _err(f"{prefix}.{k}", f"unknown parameter or class; parameters are {list(PARAM_NAMES)}, "
                                            f"classes {list(CLASSES)} (per-class axes: <class>.<parameter>)",
                           source)
            for name, spec in v.items():
                out.append(_class_axis(k, name, spec, f"{prefix}.{k}.{name}", source, classes))
        else:
            out.append(_param_axis(k, v, f"{prefix}.{k}", source))
    return tuple(out)


def _positive_int(doc, key, default, source, minimum=1, prefix=""):
    v = doc.get(key, default)
    if v is None:
        return None
    if not isinstance(v, int) or isinstance(v, bool) or v < minimum:
        raise _err(prefix + key, f"{v!r}: expected an integer >= {minimum}", source)
    return v


def _parse_sequences(v, key, source) -> tuple[str, ...] | None:
    if v is None or v == "all":
        return None
    if isinstance(v, str):
        v = [s for s in v.split(",") if s.strip()]
    if not isinstance(v, list) or not v:
        raise _err(key, f"expected \"all\", a list of sequence names or a comma-separated string, got {v!r}", source)
    out = []
    for s in v:
        if isinstance(s, bool) or not isinstance(s, (int, str)):
            raise _err(key, f"{s!r} is not a sequence name", source)
        out.append(f"{s:04d}" if isinstance(s, int) else s.strip().zfill(4))
    if len(set(out)) != len(out):
        raise _err(key, "a sequence is listed twice", source)
    return tuple(out)


def _level_values(spec, key: str, source) -> list:
    """Levels given as a number, a list, or {grid | linspace | logspace = [...]} (unchecked numbers)."""
    if isinstance(spec, Mapping):
        if len(spec) != 1 or next(iter(spec)) not in GRID_KINDS:
            raise _err(key, f"levels are a number, a list or one of {{{', '.join(GRID_KINDS)} = [...]}}, got "
                            f"{dict(spec)!r}", source)
        kind, arg = next(iter(spec.items()))
        key = f"{key}.{kind}"
        if not isinstance(arg, list):
            raise _err(key, f"expected a list, got {arg!r}", source)
        if kind == "grid":
            spec = arg
        else:
            if len(arg) != 3 or not all(_is_number(a) for a in arg) or not float(arg[2]).is_integer() or arg[2] < 1:
                raise _err(key, f"expected [low, high, count >= 1], got {arg!r}", source)
            lo, hi, n = float(arg[0]), float(arg[1]), int(arg[2])
            if kind == "logspace" and (lo <= 0 or hi <= 0):
                raise _err(key, f"logspace needs positive ends, got {arg!r}", source)
            raw = np.geomspace(lo, hi, n) if kind == "logspace" else np.linspace(lo, hi, n)
            return [(key, _clean_float(v)) for v in raw]
    if isinstance(spec, list):
        if not spec:
            raise _err(key, "empty list: nothing to sweep", source)
        return [(f"{key}[{i}]", v) for i, v in enumerate(spec)]
    return [(key, spec)]


def _check_level(kind: str, v, key: str, source, clutter_slots: int, burst_max: int) -> float:
    if not _is_number(v):
        raise _err(key, f"{v!r} is not a number", source)
    v = float(v)
    if not math.isfinite(v):
        raise _err(key, f"{v!r} is not finite", source)
    if v < 0:
        raise _err(key, f"level {v:g} < 0: levels are >= 0 (0 = undistorted)", source)
    if kind in PROBABILITY_KINDS and v > 1:
        raise _err(key, f"level {v:g} of kind {kind!r} is a probability: expected <= 1", source)
    if kind == "burst" and v > burst_max:
        raise _err(key, f"mean burst length {v:g} > burst_max = {burst_max} (lengths are capped at burst_max; "
                        f"raise distortion.burst_max)", source)
    if kind.startswith("clutter") and v > 0 and v > clutter_slots:
        raise _err(key, f"{v:g} false positives per frame need distortion.clutter_slots >= {math.ceil(v)} "
                        f"(clutter_slots = {clutter_slots})", source)
    return v


def _parse_distortion(d, source) -> DistortionAxes | None:
    if d is None:
        return None
    _check_keys(d, DISTORTION_KEYS, "distortion.", source)
    kinds_doc = d.get("kind")
    levels_doc = d.get("levels")
    if levels_doc is not None and not isinstance(levels_doc, Mapping):
        raise _err("distortion.levels", f"expected a table kind = [levels], got {levels_doc!r}", source)
    if kinds_doc is None:
        if not levels_doc:
            raise _err("distortion.kind", "missing: the distortion kind(s) to sweep, e.g. kind = [\"drop\", "
                                          "\"burst\"]", source)
        kinds = [(f"distortion.levels.{k}", k) for k in levels_doc]
    else:
        if isinstance(kinds_doc, str):
            kinds = [("distortion.kind", kinds_doc)]
        elif isinstance(kinds_doc, list) and kinds_doc:
            kinds = [(f"distortion.kind[{i}]", k) for i, k in enumerate(kinds_doc)]
        else:
            raise _err("distortion.kind", f"{kinds_doc!r}: expected a kind or a non-empty list of kinds", source)
    known = tuple(k for k in distort.KINDS if k != "none")
    for key, k in kinds:
        if not isinstance(k, str) or k not in known:
            hint = " (level 0 of every kind is the undistorted run: add 0 to the levels)" if k == "none" else ""
            raise _err(key, f"unknown distortion kind {k!r}{hint}; expected one of {list(known)}", source)
    if len({k for _, k in kinds}) != len(kinds):
        raise _err("distortion.kind", "a kind is listed twice", source)
    if levels_doc:
        for k in levels_doc:
            if k not in {kk for _, kk in kinds}:
                raise _err(f"distortion.levels.{k}", f"kind {k!r} is not in distortion.kind "
                                                     f"{[kk for _, kk in kinds]}", source)
    clutter_slots = _positive_int(d, "clutter_slots", 0, source, minimum=0, prefix="distortion.")
    burst_max = _positive_int(d, "burst_max", 30, source, prefix="distortion.")
    burst_dist = d.get("burst_dist", "fixed")
    if burst_dist not in distort.BURST_DISTS:
        raise _err("distortion.burst_dist", f"{burst_dist!r}: expected one of {list(distort.BURST_DISTS)}", source)
    burst_rate = d.get("burst_rate", distort.BURST_RATE)
    if not _is_number(burst_rate) or not 0 < float(burst_rate) <= 1:
        raise _err("distortion.burst_rate", f"{burst_rate!r}: the burst start rate of kind \"burst\" is a "
                                            f"probability in (0, 1]", source)
    burst_len = d.get("burst_len", distort.BURST_LEN)
    if not _is_number(burst_len) or not 0 < float(burst_len) <= (burst_max if any(k == "burst_rate" for _, k in kinds)
                                                                 else math.inf):
        raise _err("distortion.burst_len", f"{burst_len!r}: the mean burst length of kind \"burst_rate\" is in "
                                           f"(0, burst_max = {burst_max}]", source)
    out = []
    for _, k in kinds:
        if levels_doc and k in levels_doc:
            raw = _level_values(levels_doc[k], f"distortion.levels.{k}", source)
        elif "level" in d:
            raw = _level_values(d["level"], "distortion.level", source)
        else:
            raise _err("distortion.levels", f"no levels for kind {k!r}: give distortion.level = [...] or "
                                            f"distortion.levels.{k} = [...]", source)
        vals = [_check_level(k, v, key, source, clutter_slots, burst_max) for key, v in raw]
        out.append((k, tuple(sorted(dict.fromkeys(vals)))))
    seeds_doc = d.get("seeds", 1)
    if isinstance(seeds_doc, list):
        if not seeds_doc:
            raise _err("distortion.seeds", "empty list: give a count (seeds = 10) or a list of seeds", source)
        for i, v in enumerate(seeds_doc):
            if not isinstance(v, int) or isinstance(v, bool) or not 0 <= v < 2 ** 31:
                raise _err(f"distortion.seeds[{i}]", f"{v!r}: a seed is an integer in [0, 2**31)", source)
        if len(set(seeds_doc)) != len(seeds_doc):
            raise _err("distortion.seeds", "a seed is listed twice", source)
        seeds = tuple(int(v) for v in seeds_doc)
    elif isinstance(seeds_doc, int) and not isinstance(seeds_doc, bool):
        if seeds_doc < 1:
            raise _err("distortion.seeds", f"{seeds_doc!r}: expected a count >= 1 (seeds 0 .. n-1) or a list of seeds",
                       source)
        seeds = tuple(range(seeds_doc))
    else:
        raise _err("distortion.seeds", f"{seeds_doc!r}: expected a count >= 1 or a list of seeds", source)
    axes = DistortionAxes(tuple(out), seeds, clutter_slots=int(clutter_slots), burst_dist=burst_dist,
                          burst_max=int(burst_max), burst_rate=float(burst_rate), burst_len=float(burst_len))
    try:        # the distortion module's own checks on every lane (belt and braces)
        dps = distort.stack_distort([axes.lane(k, v, s) for k, lv in axes.kinds for v in lv for s in seeds[:1]])
        distort.check_params(dps, axes.make_spec(Options(), dps=dps))
    except ValueError as e:
        raise _err("distortion", str(e), source) from None
    return axes


def _parse_contrast(c, source) -> Contrast | None:
    if c is None:
        return None
    _check_keys(c, CONTRAST_KEYS, "report.contrast.", source)
    axis = c.get("axis")
    if axis not in PARAM_NAMES + OPTION_NAMES:
        raise _err("report.contrast.axis", f"{axis!r}: expected a parameter or option name", source)
    groups = []
    for k in ("high", "low"):
        v = c.get(k)
        if v is None:
            raise _err(f"report.contrast.{k}", "missing: the axis values of this group", source)
        v = v if isinstance(v, list) else [v]
        if not v:
            raise _err(f"report.contrast.{k}", "empty list", source)
        groups.append(tuple(v))
    if set(groups[0]) & set(groups[1]):
        raise _err("report.contrast", f"a value is in both groups: {sorted(set(groups[0]) & set(groups[1]), key=str)}",
                   source)
    by = c.get("by", [])
    by = [by] if isinstance(by, str) else by
    if not isinstance(by, list) or any(b not in PARAM_NAMES + OPTION_NAMES or b == axis for b in by):
        raise _err("report.contrast.by", f"{by!r}: expected a list of other parameter / option names", source)
    return Contrast(axis, groups[0], groups[1], tuple(by))


def _parse_classes(v, source) -> tuple[str, ...]:
    """``data.class``: a class name or a non-empty list of distinct class names."""
    if isinstance(v, str):
        items = [("data.class", v)]
    elif isinstance(v, list) and v:
        items = [(f"data.class[{i}]", c) for i, c in enumerate(v)]
    else:
        raise _err("data.class", f"{v!r}: expected a class name or a non-empty list of classes {list(CLASSES)}",
                   source)
    for key, c in items:
        if c not in CLASSES:
            raise _err(key, f"{c!r} is not one of {list(CLASSES)}", source)
    out = tuple(c for _, c in items)
    if len(set(out)) != len(out):
        raise _err("data.class", "a class is listed twice", source)
    return out


def parse_spec(doc: Mapping, source: str | None = None) -> SweepSpec:
    """Validate a sweep given as a dict (the parsed TOML); raises :class:`SweepConfigError`."""
    _check_keys(doc, TOP_KEYS, "", source)
    name = doc.get("name", Path(source).stem if source else "sweep")
    if not isinstance(name, str) or not name:
        raise _err("name", f"{name!r}: expected a non-empty string", source)
    desc = doc.get("description", "")
    chunk = _positive_int(doc, "chunk", 64, source)
    samples = _positive_int(doc, "samples", 1, source)
    seed = _positive_int(doc, "seed", 0, source, minimum=0)

    data = doc.get("data", {})
    _check_keys(data, DATA_KEYS, "data.", source)
    for k in ("root", "det2d", "det3d"):
        if k in data and (not isinstance(data[k], str) or not data[k]):
            raise _err(f"data.{k}", f"{data[k]!r}: expected a non-empty string", source)
    classes = _parse_classes(data.get("class", "car"), source)
    cls = classes[0]
    root = data.get("root")
    if root is not None and source is not None and not Path(root).expanduser().is_absolute():
        root = str((Path(source).parent / Path(root).expanduser()).resolve())
    sequences = _parse_sequences(data.get("sequences"), "data.sequences", source)

    base = doc.get("baseline", "dfr2023")
    base_cls = None
    if isinstance(base, Mapping):
        _check_keys(base, BASELINE_KEYS, "baseline.", source)
        base_cls = base.get("class")
        if base_cls is not None and base_cls not in CLASSES:
            raise _err("baseline.class", f"{base_cls!r}: expected one of {list(CLASSES)} (every class's "
                                         f"baseline is the preset as tuned for this class)", source)
        base = base.get("preset", "dfr2023")
        bkey = "baseline.preset"
    else:
        bkey = "baseline"
    if base not in PRESETS:
        raise _err(bkey, f"unknown preset {base!r}; expected one of {sorted(PRESETS)}", source)

    params = _axes(doc.get("params"), "params", "params", source, classes)
    options = _axes(doc.get("options"), "options", "options", source)
    variants_doc = doc.get("variants")
    variants = []
    if variants_doc is None:
        variants.append(Variant("grid", params, options))
    else:
        if not isinstance(variants_doc, list) or not variants_doc:
            raise _err("variants", "expected a non-empty array of tables ([[variants]])", source)
        for i, v in enumerate(variants_doc):
            _check_keys(v, VARIANT_KEYS, f"variants[{i}].", source)
            vp = _axes(v.get("params"), "params", f"variants[{i}].params", source, classes)
            vo = _axes(v.get("options"), "options", f"variants[{i}].options", source)
            over_p = {a.name for a in vp}
            over_o = {a.name for a in vo}
            variants.append(Variant(str(v.get("name", f"variant{i}")),
                                    tuple(a for a in params if a.name not in over_p) + vp,
                                    tuple(a for a in options if a.name not in over_o) + vo))

    rep = doc.get("report", {})
    _check_keys(rep, REPORT_KEYS, "report.", source)
    objective = rep.get("objective", "HOTA")
    if not isinstance(objective, str):
        raise _err("report.objective", f"{objective!r}: expected a metric name", source)
    folds = _positive_int(rep, "folds", None, source, minimum=2)
    top = _positive_int(rep, "top", 10, source)
    contrast = _parse_contrast(rep.get("contrast"), source)
    report_class = rep.get("class")
    if report_class is not None and report_class not in classes + (AVERAGE,):
        raise _err("report.class", f"{report_class!r}: expected one of the sweep's classes {list(classes)} or "
                                   f"{AVERAGE!r}", source)
    distortion = _parse_distortion(doc.get("distortion"), source)

    spec = SweepSpec(name=name, description=str(desc), chunk=chunk, seed=seed, samples=samples, data_root=root,
                     det2d=data.get("det2d", "rrc"), det3d=data.get("det3d", "pointrcnn"), cls=cls,
                     sequences=sequences, baseline=base, variants=tuple(variants), objective=objective,
                     folds=folds, top=top, distortion=distortion, contrast=contrast, source=source,
                     raw=dict(doc), classes=classes, baseline_class=base_cls, report_class=report_class)
    for v in spec.variants:
        if samples > 1 and all(a.is_grid for a in v.params):
            raise _err("samples", f"samples = {samples} repeats the grid with random parameters redrawn, but "
                                  f"variant {v.name!r} has no random parameter (uniform, loguniform, randint, "
                                  f"choice): every config would repeat", source)
    return spec


def _as_spec(spec) -> SweepSpec:
    if isinstance(spec, SweepSpec):
        return spec
    if isinstance(spec, Mapping):
        return parse_spec(spec)
    return load_spec(spec)


# ---------------------------------------------------------------------------------------------
# The config table


def _canon(name: str, v):
    """Canonical value for hashing: parameters as the tracker sees them (float32 / int32)."""
    if name in PARAM_NAMES:
        return int(v) if name in INT_PARAMS else repr(float(np.float32(v)))
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    return str(v)


def _split_class_column(name: str) -> tuple[str, str] | None:
    """``"pedestrian.a_l"`` -> ("pedestrian", "a_l"); None for any other column."""
    if not isinstance(name, str) or "." not in name:
        return None
    cls, param = name.split(".", 1)
    return (cls, param) if cls in CLASSES and param in PARAM_NAMES else None


def class_columns(columns) -> list[str]:
    """The per-class parameter columns (``<class>.<parameter>``) among ``columns``, in their order."""
    return [c for c in columns if _split_class_column(c) is not None]


def _class_extra(row: Mapping[str, Any]) -> dict:
    """{class: {parameter: canonical value}} of the row's class columns that differ from its plain ones."""
    out: dict[str, dict] = {}
    for col in row:
        cp = _split_class_column(col)
        if cp is None:
            continue
        cls, p = cp
        v = _canon(p, row[col])
        if v != _canon(p, row[p]):
            out.setdefault(cls, {})[p] = v
    return out


def config_hash(row: Mapping[str, Any], settings: Mapping[str, Any] | None = None) -> str:
    """Stable 16-hex-digit hash of a config: every parameter and option (+ extra axes off their
    default, such as the distortion axes; + ``settings``, sweep-wide values off their defaults that
    change this row, e.g. a distortion lane's burst start rate; + a sweep over several classes' per-class
    values, columns ``<class>.<parameter>``, where they differ from the plain column: a row without
    such a difference hashes exactly as before)."""
    key = {"params": {n: _canon(n, row[n]) for n in PARAM_NAMES},
           "options": {n: _canon(n, row[n]) for n in OPTION_NAMES}}
    extra = {n: _canon(n, row[n]) for n, d in _extra_axes().items() if n in row and row[n] != d}
    if settings:
        extra["settings"] = dict(settings)
    classes = _class_extra(row)
    if classes:
        extra["classes"] = classes
    if extra:
        key["extra"] = extra
    text = json.dumps(key, sort_keys=True, separators=(",", ":"))
    return hashlib.sha1(text.encode()).hexdigest()[:16]


def _draw(axis: Axis, rng: np.random.Generator, n: int) -> list:
    lo_hi = axis.values
    if axis.kind == "uniform":
        return [float(v) for v in rng.uniform(lo_hi[0], lo_hi[1], n)]
    if axis.kind == "loguniform":
        return [float(v) for v in np.exp(rng.uniform(np.log(lo_hi[0]), np.log(lo_hi[1]), n))]
    if axis.kind == "randint":
        return [int(v) for v in rng.integers(lo_hi[0], lo_hi[1], n)]
    if axis.kind == "choice":
        return [axis.values[i] for i in rng.integers(0, len(axis.values), n)]
    raise AssertionError(axis.kind)


def expand(spec) -> pd.DataFrame:
    """The config table of a sweep: one row per config, the baseline first.

    Columns: ``config`` (row number), ``config_hash``, ``variant``, ``baseline`` (bool), every
    parameter (``PARAM_NAMES``) and option (``OPTION_NAMES``). Grid axes are crossed (the first axis
    slowest; parameters, then options); random axes (uniform, loguniform, randint, choice) are drawn
    per config from ``numpy.random.default_rng(seed)``; ``samples`` repeats each variant's grid with
    the random axes redrawn (Ray Tune's ``num_samples``). Configs that hash alike are kept once.

    With a [distortion] table every config (the baseline too) is crossed with the distortion lanes,
    innermost (kind, then level, then seed), adding the columns ``DISTORTION_AXES``
    (``distortion.kind``, ``distortion.level``, ``distortion.seed``). Level 0 is the identity for
    every kind and seed: it is one lane per config, the undistorted one (kind "none", level 0, seed
    0: the same hash as the config without distortion). Without [distortion] the table is as before
    (no distortion columns).
    """
    spec = _as_spec(spec)
    src = spec.source
    single = len(spec.classes) == 1
    base_row, class_base = _baseline_rows(spec)
    # per-class columns: class defaults off the plain baseline, and every per-class axis
    explicit = [a.name for v in spec.variants for a in v.params if a.cls] if not single else []
    derived = [f"{k}.{p}" for k, b in class_base.items() for p in PARAM_NAMES
               if _canon(p, b[p]) != _canon(p, base_row[p])]
    ccols = [f"{k}.{p}" for k in spec.classes for p in PARAM_NAMES if f"{k}.{p}" in set(explicit + derived)]
    rng = np.random.default_rng(spec.seed)
    first = {**base_row, **{c: class_base[_split_class_column(c)[0]][_split_class_column(c)[1]] for c in ccols}}
    rows: list[dict] = [{"variant": "baseline", "baseline": True, **first}]
    for v in spec.variants:
        grid_axes = [a for a in v.params if a.is_grid] + list(v.options)
        rand_axes = [a for a in v.params if not a.is_grid]
        plain_set = {a.name for a in v.params if not a.cls}
        combos = list(itertools.product(*(a.values for a in grid_axes)))
        n = len(combos) * spec.samples
        draws = {a.name: _draw(a, rng, n) for a in rand_axes}
        i = 0
        for _ in range(spec.samples):
            for combo in combos:
                vals = {a.name: val for a, val in zip(grid_axes, combo)}
                vals.update({name: d[i] for name, d in draws.items()})
                row = {"variant": v.name, "baseline": False, **base_row}
                row.update({k: x for k, x in vals.items() if _split_class_column(k) is None})
                if single:           # the one class's per-class axes are its parameters
                    row.update({_split_class_column(k)[1]: x for k, x in vals.items()
                                if _split_class_column(k) is not None})
                for c in ccols:      # precedence: per-class axis > plain axis > the class's baseline
                    k, p = _split_class_column(c)
                    row[c] = vals[c] if c in vals else row[p] if p in plain_set else class_base[k][p]
                rows.append(row)
                i += 1
    table = pd.DataFrame(rows, columns=["variant", "baseline"] + list(PARAM_NAMES) + ccols + list(OPTION_NAMES))
    for c in ccols:          # a class default that no row moves off the plain value says nothing
        k, p = _split_class_column(c)
        if c not in explicit and all(_canon(p, x) == _canon(p, y) for x, y in zip(table[c], table[p])):
            table = table.drop(columns=[c])
    for n in list(PARAM_NAMES) + class_columns(table.columns):
        t = _split_class_column(n)[1] if _split_class_column(n) else n
        table[n] = table[n].astype("int64" if t in INT_PARAMS else "float64")
    for n in OPTION_NAMES:
        d = Options._field_defaults[n]
        table[n] = table[n].astype(bool if isinstance(d, bool) else "int64" if isinstance(d, int) else object)
    hashes = [config_hash(r) for r in table.to_dict("records")]
    table.insert(0, "config_hash", hashes)
    table = table.drop_duplicates("config_hash", keep="first").reset_index(drop=True)
    if spec.distortion is not None:
        table = _cross_distortion(table, spec.distortion)
    table.insert(0, "config", np.arange(len(table), dtype=np.int64))
    if len(table) < 2:
        raise _err("params", "the sweep has no config besides the baseline: add parameters or options to sweep",
                   src)
    for kl in ["keep_lost"] + [c for c in class_columns(table.columns) if c.endswith(".keep_lost")]:
        bad = table[(table[kl] > 0) & (table["output"] == "detections")]
        if not len(bad):
            continue
        r = bad.iloc[0]
        raise _err(f"params.{kl}", f"{kl} = {r[kl]} writes lost tracks' predicted boxes and needs "
                                       f"output = \"filtered\" (variant {r['variant']!r} pairs it with output = "
                                       f"\"detections\"); use [[variants]] to give keep_lost its own output", src)
    return table


def _baseline_rows(spec: SweepSpec) -> tuple[dict, dict[str, dict]]:
    """(the plain baseline row: parameters and options, {class: its baseline parameters}).

    One class: the plain row is ``preset(baseline, baseline_class or the class)`` and there are no
    per-class values. Several: the plain row is the bare preset (``PRESETS[baseline]``; with
    ``[baseline] class``, ``preset(baseline, that class)``), and class ``k``'s baseline is
    ``preset(baseline, baseline_class or k)``."""
    if len(spec.classes) == 1:
        p, o = preset(spec.baseline, spec.baseline_class or spec.classes[0])
        return {**p._asdict(), **o._asdict()}, {}
    p, o = preset(spec.baseline, spec.baseline_class) if spec.baseline_class else PRESETS[spec.baseline]
    per = {k: preset(spec.baseline, spec.baseline_class or k)[0]._asdict() for k in spec.classes}
    return {**p._asdict(), **o._asdict()}, per


def _cross_distortion(table: pd.DataFrame, dist: DistortionAxes) -> pd.DataFrame:
    """Every config x the distortion lanes (level 0 once, undistorted), hashes recomputed."""
    lanes: list[tuple[str, float, int]] = []
    if any(0.0 in lv for _, lv in dist.kinds):
        lanes.append(("none", 0.0, 0))
    for kind, levels in dist.kinds:
        lanes.extend((kind, float(v), int(s)) for v in levels if v != 0.0 for s in dist.seeds)
    base = table.drop(columns=["config_hash"]).to_dict("records")
    rows = []
    for i, r in enumerate(base):
        own = lanes if i > 0 or ("none", 0.0, 0) in lanes else [("none", 0.0, 0)] + lanes   # the baseline row stays
        for kind, level, seed in own:
            rows.append({**r, "baseline": bool(r["baseline"]) and kind == "none",
                         "distortion.kind": kind, "distortion.level": level, "distortion.seed": seed})
    out = pd.DataFrame(rows, columns=list(table.columns.drop("config_hash")) + list(DISTORTION_AXES))
    for c in table.columns.drop("config_hash"):
        out[c] = out[c].astype(table[c].dtype)
    out["distortion.kind"] = out["distortion.kind"].astype(object)
    out["distortion.level"] = out["distortion.level"].astype("float64")
    out["distortion.seed"] = out["distortion.seed"].astype("int64")
    hashes = [config_hash(r, dist.hash_extra(r["distortion.kind"])) for r in out.to_dict("records")]
    out.insert(0, "config_hash", hashes)
    return out.drop_duplicates("config_hash", keep="first").reset_index(drop=True)


def resolve_data_all(spec, data_root=None) -> tuple[DataSettings, ...]:
    """The data settings of every class of the sweep (``data.class`` order), each checked before any
    work: each class has its own split (the sequences whose ground truth has the class, or
    ``data.sequences``)."""
    spec = _as_spec(spec)
    return tuple(resolve_data(spec, data_root, cls=c) for c in spec.classes)


def resolve_data(spec, data_root=None, cls: str | None = None) -> DataSettings:
    """Resolve and check the data settings (root, detectors, class, sequences) before any work.

    ``cls``: which of the sweep's classes (default: the first; :func:`resolve_data_all` gives all)."""
    from .data import detection_dir, sequences_with_class
    from .io.kitti import KittiFormatError, sequence_lengths
    from .paths import default_data_root

    spec = _as_spec(spec)
    if cls is not None:
        if cls not in spec.classes:
            raise ValueError(f"class {cls!r} is not one of the sweep's classes {list(spec.classes)}")
        spec = replace(spec, cls=cls)
    src = spec.source
    root = Path(data_root if data_root is not None else (spec.data_root or default_data_root())).expanduser()
    if not (root / "label_02").is_dir():
        raise _err("data.root", f"{root} has no label_02/ (the KITTI tracking training root; set it in the "
                                f"sweep file, with --data, or with $DFRMOT_DATA)", src)
    root = root.resolve()
    for key, det in (("data.det2d", spec.det2d), ("data.det3d", spec.det3d)):
        try:
            detection_dir(root, det, spec.cls)
        except KittiFormatError as e:
            raise _err(key, e.message, src) from None
    if spec.sequences is None:
        seqs = tuple(sequences_with_class(root, spec.cls))
        if not seqs:
            raise _err("data.sequences", f"no sequence under {root / 'label_02'} has class {spec.cls}", src)
    else:
        missing = [s for s in spec.sequences if not (root / "label_02" / f"{s}.txt").is_file()]
        if missing:
            raise _err("data.sequences", f"no ground truth for {missing} under {root / 'label_02'}", src)
        seqs = spec.sequences
    lengths = sequence_lengths(root, list(seqs))
    return DataSettings(str(root), str(spec.det2d), str(spec.det3d), spec.cls, tuple(seqs),
                        tuple(int(lengths[s]) for s in seqs))


@dataclass(frozen=True)
class Chunk:
    id: str
    group: int
    options: Options
    configs: tuple[int, ...]
    cls: str = "car"


def _row_options(row: Mapping) -> Options:
    return Options(**{n: type(Options._field_defaults[n])(row[n]) for n in OPTION_NAMES})


def _groups(table: pd.DataFrame) -> dict[Options, list[int]]:
    """Config rows by static options, in first-appearance order."""
    groups: dict[Options, list[int]] = {}
    for row in table[["config"] + list(OPTION_NAMES)].to_dict("records"):
        groups.setdefault(_row_options(row), []).append(int(row["config"]))
    return groups


def plan(table: pd.DataFrame, data: DataSettings | Sequence[DataSettings], chunk: int,
         distortion: DistortionAxes | None = None) -> list[Chunk]:
    """Group the configs by static options (first appearance order), cut each group into chunks.

    A chunk's id hashes the data settings (its class's), its config hashes and (distortion sweeps)
    the distortion settings (``DistortionAxes.identity``). ``data``: one class's settings or, for a
    sweep over several classes, every class's (:func:`resolve_data_all`): the chunks of each class
    in turn, every config in every class."""
    if not isinstance(data, DataSettings):
        return [c for d in data for c in plan(table, d, chunk, distortion)]
    groups = _groups(table)
    hashes = table["config_hash"].to_numpy()
    ident = data.identity()
    out = []
    for g, (opts, idx) in enumerate(groups.items()):
        for a in range(0, len(idx), chunk):
            part = tuple(idx[a:a + chunk])
            doc = {"data": ident, "configs": [hashes[i] for i in part]}
            if distortion is not None:
                doc["distortion"] = distortion.identity()
            text = json.dumps(doc, sort_keys=True)
            out.append(Chunk(hashlib.sha1(text.encode()).hexdigest()[:20], g, opts, part, data.cls))
    return out


# ---------------------------------------------------------------------------------------------
# Metrics of a chunk


def _metric_fields():
    from .metrics import clear, hota, identity
    from .metrics.table import COUNT_FIELDS, TABLE_FIELDS

    return hota, clear, identity, TABLE_FIELDS, COUNT_FIELDS


def summary_columns(seq: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """TrackEval fields (arrays [..., 19] or [...]) -> the summary columns of ``metrics_table``
    (HOTA family: mean over alphas x100; other ratios x100; counts int64), vectorised."""
    hota, _, _, table_fields, count_fields = _metric_fields()
    out = {}
    for f in table_fields:
        if f not in seq:
            continue
        v = np.asarray(seq[f])
        if f in count_fields:
            out[f] = np.rint(v.astype(np.float64)).astype(np.int64)
        elif f in hota.FLOAT_ARRAY_FIELDS:
            out[f] = 100.0 * np.mean(v.astype(np.float64), axis=-1)
        else:
            out[f] = 100.0 * v.astype(np.float64)
    for f in ("CLR_Frames",):
        if f in seq:
            out[f] = np.rint(np.asarray(seq[f], np.float64)).astype(np.int64)
    if "MOTP_sum" in seq:
        out["MOTP_sum"] = np.asarray(seq["MOTP_sum"], np.float64)
    return out


def _raw_stack(seq: Mapping[str, np.ndarray]) -> np.ndarray:
    """[..., 7 * 19] the per-alpha fields needed to re-combine sequences."""
    return np.concatenate([np.asarray(seq[f], np.float64) for f in RAW_FIELDS], axis=-1)


def combine_sequences(seq_rows: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """TrackEval's ``combine_sequences`` over axis 1 of per-sequence fields [C, S(, 19)] -> fields [C(, 19)].

    ``seq_rows`` holds ``RAW_FIELDS`` (per alpha), CLEAR's summed fields, Identity's and the counts.
    """
    hota, clear, identity, _, _ = _metric_fields()
    h = hota.hota_combine({f: seq_rows[f] for f in RAW_FIELDS})
    c = clear.clear_combine({f: seq_rows[f] for f in clear.SUMMED_FIELDS})
    i = identity.identity_combine({f: seq_rows[f] for f in identity.INTEGER_FIELDS})
    out = {**h, **c, **i}
    for f in ("Dets", "GT_Dets", "IDs", "GT_IDs"):
        if f in seq_rows:
            out[f] = seq_rows[f].sum(axis=1)
    return out


class _Evaluator:
    """Scores chunks of tracker output: ground truth prepared once; identical outputs scored once."""

    def __init__(self, gt, offsets, lanes_per_batch: int = 16):
        self.gt = gt
        self.offsets = np.asarray(offsets, np.int64)
        self.lanes_per_batch = lanes_per_batch
        self.memo: dict[bytes, tuple[dict, dict]] = {}

    @staticmethod
    def digests(ids: np.ndarray, boxes: np.ndarray) -> list[bytes]:
        out = []
        for b in range(ids.shape[0]):
            h = hashlib.sha1(np.ascontiguousarray(ids[b]).tobytes())
            if boxes.ndim == 4:
                h.update(np.ascontiguousarray(boxes[b][ids[b] >= 0]).tobytes())
            out.append(h.digest())
        return out

    def dets(self, ids, boxes, lanes):
        from .metrics.kitti import tracker_dets_from_arrays

        lanes = np.asarray(lanes, np.int64)
        bx = boxes[lanes] if boxes.ndim == 4 else np.broadcast_to(boxes, (len(lanes),) + boxes.shape)
        return tracker_dets_from_arrays(self.gt, ids[lanes], bx, self.offsets)


def _evaluate_dets(gt, dets, lanes_per_batch: int) -> dict:
    """evaluate_batch over sub-batches of lanes; returns {'seq': {f: [L, S(, 19)]}, 'comb': {f: [L(, 19)]}}."""
    from .metrics import evaluate_batch

    outs = []
    for a in range(0, dets.n_lanes, lanes_per_batch):
        outs.append(evaluate_batch(gt, _lanes(dets, a, min(a + lanes_per_batch, dets.n_lanes))))
    return {p: {f: np.concatenate([o[p][f] for o in outs], axis=0) for f in outs[0][p]} for p in ("seq", "comb")}


def _lanes(dets, a: int, b: int):
    """Lanes a..b-1 of flattened tracker output (rows are sorted by lane)."""
    i, j = np.searchsorted(dets.lane, [a, b], side="left")
    return dets._replace(n_lanes=b - a, lane=dets.lane[i:j] - a, frame=dets.frame[i:j],
                         track_id=dets.track_id[i:j], box=dets.box[i:j], source=dets.source[i:j],
                         paths=dets.paths[a:b] if dets.paths else dets.paths)


_WORKER_GT = None


def _worker_init(gt) -> None:
    global _WORKER_GT
    _WORKER_GT = gt


def _worker_eval(dets, lanes_per_batch: int) -> dict:
    return _evaluate_dets(_WORKER_GT, dets, lanes_per_batch)


# ---------------------------------------------------------------------------------------------
# Running a sweep


def _versions() -> tuple[str, str]:
    import jax

    from . import __version__

    return __version__, jax.__version__


def _params_of(table: pd.DataFrame, rows: Sequence[int], cls: str | None = None) -> Params:
    """The parameters of table rows for class ``cls`` (its ``<cls>.<parameter>`` columns where the
    table has them, else the plain ones)."""
    from .config import as_arrays

    sub = table.iloc[list(rows)]
    return as_arrays(Params(**{n: sub[f"{cls}.{n}" if f"{cls}.{n}" in sub.columns else n].to_numpy()
                               for n in PARAM_NAMES}))


def _chunk_frame(table, chunk: Chunk, data: DataSettings, seq_names, lengths, metrics: dict, res, versions,
                 spec_name: str) -> pd.DataFrame:
    """The tidy rows of one chunk: per config, one row per sequence then COMBINED."""
    L = len(chunk.configs)
    S = len(seq_names)
    R = S + 1
    sub = table.iloc[list(chunk.configs)].reset_index(drop=True)
    cols: dict[str, Any] = {}
    cols["config"] = np.repeat(sub["config"].to_numpy(), R)
    cols["config_hash"] = np.repeat(sub["config_hash"].to_numpy(), R)
    cols["sequence"] = np.tile(np.array(list(seq_names) + [COMBINED], dtype=object), L)
    for c in ["variant", "baseline"] + list(PARAM_NAMES) + class_columns(sub.columns) + list(OPTION_NAMES) + \
            [n for n in _extra_axes() if n in sub.columns]:
        cols[c] = np.repeat(sub[c].to_numpy(), R)
    seq_sum = summary_columns(metrics["seq"])
    comb_sum = summary_columns(metrics["comb"])
    for f, sv in seq_sum.items():
        cols[f] = np.concatenate([sv, comb_sum[f][:, None]], axis=1).reshape(-1)
    # robustness: counts
    frames = np.array(list(lengths) + [int(np.sum(lengths))], np.int64)
    cols["frames"] = np.tile(frames, L)
    offs = np.concatenate([[0], np.cumsum(lengths)])
    cs = np.concatenate([np.zeros((L, 1), np.int64), np.cumsum(res.dropped.astype(np.int64), axis=1)], axis=1)
    per_seq = cs[:, offs[1:]] - cs[:, offs[:-1]]
    cols["overflow"] = np.concatenate([per_seq, res.overflow.astype(np.int64)[:, None]], axis=1).reshape(-1)
    cols["peak_tracks"] = np.repeat(res.peak.astype(np.int64), R)
    cols["det2d"] = np.repeat(np.array([data.det2d], dtype=object), L * R)
    cols["det3d"] = np.repeat(np.array([data.det3d], dtype=object), L * R)
    cols["class"] = np.repeat(np.array([data.cls], dtype=object), L * R)
    cols["sweep"] = np.repeat(np.array([spec_name], dtype=object), L * R)
    cols["chunk"] = np.repeat(np.array([chunk.id], dtype=object), L * R)
    cols["dfrmot_jax_version"] = np.repeat(np.array([versions[0]], dtype=object), L * R)
    cols["jax_version"] = np.repeat(np.array([versions[1]], dtype=object), L * R)
    raw = np.concatenate([_raw_stack(metrics["seq"]), _raw_stack(metrics["comb"])[:, None, :]], axis=1)
    cols[RAW_COLUMN] = list(raw.reshape(L * R, -1))
    return pd.DataFrame(cols)


def _atomic_parquet(df: pd.DataFrame, path: Path) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    df.to_parquet(tmp, index=False)
    os.replace(tmp, path)


def _atomic_text(text: str, path: Path) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def _chunk_path(out: Path, chunk: Chunk) -> Path:
    return out / "chunks" / f"{chunk.id}.parquet"


def _finish(df: pd.DataFrame, classes: Sequence[str] = ()) -> pd.DataFrame:
    """Rows by config (within a config: classes in order, each its sequences then COMBINED); with
    several classes, each config's class-average row last (:func:`_average_rows`)."""
    df = df[df["class"] != AVERAGE] if "class" in df.columns else df
    classes = list(classes) or list(pd.unique(df["class"])) if "class" in df.columns else []
    if len(classes) > 1:
        df = pd.concat([df, _average_rows(df, classes)], ignore_index=True)
        order = {c: i for i, c in enumerate(list(classes) + [AVERAGE])}
        key = df["class"].map(order).to_numpy()
        df = df.iloc[np.lexsort((np.arange(len(df)), key, df["config"].to_numpy()))]
    else:
        df = df.sort_values("config", kind="mergesort")
    return df.reset_index(drop=True)


def _metric_combiner(col: str) -> str | None:
    """How the class average treats a metric column: "sum" (counts), "mean" (ratios) or None."""
    from .metrics.evaluate import CLASS_AVERAGED_FIELDS, CLASS_SUMMED_FIELDS

    if col in CLASS_SUMMED_FIELDS:
        return "sum"
    if col in CLASS_AVERAGED_FIELDS:
        return "mean"
    return None


def _class_average_columns(per_class: Sequence[Mapping[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """The class average of summary columns (arrays [C] per class, x100 ratios): TrackEval's
    ``combine_classes_class_averaged`` as :func:`dfrmot_jax.metrics.evaluate.class_average` does it
    (``CLASS_SUMMED_FIELDS`` summed, ``CLASS_AVERAGED_FIELDS`` averaged), vectorised over configs.
    A summary column is a linear function of its field (a ratio x100, HOTA's the mean over alphas),
    so averaging the columns equals the summary of the averaged fields."""
    out = {}
    for f in per_class[0]:
        how = _metric_combiner(f)
        if how is None or not all(f in p for p in per_class):
            continue
        stack = np.stack([np.asarray(p[f]) for p in per_class])
        out[f] = stack.sum(axis=0) if how == "sum" else stack.astype(np.float64).mean(axis=0)
    return out


def _average_rows(df: pd.DataFrame, classes: Sequence[str]) -> pd.DataFrame:
    """One ``class = "average"``, ``sequence = COMBINED`` row per config that has every class's
    COMBINED row: metric columns the class average (:func:`_class_average_columns`), ``frames``
    and ``overflow`` summed, ``peak_tracks`` the largest, ``chunk`` empty, the per-alpha column
    the class average of its fields; the config's other columns as in its rows."""
    comb = df[df["sequence"] == COMBINED]
    parts = [comb[comb["class"] == c].set_index("config") for c in classes]
    configs = parts[0].index
    for p in parts[1:]:
        configs = configs.intersection(p.index, sort=False)
    if not len(configs):
        return df.iloc[:0]
    parts = [p.loc[configs] for p in parts]
    out = parts[0].copy()
    metrics = _class_average_columns([{c: p[c].to_numpy() for c in p.columns if _metric_combiner(c)}
                                      for p in parts])
    for f, v in metrics.items():
        out[f] = v.astype(out[f].dtype) if np.issubdtype(out[f].dtype, np.integer) else v
    for f, how in (("frames", "sum"), ("overflow", "sum"), ("peak_tracks", "max")):
        if f in out.columns:
            stack = np.stack([p[f].to_numpy() for p in parts])
            out[f] = stack.sum(axis=0) if how == "sum" else stack.max(axis=0)
    if RAW_COLUMN in out.columns:
        raws = np.stack([np.stack(p[RAW_COLUMN].to_numpy()) for p in parts])      # [K, C, 7 * 19]
        raws = raws.reshape(raws.shape[:2] + (len(RAW_FIELDS), -1))
        avg = np.stack([raws[:, :, i].sum(axis=0) if _metric_combiner(f) == "sum" else raws[:, :, i].mean(axis=0)
                        for i, f in enumerate(RAW_FIELDS)], axis=1)
        out[RAW_COLUMN] = list(avg.reshape(len(configs), -1))
    out["class"] = AVERAGE
    if "chunk" in out.columns:
        out["chunk"] = ""
    return out.reset_index()[df.columns]


@dataclass
class _Pending:
    chunk: Chunk
    res: Any
    digests: list
    todo: list          # unique lanes to score (index into the chunk)
    future: Any = None
    result: Any = None


def sweep(spec, out=None, *, data_root=None, chunk: int | None = None, folds: int | None = None,
          progress: bool = True, workers: int | None = None, log=None, raw: bool = True) -> pd.DataFrame:
    """Run a sweep (TOML path, dict or :class:`SweepSpec`) and return its tidy table.

    One row per (config, sequence) and one ``COMBINED`` row per config, with every parameter and
    option, the metrics (TrackEval summary names, as ``dfrmot eval``), overflow counts, versions and
    ``config_hash``. ``out``: a directory; each finished chunk is written there as Parquet and a
    rerun skips finished chunks (resume); ``results.parquet`` holds the final table. Without
    ``out`` nothing is written. ``data_root`` / ``chunk`` override the file; ``folds`` is stored for
    the report (``sweep_report``); ``workers``: metric processes running beside the tracker
    (default: 2 for large sweeps, 0 = in-process); ``raw=False`` drops the per-alpha column
    ``_hota_alpha`` (needed for cross-validation).
    Bad files fail before any work with a :class:`SweepConfigError` naming the key.

    Several classes (``data.class = ["car", "pedestrian"]``): every config is run for every class,
    each on its own split; rows carry their ``class``, and each config gets one more row, ``class =
    "average"``, ``sequence = COMBINED``: the class average (TrackEval's / KITTI's: ratios averaged
    over the classes, counts summed; :func:`dfrmot_jax.metrics.evaluate.class_average`).
    """
    spec = _as_spec(spec)
    if chunk is not None:
        if chunk < 1:
            raise SweepConfigError("chunk", f"{chunk}: expected an integer >= 1", spec.source)
        spec = replace(spec, chunk=int(chunk))
    if folds is not None:
        spec = replace(spec, folds=int(folds))
    log = log if log is not None else (lambda msg: print(msg, file=sys.stderr, flush=True))
    table = expand(spec)
    datas = resolve_data_all(spec, data_root)
    data = datas[0]
    n_seq = min(len(d.sequences) for d in datas)
    if spec.folds is not None and not 2 <= spec.folds <= n_seq:
        raise SweepConfigError("folds", f"{spec.folds}: expected 2 .. {n_seq} (the sequences"
                               + (" of the class with the fewest)" if len(datas) > 1 else ")"), spec.source)
    chunks = plan(table, datas, spec.chunk, spec.distortion)
    outdir = Path(out) if out is not None else None
    if outdir is not None:
        (outdir / "chunks").mkdir(parents=True, exist_ok=True)
        manifest = {"name": spec.name, "description": spec.description, "source": spec.source,
                    "data": data.identity(), "lengths": list(data.lengths), "baseline": spec.baseline,
                    "chunk": spec.chunk, "objective": spec.objective, "folds": spec.folds, "top": spec.top,
                    "configs": len(table), "chunks": [c.id for c in chunks], "spec": _jsonable(spec.raw)}
        if len(datas) > 1:
            manifest["classes"] = list(spec.classes)
            manifest["class_data"] = {d.cls: {**d.identity(), "lengths": list(d.lengths)} for d in datas}
        if spec.baseline_class is not None:
            manifest["baseline_class"] = spec.baseline_class
        if spec.report_class is not None:
            manifest["report_class"] = spec.report_class
        if spec.distortion is not None:
            manifest["distortion"] = {"kinds": {k: list(v) for k, v in spec.distortion.kinds},
                                      "seeds": list(spec.distortion.seeds), **spec.distortion.identity()}
        if spec.contrast is not None:
            manifest["contrast"] = _contrast_doc(spec.contrast)
        _atomic_text(json.dumps(manifest, indent=1), outdir / "manifest.json")
        _atomic_parquet(table, outdir / "configs.parquet")
    done = {c.id for c in chunks if outdir is not None and _chunk_path(outdir, c).is_file()}
    frames_out: dict[str, pd.DataFrame] = {}
    for d in datas:
        cchunks = [c for c in chunks if c.cls == d.cls]
        todo = [c for c in cchunks if c.id not in done]
        n_done = sum(len(c.configs) for c in cchunks if c.id in done)
        total_cf = len(table) * sum(d.lengths)
        n_groups = len({c.group for c in cchunks})
        lanes = ""
        if spec.distortion is not None:
            n_set = n_settings(table)
            lanes = (f" = {n_set:,} settings x {spec.distortion.n_lanes} distortion lanes (kinds "
                     f"{', '.join(k for k, _ in spec.distortion.kinds)}; {len(spec.distortion.seeds)} seeds)")
        name = spec.name if len(datas) == 1 else f"{spec.name} [{d.cls}]"
        log(f"sweep {name}: {len(table):,} configs{lanes} ({n_groups} option group(s), {len(cchunks)} chunks of <= "
            f"{spec.chunk}; {sum(c.id in done for c in cchunks)} done) x {len(d.sequences)} sequences / "
            f"{sum(d.lengths):,} frames = {total_cf / 1e6:.1f} M config-frames" + (f" -> {outdir}" if outdir else ""))
        if todo:
            _run_chunks(spec, table, d, todo, outdir, frames_out, n_done, len(table), progress, workers, log)
    if outdir is None:
        df = pd.concat([frames_out[c.id] for c in chunks], ignore_index=True)
    else:
        df = pd.concat([pd.read_parquet(_chunk_path(outdir, c)) for c in chunks], ignore_index=True)
    df = _finish(df, spec.classes)
    if outdir is not None:
        _atomic_parquet(df, outdir / "results.parquet")
    if not raw:
        df = df.drop(columns=[RAW_COLUMN])
    return df


def _jsonable(obj):
    try:
        return json.loads(json.dumps(obj, default=str))
    except (TypeError, ValueError):
        return None


def _capacity_hint(peak: int) -> int:
    """Track slots for a chunk whose group peaked at ``peak`` live tracks so far: 25 % + 4 headroom,
    a multiple of 8."""
    return max(16, int(math.ceil((1.25 * peak + 4) / 8.0)) * 8)


#: lanes per compiled tracker call (the batch is split over the host devices)
TRACK_CHUNK = 32


def _run_chunks(spec, table, data, todo, outdir, frames_out, n_done, n_total, progress, workers, log):
    from .api import default_capacity, track
    from .data import load_split, prepare_frames
    from .metrics import cached_gt

    t0 = time.perf_counter()
    label = spec.name if len(spec.classes) == 1 else f"{spec.name} [{data.cls}]"
    split = load_split(data.root, data.det2d, data.det3d, data.cls, list(data.sequences))
    gt = cached_gt(data.root, data.cls, list(data.sequences))
    if tuple(gt.sequences) != tuple(split.names) or not np.array_equal(gt.lengths, split.lengths):
        raise RuntimeError("ground truth and detections disagree on the sequences or their lengths")
    versions = _versions()
    ev = _Evaluator(gt, split.offsets)
    setup_seconds = time.perf_counter() - t0
    track_chunk = max(1, min(spec.chunk, TRACK_CHUNK))
    pending_cf = sum(len(c.configs) for c in todo) * split.n_frames
    if workers is None:
        workers = min(2, os.cpu_count() or 1) if pending_cf >= 2_000_000 else 0
    pool = None
    if workers > 0:
        ctx = mp.get_context("forkserver") if "forkserver" in mp.get_all_start_methods() else mp.get_context("spawn")
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_worker_init, initargs=(gt,))
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=n_total, initial=n_done, unit="cfg", desc=label, dynamic_ncols=True, smoothing=0.05,
                   file=sys.stderr)
    inflight: deque[_Pending] = deque()

    timing = {"setup": setup_seconds, "track": 0.0, "metrics": 0.0, "wait": 0.0, "write": 0.0}

    def complete(p: _Pending) -> None:
        tw = time.perf_counter()
        if p.future is not None:
            p.result = p.future.result()
        timing["wait"] += time.perf_counter() - tw
        tw = time.perf_counter()
        _store(p)
        metrics = _gather(p)
        df = _chunk_frame(table, p.chunk, data, split.names, split.lengths, metrics, p.res, versions, spec.name)
        if outdir is not None:
            _atomic_parquet(df, _chunk_path(outdir, p.chunk))
        else:
            frames_out[p.chunk.id] = df
        timing["write"] += time.perf_counter() - tw
        if bar is not None:
            bar.update(len(p.chunk.configs))

    def _store(p: _Pending) -> None:
        if not p.todo:
            return
        r = p.result
        for j, lane in enumerate(p.todo):
            d = p.digests[lane]
            if d not in ev.memo:
                ev.memo[d] = ({f: v[j] for f, v in r["seq"].items()}, {f: v[j] for f, v in r["comb"].items()})

    def _gather(p: _Pending) -> dict:
        per = [ev.memo[d] for d in p.digests]
        return {"seq": {f: np.stack([s[f] for s, _ in per]) for f in per[0][0]},
                "comb": {f: np.stack([c[f] for _, c in per]) for f in per[0][1]}}

    dist = spec.distortion
    groups = _groups(table) if dist is not None else {}
    try:
        frames_cache: tuple | None = None
        caps: dict[Options, int] = {}
        dspecs: dict[Options, Any] = {}
        for c in todo:
            if frames_cache is None or frames_cache[0] != c.options:
                frames_cache = (c.options, prepare_frames(split, c.options))
            frames = frames_cache[1]
            params = _params_of(table, c.configs, data.cls)
            opts = c.options
            dps = None
            if dist is not None:
                # one DistortSpec per option group, covering every lane of the group (all of the
                # table, not only the chunks left to run): one compilation, whatever is resumed
                dps = _distort_of(table, c.configs, dist)
                if c.options not in dspecs:
                    dspecs[c.options] = dist.make_spec(c.options, frames=frames,
                                                       dps=_distort_of(table, groups[c.options], dist))
            if opts.capacity == 0:
                # Track slots: the tracker's data-sized default for the whole option group (one
                # compilation), raised from the peaks once a chunk overflowed (``track`` re-runs an
                # overflowing lane with twice the slots, so results never depend on this choice).
                if c.options not in caps:
                    group = _params_of(table, [i for d in todo if d.options == c.options for i in d.configs],
                                       data.cls)
                    caps[c.options] = default_capacity(frames, group, opts)
                    if dist is not None and dist.clutter_slots:      # room for the clutter's births
                        caps[c.options] += 8 * math.ceil(3 * dist.clutter_slots / 8)
                opts = opts._replace(capacity=caps[c.options])
            tt = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)   # overflow is a column of the table
                if dps is None:
                    res = track(frames, params, opts, chunk=track_chunk, grow=True)
                else:       # distortion lanes vmapped with the parameter lanes; per-lane output boxes
                    res = track(split, params, opts, chunk=track_chunk, grow=True, distortion=dps,
                                spec=dspecs[c.options])
            if c.options.capacity == 0 and int(res.capacity.max(initial=0)) > caps[c.options]:
                caps[c.options] = max(int(res.capacity.max()), _capacity_hint(int(res.peak.max(initial=0))))
            timing["track"] += time.perf_counter() - tt
            boxes = res.boxes
            digests = ev.digests(res.ids, boxes)
            seen: dict[bytes, int] = {}
            lanes = []
            for i, d in enumerate(digests):
                if d not in ev.memo and d not in seen:
                    seen[d] = i
                    lanes.append(i)
            p = _Pending(c, _Slim(res.dropped, res.overflow, res.peak, res.capacity), digests, [])
            # lanes identical to one still being scored (an earlier chunk in flight) wait for it
            busy = {q.digests[i] for q in inflight for i in q.todo}
            p.todo = [i for i in lanes if digests[i] not in busy]
            if p.todo:
                dets = ev.dets(res.ids, boxes, p.todo)
                if pool is not None:
                    p.future = pool.submit(_worker_eval, dets, ev.lanes_per_batch)
                else:
                    tm = time.perf_counter()
                    p.result = _evaluate_dets(gt, dets, ev.lanes_per_batch)
                    timing["metrics"] += time.perf_counter() - tm
            del res, boxes
            inflight.append(p)
            # complete in submission order (a chunk may rely on an earlier one's scores)
            while inflight and (inflight[0].future is None or inflight[0].future.done()):
                complete(inflight.popleft())
            while len(inflight) > max(1, workers):
                complete(inflight.popleft())
        while inflight:
            complete(inflight.popleft())
    finally:
        if bar is not None:
            bar.close()
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
    dt = time.perf_counter() - t0
    n = sum(len(c.configs) for c in todo)
    log(f"sweep {label}: {n:,} configs tracked and scored in {dt:.1f} s ({n / dt:.1f} configs/s, "
        f"{n * split.n_frames / dt / 1e3:.0f} k config-frames/s; setup {timing['setup']:.1f} s, tracking "
        f"{timing['track']:.1f} s, metrics {timing['metrics']:.1f} s in-process + {timing['wait']:.1f} s waiting "
        f"for workers, tables {timing['write']:.1f} s; {len(ev.memo):,} distinct outputs scored)")


def _distort_of(table: pd.DataFrame, rows: Sequence[int], dist: DistortionAxes):
    """``DistortParams [B]`` of the table rows (their distortion.kind / level / seed)."""
    sub = table.iloc[list(rows)]
    return distort.stack_distort([dist.lane(k, v, s) for k, v, s in zip(
        sub["distortion.kind"], sub["distortion.level"], sub["distortion.seed"])])


@dataclass
class _Slim:
    dropped: np.ndarray
    overflow: np.ndarray
    peak: np.ndarray
    capacity: np.ndarray


# ---------------------------------------------------------------------------------------------
# Reading results


def load_results(out, *, allow_partial: bool = False) -> pd.DataFrame:
    """The tidy table of a sweep directory (``results.parquet``, else its finished chunks)."""
    out = Path(out)
    manifest = _manifest(out)
    paths = [out / "chunks" / f"{cid}.parquet" for cid in manifest["chunks"]]
    final = out / "results.parquet"
    if final.is_file() and all(p.is_file() for p in paths):
        df = pd.read_parquet(final)
        if set(df.loc[df["chunk"] != "", "chunk"].unique()) == set(manifest["chunks"]):
            return df
    have = [p for p in paths if p.is_file()]
    if len(have) < len(paths) and not allow_partial:
        raise FileNotFoundError(f"{out}: {len(paths) - len(have)} of {len(paths)} chunks not finished "
                                f"(rerun the sweep to resume)")
    if not have:
        raise FileNotFoundError(f"{out}: no finished chunk yet")
    return _finish(pd.concat([pd.read_parquet(p) for p in have], ignore_index=True), manifest.get("classes", ()))


def _manifest(out: Path) -> dict:
    path = Path(out) / "manifest.json"
    if not path.is_file():
        raise FileNotFoundError(f"{out} is not a sweep directory (no manifest.json)")
    return json.loads(path.read_text())


# ---------------------------------------------------------------------------------------------
# Reports: best configs, sensitivity, cross-validation


def _direction(objective: str) -> int:
    return -1 if objective in MINIMISE else 1


def _check_objective(df: pd.DataFrame, objective: str) -> None:
    if objective not in df.columns or objective in PARAM_NAMES or objective in OPTION_NAMES:
        known = [c for c in df.columns if c in _metric_fields()[3]]
        raise ValueError(f"objective {objective!r}: not a metric column; expected one of {known}")


def _rank(values: np.ndarray, objective: str) -> np.ndarray:
    """Order of configs best first; ties by position (config order)."""
    key = -_direction(objective) * np.asarray(values, np.float64)
    return np.lexsort((np.arange(len(key)), key))


def varied_axes(df: pd.DataFrame) -> list[str]:
    comb = df[df["sequence"] == COMBINED]
    return [c for c in list(PARAM_NAMES) + class_columns(comb.columns) + list(OPTION_NAMES) + list(_extra_axes())
            if c in comb.columns and comb[c].nunique() > 1]


def _axis_groups(comb: pd.DataFrame, axes: list[str]) -> list[tuple[str, ...]]:
    """Axes that always move together (e.g. gains swept as one set) form one group."""
    codes = {a: tuple(pd.factorize(comb[a])[0]) for a in axes}
    groups: dict[tuple, list[str]] = {}
    for a in axes:
        groups.setdefault(codes[a], []).append(a)
    return [tuple(g) for g in groups.values()]


def sensitivity(df: pd.DataFrame, objective: str = "HOTA", bins: int = 5) -> pd.DataFrame:
    """How much the objective moves with each varied axis (COMBINED rows).

    Per axis: ``values`` (distinct values; a numeric axis with more than 8, e.g. a random one, is
    cut into ``bins`` quantile bins), ``spread_best`` = the range over values (bins) of the best
    config having that value, ``spread_mean`` = the range over values of the mean objective (a main
    effect), ``corr`` = Spearman rank correlation of a numeric axis with the objective,
    ``best_value`` (the overall best config's value) and ``oat_range`` = the range when only this
    axis moves away from the best config (NaN when the sweep has no such configs). Axes that always
    move together (e.g. gains swept as one set through [[variants]]) are one row, ``a+b+c``.
    Sorted by ``spread_best``, largest first.
    """
    comb = df[df["sequence"] == COMBINED].reset_index(drop=True)
    y = comb[objective].to_numpy(np.float64)
    d = _direction(objective)
    best = int(_rank(y, objective)[0])
    rows = []
    for group in _axis_groups(comb, varied_axes(df)):
        a = group[0]
        col = comb[a]
        numeric = len(group) == 1 and pd.api.types.is_numeric_dtype(col) and not pd.api.types.is_bool_dtype(col)
        key = col
        if numeric and col.nunique() > 8:
            key = pd.qcut(col.rank(method="first"), bins, labels=False)
        g = comb[objective].groupby(key.to_numpy(), sort=True)
        by_best = g.max() if d > 0 else g.min()
        by_mean = g.mean()
        mask = np.ones(len(comb), bool)
        for other in _axis_groups(comb, varied_axes(df)):
            if other != group:
                for o in other:
                    mask &= (comb[o] == comb.at[best, o]).to_numpy()
        oat = y[mask]
        corr = float(col.rank().corr(comb[objective].rank())) if numeric else float("nan")
        rows.append({"axis": "+".join(group), "values": int(g.ngroups),
                     "spread_best": float(by_best.max() - by_best.min()),
                     "spread_mean": float(by_mean.max() - by_mean.min()), "corr": corr,
                     "best_value": "/".join(_fmt(comb.at[best, o]) for o in group) if len(group) > 1
                     else comb.at[best, a],
                     "oat_range": float(oat.max() - oat.min()) if oat.size > 1 else float("nan")})
    cols = ["axis", "values", "spread_best", "spread_mean", "corr", "best_value", "oat_range"]
    out = pd.DataFrame(rows, columns=cols)
    return out.sort_values("spread_best", ascending=False, kind="mergesort").reset_index(drop=True)


# ---------------------------------------------------------------------------------------------
# Robustness: metrics against distortion levels (sweeps with a [distortion] table)


def _check_distorted(df: pd.DataFrame) -> None:
    if "distortion.kind" not in df.columns:
        raise ValueError("the table has no distortion columns (a sweep without a [distortion] table)")


def n_settings(table: pd.DataFrame) -> int:
    """Distinct parameter / option settings of a table (a distortion sweep's configs without lanes)."""
    return int(len(table.drop_duplicates(list(PARAM_NAMES) + class_columns(table.columns) + list(OPTION_NAMES))))


def setting_axes(df: pd.DataFrame) -> list[str]:
    """The varied parameter / option axes (a *setting* is one value of each: every distortion lane
    of one config)."""
    return [a for a in varied_axes(df) if a not in DISTORTION_AXES]


def _level0_per_kind(rows: pd.DataFrame) -> pd.DataFrame:
    """Rows with the undistorted (level 0, kind "none") rows repeated under every kind: the start
    of each kind's curve."""
    kinds = [k for k in pd.unique(rows["distortion.kind"]) if k != "none"]
    zero = rows[rows["distortion.kind"] == "none"]
    if not kinds:
        return zero
    parts = []
    for k in kinds:
        parts.append(zero.assign(**{"distortion.kind": k}))
        parts.append(rows[rows["distortion.kind"] == k])
    return pd.concat(parts, ignore_index=True)


def _setting_labels(rows: pd.DataFrame, axes: Sequence[str]) -> pd.Series:
    if not axes:
        return pd.Series("all", index=rows.index, dtype=object)
    return rows[list(axes)].apply(lambda r: " ".join(f"{a}={_fmt(r[a])}" for a in axes), axis=1).astype(object)


def _se(x: pd.Series) -> float:
    n = x.count()
    return float(x.std(ddof=1) / math.sqrt(n)) if n > 1 else 0.0


def robustness_curves(df: pd.DataFrame, metrics: Sequence[str] = ("HOTA", "AssA", "IDSW"),
                      sequence: str = COMBINED) -> pd.DataFrame:
    """Metrics against the distortion level: one row per (setting, kind, level).

    A setting is one value of every varied parameter / option (``setting_axes``; its columns are
    kept, plus ``setting``, a label such as ``"epsilon=30 filter=kalman"``). Per metric: ``M`` the
    mean over seeds, ``M_se`` its standard error (std / sqrt(n); 0 for level 0, which has no
    randomness and one row), ``M_min``, ``M_max``; ``n`` the seeds. The undistorted level-0 row
    starts every kind's curve. ``sequence``: "COMBINED" (default) or one sequence's rows.
    """
    _check_distorted(df)
    metrics = [metrics] if isinstance(metrics, str) else list(metrics)
    for m in metrics:
        _check_objective(df, m)
    axes = setting_axes(df)
    rows = _level0_per_kind(df[df["sequence"] == sequence].reset_index(drop=True))
    rows = rows.assign(setting=_setting_labels(rows, axes))
    keys = ["setting"] + axes + ["distortion.kind", "distortion.level"]
    g = rows.groupby(keys, sort=False)
    out = g.size().rename("n").to_frame()
    for m in metrics:
        x = g[m]
        out[m] = x.mean()
        out[f"{m}_se"] = x.agg(_se)
        out[f"{m}_min"] = x.min()
        out[f"{m}_max"] = x.max()
    out = out.reset_index().rename(columns={"distortion.kind": "kind", "distortion.level": "level"})
    order_s = {s: i for i, s in enumerate(pd.unique(rows["setting"]))}
    order_k = {k: i for i, k in enumerate(pd.unique(rows["distortion.kind"]))}
    out = out.assign(_s=out["setting"].map(order_s), _k=out["kind"].map(order_k))
    return out.sort_values(["_s", "_k", "level"], kind="mergesort").drop(columns=["_s", "_k"]).reset_index(drop=True)


def robustness_contrast(df: pd.DataFrame, axis: str, high: Sequence, low: Sequence,
                        metrics: Sequence[str] = ("HOTA", "AssA", "IDSW"), by: Sequence[str] = (),
                        sequence: str = COMBINED, alpha: float = 0.05) -> pd.DataFrame:
    """How much the ``high`` values of ``axis`` beat the ``low`` ones at each distortion level.

    E.g. long memory (``epsilon`` in 30, 60) against short memory (``epsilon`` in 1, 2, 3). For
    every (``by`` values, kind, level, seed): the mean metric over the configs in ``high`` minus
    the mean over those in ``low`` (paired by seed: the same seed distorts every config's detections
    identically, so the difference is free of the detection noise that the configs share); then
    over seeds: ``gap`` (mean), ``se`` (standard error), ``n``. ``high_mean`` / ``low_mean`` are
    the two groups' means. ``helps``: the gap is in the metric's better direction (higher, or lower
    for IDSW etc.) and significantly so (one-sided paired t-test at ``alpha``; ``p``); at level 0
    (deterministic, one row) it is the sign. One row per (by..., kind, level, metric).
    """
    from scipy import stats

    _check_distorted(df)
    metrics = [metrics] if isinstance(metrics, str) else list(metrics)
    by = [by] if isinstance(by, str) else list(by)
    for m in metrics:
        _check_objective(df, m)
    for a in [axis] + by:
        if a not in df.columns:
            raise ValueError(f"contrast: {a!r} is not a column of the table")
    rows = _level0_per_kind(df[df["sequence"] == sequence].reset_index(drop=True))
    hi, lo = rows[rows[axis].isin(list(high))], rows[rows[axis].isin(list(low))]
    if not len(hi) or not len(lo):
        raise ValueError(f"contrast: no rows with {axis} in {list(high) if not len(hi) else list(low)}")
    keys = by + ["distortion.kind", "distortion.level", "distortion.seed"]
    mh = hi.groupby(keys, sort=False)[metrics].mean()
    ml = lo.groupby(keys, sort=False)[metrics].mean()
    mh, ml = mh.align(ml, join="inner")
    diff = mh - ml
    out = []
    for key, d in diff.groupby(level=list(range(len(by) + 2)), sort=False):
        key = key if isinstance(key, tuple) else (key,)
        for m in metrics:
            x = d[m].to_numpy(np.float64)
            n = x.size
            gap = float(x.mean())
            se = float(x.std(ddof=1) / math.sqrt(n)) if n > 1 else 0.0
            sign = _direction(m)
            if n > 1 and se > 0:
                t = sign * gap / se
                pval = float(stats.t.sf(t, n - 1))
                helps = bool(pval < alpha)
            else:
                pval = float("nan")
                helps = bool(sign * gap > 0)
            out.append({**dict(zip(by, key[:len(by)])), "kind": key[len(by)], "level": float(key[len(by) + 1]),
                        "metric": m, "high_mean": float(mh.loc[d.index, m].mean()),
                        "low_mean": float(ml.loc[d.index, m].mean()),
                        "gap": gap, "se": se, "n": int(n), "p": pval, "helps": helps})
    res = pd.DataFrame(out)
    order_k = {k: i for i, k in enumerate(pd.unique(rows["distortion.kind"]))}
    order_m = {m: i for i, m in enumerate(metrics)}
    res = res.assign(_k=res["kind"].map(order_k), _m=res["metric"].map(order_m))
    res = res.sort_values(by + ["_k", "_m", "level"], kind="mergesort").drop(columns=["_k", "_m"])
    res.attrs.update(axis=axis, high=list(high), low=list(low), by=by, alpha=alpha)
    return res.reset_index(drop=True)


def robustness_summary(contrast: pd.DataFrame) -> pd.DataFrame:
    """The answer of a contrast (:func:`robustness_contrast`), one row per (by..., kind, metric).

    ``helps_up_to``: the highest level up to which the ``high`` group is significantly better at
    every level from the first distorted one (NaN: not even there); ``stops_at``: the first level
    where it is not (NaN: it helps at every level studied); ``crossing``: the first level where the
    mean gap is no longer in the better direction (NaN: never); ``gap_before``: the mean gap over the
    distorted levels up to ``helps_up_to``; ``max_gap`` / ``max_gap_level``: the largest gap (in
    the better direction) and its level; ``gap_at_0``: the gap without distortion.
    """
    by = list(contrast.attrs.get("by", []))
    out = []
    for key, d in contrast.groupby(by + ["kind", "metric"], sort=False):
        key = key if isinstance(key, tuple) else (key,)
        d = d.sort_values("level")
        sign = _direction(str(key[-1]))
        dist = d[d["level"] > 0]
        bad = dist[~dist["helps"]]
        stops = float(bad["level"].iloc[0]) if len(bad) else float("nan")
        ok = dist[dist["level"] < stops] if len(bad) else dist
        cross = d[(d["level"] > 0) & (sign * d["gap"] <= 0)]
        best = int(np.argmax(sign * d["gap"].to_numpy()))
        zero = d[d["level"] == 0]
        out.append({**dict(zip(by + ["kind", "metric"], key)),
                    "gap_at_0": float(zero["gap"].iloc[0]) if len(zero) else float("nan"),
                    "helps_up_to": float(ok["level"].iloc[-1]) if len(ok) else float("nan"),
                    "stops_at": stops,
                    "crossing": float(cross["level"].iloc[0]) if len(cross) else float("nan"),
                    "gap_before": float(ok["gap"].mean()) if len(ok) else float("nan"),
                    "max_gap": float(d["gap"].iloc[best]), "max_gap_level": float(d["level"].iloc[best])})
    return pd.DataFrame(out)


def _contrast_doc(c: Contrast) -> dict:
    return {"axis": c.axis, "high": list(c.high), "low": list(c.low), "by": list(c.by)}


def _robustness_text(df: pd.DataFrame, objective: str, top: int) -> tuple[list[str], dict]:
    """Report lines: the objective per level (mean ± SE over seeds) per kind, for the best settings."""
    curves = robustness_curves(df, [objective])
    d = _direction(objective)
    lines, summary = [], {}
    n_seeds = int(curves.loc[curves["level"] > 0, "n"].max()) if (curves["level"] > 0).any() else 1
    lines.append(f"robustness: {objective} (COMBINED) per distortion level, mean ± SE over {n_seeds} seed(s) "
                 f"(level 0 = undistorted); settings ranked by their mean {objective} over the kind's levels")
    for kind, ck in curves.groupby("kind", sort=False):
        rank = ck.groupby("setting", sort=False)[objective].mean()
        order = rank.sort_values(ascending=d < 0, kind="mergesort").index[:top]
        levels = sorted(ck["level"].unique())
        table = {}
        for st in order:
            cs = ck[ck["setting"] == st].set_index("level")
            table[st] = [f"{cs.at[v, objective]:.2f}" + (f"±{cs.at[v, f'{objective}_se']:.2f}"
                                                          if cs.at[v, "n"] > 1 else "")
                         if v in cs.index else "" for v in levels]
        view = pd.DataFrame.from_dict(table, orient="index", columns=[_fmt(v) for v in levels])
        view.index.name = f"{kind} \\ level"
        lines.append("")
        lines.append(view.to_string())
        summary[kind] = {"levels": [float(v) for v in levels],
                         "settings": {st: [float(x) for x in ck[ck["setting"] == st].set_index("level")
                                           .reindex(levels)[objective]] for st in order}}
    return lines, summary


def _contrast_text(df: pd.DataFrame, c: Contrast, objective: str) -> tuple[list[str], list[dict]]:
    metrics = list(dict.fromkeys([objective, "HOTA", "AssA", "IDSW"]))
    metrics = [m for m in metrics if m in df.columns]
    lines = []
    answers: list[dict] = []
    for by in [[]] + ([list(c.by)] if c.by else []):
        try:
            con = robustness_contrast(df, c.axis, c.high, c.low, metrics, by=by)
        except ValueError as e:          # e.g. an axis value the sweep does not have: report, do not fail
            lines.extend(["", f"contrast {c.axis} {list(c.high)} vs {list(c.low)}: {e}"])
            break
        head = f"per {', '.join(by)}" if by else "over all other settings"
        lines.append("")
        lines.append(f"contrast {c.axis} in {list(c.high)} minus {c.axis} in {list(c.low)} ({head}): mean gap ± SE "
                     f"over seeds, paired by seed; * = significantly better (one-sided t-test, 5 %; level 0: sign)")
        con = con.assign(cell=[f"{g:+.2f}" + (f"±{s:.2f}" if n > 1 else "") + ("*" if h else "")
                               for g, s, n, h in zip(con["gap"], con["se"], con["n"], con["helps"])])
        for kind, ck in con.groupby("kind", sort=False):
            view = ck.pivot_table(index=by + ["metric"], columns="level", values="cell", aggfunc="first", sort=False)
            view.columns = [_fmt(v) for v in view.columns]
            view.columns.name = f"{kind} level"
            lines.append(view.fillna("").to_string())
        summ = robustness_summary(con)
        lines.append("answer: helps_up_to = highest level up to which the gap is significantly better at every "
                     "distorted level; stops_at = first level where it is not; crossing = first level where the "
                     "mean gap changes sign")
        lines.append(summ.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
        answers.extend({k: _json_value(v) if not (isinstance(v, float) and math.isnan(v)) else None
                        for k, v in r.items()} for r in summ.to_dict("records"))
    return lines, answers


def make_folds(names: Sequence[str], lengths: Sequence[int], k: int) -> list[list[str]]:
    """k folds of sequences stratified by frame count (deterministic).

    Sequences sorted by length (longest first, then name) are taken k at a time (a stratum of
    similar lengths) and each stratum gives one sequence to every fold (the longest to the fold
    with the fewest frames so far); then sequences of the same stratum are swapped between folds
    while that evens the folds' frame totals. Folds get alike mixes of long and short sequences
    and alike totals.
    """
    if not 2 <= k <= len(names):
        raise ValueError(f"folds={k}: expected 2 .. {len(names)} (the number of sequences)")
    L = [int(v) for v in lengths]
    order = sorted(range(len(names)), key=lambda i: (-L[i], str(names[i])))
    strata = [order[a:a + k] for a in range(0, len(order), k)]
    fold_of: dict[int, int] = {}
    total = [0] * k
    for stratum in strata:
        for i, f in zip(stratum, sorted(range(k), key=lambda f: (total[f], f))):
            fold_of[i] = f
            total[f] += L[i]
    improved = True
    while improved:
        improved = False
        for stratum in strata:
            for x in range(len(stratum)):
                for y in range(x + 1, len(stratum)):
                    i, j = stratum[x], stratum[y]
                    fi, fj = fold_of[i], fold_of[j]
                    d = L[i] - L[j]
                    # swapping i and j changes the two totals by -d and +d: keep it if the spread shrinks
                    if d and abs((total[fi] - d) - (total[fj] + d)) < abs(total[fi] - total[fj]) and \
                            max(total[fi] - d, total[fj] + d) < max(total[fi], total[fj]):
                        fold_of[i], fold_of[j] = fj, fi
                        total[fi] -= d
                        total[fj] += d
                        improved = True
    folds: list[list[str]] = [[] for _ in range(k)]
    for i, f in fold_of.items():
        folds[f].append(str(names[i]))
    return [sorted(f) for f in folds]


def _per_sequence_arrays(df: pd.DataFrame):
    """Per-sequence fields as arrays [C, S(, 19)] in config order; returns (comb rows, names, lengths, arrays)."""
    _, clear, identity, _, _ = _metric_fields()
    if RAW_COLUMN not in df.columns:
        raise ValueError(f"cross-validation needs the {RAW_COLUMN!r} column (sweep(..., raw=True))")
    seq = df[df["sequence"] != COMBINED]
    comb = df[df["sequence"] == COMBINED].reset_index(drop=True)
    first = seq[seq["config"] == comb.at[0, "config"]]
    names = list(first["sequence"])
    lengths = list(first["frames"])
    C, S = len(comb), len(names)
    seq = seq.sort_values("config", kind="mergesort")
    if len(seq) != C * S or list(seq["sequence"].iloc[:S]) != names:
        raise ValueError("the table does not hold the same sequences for every config")
    raw = np.stack(seq[RAW_COLUMN].to_numpy()).reshape(C, S, len(RAW_FIELDS), -1)
    arrays = {f: raw[:, :, i] for i, f in enumerate(RAW_FIELDS)}
    for f in tuple(clear.SUMMED_FIELDS) + tuple(identity.INTEGER_FIELDS) + ("Dets", "GT_Dets", "IDs", "GT_IDs"):
        if f in seq.columns:
            v = seq[f].to_numpy().reshape(C, S)
            arrays[f] = v
    return comb, names, lengths, arrays


def _objective_on(arrays: dict, cols: Sequence[int], objective: str, rows=None) -> np.ndarray:
    sub = {f: (v[:, cols] if rows is None else v[rows][:, cols]) for f, v in arrays.items()}
    return summary_columns(combine_sequences(sub))[objective]


def cross_validate(df: pd.DataFrame, folds: int = 5, objective: str = "HOTA", cls: str | None = None) -> dict:
    """k-fold cross-validation over sequences (:func:`make_folds`, stratified by frame count).

    For each fold the best config by ``objective`` on the other folds (COMBINED over them, exactly
    as TrackEval combines sequences) is scored on the held-out fold. ``cross_validated`` is the
    objective over all sequences when each sequence is tracked with the config chosen without it
    (directly comparable to a config's COMBINED figure); ``mean_held_out`` the mean of the folds'
    held-out figures. Returns a dict with per-fold details and the baseline's figures.

    A sweep over several classes: ``cls`` = one class (its rows, :func:`class_view`) or
    ``"average"`` (the default): the objective is the class average (ratios averaged over the
    classes, counts summed) of each class's COMBINED over its sequences in the fold. Each class's
    sequences are folded on their own (``make_folds`` per class; fold f holds out fold f of every
    class, so every fold scores every class); a config is chosen on the class average over the
    other folds of every class and scored on the class average over the held-out ones. The unit
    held out is a (class, sequence) pair: a scene held out for one class may be in the training
    folds of another (the classes' ground truth is disjoint). ``test_sequences`` of a fold (and
    ``fold_sequences``) are then ``{class: [sequences]}``.
    """
    _check_objective(df, objective)
    classes = _classes_of(df)
    cls = report_class_of(df, cls)
    if cls == AVERAGE:
        return _cross_validate_average(df, classes, folds, objective)
    if classes:
        df = class_view(df, cls)
    comb, names, lengths, arrays = _per_sequence_arrays(df)
    fold_names = make_folds(names, lengths, folds)
    base = np.flatnonzero(comb["baseline"].to_numpy())
    b = int(base[0]) if base.size else None
    chosen = np.zeros(len(names), np.int64)
    per_fold = []
    for f, test in enumerate(fold_names):
        te = [names.index(s) for s in test]
        tr = [i for i in range(len(names)) if i not in te]
        train_score = _objective_on(arrays, tr, objective)
        best = int(_rank(train_score, objective)[0])
        test_score = _objective_on(arrays, te, objective)
        chosen[te] = best
        per_fold.append({"fold": f, "test_sequences": test, "config": int(comb.at[best, "config"]),
                         "config_hash": comb.at[best, "config_hash"], "train": float(train_score[best]),
                         "held_out": float(test_score[best]),
                         "baseline_held_out": None if b is None else float(test_score[b])})
    pooled = {fname: np.stack([v[chosen[s], s] for s in range(len(names))])[None] for fname, v in arrays.items()}
    cv = float(summary_columns(combine_sequences(pooled))[objective][0])
    return {"objective": objective, "folds": folds, "cross_validated": cv,
            "mean_held_out": float(np.mean([p["held_out"] for p in per_fold])),
            "baseline": None if b is None else float(comb.at[b, objective]), "per_fold": per_fold,
            "fold_sequences": fold_names}


def _cross_validate_average(df: pd.DataFrame, classes: Sequence[str], folds: int, objective: str) -> dict:
    """:func:`cross_validate` on the class average (every class's sequences folded on their own)."""
    avg = df[(df["class"] == AVERAGE) & (df["sequence"] == COMBINED)]
    configs = avg["config"].to_numpy()
    comb = avg.reset_index(drop=True)
    per = []
    for k in classes:
        rows = df[(df["class"] == k) & df["config"].isin(configs)]
        ck, names, lengths, arrays = _per_sequence_arrays(rows)
        if not np.array_equal(ck["config"].to_numpy(), configs):
            raise ValueError(f"class {k!r} does not hold the configs of the class-average rows")
        per.append((k, names, lengths, arrays, make_folds(names, lengths, folds)))

    def score(cols_of) -> np.ndarray:
        return _class_average_columns([{objective: _objective_on(arrays, cols_of(i, names), objective)}
                                       for i, (_, names, _, arrays, _) in enumerate(per)])[objective]

    base = np.flatnonzero(comb["baseline"].to_numpy())
    b = int(base[0]) if base.size else None
    chosen = [np.zeros(len(names), np.int64) for _, names, _, _, _ in per]
    per_fold = []
    for f in range(folds):
        test = {k: fs[f] for k, _, _, _, fs in per}
        train_score = score(lambda i, names: [j for j, s in enumerate(names) if s not in test[per[i][0]]])
        test_score = score(lambda i, names: [names.index(s) for s in test[per[i][0]]])
        best = int(_rank(train_score, objective)[0])
        for i, (k, names, _, _, _) in enumerate(per):
            chosen[i][[names.index(s) for s in test[k]]] = best
        per_fold.append({"fold": f, "test_sequences": test, "config": int(comb.at[best, "config"]),
                         "config_hash": comb.at[best, "config_hash"], "train": float(train_score[best]),
                         "held_out": float(test_score[best]),
                         "baseline_held_out": None if b is None else float(test_score[b])})
    pooled = []
    for i, (_, names, _, arrays, _) in enumerate(per):
        sub = {fname: np.stack([v[chosen[i][s], s] for s in range(len(names))])[None] for fname, v in arrays.items()}
        pooled.append({objective: summary_columns(combine_sequences(sub))[objective]})
    cv = float(_class_average_columns(pooled)[objective][0])
    return {"objective": objective, "folds": folds, "class": AVERAGE, "classes": list(classes),
            "cross_validated": cv, "mean_held_out": float(np.mean([p["held_out"] for p in per_fold])),
            "baseline": None if b is None else float(comb.at[b, objective]), "per_fold": per_fold,
            "fold_sequences": [{k: fs[f] for k, _, _, _, fs in per} for f in range(folds)]}


def _classes_of(df: pd.DataFrame) -> list[str]:
    """The classes of a table (``class`` column, in order; the class average left out)."""
    if "class" not in df.columns:
        return []
    return [c for c in pd.unique(df["class"]) if c != AVERAGE]


def report_class_of(df: pd.DataFrame, cls: str | None = None) -> str | None:
    """The class a report ranks on: ``cls`` checked against the table, by default ``"average"``
    for a sweep over several classes, else its class. ``"average"`` of one class is that class."""
    classes = _classes_of(df)
    if cls is None or cls == AVERAGE:
        if len(classes) > 1:
            return AVERAGE
        return classes[0] if classes else None
    if cls not in classes:
        raise ValueError(f"class {cls!r}: not in the table; its classes are {classes}"
                         + (f" (or {AVERAGE!r})" if len(classes) > 1 else ""))
    return cls


def class_view(df: pd.DataFrame, cls: str) -> pd.DataFrame:
    """The rows of one class of a sweep table, as a single-class table of that class.

    Per-class columns ``<cls>.<parameter>`` replace the plain ones (every parameter column then
    holds the value that class was tracked with) and all per-class columns are dropped; configs
    that are then alike (differing only in another class's values) are kept once (the first). A
    single-class table without per-class columns is returned as it is. ``cls = "average"``: the
    class-average rows (one per config, ``sequence = COMBINED``), all columns kept.
    """
    classes = _classes_of(df)
    cls = report_class_of(df, cls)
    ccols = class_columns(df.columns)
    if cls == AVERAGE:
        return df[df["class"] == AVERAGE].reset_index(drop=True)
    if len(classes) <= 1 and not ccols:
        return df
    rows = df[df["class"] == cls].copy()
    for c in ccols:
        k, p = _split_class_column(c)
        if k == cls:
            rows[p] = rows[c]
    rows = rows.drop(columns=ccols)
    keys = list(PARAM_NAMES) + list(OPTION_NAMES) + [n for n in _extra_axes() if n in rows.columns]
    comb = rows[rows["sequence"] == COMBINED]
    keep = comb.drop_duplicates(keys, keep="first")["config"]
    if len(keep) < len(comb):
        rows = rows[rows["config"].isin(keep.to_numpy())]
    return rows.reset_index(drop=True)


@dataclass
class SweepReport:
    """``text`` (the printed report) and ``summary`` (the JSON-able dict of its last line)."""

    text: str
    summary: dict
    top: pd.DataFrame
    sensitivity: pd.DataFrame
    cv: dict | None = None
    curves: pd.DataFrame | None = None          # distortion sweeps: robustness_curves(df, objective)
    contrast: list | None = None                # with a contrast: robustness_summary rows (dicts)

    def __str__(self) -> str:
        return self.text


def _fmt(v) -> str:
    if isinstance(v, (float, np.floating)):
        return f"{v:.4g}" if abs(v) < 1e4 else f"{v:.6g}"
    return str(v)


def _json_value(v):
    if isinstance(v, (np.integer,)):
        return int(v)
    if isinstance(v, (np.floating,)):
        return float(v)
    if isinstance(v, (np.bool_,)):
        return bool(v)
    return v


def sweep_report(results, objective: str = "HOTA", folds: int | None = None, top: int = 10,
                 contrast: Contrast | Mapping | None = None, cls: str | None = None) -> SweepReport:
    """Best configs by ``objective`` (HOTA, MOTA, IDF1, AssA, ... maximised; IDSW, Frag, ...
    minimised), the baseline beside them, the sensitivity per axis and, with ``folds``, the
    cross-validated best. ``results``: a table from :func:`sweep` or a sweep directory.

    Distortion sweeps add the objective per distortion level and kind (mean ± SE over seeds) for
    the ``top`` settings and, with ``contrast`` (a :class:`Contrast`, a dict ``{axis, high, low,
    by}`` or, for a directory, the sweep file's ``report.contrast``), the gap between two groups of
    an axis per level (:func:`robustness_contrast`) and where it stops helping
    (:func:`robustness_summary`).

    A sweep over several classes ranks on ``cls``: one class (its rows with its own parameter values,
    :func:`class_view`) or ``"average"`` (default; for a directory: the file's ``report.class``):
    the class average (ratios averaged over the classes, counts summed), cross-validated with each
    class's sequences folded on their own (:func:`cross_validate`)."""
    if not isinstance(results, pd.DataFrame):
        d = Path(results)
        manifest = _manifest(d)
        df = load_results(d, allow_partial=True)
        if folds is None:
            folds = manifest.get("folds")
        if contrast is None and manifest.get("contrast"):
            contrast = manifest["contrast"]
        if cls is None:
            cls = manifest.get("report_class")
        n_expected = manifest.get("configs")
    else:
        df, n_expected = results, None
    if isinstance(contrast, Mapping):
        contrast = _parse_contrast(dict(contrast), None)
    _check_objective(df, objective)
    full = df
    classes = _classes_of(full)
    cls = report_class_of(full, cls)
    if classes:
        df = class_view(full, cls)
    comb = df[df["sequence"] == COMBINED].reset_index(drop=True)
    axes = varied_axes(df)
    order = _rank(comb[objective].to_numpy(), objective)
    best = comb.iloc[int(order[0])]
    base_rows = comb[comb["baseline"]]
    baseline = base_rows.iloc[0] if len(base_rows) else None
    show = list(dict.fromkeys([objective, "HOTA", "DetA", "AssA", "MOTA", "IDF1", "IDSW"]))
    show = [c for c in show if c in comb.columns]
    topdf = comb.iloc[order[:top]][["config", "config_hash"] + show + axes + ["overflow"]].copy()
    topdf.insert(0, "rank", np.arange(1, len(topdf) + 1))
    lines = []
    name = df["sweep"].iloc[0] if "sweep" in df.columns else "sweep"
    n_cfg = int(full["config"].nunique())
    partial = f" (partial: {n_cfg} of {n_expected} configs)" if n_expected and n_expected != n_cfg else ""
    better = "lower" if _direction(objective) < 0 else "higher"
    if len(classes) > 1:
        per = {k: full.loc[(full["class"] == k) & (full["sequence"] != COMBINED), "sequence"].nunique()
               for k in classes}
        seqs = per[cls] if cls != AVERAGE else sum(per.values())
        on = (f"the class average ({', '.join(classes)}: ratios averaged over the classes, counts summed)"
              if cls == AVERAGE else f"class {cls}" + (f" ({len(comb):,} distinct configs for it)"
                                                        if len(comb) != n_cfg else ""))
        lines.append(f"sweep {name}: {n_cfg:,} configs x classes "
                     f"{', '.join(f'{k} ({n} sequences)' for k, n in per.items())}{partial}; objective "
                     f"{objective} ({better} is better) on {on}")
    else:
        seqs = df.loc[df["sequence"] != COMBINED, "sequence"].nunique()
        lines.append(f"sweep {name}: {len(comb):,} configs x {seqs} sequences{partial}; objective {objective} "
                     f"({better} is better)" + (f"; class {cls}" if cls and cls != "car" else ""))
    lines.append("")
    lines.append(f"top {len(topdf)} configs (in-sample, COMBINED over all sequences):")
    view = topdf.copy()
    if baseline is not None:
        brow = {"rank": "base", "config": baseline["config"], "config_hash": baseline["config_hash"],
                **{c: baseline[c] for c in show + axes + ["overflow"]}}
        view = pd.concat([view, pd.DataFrame([brow])], ignore_index=True)
    lines.append(view.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    if baseline is not None:
        diff = [f"{a}={_fmt(best[a])} (baseline {_fmt(baseline[a])})" for a in axes if best[a] != baseline[a]]
        lines.append(f"best vs baseline: {objective} {best[objective]:.3f} vs {baseline[objective]:.3f} "
                     f"({best[objective] - baseline[objective]:+.3f}); changed: {', '.join(diff) or 'nothing'}")
    sens = sensitivity(df, objective) if axes else pd.DataFrame()
    if len(sens):
        lines.append("")
        lines.append(f"sensitivity of {objective} per axis (spread_best: range over an axis' values of the best "
                     f"config with that value; spread_mean: range of the means; corr: rank correlation; oat_range: "
                     f"moving only this axis away from the best config):")
        lines.append(sens.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    curves = answers = None
    if "distortion.kind" in df.columns and (df["distortion.kind"] != "none").any():
        rob_lines, rob_summary = _robustness_text(df, objective, top)
        lines.append("")
        lines.extend(rob_lines)
        curves = robustness_curves(df, [objective])
        if contrast is not None:
            con_lines, answers = _contrast_text(df, contrast, objective)
            lines.extend(con_lines)
    cv = None
    if folds:
        cv = cross_validate(full, folds, objective, cls)
        lines.append("")
        lines.append(f"{folds}-fold cross-validation over sequences (stratified by frame count"
                     + ("; each class's sequences folded on their own" if cv.get("class") == AVERAGE else "")
                     + "): best config chosen on the training folds, scored on the held-out fold")
        fold_rows = []
        for p in cv["per_fold"]:
            row = comb[comb["config"] == p["config"]].iloc[0]
            changed = ", ".join(f"{a}={_fmt(row[a])}" for a in axes if baseline is None or row[a] != baseline[a])
            test = p["test_sequences"]
            held = (" ".join(f"{k}:{','.join(v)}" for k, v in test.items()) if isinstance(test, Mapping)
                    else ",".join(test))
            fold_rows.append({"fold": p["fold"], "held_out_sequences": held,
                              "config": p["config"], "train": p["train"], "held_out": p["held_out"],
                              "baseline_held_out": p["baseline_held_out"], "changed": changed or "(baseline)"})
        lines.append(pd.DataFrame(fold_rows).to_string(index=False, float_format=lambda v: f"{v:.3f}"))
        lines.append(f"{objective}: cross-validated {cv['cross_validated']:.3f} (each sequence scored with the config "
                     f"chosen without it) | in-sample best {best[objective]:.3f}"
                     + (f" | baseline {baseline[objective]:.3f}" if baseline is not None else ""))
    summary = {"objective": objective, "direction": "min" if _direction(objective) < 0 else "max",
               "configs": int(len(comb)), "sequences": int(seqs),
               **({"class": cls} if classes else {}), **({"classes": classes} if len(classes) > 1 else {}),
               "baseline": None if baseline is None else float(baseline[objective]),
               "best_in_sample": float(best[objective]),
               "best_config": {"config": int(best["config"]), "config_hash": best["config_hash"],
                               **{a: _json_value(best[a]) for a in axes}}}
    if baseline is not None:
        summary["baseline_config_hash"] = baseline["config_hash"]
    if cv is not None:
        summary["best_cross_validated"] = cv["cross_validated"]
        summary["folds"] = folds
        summary["mean_held_out"] = cv["mean_held_out"]
        summary["fold_configs"] = [p["config_hash"] for p in cv["per_fold"]]
    if curves is not None:
        summary["robustness"] = rob_summary
    if answers is not None:
        summary["contrast"] = {**_contrast_doc(contrast), "answer": answers}
    lines.append("")
    lines.append(json.dumps(summary))
    return SweepReport("\n".join(lines), summary, topdf, sens, cv, curves, answers)
