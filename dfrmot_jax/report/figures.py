"""The figures of the HTML report (:mod:`.html`), drawn with Matplotlib as inline SVG.

Each function takes numbers the report and analysis functions computed (nothing is computed here
but what a plot needs: positions, a running best) and returns one ``<svg>`` element as text.
Matplotlib is imported inside the functions (an optional dependency at import time; no pyplot, no
backend switched, no global setting changed: figures are ``matplotlib.figure.Figure`` objects
rendered under an ``rc_context``). Text is drawn as paths, so the SVG needs no font; the ids inside
each SVG are prefixed per figure, so that several can share one page.
"""

from __future__ import annotations

import contextlib
import io
import hashlib
import itertools
import math
import re
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from .analysis import fmt_value

#: a colour per line, colour-blind safe (Okabe-Ito)
COLOURS = ("#0072B2", "#E69F00", "#009E73", "#CC79A7", "#56B4E9", "#D55E00", "#F0E442", "#000000")
_RC = {"svg.fonttype": "path", "svg.hashsalt": "dfrmot", "font.size": 9, "axes.titlesize": 9,
       "axes.spines.top": False, "axes.spines.right": False, "legend.fontsize": 8, "legend.frameon": False}


@contextlib.contextmanager
def _rc():
    """Matplotlib's default settings and :data:`_RC`, whatever the process set before (Optuna's plots
    set the ggplot style globally): a page is a function of its report alone."""
    import matplotlib

    with matplotlib.rc_context():
        matplotlib.rcdefaults()
        matplotlib.rcParams.update(_RC)
        yield


def _figure(width: float, height: float):
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), layout="constrained")


def to_svg(fig) -> str:
    """One ``<svg>`` element (no XML header), its ids prefixed so that it can share a page: the prefix
    is a digest of the figure's own SVG, so a page is a function of its report alone (a counter made
    it depend on the figures the process had drawn before; figures drawn alike share their ids and
    their content)."""

    buf = io.StringIO()
    with _rc():
        fig.savefig(buf, format="svg", metadata={"Date": None, "Creator": None})
    text = buf.getvalue()
    text = re.sub(r"<metadata>.*?</metadata>\s*", "", text[text.index("<svg"):], flags=re.S)
    pre = f"f{hashlib.sha1(text.encode()).hexdigest()[:10]}-"
    text = re.sub(r'\bid="([^"]+)"', lambda m: f'id="{pre}{m.group(1)}"', text)
    text = re.sub(r'(href=")#([^"]+)"', lambda m: f'{m.group(1)}#{pre}{m.group(2)}"', text)
    return re.sub(r"url\(#([^)]+)\)", lambda m: f"url(#{pre}{m.group(1)})", text)


def _draw(width: float, height: float, nrows: int = 1, ncols: int = 1, **kw):
    with _rc():
        fig = _figure(width, height)
        axes = fig.subplots(nrows, ncols, squeeze=False, **kw)
    return fig, axes


def sensitivity_figure(profiles: Mapping[str, pd.DataFrame], objective: str, baseline: float | None) -> str:
    """One panel per axis: the objective of the best config with each value (line) and the mean
    over the configs with it (dashed); the baseline as a grey line. ``profiles``:
    :func:`~.analysis.axis_profiles`."""

    n = len(profiles)
    cols = min(3, n)
    rows = math.ceil(n / cols)
    with _rc():
        fig, axes = _draw(3.1 * cols, 2.3 * rows, rows, cols)
        for ax, (name, p) in zip(axes.flat, profiles.items()):
            numeric = pd.api.types.is_numeric_dtype(p["value"]) and not pd.api.types.is_bool_dtype(p["value"])
            x = p["value"].to_numpy(np.float64) if numeric else np.arange(len(p))
            ax.plot(x, p["best"], "o-", color=COLOURS[0], label="best config with the value")
            ax.plot(x, p["mean"], "s--", color=COLOURS[1], label="mean over the configs")
            if baseline is not None:
                ax.axhline(baseline, color="0.55", lw=1, label="baseline")
            if not numeric:
                ax.set_xticks(x, list(p["label"]), rotation=20 if len(p) > 3 else 0)
            ax.set_title(name)
            ax.set_ylabel(objective)
        for ax in list(axes.flat)[n:]:
            ax.set_visible(False)
        fig.legend(*axes.flat[0].get_legend_handles_labels(), loc="outside lower center", ncols=3)
        return to_svg(fig)


