"""Analysis of a sweep table: ranking by an objective, sensitivity per axis, folds over sequences
and cross-validation (each sequence scored with the config chosen without it), class views."""

from __future__ import annotations

from typing import Sequence

import numpy as np
import pandas as pd

from ..metrics.samota.table import AB3DMOT_COLUMNS, AB3DMOT_COUNT_COLUMNS
from ..metrics.columns import canonical_objective, class_average_columns  # noqa: F401
from ..metrics.kitti2d import clear, identity
from ..metrics.kitti2d.evaluate import RAW_FIELDS, combine_sequences, summary_columns
from ..metrics.kitti2d.table import TABLE_FIELDS
from ..table_columns import (AVERAGE, COMBINED, RAW_COLUMN, canonical_params, class_columns, extra_axes, setting_names, split_class_column, table_family)

#: Objectives the report knows by name (any metric column works); these are minimised.
MINIMISE = frozenset({"IDSW", "Frag", "ML", "CLR_FN", "CLR_FP", "IDFN", "IDFP", "PT", "MLR", "FP_per_frame",
                      *AB3DMOT_COUNT_COLUMNS})
OBJECTIVES = ("HOTA", "MOTA", "IDF1", "AssA", "DetA", "IDSW")


def objective_direction(objective: str) -> int:
    return -1 if objective in MINIMISE else 1


def check_objective(df: pd.DataFrame, objective: str, family=None) -> None:
    """ValueError unless ``objective`` is a metric column of ``df`` (not one of its tracker family's
    parameters or options; ``family`` None: read from its columns, ``columns.table_family``)."""
    if objective not in df.columns or objective in setting_names(table_family(df.columns, family)):
        known = [c for c in df.columns if c in TABLE_FIELDS]
        raise ValueError(f"objective {objective!r}: not a metric column; expected one of {known}")


def rank_configs(values: np.ndarray, objective: str) -> np.ndarray:
    """Order of configs best first; ties by position (config order)."""
    key = -objective_direction(objective) * np.asarray(values, np.float64)
    return np.lexsort((np.arange(len(key)), key))


#: axes whose values are replicates, not settings (a distortion lane's seed): no axis of the sensitivity
REPLICATE_AXES = ("distortion.seed",)


def _sensitivity_axes(comb: pd.DataFrame, family=None) -> list[str]:
    return [a for a in varied_axes(comb, family) if a not in REPLICATE_AXES]


def varied_axes(df: pd.DataFrame, family=None) -> list[str]:
    """The columns of the configs' settings that vary over ``df``'s COMBINED rows: its tracker family's
    parameters (plain, then per class), options, then the per-lane axes. ``family``: the table's (a
    name or its settings; None: read from its columns, ``columns.table_family``)."""
    comb = df[df["sequence"] == COMBINED]
    fc = table_family(df.columns, family)
    return [c for c in list(fc.Params._fields) + class_columns(comb.columns, fc) + list(fc.Options._fields)
            + list(extra_axes()) if c in comb.columns and comb[c].nunique() > 1]


def _axis_groups(comb: pd.DataFrame, axes: list[str]) -> list[tuple[str, ...]]:
    """Axes that always move together (e.g. gains swept as one set) form one group."""
    codes = {a: tuple(pd.factorize(comb[a])[0]) for a in axes}
    groups: dict[tuple, list[str]] = {}
    for a in axes:
        groups.setdefault(codes[a], []).append(a)
    return [tuple(g) for g in groups.values()]


def _profile(comb: pd.DataFrame, group: tuple[str, ...], objective: str, bins: int) -> pd.DataFrame:
    """The objective per value of an axis group (COMBINED rows ``comb``): one row per value (a numeric
    axis with more than 8 values: per quantile bin) with ``value`` (the bin's median), ``label``,
    ``best`` (the best config with it), ``mean`` and ``n``."""
    col = comb[group[0]]
    numeric = len(group) == 1 and pd.api.types.is_numeric_dtype(col) and not pd.api.types.is_bool_dtype(col)
    binned = numeric and col.nunique() > 8
    key = (pd.qcut(col.rank(method="first"), bins, labels=False) if binned else col).to_numpy()
    g = comb[objective].groupby(key, sort=True)
    out = pd.DataFrame({"best": g.max() if objective_direction(objective) > 0 else g.min(), "mean": g.mean(),
                        "n": g.size()})
    out["value"] = col.groupby(key, sort=True).median() if binned else out.index
    first = comb.groupby(key, sort=True)[list(group)].first()
    out["label"] = [f"~{fmt_value(v)}" for v in out["value"]] if binned else \
        ["/".join(fmt_value(v) for v in r) for r in first.itertuples(index=False)]
    return out.reset_index(drop=True)


