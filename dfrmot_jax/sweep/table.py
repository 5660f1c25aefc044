"""The config table of a sweep (``expand``: one row per config) and its identity (``config_hash``).

``config_hash`` is the resume identity of a config: result rows and chunk ids
(:func:`dfrmot_jax.sweep.plan.plan`) are keyed by it. Its scheme is versioned: :data:`HASH_VERSION`
is recorded in every sweep directory's manifest (``hash_version``; a directory without it is
version 1, the scheme of every directory written before the version existed). A change that
alters any hash or chunk id must bump it.

The configs are of the sweep's tracker family (``SweepSpec.family``): its presets make the baseline,
its types the columns' types, its checks refuse a table (``TrackerFamily.table_problem``); a config
of another family than the default (``"dfr"``) hashes with its family's name, so that every config
of the default family keeps the hash it had before families existed.
"""

from __future__ import annotations

import hashlib
import itertools
import json
from typing import Any, Mapping, Sequence

import numpy as np
import pandas as pd

from ..checks import config_error
from ..trackers.protocol import DEFAULT_FAMILY
from ..trackers.registry import family_config
from ..trackers.registry import family_of
from ..lidar import lidar_dir
from .axes import AxisKind, cross_rows, hash_settings
from .lidar_axes import tie_table_scores
from ..table_columns import class_columns, extra_axes, param_key, settings_of, split_class_column
from .spec import Axis, SweepSpec, Variant, as_spec

#: The scheme of ``config_hash`` and chunk ids; recorded in the manifest as ``hash_version``.
HASH_VERSION = 1
#: Default most configs a sweep may expand to (``expand`` / ``run_sweep(max_configs=...)``, ``dfrmot
#: sweep --max-configs``), checked before expanding: a config table takes about 3 kB and 50 us per config.
MAX_CONFIGS = 250_000



def canonical_value(name: str, v, family=DEFAULT_FAMILY):
    """Canonical value for hashing: parameters (of the tracker ``family``, a name or its settings) as
    the tracker sees them (float32 / int32)."""
    fc = settings_of(family)
    if name in fc.Params._fields:
        return param_key(name, v, fc)
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    return str(v)


def _class_extra(row: Mapping[str, Any], fc) -> dict:
    """{class: {parameter: canonical value}} of the row's class columns (of family settings ``fc``)
    that differ from its plain ones."""
    out: dict[str, dict] = {}
    for col in row:
        cp = split_class_column(col, fc)
        if cp is None:
            continue
        cls, p = cp
        v = canonical_value(p, row[col], fc)
        if v != canonical_value(p, row[p], fc):
            out.setdefault(cls, {})[p] = v
    return out


def config_hash(row: Mapping[str, Any], settings: Mapping[str, Any] | None = None,
                family: str = DEFAULT_FAMILY) -> str:
    """Stable 16-hex-digit hash of a config: every parameter and option (+ extra axes off their
    default, such as the distortion axes; + ``settings``, sweep-wide values off their defaults that
    change this row, e.g. a distortion lane's burst start rate; + a sweep over several classes' per-class
    values, columns ``<class>.<parameter>``, where they differ from the plain column: a row without
    such a difference hashes exactly as before; an option of the family's ``late_options`` or a
    parameter of its ``late_params`` only off its default; + the tracker ``family`` unless it is the
    default one). The parameters and options are ``family``'s (its name)."""
    fc = settings_of(family)
    late_o, late_p = fc.late_options, fc.late_params
    late = {n: canonical_value(n, row.get(n, d), fc) for n, d in late_o.items()}
    key = {"params": {n: canonical_value(n, row[n], fc) for n in fc.Params._fields
                      if n not in late_p or canonical_value(n, row.get(n, late_p[n]), fc) != canonical_value(n, late_p[n], fc)},
           "options": {**{n: canonical_value(n, row[n], fc) for n in fc.Options._fields if n not in late_o},
                       **{n: v for n, v in late.items() if v != canonical_value(n, late_o[n], fc)}}}
    extra = {n: canonical_value(n, row[n], fc) for n, d in extra_axes().items() if n in row and row[n] != d}
    if settings:
        extra["settings"] = dict(settings)
    classes = _class_extra(row, fc)
    if classes:
        extra["classes"] = classes
    if extra:
        key["extra"] = extra
    if family != DEFAULT_FAMILY:
        key["family"] = family
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