def heatmap_figure(values: pd.DataFrame, objective: str) -> str:
    """``values``: [configs, sequences] of the objective (row labels: config; columns: sequence)."""

    r, c = values.shape
    with _rc():
        fig, axes = _draw(min(12.0, 2.2 + 0.55 * c), 1.3 + 0.32 * r)
        ax = axes[0, 0]
        im = ax.imshow(values.to_numpy(np.float64), aspect="auto", cmap="viridis")
        ax.set_xticks(np.arange(c), [str(x) for x in values.columns], rotation=45 if c > 8 else 0)
        ax.set_yticks(np.arange(r), [str(x) for x in values.index])
        ax.set_xlabel("sequence")
        if r * c <= 300:
            arr = values.to_numpy(np.float64)
            mid = np.nanmean(arr)
            for i in range(r):
                for j in range(c):
                    if np.isfinite(arr[i, j]):
                        ax.text(j, i, f"{arr[i, j]:.1f}", ha="center", va="center", fontsize=7,
                                color="white" if arr[i, j] < mid else "black")
        fig.colorbar(im, ax=ax, label=objective, shrink=0.9)
        return to_svg(fig)


def folds_figure(cv: Mapping, objective: str, in_sample: float | None = None) -> str:
    """Per fold: the chosen config's objective on the training folds and on the held-out fold, and
    the baseline's on the held-out fold; lines: the cross-validated figure, the in-sample best and
    the baseline. ``cv``: :func:`~.analysis.cross_validate`'s dict (or a tune's ``nested.json``)."""

    folds = list(cv["per_fold"])
    x = np.arange(len(folds))
    w = 0.27
    with _rc():
        fig, axes = _draw(max(4.5, 1.2 * len(folds) + 2.5), 3.0)
        ax = axes[0, 0]
        bars = [("train (chosen)", "train", COLOURS[4]), ("held out (chosen)", "held_out", COLOURS[0]),
                ("held out (baseline)", "baseline_held_out", "0.6")]
        for k, (label, key, colour) in enumerate(bars):
            v = [np.nan if f.get(key) is None else f[key] for f in folds]
            ax.bar(x + (k - 1) * w, v, w, label=label, color=colour)
        ax.axhline(cv["cross_validated"], color=COLOURS[5], lw=1.5, label=f"cross-validated {cv['cross_validated']:.2f}")
        if in_sample is not None:
            ax.axhline(in_sample, color=COLOURS[2], lw=1, ls="--", label=f"in-sample best {in_sample:.2f}")
        if cv.get("baseline") is not None:
            ax.axhline(cv["baseline"], color="0.35", lw=1, ls=":", label=f"baseline {cv['baseline']:.2f}")
        vals = [f[k] for f in folds for k in ("train", "held_out", "baseline_held_out") if f.get(k) is not None]
        lo, hi = min(vals + [cv["cross_validated"]]), max(vals + [cv["cross_validated"]])
        ax.set_ylim(max(0.0, lo - 0.15 * (hi - lo + 1)), hi + 0.1 * (hi - lo + 1))
        ax.set_xticks(x, [f"fold {f['fold']}" for f in folds])
        ax.set_ylabel(objective)
        ax.legend(loc="center left", bbox_to_anchor=(1.0, 0.5))
        return to_svg(fig)


def curves_figure(curves: pd.DataFrame, objective: str, settings: Mapping[str, Sequence[str]]) -> str:
    """The objective against the distortion level (mean ± SE over seeds), one panel per kind, a
    line per setting (``settings``: kind -> the settings to draw, best first). ``curves``:
    :func:`~.robustness.robustness_curves`."""

    kinds = list(settings)
    with _rc():
        fig, axes = _draw(4.2 * len(kinds), 3.6, 1, len(kinds))
        for ax, kind in zip(axes.flat, kinds):
            ck = curves[curves["kind"] == kind]
            for colour, st in zip(itertools.cycle(COLOURS), settings[kind]):
                cs = ck[ck["setting"] == st].sort_values("level")
                ax.errorbar(cs["level"], cs[objective], yerr=cs[f"{objective}_se"], color=colour, marker="o",
                            ms=3, capsize=3, lw=1.2, label=st)
            ax.set_title(f"{kind}")
            ax.set_xlabel("distortion level")
            ax.set_ylabel(f"{objective} (mean ± SE)")
        fig.legend(*axes.flat[0].get_legend_handles_labels(), loc="outside lower center", ncols=min(3, len(
            settings[kinds[0]])))
        return to_svg(fig)