def _axis_views(comb: pd.DataFrame, family=None) -> list[tuple[str, tuple[str, ...], pd.DataFrame]]:
    """(name, axis group, its configs) per axis of the sensitivity: every group on all configs, but a
    parameter whose unit an option sets (``FamilyConfig.unit_of``: AB3DMOT's ``threshold`` by
    ``metric``) while that option varies is one axis per value of the option, on its configs
    (``threshold [metric=giou_3d]``): IoUs and metres are never binned into one axis."""
    fc = table_family(comb.columns, family)
    out = []
    for g in _axis_groups(comb, _sensitivity_axes(comb, family)):
        opt = fc.unit_of.get(g[0]) if len(g) == 1 else None
        if opt is None or opt not in comb.columns or comb[opt].nunique() < 2:
            out.append(("+".join(g), g, comb))
            continue
        for v in pd.unique(comb[opt]):
            sub = comb[comb[opt] == v].reset_index(drop=True)
            if sub[g[0]].nunique() > 1:
                out.append((f"{g[0]} [{opt}={fmt_value(v)}]", g, sub))
    return out


def axis_profiles(df: pd.DataFrame, objective: str = "HOTA", bins: int = 5, family=None) -> dict[str, pd.DataFrame]:
    """Per varied axis (axes that always move together: one, ``a+b+c``; a parameter whose unit an option
    sets: one per value of the option, :func:`_axis_views`) the objective per value (:func:`_profile`:
    ``value``, ``label``, ``best``, ``mean``, ``n``): what :func:`sensitivity` measures the spread of,
    for plots."""
    comb = canonical_params(df[df["sequence"] == COMBINED].reset_index(drop=True), family)
    return {name: _profile(sub, g, objective, bins) for name, g, sub in _axis_views(comb, family)}


def sensitivity(df: pd.DataFrame, objective: str = "HOTA", bins: int = 5, family=None) -> pd.DataFrame:
    """How much the objective moves with each varied axis (COMBINED rows).

    Per axis: ``values`` (distinct values; a numeric axis with more than 8, e.g. a random one, is
    cut into ``bins`` quantile bins), ``spread_best`` = the range over values (bins) of the best
    config having that value, ``spread_mean`` = the range over values of the mean objective (a main
    effect), ``corr`` = Spearman rank correlation of a numeric axis with the objective,
    ``best_value`` (the overall best config's value) and ``oat_range`` = the range when only this
    axis moves away from the best config (NaN when the sweep has no such configs). Axes that always
    move together (e.g. gains swept as one set through [[variants]]) are one row, ``a+b+c``; values
    that are one setting (:func:`~.columns.canonical_params`) are one value; a distortion lane's seed
    (:data:`REPLICATE_AXES`) is no axis; a parameter whose unit an option sets is one row per value of
    the option, each on its configs (:func:`_axis_views`: AB3DMOT's ``threshold [metric=iou_3d]``,
    ``threshold [metric=dist_3d]``; ``best_value`` and ``oat_range`` then of that variant's best
    config). Sorted by ``spread_best``, largest first. ``family``: the table's tracker family (None:
    read from its columns).
    """
    full = canonical_params(df[df["sequence"] == COMBINED].reset_index(drop=True), family)
    axes = _sensitivity_axes(full, family)
    rows = []
    for name, group, comb in _axis_views(full, family):
        y = comb[objective].to_numpy(np.float64)
        best = int(rank_configs(y, objective)[0])
        a = group[0]
        col = comb[a]
        numeric = len(group) == 1 and pd.api.types.is_numeric_dtype(col) and not pd.api.types.is_bool_dtype(col)
        prof = _profile(comb, group, objective, bins)
        by_best, by_mean = prof["best"], prof["mean"]
        mask = np.ones(len(comb), bool)
        for other in _axis_groups(full, axes):
            if other != group:
                for o in other:
                    mask &= (comb[o] == comb.at[best, o]).to_numpy()
        oat = y[mask]
        corr = float(col.rank().corr(comb[objective].rank())) if numeric else float("nan")
        rows.append({"axis": name, "values": len(prof),
                     "spread_best": float(by_best.max() - by_best.min()),
                     "spread_mean": float(by_mean.max() - by_mean.min()), "corr": corr,
                     "best_value": "/".join(fmt_value(comb.at[best, o]) for o in group) if len(group) > 1
                     else comb.at[best, a],
                     "oat_range": float(oat.max() - oat.min()) if oat.size > 1 else float("nan")})
    cols = ["axis", "values", "spread_best", "spread_mean", "corr", "best_value", "oat_range"]
    out = pd.DataFrame(rows, columns=cols)
    return out.sort_values("spread_best", ascending=False, kind="mergesort").reset_index(drop=True)



