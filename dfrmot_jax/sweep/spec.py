"""The sweep file: spec dataclasses, TOML parsing and validation (``load_spec``, ``parse_spec``).

Every parameter and option value is checked by the one validator of the sweep's tracker family
(``[options] family``, default ``"dfr"``: its :class:`~dfrmot_jax.trackers.protocol.FamilyConfig`'s
``param_problem`` / ``option_problem``, presets and classes); a bad file fails before any work with a
:class:`SweepConfigError` naming the key. The format is documented in ``sweeps/README.md``.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..trackers.protocol import DEFAULT_FAMILY, FamilyConfig
from ..trackers.registry import family_config, family_names
from ..lidar import lidar_dir
from ..choices import DEFAULT_AB3DMOT_IOU, parse_iou
from ..metrics.samota.sums import DEFAULT_SUM, SUMS
from ..metrics.samota.table import AB3DMOT_COLUMNS
from ..metrics.columns import canonical_objective
from ..checks import (
    GRID_KINDS,
    SweepConfigError,
    Table,
    check_count,
    clean_float,
    config_error,
    is_number,
    type_name,
)
from .axes import AxisKind
from .distortion import DistortionAxes, parse_distortion
from .lidar_axes import LidarAxes, parse_lidar
from ..table_columns import AVERAGE, Contrast, parse_contrast

RANDOM_KINDS = ("uniform", "loguniform", "randint", "choice")

TOP_KEYS = ("name", "description", "chunk", "seed", "samples", "data", "baseline", "params", "options", "variants",
            "distortion", "report", "metrics", "lift", "simulate")
METRICS_KEYS = ("ab3dmot", "ab3dmot_columns", "ab3dmot_sum")
DATA_KEYS = ("root", "det2d", "det3d", "class", "sequences")
BASELINE_KEYS = ("preset", "class")
REPORT_KEYS = ("objective", "folds", "top", "contrast", "class")
VARIANT_KEYS = ("name", "params", "options")




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
class SweepSpec:
    """A parsed sweep file. ``data_root`` None = ``$DFRMOT_DATA`` / the default root.

    ``classes``: the classes every config is run for (``data.class``, a name or a list; ``cls``
    is the first). The baseline of class ``k`` is ``params.preset(baseline, baseline_class or k)``.
    """

    def __post_init__(self):
        if not self.classes:
            object.__setattr__(self, "classes", (self.cls,))

    @property
    def axes(self) -> tuple[AxisKind, ...]:
        """The sweep's axis kinds beyond parameters and options, in crossing order (innermost last):
        what :func:`~.table.expand` crosses the configs with and :mod:`.plan` splits them by."""
        return tuple(a for a in (self.lidar, self.distortion) if a is not None)

    def metrics_identity(self) -> str | None:
        """What the chunks' metric columns depend on beyond the 2D metrics (part of the chunk ids):
        AB3DMOT's IoU setting, when not "kitti" the result columns it scores, and the sum of its
        track scores (always named: chunks written before the sum was a setting summed sequentially,
        so their ids, which lack it, are never taken for another sum's); None without it."""
        if self.ab3dmot is None:
            return None
        columns = "" if self.ab3dmot_columns == "kitti" else f" {self.ab3dmot_columns}"
        return f"{self.ab3dmot}{columns} sum={self.ab3dmot_sum}"

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
    ab3dmot: str | None = None                  # metrics.ab3dmot: AB3DMOT's figures too, at this IoU ("3d:0.25")
    ab3dmot_columns: str = "kitti"              # metrics.ab3dmot_columns: the result columns scored ("kitti-stale")
    ab3dmot_sum: str = DEFAULT_SUM              # metrics.ab3dmot_sum: how its evaluator sums track scores
    top: int = 10
    distortion: DistortionAxes | None = None
    lidar: LidarAxes | None = None              # [lift] / [simulate]: LiDAR settings crossed with every config
    contrast: Contrast | None = None
    source: str | None = None
    raw: Mapping | None = field(default=None, compare=False, repr=False)
    family: str = DEFAULT_FAMILY                # [options] family: the tracker family of every config


def load_spec(path) -> SweepSpec:
    """Read and validate a sweep TOML file (see ``sweeps/README.md``)."""
    return parse_spec(read_toml(path), source=str(path))


def read_toml(path, what: str = "sweep file") -> dict:
    """The table of a UTF-8 TOML file (a leading byte-order mark is skipped). A missing file raises
    FileNotFoundError, text that is not UTF-8 or not TOML :class:`SweepConfigError` naming the file."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{what} {path} not found")
    try:
        return tomllib.loads(path.read_bytes().decode("utf-8-sig"))
    except UnicodeDecodeError as e:
        raise SweepConfigError("(file)", f"not UTF-8 text ({e.reason} at byte {e.start})", str(path)) from None
    except tomllib.TOMLDecodeError as e:
        raise SweepConfigError("(file)", f"not valid TOML: {e}", str(path)) from None


def _check_param_value(name: str, v, key: str, source, fc: FamilyConfig) -> int | float:
    problem = fc.param_problem(name, v) if is_number(v) else f"not a number ({type_name(v)})"
    if problem:
        raise config_error(key, f"{v!r}: parameter {name}: {problem}", source)
    return int(round(float(v))) if name in fc.int_params else float(v)


def _param_axis(name: str, spec, key: str, source, fc: FamilyConfig) -> Axis:
    if name not in fc.Params._fields:
        hint = " (a static option: put it under [options])" if name in fc.Options._fields else ""
        raise config_error(key, f"unknown parameter{hint}; parameters are {list(fc.Params._fields)}", source)
    if isinstance(spec, Mapping):
        if len(spec) != 1:
            raise config_error(key, f"a distribution table has exactly one key among {list(GRID_KINDS + RANDOM_KINDS)}, "
                            f"got {sorted(spec)}", source)
        kind, arg = next(iter(spec.items()))
        k2 = f"{key}.{kind}"
        if kind not in GRID_KINDS + RANDOM_KINDS:
            raise config_error(k2, f"unknown distribution; expected one of {list(GRID_KINDS + RANDOM_KINDS)}", source)
        if not isinstance(arg, list):
            raise config_error(k2, f"expected a list, got {arg!r}", source)
        if kind in ("grid", "choice"):
            if not arg:
                raise config_error(k2, "empty list: nothing to sweep", source)
            vals = tuple(_check_param_value(name, v, f"{k2}[{i}]", source, fc) for i, v in enumerate(arg))
            return Axis(name, "grid" if kind == "grid" else "choice", vals, key)
        if kind in ("linspace", "logspace"):
            if len(arg) != 3 or not all(is_number(a) for a in arg) or isinstance(arg[2], float) and \
                    not float(arg[2]).is_integer():
                raise config_error(k2, f"expected [low, high, count], got {arg!r}", source)
            lo, hi, n = float(arg[0]), float(arg[1]), int(arg[2])
            if n < 1:
                raise config_error(k2, f"count {n} < 1: empty grid", source)
            check_count(n, k2, source)
            _check_param_value(name, lo, k2, source, fc)
            _check_param_value(name, hi, k2, source, fc) if name not in fc.int_params else None
            if kind == "logspace":
                if lo <= 0 or hi <= 0:
                    raise config_error(k2, f"logspace needs positive ends, got {arg!r}", source)
                raw = np.geomspace(lo, hi, n)
            else:
                raw = np.linspace(lo, hi, n)
            if name in fc.int_params:
                rounded = np.round(raw)
                if np.any(np.abs(raw - rounded) > 1e-9):
                    raise config_error(k2, f"gives non-integer values {raw.tolist()} for integer parameter {name}", source)
                raw = rounded
            vals = tuple(dict.fromkeys(_check_param_value(name, clean_float(v), k2, source, fc) for v in raw))
            return Axis(name, "grid", vals, key)
        # uniform / loguniform / randint: [low, high]
        if len(arg) != 2 or not all(is_number(a) for a in arg):
            raise config_error(k2, f"expected [low, high], got {arg!r}", source)
        lo, hi = arg
        if not float(lo) < float(hi):
            raise config_error(k2, f"low {lo!r} must be below high {hi!r}", source)
        if kind == "randint":
            if not all(float(a).is_integer() for a in arg):
                raise config_error(k2, f"randint takes integers, got {arg!r}", source)
            lo, hi = int(lo), int(hi)
            _check_param_value(name, lo, k2, source, fc)
            _check_param_value(name, hi - 1, k2, source, fc)
            return Axis(name, kind, (lo, hi), key)
        if name in fc.int_params:
            raise config_error(k2, f"parameter {name} takes integers: use randint", source)
        if kind == "loguniform" and float(lo) <= 0:
            raise config_error(k2, f"loguniform needs low > 0, got {lo!r}", source)
        _check_param_value(name, lo, k2, source, fc)
        _check_param_value(name, hi, k2, source, fc)
        return Axis(name, kind, (float(lo), float(hi)), key)
    if isinstance(spec, list):
        if not spec:
            raise config_error(key, "empty list: nothing to sweep", source)
        vals = tuple(_check_param_value(name, v, f"{key}[{i}]", source, fc) for i, v in enumerate(spec))
        return Axis(name, "grid", vals, key)
    return Axis(name, "grid", (_check_param_value(name, spec, key, source, fc),), key)


def _check_option_value(name: str, v, key: str, source, fc: FamilyConfig):
    problem = fc.option_problem(name, v)
    if problem:
        raise config_error(key, f"{v!r}: {problem}", source)
    return v


def _option_axis(name: str, spec, key: str, source, fc: FamilyConfig) -> Axis:
    if name not in fc.Options._fields:
        hint = " (a dynamic parameter: put it under [params])" if name in fc.Params._fields else ""
        raise config_error(key, f"unknown option{hint}; options are {list(fc.Options._fields)}", source)
    if isinstance(spec, Mapping):
        if list(spec) != ["grid"]:
            raise config_error(key, "static options take a value, a list or {grid = [...]} (each value is its own "
                            "compilation; random distributions are for parameters)", source)
        spec = spec["grid"]
        key = f"{key}.grid"
    vals = spec if isinstance(spec, list) else [spec]
    if not vals:
        raise config_error(key, "empty list: nothing to sweep", source)
    vals = tuple(dict.fromkeys(_check_option_value(name, v, f"{key}[{i}]" if isinstance(spec, list) else key,
                                                   source, fc)
                               for i, v in enumerate(vals)))
    return Axis(name, "grid", vals, key)


def _class_axis(cls: str, name: str, spec, key: str, source, classes: Sequence[str], fc: FamilyConfig) -> Axis:
    """A per-class parameter axis ``<cls>.<name>`` (``key`` names it in errors)."""
    if cls not in fc.classes:
        raise config_error(key.rsplit(".", 1)[0] if "." in key else key,
                   f"{cls!r} is neither a parameter nor a class; parameters are {list(fc.Params._fields)}, "
                   f"classes {list(fc.classes)} (per-class axes: <class>.<parameter>)", source)
    if cls not in classes:
        raise config_error(key, f"class {cls!r} is not swept (data.class = {list(classes)})", source)
    if name in fc.Options._fields and name not in fc.Params._fields:
        raise config_error(key, "static options apply to every class; per-class axes are for parameters", source)
    axis = _param_axis(name, spec, key, source, fc)
    return replace(axis, name=f"{cls}.{name}", cls=cls)


def _axes(table, kind: str, prefix: str, source, fc: FamilyConfig,
          classes: Sequence[str] = ("car",)) -> tuple[Axis, ...]:
    if table is None:
        return ()
    if not isinstance(table, Mapping):
        raise config_error(prefix, f"expected a table, got {type(table).__name__}", source)
    if kind != "params":
        for k in table:
            if k in fc.classes or "." in k:
                raise config_error(f"{prefix}.{k}", "static options apply to every class: per-class axes "
                                            "(<class>.<name>) are for [params]", source)
        return tuple(_option_axis(k, v, f"{prefix}.{k}", source, fc) for k, v in table.items() if k != FAMILY_KEY)
    out = []
    for k, v in table.items():
        if "." in k:                                   # a quoted key "pedestrian.a_l"
            cls, name = k.split(".", 1)
            out.append(_class_axis(cls, name, v, f"{prefix}.{k}", source, classes, fc))
        elif k not in fc.Params._fields and k not in fc.Options._fields and isinstance(v, Mapping) and \
                not set(v) & set(GRID_KINDS + RANDOM_KINDS):      # pedestrian.a_l = ... / [params.pedestrian]
            if k not in fc.classes:
                raise config_error(f"{prefix}.{k}", f"unknown parameter or class; parameters are {list(fc.Params._fields)}, "
                                            f"classes {list(fc.classes)} (per-class axes: <class>.<parameter>)",
                           source)
            for name, spec in v.items():
                out.append(_class_axis(k, name, spec, f"{prefix}.{k}.{name}", source, classes, fc))
        else:
            out.append(_param_axis(k, v, f"{prefix}.{k}", source, fc))
    return tuple(out)


def _parse_sequences(v, key, source) -> tuple[str, ...] | None:
    if v is None or v == "all":
        return None
    if isinstance(v, str):
        v = [s for s in v.split(",") if s.strip()]
    if not isinstance(v, list) or not v:
        raise config_error(key, f"expected \"all\", a list of sequence names or a comma-separated string, got {v!r}", source)
    out = []
    for s in v:
        if isinstance(s, bool) or not isinstance(s, (int, str)) or isinstance(s, int) and s < 0:
            raise config_error(key, f"{s!r} is not a sequence name", source)
        out.append(f"{s:04d}" if isinstance(s, int) else s.strip().zfill(4))
    if len(set(out)) != len(out):
        raise config_error(key, "a sequence is listed twice", source)
    return tuple(out)


def _parse_classes(v, source, fc: FamilyConfig) -> tuple[str, ...]:
    """``data.class``: a class name or a non-empty list of distinct class names."""
    if isinstance(v, str):
        items = [("data.class", v)]
    elif isinstance(v, list) and v:
        items = [(f"data.class[{i}]", c) for i, c in enumerate(v)]
    else:
        raise config_error("data.class", f"{v!r}: expected a class name or a non-empty list of classes "
                                         f"{list(fc.classes)}", source)
    for key, c in items:
        if c not in fc.classes:
            raise config_error(key, f"{c!r} is not one of {list(fc.classes)}", source)
    out = tuple(c for _, c in items)
    if len(set(out)) != len(out):
        raise config_error("data.class", "a class is listed twice", source)
    return out


def parse_spec(doc: Mapping, source: str | None = None) -> SweepSpec:
    """Validate a sweep given as a dict (the parsed TOML); raises :class:`SweepConfigError`
    naming the full key (every table is read through a :class:`~dfrmot_jax.checks.Table`)."""
    top = Table(doc, "", source, TOP_KEYS)
    name = top.string("name", Path(source).stem if source else "sweep")
    desc = top.string("description", "", empty=True)
    chunk = top.integer("chunk", 64)
    samples = top.integer("samples", 1)
    seed = top.integer("seed", 0, minimum=0)
    family = parse_family(doc, source)
    fc = family_config(family)
    data, classes, root, sequences = _parse_data(top, source, fc)
    base, base_cls = _parse_baseline(top, fc)
    variants = _parse_variants(doc, top, classes, source, fc)
    rep = top.table("report", REPORT_KEYS)
    try:
        objective = canonical_objective(rep.string("objective", "HOTA"))
    except ValueError as e:
        raise rep.error("objective", str(e).removeprefix("objective ")) from None
    folds = rep.integer("folds", None, minimum=2)
    top_n = rep.integer("top", 10)
    contrast = parse_contrast(rep.get("contrast"), source, fc)
    report_class = rep.get("class")
    if report_class is not None and (not isinstance(report_class, str) or report_class not in classes + (AVERAGE,)):
        raise rep.error("class", f"{report_class!r}: expected one of the sweep's classes {list(classes)} or "
                                 f"{AVERAGE!r}")
    distortion = parse_distortion(doc.get("distortion"), source, fc.detections, fc.title)
    metrics = top.table("metrics", METRICS_KEYS)
    ab3dmot = _parse_metrics(metrics, rep, objective, folds)
    ab3dmot_columns = metrics.choice("ab3dmot_columns", "kitti", ("kitti", "kitti-stale"),
                                     "the result columns AB3DMOT's figures score")
    ab3dmot_sum = metrics.choice("ab3dmot_sum", DEFAULT_SUM, SUMS, "how AB3DMOT's evaluator sums track scores "
                                 "(compensated: CPython >= 3.12; sequential: CPython <= 3.11)")

    spec = SweepSpec(name=name, description=desc, chunk=chunk, seed=seed, samples=samples, data_root=root,
                     det2d=data.get("det2d", "rrc"), det3d=data.get("det3d", "pointrcnn"), cls=classes[0],
                     sequences=sequences, baseline=base, variants=variants, objective=objective,
                     folds=folds, top=top_n, distortion=distortion, contrast=contrast, source=source,
                     raw=dict(doc), classes=classes, baseline_class=base_cls, report_class=report_class,
                     ab3dmot=ab3dmot, ab3dmot_columns=ab3dmot_columns, ab3dmot_sum=ab3dmot_sum,
                     lidar=parse_lidar(doc, source), family=family)
    for v in spec.variants:
        if samples > 1 and all(a.is_grid for a in v.params):
            raise config_error("samples", f"samples = {samples} repeats the grid with random parameters redrawn, but "
                                  f"variant {v.name!r} has no random parameter (uniform, loguniform, randint, "
                                  f"choice): every config would repeat", source)
    return spec


def _parse_data(top: Table, source,
                fc: FamilyConfig) -> tuple[Table, tuple[str, ...], str | None, tuple[str, ...] | None]:
    """The [data] table: (the table, its classes, its root resolved against the file's folder, its sequences)."""
    data = top.table("data", DATA_KEYS)
    for k in ("root", "det2d", "det3d"):
        data.string(k, None)
    try:
        lidar_dir(data.get("det3d", ""))                # "lidar:" without its folder
    except ValueError as e:
        raise data.error("det3d", str(e)) from None
    classes = _parse_classes(data.get("class", "car"), source, fc)
    root = data.get("root")
    if root is not None and source is not None and not Path(root).expanduser().is_absolute():
        root = str((Path(source).parent / Path(root).expanduser()).resolve())
    return data, classes, root, _parse_sequences(data.get("sequences"), "data.sequences", source)


def _parse_baseline(top: Table, fc: FamilyConfig) -> tuple[str, str | None]:
    """``baseline = "preset"`` or the [baseline] table: (the preset, its class or None)."""
    base = top.get("baseline", fc.default_preset)
    if not isinstance(base, Mapping):
        return top.choice("baseline", fc.default_preset, sorted(fc.presets), "unknown preset"), None
    bt = top.table("baseline", BASELINE_KEYS)
    base_cls = bt.get("class")
    if base_cls is not None and (not isinstance(base_cls, str) or base_cls not in fc.classes):
        raise bt.error("class", f"{base_cls!r}: expected one of {list(fc.classes)} (every class's baseline is the "
                                f"preset as tuned for this class)")
    return bt.choice("preset", fc.default_preset, sorted(fc.presets), "unknown preset"), base_cls


#: the static option that names the sweep's tracker family (``[options] family``)
FAMILY_KEY = "family"


def parse_family(doc: Mapping, source: str | None = None) -> str:
    """``[options] family`` (and each ``[[variants]]``' ``options.family``): the tracker family of every
    config, one name of :mod:`dfrmot_jax.trackers.registry` (default ``"dfr"``). A sweep is of one family:
    its tables hold that family's parameter and option columns (and its stored directory's manifest
    names the family, but for the default one's)."""
    found = []
    variants = doc.get("variants") if isinstance(doc.get("variants"), list) else []
    for key, table in [("options", doc.get("options"))] + [(f"variants[{i}].options", v.get("options"))
                                                           for i, v in enumerate(variants) if isinstance(v, Mapping)]:
        if isinstance(table, Mapping) and FAMILY_KEY in table:
            found.append((f"{key}.{FAMILY_KEY}", table[FAMILY_KEY]))
    for key, v in found:
        if not isinstance(v, str) or v not in family_names():
            raise config_error(key, f"{v!r}: expected one tracker family of {list(family_names())} (a sweep is of "
                                    f"one family)", source)
    names = list(dict.fromkeys(v for _, v in found))
    if len(names) > 1:
        raise config_error(found[[v for _, v in found].index(names[1])][0],
                           f"{names[1]!r}: a sweep is of one tracker family, and another entry names {names[0]!r}; "
                           f"sweep each family in a file of its own", source)
    return names[0] if names else DEFAULT_FAMILY


def _parse_variants(doc: Mapping, top: Table, classes: tuple[str, ...], source,
                    fc: FamilyConfig) -> tuple[Variant, ...]:
    """[params] and [options], and each [[variants]] entry overriding them (one variant "grid" without any)."""
    params = _axes(doc.get("params"), "params", "params", source, fc, classes)
    options = _axes(doc.get("options"), "options", "options", source, fc)
    variants_doc = doc.get("variants")
    if variants_doc is None:
        return (Variant("grid", params, options),)
    if not isinstance(variants_doc, list) or not variants_doc:
        raise top.error("variants", "expected a non-empty array of tables ([[variants]])")
    variants = []
    for i, v in enumerate(variants_doc):
        vt = Table(v, f"variants[{i}]", source, VARIANT_KEYS)
        vname = vt.string("name", f"variant{i}")
        vp = _axes(v.get("params"), "params", f"variants[{i}].params", source, fc, classes)
        vo = _axes(v.get("options"), "options", f"variants[{i}].options", source, fc)
        over_p = {a.name for a in vp}
        over_o = {a.name for a in vo}
        variants.append(Variant(vname,
                                tuple(a for a in params if a.name not in over_p) + vp,
                                tuple(a for a in options if a.name not in over_o) + vo))
    return tuple(variants)


def _parse_metrics(metrics: Table, rep: Table, objective: str, folds: int | None) -> str | None:
    """The [metrics] table's ``ab3dmot = "3d:0.25"`` (or ``"2d:0.5"``, ``true`` for the default): adds
    AB3DMOT's figures (``sAMOTA`` ...) to the COMBINED rows; an AB3DMOT objective turns it on."""
    v = metrics.get("ab3dmot", objective in AB3DMOT_COLUMNS)
    if v is False:
        if objective in AB3DMOT_COLUMNS:
            raise metrics.error("ab3dmot", f"false, but report.objective = {objective!r} is one of AB3DMOT's figures")
        return None
    if v is True:
        v = DEFAULT_AB3DMOT_IOU
    if not isinstance(v, str):
        raise metrics.error("ab3dmot", f"{v!r}: expected true, false or \"2d:T\" / \"3d:T\" (the IoU and its "
                                       f"threshold, e.g. \"3d:0.25\")")
    try:
        kind, thres = parse_iou(v)
    except ValueError as e:
        raise metrics.error("ab3dmot", str(e)) from None
    if objective in AB3DMOT_COLUMNS and folds is not None:
        raise rep.error("folds", f"{folds}: {objective} is not a sum over sequences (AB3DMOT draws its recall "
                                 f"thresholds from all sequences together), so a sweep's rows cannot be re-combined "
                                 f"into folds: cross-validate it with a nested tune ([tune] folds = {folds})")
    return f"{kind}:{thres:g}"


def as_spec(spec) -> SweepSpec:
    if isinstance(spec, SweepSpec):
        return spec
    if isinstance(spec, Mapping):
        return parse_spec(spec)
    return load_spec(spec)



