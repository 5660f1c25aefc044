"""Two outputs compared: per-sequence differences and paired bootstrap intervals (``dfrmot compare``).

:func:`compare_outputs` scores outputs A and B on the same sequences (TrackEval's HOTA / CLEAR /
Identity, exactly as ``dfrmot eval``), then resamples the sequences with replacement, the same draw
for both (:mod:`dfrmot_jax.metrics.kitti2d.bootstrap`: each resample recombined exactly as the
metrics combine sequences). The result is a tidy table, one row per (class, sequence or
``COMBINED``, metric) with the columns :data:`COLUMNS`: ``diff = b - a`` in ``dfrmot eval``'s units
(percent for ratios, counts), and on the ``COMBINED`` rows the 95 % percentile interval of the
difference over the resamples, the share of resamples where B is better (``p_b_better``: larger
ratios, fewer FP / FN / IDSW / Frag; ties count half) and the number of resamples. The per-sequence
rows carry no interval (one sequence is not resampled).

What the interval means: the spread of the difference if the sequences were another draw of the
same kind of sequences (the paired bootstrap over the evaluation's units, as in significance tests
of MT / NLP systems). It does not cover the variation of the detections or of the trackers' own
randomness, and with 20 sequences the tails are coarse: read ``p_b_better`` near 0.5 as "not
distinguishable", not as a p-value.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from ..choices import DEFAULT_RESAMPLES
from ..metrics.kitti2d.bootstrap import (BOOTSTRAP_FIELDS, LOWER_IS_BETTER, batch_seq_fields, intervals,
                                         paired_bootstrap)
from ..metrics.kitti2d.evaluate import combine_sequences, result_dicts
from ..metrics.kitti2d.kitti import preprocess
from ..metrics.kitti2d.table import summary_row
from ..table_columns import COMBINED
from .compare_views import differing_tracks, output_events

__all__ = ["COLUMNS", "Comparison", "compare_outputs", "comparison_text", "DEFAULT_RESAMPLES"]

COLUMNS = ("class", "seq", "metric", "a", "b", "diff", "ci_low", "ci_high", "p_b_better", "resamples")


@dataclass
class Comparison:
    """The tidy table (:data:`COLUMNS`) and what it was made from: the names of A and B, the
    resamples, the seed and the interval level; per class the ground truth, both outputs' CLEAR
    matches (``events``: class -> (gt, A's, B's :class:`~.compare_views.OutputEvents`)) and the
    ground-truth tracks they treat most differently (``differing``: class -> DataFrame); with AB3DMOT's
    figures, per class A's and B's result dicts (``ab3dmot``: class -> (A's, B's), each with the other
    sum's figures and the per-pass tables of both sums)."""

    table: pd.DataFrame
    name_a: str
    name_b: str
    resamples: int
    seed: int
    level: float = 0.95
    events: dict | None = None
    differing: dict | None = None
    ab3dmot: dict | None = None


def _scored(gt, fields: Mapping) -> dict:
    """One output's result dict ``{seq | 'COMBINED': {field: value}}`` from its per-sequence fields
    (what ``dfrmot eval`` prints)."""
    one = {f: np.asarray(v)[None] for f, v in fields.items()}
    return result_dicts(gt, {"seq": one, "comb": combine_sequences(one)})[0]


def compare_outputs(gts: Mapping[str, object], dets_a: Mapping[str, object], dets_b: Mapping[str, object],
                    name_a: str = "A", name_b: str = "B", resamples: int = DEFAULT_RESAMPLES, seed: int = 0,
                    level: float = 0.95) -> Comparison:
    """Compare two outputs per class: ``gts`` class -> prepared ground truth
    (:func:`~dfrmot_jax.metrics.kitti2d.evaluate.cached_gt`), ``dets_a`` / ``dets_b`` class -> the
    output's rows (:func:`~dfrmot_jax.metrics.kitti2d.tracker_files.read_tracker_files`). Every class
    draws its own resamples from ``seed`` (the same for A and B)."""
    if resamples < 1:
        raise ValueError(f"resamples must be at least 1, got {resamples}")
    rows: list[dict] = []
    events: dict[str, tuple] = {}
    differing: dict[str, pd.DataFrame] = {}
    for cls, gt in gts.items():
        ba, bb = preprocess(gt, dets_a[cls]), preprocess(gt, dets_b[cls])          # once per output
        ev_a, ev_b = output_events(gt, dets_a[cls], ba), output_events(gt, dets_b[cls], bb)
        events[cls] = (gt, ev_a, ev_b)
        differing[cls] = differing_tracks(gt, ev_a, ev_b)
        fa, fb = batch_seq_fields(ba), batch_seq_fields(bb)
        da, db = _scored(gt, fa), _scored(gt, fb)
        boot_a, boot_b, _ = paired_bootstrap(fa, fb, resamples, seed)
        ci = intervals(boot_a, boot_b, level)
        for s in list(gt.sequences) + [COMBINED]:
            ra, rb = summary_row(da[s]), summary_row(db[s])
            for m in BOOTSTRAP_FIELDS:
                a, b = float(ra[m]), float(rb[m])
                rows.append({"class": cls, "seq": s, "metric": m, "a": a, "b": b, "diff": b - a,
                             **({**ci[m], "resamples": resamples} if s == COMBINED else {})})
    table = pd.DataFrame(rows, columns=list(COLUMNS))
    table["resamples"] = table["resamples"].astype("Int64")
    return Comparison(table, name_a, name_b, resamples, seed, level, events, differing)


def comparison_text(c: Comparison, top: int = 5, metrics: Sequence[str] = BOOTSTRAP_FIELDS) -> str:
    """The comparison as text: per class, the COMBINED figures of A and B, B - A with its interval and
    P(B better); then the sequences where HOTA moves most."""
    pct = int(round(100 * c.level))
    lines = [f"A = {c.name_a}", f"B = {c.name_b}",
             f"paired bootstrap over sequences: {c.resamples:,} resamples (seed {c.seed}); {pct} % interval of "
             f"B - A; P(B better): share of resamples where B is better (fewer IDSW / FP / FN / Frag)"]
    t = c.table
    for cls, g in t.groupby("class", sort=False):
        comb = g[g["seq"] == COMBINED].set_index("metric")
        n_seq = g.loc[g["seq"] != COMBINED, "seq"].nunique()
        lines += ["", f"{cls}, {n_seq} sequences (TrackEval Kitti2DBox; HOTA family mean over alphas, %)",
                  f"{'metric':<8} {'A':>9} {'B':>9} {'B - A':>9}   {pct} % interval        P(B better)"]
        for m in metrics:
            r = comb.loc[m]
            f = _fmt(m)
            lines.append(f"{m:<8} {f(r['a']):>9} {f(r['b']):>9} {_signed(m, r['diff']):>9}   "
                         f"[{_signed(m, r['ci_low']):>8}, {_signed(m, r['ci_high']):>8}]   {r['p_b_better']:.3f}")
        per = g[(g["seq"] != COMBINED) & (g["metric"] == "HOTA")]
        moved = per.reindex(per["diff"].abs().sort_values(ascending=False).index).head(top)
        if len(moved):
            lines.append("HOTA by sequence, largest moves: " + ", ".join(
                f"{r.seq} {r.a:.2f} -> {r.b:.2f} ({r.diff:+.2f})" for r in moved.itertuples()))
        lines += _differing_lines(c, cls, top)
    return "\n".join(lines)


def _differing_lines(c: Comparison, cls: str, top: int) -> list[str]:
    """The ground-truth tracks where A and B differ most (CLEAR's misses, switches, fragmentations)."""
    d = None if c.differing is None else c.differing.get(cls)
    if d is None or not len(d):
        return ["no ground-truth track is treated differently (same misses, switches, fragmentations)"]
    lines = ["ground-truth tracks where they differ most (CLEAR at IoU 0.5; missed frames, switches, "
             "fragmentations of A -> B):"]
    for r in d.head(top).itertuples():
        lines.append(f"  sequence {r.seq} gt id {r.gt_id} frames {r.first}-{r.last} ({r.present} present): missed "
                     f"{r.missed_a} -> {r.missed_b}, switches {r.switches_a} -> {r.switches_b}, frags {r.frags_a} "
                     f"-> {r.frags_b}")
    return lines


def _fmt(metric: str):
    return (lambda v: f"{int(round(v))}") if metric in LOWER_IS_BETTER else (lambda v: f"{v:.2f}")


def _signed(metric: str, v: float) -> str:
    return f"{int(round(v)):+d}" if metric in LOWER_IS_BETTER else f"{v:+.2f}"