def fmt_value(v) -> str:
    if isinstance(v, (float, np.floating)):
        return f"{v:.4g}" if abs(v) < 1e4 else f"{v:.6g}"
    return str(v)


def json_value(v):
    if isinstance(v, (np.integer,)):
        return int(v)
    if isinstance(v, (np.floating,)):
        return float(v)
    if isinstance(v, (np.bool_,)):
        return bool(v)
    return v


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


def per_sequence_arrays(df: pd.DataFrame):
    """Per-sequence fields as arrays [C, S(, 19)] in config order; returns (comb rows, names, lengths, arrays)."""
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


def objective_on(arrays: dict, cols: Sequence[int], objective: str, rows=None) -> np.ndarray:
    sub = {f: (v[:, cols] if rows is None else v[rows][:, cols]) for f, v in arrays.items()}
    return summary_columns(combine_sequences(sub))[objective]


def _pooled(arrays: dict, rows: Sequence[int], cols: Sequence[int]) -> dict:
    """Per-sequence fields [1, S'] of sequences ``cols``, sequence ``cols[j]`` from config row ``rows[j]``."""
    return {f: np.stack([v[r, s] for r, s in zip(rows, cols)])[None] for f, v in arrays.items()}


def pooled_objective(arrays: dict, rows: Sequence[int], cols: Sequence[int], objective: str) -> float:
    """The objective over sequences ``cols``, each tracked by config row ``rows[j]`` (TrackEval's
    combination of sequences): a cross-validated figure when each row was chosen without its sequence."""
    return float(summary_columns(combine_sequences(_pooled(arrays, rows, cols)))[objective][0])