def contrast_figure(con: pd.DataFrame, objective: str, high: str, low: str) -> str:
    """A contrast of two groups of an axis (:func:`~.robustness.robustness_contrast` rows of one
    metric): per kind (and ``by`` value), the two groups' means against the level (top) and their
    gap ± SE over seeds (bottom; filled markers: significantly better)."""

    by = [c for c in con.attrs.get("by", [])]
    keys = list(con.groupby(by + ["kind"], sort=False).groups) if by else list(pd.unique(con["kind"]))
    with _rc():
        fig, axes = _draw(max(4.0, 3.3 * len(keys)), 5.0, 2, len(keys), sharex="col")
        for j, key in enumerate(keys):
            key = key if isinstance(key, tuple) else (key,)
            d = con
            for col, v in zip(by + ["kind"], key):
                d = d[d[col] == v]
            d = d.sort_values("level")
            top, bottom = axes[0, j], axes[1, j]
            top.plot(d["level"], d["high_mean"], "o-", color=COLOURS[0], ms=3, label=high)
            top.plot(d["level"], d["low_mean"], "s-", color=COLOURS[1], ms=3, label=low)
            top.set_title(" ".join(fmt_value(v) for v in key))
            top.set_ylabel(objective)
            bottom.axhline(0, color="0.6", lw=1)
            bottom.errorbar(d["level"], d["gap"], yerr=d["se"], color=COLOURS[5], capsize=3, lw=1.2, fmt="-")
            sig = d["helps"].to_numpy(bool)
            bottom.plot(d["level"][sig], d["gap"][sig], "o", color=COLOURS[5], ms=5, label="significant")
            bottom.plot(d["level"][~sig], d["gap"][~sig], "o", mfc="white", color=COLOURS[5], ms=5,
                        label="not significant")
            bottom.set_xlabel("distortion level")
            bottom.set_ylabel("gap ± SE")
        axes[0, 0].legend(loc="best")
        axes[1, 0].legend(loc="best")
        return to_svg(fig)


def history_figure(trials: pd.DataFrame, objective: str, minimise: bool) -> str:
    """A tune's trials in order: the objective of each (grey: refinement steps) and the best so far."""

    t = trials.sort_values("trial")
    y = t[objective].to_numpy(np.float64)
    best = np.fmin.accumulate(y) if minimise else np.fmax.accumulate(y)
    with _rc():
        fig, axes = _draw(6.5, 3.0)
        ax = axes[0, 0]
        search = (t["phase"] == "search").to_numpy() if "phase" in t.columns else np.ones(len(t), bool)
        ax.plot(t["trial"][search], y[search], "o", ms=4, color=COLOURS[0], alpha=0.7, label="search trial")
        if (~search).any():
            ax.plot(t["trial"][~search], y[~search], "^", ms=4, color=COLOURS[2], alpha=0.7, label="refinement")
        ax.step(t["trial"], best, where="post", color=COLOURS[5], lw=1.5, label="best so far")
        if "baseline" in t.columns and t["baseline"].any():
            ax.axhline(float(t.loc[t["baseline"].to_numpy(bool), objective].iloc[0]), color="0.55", lw=1,
                       label="baseline")
        ax.set_xlabel("trial")
        ax.set_ylabel(objective)
        ax.legend(loc="best")
        return to_svg(fig)


def pareto_figure(trials: pd.DataFrame, front: pd.DataFrame, objectives: Sequence[str]) -> str:
    """Every trial of a two-objective tune, its Pareto front joined (``front``: :func:`~.analysis.pareto_front`)."""

    a, b = objectives
    with _rc():
        fig, axes = _draw(5.0, 3.6)
        ax = axes[0, 0]
        ax.plot(trials[a], trials[b], "o", ms=4, color="0.65", label="trial")
        f = front.sort_values(a)
        ax.plot(f[a], f[b], "o-", ms=5, color=COLOURS[5], label="Pareto front")
        ax.set_xlabel(a)
        ax.set_ylabel(b)
        ax.legend(loc="best")
        return to_svg(fig)


def recall_points_figure(table: pd.DataFrame) -> str:
    """AB3DMOT's recall points of one class (:func:`~dfrmot_jax.metrics.samota.table.recall_table`
    rows of one or more ``tracker`` values, each sum's): two panels against the recall point, sMOTA and
    TP_ignored (the matches to ignored ground truth), one line per output and sum (solid: compensated,
    dashed: sequential), and a red cross on each pass where the sequential sum's drift dropped tracks
    (``drifted`` > 0)."""
    keys = [k for k in ("tracker", "sum") if k in table.columns]
    with _rc():
        fig, axes = _draw(8.0, 2.8, 1, 2)
        for i, (key, g) in enumerate(table.groupby(keys, sort=False)):
            key = key if isinstance(key, tuple) else (key,)
            label = " ".join(str(k) for k in key)
            style = "--" if "sequential" in key else "-"
            colour = COLOURS[i % len(COLOURS)]
            for ax, col in zip(axes[0], ("sMOTA", "TP_ignored")):
                ax.plot(g["recall_point"], g[col], style, color=colour, lw=1.2, marker=".", ms=3, label=label)
                hit = g[g["drifted"] > 0]
                if len(hit):
                    ax.plot(hit["recall_point"], hit[col], "x", color=COLOURS[5], ms=6, mew=1.5,
                            label=f"{label}: tracks dropped by the drift" if col == "sMOTA" else None)
        for ax, col in zip(axes[0], ("sMOTA (%)", "TP_ignored (matches)")):
            ax.set_xlabel("recall point (%)")
            ax.set_ylabel(col)
        axes[0, 1].legend(*axes[0, 0].get_legend_handles_labels(), loc="center left", bbox_to_anchor=(1.0, 0.5))
        return to_svg(fig)