def config_count(spec) -> tuple[int, str, str]:
    """(configs, how they are made up, the key of the largest factor) of a sweep, without expanding:
    per variant the product of its grid axes' value counts x ``samples``, plus the baseline, then
    crossed with each axis kind (``AxisKind.size``: x the LiDAR settings, x the distortion lanes; an
    upper bound: configs that hash alike are kept once)."""
    spec = as_spec(spec)
    total, parts, factors = 1, [], [(1, "params")]
    for v in spec.variants:
        axes = [a for a in v.params if a.is_grid] + list(v.options)
        counts = [(len(a.values), a.key, a.name) for a in axes] + [(spec.samples, "samples", "samples")]
        total += int(np.prod([c for c, _, _ in counts], dtype=object))
        factors += [(c, k) for c, k, _ in counts]
        parts.append(f"variant {v.name!r}: " + (" x ".join(f"{name} {c:,}" for c, _, name in counts
                                                           if c > 1 or name != "samples") or "1"))
    desc = "the baseline + " + "; ".join(parts)
    for kind in spec.axes:
        total, text, more = kind.size(total)
        desc = f"{desc}; {text}"
        factors += more
    return total, desc, max(factors)[1]


def expand(spec, max_configs: int | None = None) -> pd.DataFrame:
    """The config table of a sweep: one row per config, the baseline first.

    Columns: ``config`` (row number), ``config_hash``, ``variant``, ``baseline`` (bool), every
    parameter and option of the sweep's tracker family (``SweepSpec.family``: its ``Params`` and
    ``Options`` fields, ``table_columns.param_names`` / ``option_names``). Grid axes are crossed (the first axis
    slowest; parameters, then options); random axes (uniform, loguniform, randint, choice) are drawn
    per config from ``numpy.random.default_rng(seed)``; ``samples`` repeats each variant's grid with
    the random axes redrawn (Ray Tune's ``num_samples``). Configs that hash alike are kept once.

    These configs are then crossed with each axis kind of the sweep in turn (``SweepSpec.axes``,
    :class:`~.axes.AxisKind`), its columns innermost: with [lift] / [simulate] the LiDAR settings
    (``lift.*``, ``simulate.*``), with a [distortion] table the distortion lanes (kind, then level,
    then seed: the columns ``DISTORTION_AXES``, ``distortion.kind``, ``distortion.level``,
    ``distortion.seed``). Level 0 is the identity for every kind and seed: it is one lane per config,
    the undistorted one (kind "none", level 0, seed 0: the same hash as the config without
    distortion). Without them the table has no such columns.

    ``max_configs`` (default :data:`MAX_CONFIGS`): a sweep of more configs (:func:`config_count`)
    fails before expanding, with a :class:`SweepConfigError` naming its largest factor.
    """
    spec = as_spec(spec)
    _check_size(spec, max_configs)
    table = settings_table(spec)
    for i, kind in enumerate(spec.axes):
        table = cross(table, kind, spec.axes[:i + 1], spec.family)
    table.insert(0, "config", np.arange(len(table), dtype=np.int64))
    _check_configs(table, spec.source, spec.family)
    return table


def _check_size(spec: SweepSpec, max_configs: int | None = None) -> None:
    """Refuse a sweep of more than ``max_configs`` configs (default :data:`MAX_CONFIGS`) before expanding."""
    limit = MAX_CONFIGS if max_configs is None else int(max_configs)
    n, desc, key = config_count(spec)
    if n > limit:
        raise config_error(key, f"the sweep expands to up to {n:,} configs ({desc}), above the limit of {limit:,} "
                        f"(dfrmot_jax.sweep.MAX_CONFIGS): sweep fewer values, or raise the limit with "
                        f"--max-configs N (run_sweep(max_configs=N))", spec.source)


