"""Robustness: metrics against distortion levels (sweeps with a [distortion] table): curves per
setting, contrasts of two groups of an axis paired by seed, and where a contrast stops helping."""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np
import pandas as pd
from scipy import stats

from .analysis import check_objective, fmt_value, json_value, objective_direction, varied_axes
from ..table_columns import COMBINED, DISTORTION_AXES, Contrast
from .text import paragraph, text_table


def _check_distorted(df: pd.DataFrame) -> None:
    if "distortion.kind" not in df.columns:
        raise ValueError("the table has no distortion columns (a sweep without a [distortion] table)")


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
    return rows[list(axes)].apply(lambda r: " ".join(f"{a}={fmt_value(r[a])}" for a in axes), axis=1).astype(object)


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
        check_objective(df, m)
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
    _check_distorted(df)
    metrics = [metrics] if isinstance(metrics, str) else list(metrics)
    by = [by] if isinstance(by, str) else list(by)
    for m in metrics:
        check_objective(df, m)
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
            sign = objective_direction(m)
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
        sign = objective_direction(str(key[-1]))
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


def robustness_text(df: pd.DataFrame, objective: str, top: int) -> tuple[list[str], dict]:
    """Report lines: the objective per level (mean ± SE over seeds) per kind, for the best settings."""
    curves = robustness_curves(df, [objective])
    d = objective_direction(objective)
    lines, summary = [], {}
    n_seeds = int(curves.loc[curves["level"] > 0, "n"].max()) if (curves["level"] > 0).any() else 1
    lines.append(paragraph(f"robustness: {objective} (COMBINED) per distortion level, mean ± SE over {n_seeds} seed(s) "
                       f"(level 0 = undistorted); settings ranked by their mean {objective} over the kind's levels"))
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
        view = pd.DataFrame.from_dict(table, orient="index", columns=[fmt_value(v) for v in levels])
        view.index.name = f"{kind} \\ level"
        lines.append("")
        lines.append(text_table(view.reset_index(), keys=(view.index.name,)))
        summary[kind] = {"levels": [float(v) for v in levels],
                         "settings": {st: [float(x) for x in ck[ck["setting"] == st].set_index("level")
                                           .reindex(levels)[objective]] for st in order}}
    return lines, summary


def contrast_text(df: pd.DataFrame, c: Contrast, objective: str) -> tuple[list[str], list[dict]]:
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
        lines.append(paragraph(f"contrast {c.axis} in {list(c.high)} minus {c.axis} in {list(c.low)} ({head}): mean gap "
                           f"± SE over seeds, paired by seed; * = significantly better (one-sided t-test, 5 %; level 0: "
                           f"sign)"))
        con = con.assign(cell=[f"{g:+.2f}" + (f"±{s:.2f}" if n > 1 else "") + ("*" if h else "")
                               for g, s, n, h in zip(con["gap"], con["se"], con["n"], con["helps"])])
        for kind, ck in con.groupby("kind", sort=False):
            view = ck.pivot_table(index=by + ["metric"], columns="level", values="cell", aggfunc="first", sort=False)
            view.columns = [fmt_value(v) for v in view.columns]
            view.columns.name = f"{kind} level"
            flat = view.fillna("").reset_index()
            flat.columns = [str(x) for x in flat.columns]
            lines.append(f"{kind}, per level:")
            lines.append(text_table(flat, keys=tuple(by + ["metric"])))
        summ = robustness_summary(con)
        lines.append(paragraph("answer: helps_up_to = highest level up to which the gap is significantly better at every "
                           "distorted level; stops_at = first level where it is not; crossing = first level where the "
                           "mean gap changes sign"))
        lines.append(text_table(summ, keys=tuple(c for c in ("kind", *by) if c in summ.columns),
                            float_format=lambda v: f"{v:.3g}"))
        answers.extend({k: json_value(v) if not (isinstance(v, float) and math.isnan(v)) else None
                        for k, v in r.items()} for r in summ.to_dict("records"))
    return lines, answers