def cross_validate(df: pd.DataFrame, folds: int = 5, objective: str = "HOTA", cls: str | None = None,
                   family=None) -> dict:
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
    ``fold_sequences``) are then ``{class: [sequences]}``. ``family``: the table's tracker family
    (None: read from its columns).
    """
    check_objective(df, objective, family)
    if objective in AB3DMOT_COLUMNS:
        raise ValueError(f"objective {objective}: AB3DMOT's figures are not sums over sequences (its recall "
                         f"thresholds come from all sequences together), so a sweep's rows cannot be re-combined "
                         f"into folds; cross-validate it with a nested tune (dfrmot tune, [tune] folds = {folds})")
    classes = classes_of(df)
    cls = report_class_of(df, cls)
    if cls == AVERAGE:
        return _cross_validate_average(df, classes, folds, objective)
    if classes:
        df = class_view(df, cls, family)
    comb, names, lengths, arrays = per_sequence_arrays(df)
    fold_names = make_folds(names, lengths, folds)
    base = np.flatnonzero(comb["baseline"].to_numpy())
    b = int(base[0]) if base.size else None
    chosen = np.zeros(len(names), np.int64)
    per_fold = []
    for f, test in enumerate(fold_names):
        te = [names.index(s) for s in test]
        tr = [i for i in range(len(names)) if i not in te]
        train_score = objective_on(arrays, tr, objective)
        best = int(rank_configs(train_score, objective)[0])
        test_score = objective_on(arrays, te, objective)
        chosen[te] = best
        per_fold.append({"fold": f, "test_sequences": test, "config": int(comb.at[best, "config"]),
                         "config_hash": comb.at[best, "config_hash"], "train": float(train_score[best]),
                         "held_out": float(test_score[best]),
                         "baseline_held_out": None if b is None else float(test_score[b])})
    cv = pooled_objective(arrays, chosen, range(len(names)), objective)
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
        ck, names, lengths, arrays = per_sequence_arrays(rows)
        if not np.array_equal(ck["config"].to_numpy(), configs):
            raise ValueError(f"class {k!r} does not hold the configs of the class-average rows")
        per.append((k, names, lengths, arrays, make_folds(names, lengths, folds)))

    def score(cols_of) -> np.ndarray:
        return class_average_columns([{objective: objective_on(arrays, cols_of(i, names), objective)}
                                       for i, (_, names, _, arrays, _) in enumerate(per)])[objective]

    base = np.flatnonzero(comb["baseline"].to_numpy())
    b = int(base[0]) if base.size else None
    chosen = [np.zeros(len(names), np.int64) for _, names, _, _, _ in per]
    per_fold = []
    for f in range(folds):
        test = {k: fs[f] for k, _, _, _, fs in per}
        train_score = score(lambda i, names: [j for j, s in enumerate(names) if s not in test[per[i][0]]])
        test_score = score(lambda i, names: [names.index(s) for s in test[per[i][0]]])
        best = int(rank_configs(train_score, objective)[0])
        for i, (k, names, _, _, _) in enumerate(per):
            chosen[i][[names.index(s) for s in test[k]]] = best
        per_fold.append({"fold": f, "test_sequences": test, "config": int(comb.at[best, "config"]),
                         "config_hash": comb.at[best, "config_hash"], "train": float(train_score[best]),
                         "held_out": float(test_score[best]),
                         "baseline_held_out": None if b is None else float(test_score[b])})
    pooled = []
    for i, (_, names, _, arrays, _) in enumerate(per):
        sub = _pooled(arrays, chosen[i], range(len(names)))
        pooled.append({objective: summary_columns(combine_sequences(sub))[objective]})
    cv = float(class_average_columns(pooled)[objective][0])
    return {"objective": objective, "folds": folds, "class": AVERAGE, "classes": list(classes),
            "cross_validated": cv, "mean_held_out": float(np.mean([p["held_out"] for p in per_fold])),
            "baseline": None if b is None else float(comb.at[b, objective]), "per_fold": per_fold,
            "fold_sequences": [{k: fs[f] for k, _, _, _, fs in per} for f in range(folds)]}


def classes_of(df: pd.DataFrame) -> list[str]:
    """The classes of a table (``class`` column, in order; the class average left out)."""
    if "class" not in df.columns:
        return []
    return [c for c in pd.unique(df["class"]) if c != AVERAGE]


def report_class_of(df: pd.DataFrame, cls: str | None = None) -> str | None:
    """The class a report ranks on: ``cls`` checked against the table, by default ``"average"``
    for a sweep over several classes, else its class. ``"average"`` of one class is that class."""
    classes = classes_of(df)
    if cls is None or cls == AVERAGE:
        if len(classes) > 1:
            return AVERAGE
        return classes[0] if classes else None
    if cls not in classes:
        raise ValueError(f"class {cls!r}: not in the table; its classes are {classes}"
                         + (f" (or {AVERAGE!r})" if len(classes) > 1 else ""))
    return cls


def class_view(df: pd.DataFrame, cls: str, family=None) -> pd.DataFrame:
    """The rows of one class of a sweep table, as a single-class table of that class.

    Per-class columns ``<cls>.<parameter>`` replace the plain ones (every parameter column then
    holds the value that class was tracked with) and all per-class columns are dropped; configs
    that are then alike (differing only in another class's values) are kept once (the first). A
    single-class table without per-class columns is returned as it is. ``cls = "average"``: the
    class-average rows (one per config, ``sequence = COMBINED``), all columns kept. ``family``: the
    table's tracker family (a name or its settings; None: read from its columns).
    """
    fc = table_family(df.columns, family)
    classes = classes_of(df)
    cls = report_class_of(df, cls)
    ccols = class_columns(df.columns, fc)
    if cls == AVERAGE:
        return df[df["class"] == AVERAGE].reset_index(drop=True)
    if len(classes) <= 1 and not ccols:
        return df
    rows = df[df["class"] == cls].copy()
    for c in ccols:
        k, p = split_class_column(c, fc)
        if k == cls:
            rows[p] = rows[c]
    rows = rows.drop(columns=ccols)
    keys = list(fc.Params._fields) + [n for n in list(fc.Options._fields) + list(extra_axes()) if n in rows.columns]
    comb = rows[rows["sequence"] == COMBINED]
    keep = comb.drop_duplicates(keys, keep="first")["config"]
    if len(keep) < len(comb):
        rows = rows[rows["config"].isin(keep.to_numpy())]
    return rows.reset_index(drop=True)



def pareto_front(df: pd.DataFrame, objectives: Sequence[str], directions: Sequence[str] | None = None) -> pd.DataFrame:
    """The non-dominated rows of ``df`` under ``objectives`` (``directions``: "maximize" /
    "minimize" each; default from the metric, :data:`MINIMISE`), one per distinct objective
    vector, sorted best first by the first objective."""
    objs = list(objectives)
    if directions is None:
        directions = ["minimize" if o in MINIMISE else "maximize" for o in objs]
    signs = np.array([1.0 if x == "maximize" else -1.0 for x in directions])
    v = df[objs].to_numpy(np.float64) * signs                  # larger is better in every column
    keep = np.array([not np.any(np.all(v >= v[i], 1) & np.any(v > v[i], 1)) for i in range(len(v))], bool)
    front = df[keep].drop_duplicates(objs) if len(df) else df
    return front.sort_values(objs[0], ascending=bool(signs[0] < 0), kind="mergesort").reset_index(drop=True)