def settings_table(spec: SweepSpec) -> pd.DataFrame:
    """The sweep's parameter / option settings (the baseline, then every variant's), typed and
    hashed (:func:`typed_table`), configs that hash alike kept once: the rows the axis kinds cross."""
    fc = family_config(spec.family)
    params = list(fc.Params._fields)
    single = len(spec.classes) == 1
    base_row, class_base = _baseline_rows(spec)
    # per-class columns: class defaults off the plain baseline, and every per-class axis
    explicit = [a.name for v in spec.variants for a in v.params if a.cls] if not single else []
    derived = [f"{k}.{p}" for k, b in class_base.items() for p in params
               if canonical_value(p, b[p], fc) != canonical_value(p, base_row[p], fc)]
    ccols = [f"{k}.{p}" for k in spec.classes for p in params if f"{k}.{p}" in set(explicit + derived)]
    rng = np.random.default_rng(spec.seed)
    first = {**base_row, **{c: class_base[split_class_column(c, fc)[0]][split_class_column(c, fc)[1]] for c in ccols}}
    rows: list[dict] = [{"variant": "baseline", "baseline": True, **first}]
    for v in spec.variants:
        rows += _variant_rows(spec, v, rng, base_row, class_base, ccols)
    table = pd.DataFrame(rows, columns=["variant", "baseline"] + params + ccols + list(fc.Options._fields))
    for c in ccols:          # a class default that no row moves off the plain value says nothing
        k, p = split_class_column(c, fc)
        if c not in explicit and all(canonical_value(p, x, fc) == canonical_value(p, y, fc)
                                     for x, y in zip(table[c], table[p])):
            table = table.drop(columns=[c])
    if lidar_dir(spec.det3d) is not None:      # lifted boxes carry their 2D score (as dfrmot track)
        table = tie_table_scores(table, {a.name for v in spec.variants for a in v.params}, fc)
    return typed_table(table, spec.family).drop_duplicates("config_hash", keep="first").reset_index(drop=True)


def _variant_rows(spec: SweepSpec, v: Variant, rng: np.random.Generator, base_row: dict,
                  class_base: dict[str, dict], ccols: list[str]) -> list[dict]:
    """The rows of one variant: its grid axes crossed, its random axes drawn, ``samples`` times."""
    fc = family_config(spec.family)
    grid_axes = [a for a in v.params if a.is_grid] + list(v.options)
    rand_axes = [a for a in v.params if not a.is_grid]
    plain_set = {a.name for a in v.params if not a.cls}
    combos = list(itertools.product(*(a.values for a in grid_axes)))
    n = len(combos) * spec.samples
    draws = {a.name: _draw(a, rng, n) for a in rand_axes}
    rows, i = [], 0
    for _ in range(spec.samples):
        for combo in combos:
            vals = {a.name: val for a, val in zip(grid_axes, combo)}
            vals.update({name: d[i] for name, d in draws.items()})
            row = {"variant": v.name, "baseline": False, **base_row}
            row.update({k: x for k, x in vals.items() if split_class_column(k, fc) is None})
            if len(spec.classes) == 1:      # the one class's per-class axes are its parameters
                row.update({split_class_column(k, fc)[1]: x for k, x in vals.items()
                            if split_class_column(k, fc) is not None})
            for c in ccols:      # precedence: per-class axis > plain axis > the class's baseline
                k, p = split_class_column(c, fc)
                row[c] = vals[c] if c in vals else row[p] if p in plain_set else class_base[k][p]
            rows.append(row)
            i += 1
    return rows


def cross(table: pd.DataFrame, kind: AxisKind, kinds: Sequence[AxisKind],
          family: str = DEFAULT_FAMILY) -> pd.DataFrame:
    """Every config of ``table`` x an axis kind's values (:func:`~.axes.cross_rows`: its columns
    innermost, typed as their defaults; the baseline still first), hashes recomputed with the
    settings of ``kinds`` (those crossed so far, ``kind`` last) and the tracker ``family``, configs that
    hash alike kept once."""
    unknown = [c for c in kind.columns if c not in extra_axes()]
    if unknown:             # (config_hash and the result rows know a kind's columns from that registry)
        raise ValueError(f"axis columns {unknown} are not registered in dfrmot_jax.table_columns.EXTRA_AXES")
    cols = list(table.columns.drop("config_hash"))
    out = pd.DataFrame(cross_rows(table[cols].to_dict("records"), kind), columns=cols + list(kind.columns))
    for c in cols:
        out[c] = out[c].astype(table[c].dtype)
    for c, d in kind.columns.items():
        out[c] = out[c].astype(_column_dtype(d))
    out.insert(0, "config_hash", [config_hash(r, hash_settings(kinds, r), family) for r in out.to_dict("records")])
    return out.drop_duplicates("config_hash", keep="first").reset_index(drop=True)


def _column_dtype(default):
    """The table's type of a column whose default is ``default`` (bool, int64, float64, or object)."""
    return bool if isinstance(default, bool) else "int64" if isinstance(default, int) else \
        "float64" if isinstance(default, float) else object


def _check_configs(table: pd.DataFrame, src: str | None, family: str = DEFAULT_FAMILY) -> None:
    """The checks on a whole table: a config besides the baseline, and the tracker family's own
    (``TrackerFamily.table_problem``; DFR-FastMOT: filtered boxes with stable fixed gains,
    ``keep_lost`` only with filtered output), a :class:`SweepConfigError` naming the key."""
    if len(table) < 2:
        raise config_error("params", "the sweep has no config besides the baseline: add parameters or options to sweep",
                   src)
    problem = family_of(family).table_problem(table)
    if problem is not None:
        raise config_error(problem[0], problem[1], src)


def typed_table(table: pd.DataFrame, family: str = DEFAULT_FAMILY) -> pd.DataFrame:
    """Config rows (``variant``, ``baseline``, every parameter, class column and option) with the
    table's column types (integer parameters int64, the others float64, options as the family's
    ``Options`` declares them) and ``config_hash`` (of the tracker ``family``) inserted first.
    Duplicates are kept."""
    fc = family_config(family)
    table = table.copy()
    for n in list(fc.Params._fields) + class_columns(table.columns, fc):
        t = split_class_column(n, fc)[1] if split_class_column(n, fc) else n
        table[n] = table[n].astype("int64" if t in fc.int_params else "float64")
    for n in fc.Options._fields:
        d = fc.Options._field_defaults[n]
        table[n] = table[n].astype(bool if isinstance(d, bool) else "int64" if isinstance(d, int) else object)
    table.insert(0, "config_hash", [config_hash(r, family=family) for r in table.to_dict("records")])
    return table


def baseline_row(spec: SweepSpec) -> dict:
    """The baseline's parameters and options of a one-class sweep (its family's ``preset(baseline, class)``)."""
    return _baseline_rows(spec)[0]


def _baseline_rows(spec: SweepSpec) -> tuple[dict, dict[str, dict]]:
    """(the plain baseline row: parameters and options, {class: its baseline parameters}).

    One class: the plain row is ``preset(baseline, baseline_class or the class)`` and there are no
    per-class values. Several: the plain row is the bare preset (``presets[baseline]``; with
    ``[baseline] class``, ``preset(baseline, that class)``), and class ``k``'s baseline is
    ``preset(baseline, baseline_class or k)``: the presets of the sweep's tracker family."""
    fc = family_config(spec.family)
    if len(spec.classes) == 1:
        p, o = fc.preset(spec.baseline, spec.baseline_class or spec.classes[0])
        return {**p._asdict(), **o._asdict()}, {}
    p, o = fc.preset(spec.baseline, spec.baseline_class) if spec.baseline_class else fc.presets[spec.baseline]
    per = {k: fc.preset(spec.baseline, spec.baseline_class or k)[0]._asdict() for k in spec.classes}
    return {**p._asdict(), **o._asdict()}, per


def n_settings(table: pd.DataFrame, family: str = DEFAULT_FAMILY) -> int:
    """Distinct parameter / option settings of a table of the tracker ``family`` (a distortion sweep's
    configs without lanes)."""
    fc = family_config(family)
    return int(len(table.drop_duplicates(list(fc.Params._fields) + class_columns(table.columns, fc)
                                         + list(fc.Options._fields))))


def params_of(table: pd.DataFrame, rows: Sequence[int], cls: str | None = None, family: str = DEFAULT_FAMILY):
    """The parameters (the tracker ``family``'s ``Params``) of table rows for class ``cls`` (its
    ``<cls>.<parameter>`` columns where the table has them, else the plain ones; a parameter of its
    ``late_params`` that a table written before it existed lacks: its default, as the report reads
    such a table)."""
    fc = family_config(family)
    sub = table.iloc[list(rows)]

    def column(n: str) -> np.ndarray:
        name = f"{cls}.{n}" if f"{cls}.{n}" in sub.columns else n
        if name not in sub.columns and n in fc.late_params:
            return np.full(len(sub), fc.late_params[n])
        return sub[name].to_numpy()

    return fc.as_arrays(fc.Params(**{n: column(n) for n in fc.Params._fields}))

