"""``dfrmot compare A B --html OUT.html``: a comparison as one self-contained page (inline CSS and SVG,
no script, the report's style): the combined figures with their intervals, HOTA per sequence, the
ground-truth tracks the outputs treat most differently and, for the first of them, the timelines and
bird's-eye views of both outputs; then the whole sequence where HOTA moves most, as timelines."""

from __future__ import annotations

import time
from html import escape

import pandas as pd

from ..io.atomic import write_text_atomic
from ..metrics.kitti2d.bootstrap import LOWER_IS_BETTER
from ..version import __version__
from ..metrics.samota.table import AB3DMOT_COUNT_COLUMNS, other_sum_line, recall_table
from ..table_columns import COMBINED
from .compare import Comparison
from .compare_views import bev_svg, timeline_svg
from .figures import recall_points_figure
from .html import CSS

__all__ = ["render_compare_html", "write_compare_html"]

#: differing ground-truth tracks drawn (timelines and bird's-eye views of both outputs each)
VIEWS_SHOWN = 3
#: frames shown before and after a differing track
MARGIN = 10


def _table(df: pd.DataFrame) -> str:
    head = "".join(f"<th>{escape(str(c))}</th>" for c in df.columns)
    body = "".join("<tr>" + "".join(f"<td>{escape(_cell(v))}</td>" for v in row) + "</tr>"
                   for row in df.itertuples(index=False))
    return f"<table><tr>{head}</tr>{body}</table>"


def _cell(v) -> str:
    if isinstance(v, float):
        return "" if pd.isna(v) else f"{v:.3f}"
    return str(v)


def _combined(comb: pd.DataFrame) -> pd.DataFrame:
    """The combined figures as shown: counts (IDSW, FP, FN, Frag) as whole numbers, their differences
    and interval bounds signed, as the printed comparison shows them; other figures as :func:`_cell`."""
    out = comb.astype(object)
    counts = out["metric"].map(_is_count).astype(bool)
    for col in ("a", "b", "diff", "ci_low", "ci_high"):
        signed = col != "a" and col != "b"
        out.loc[counts, col] = [("" if pd.isna(v) else f"{int(round(v)):+d}" if signed else f"{int(round(v))}")
                                for v in out.loc[counts, col]]
    return out


def _is_count(metric: str) -> bool:
    """A count, shown whole: TrackEval's IDSW, FP, FN, Frag and AB3DMOT's (``ab3dmot_FP@3d:0.25``, ...)."""
    base = str(metric).split("@")[0]
    return base in LOWER_IS_BETTER or base in AB3DMOT_COUNT_COLUMNS


def _resamples_text(c: Comparison) -> str:
    """How many resamples each row used: the kitti2d figures ``c.resamples``; AB3DMOT's rows (each
    resample a full rescoring) their own, as the table's ``resamples`` column says."""
    t = c.table
    other = sorted({int(n) for m, n in zip(t["metric"], t["resamples"])
                    if "@" in str(m) and not pd.isna(n) and int(n) != c.resamples})
    text = f"{c.resamples:,} resamples (seed {c.seed}), each recombined as TrackEval combines sequences"
    if other:
        text += (f"; AB3DMOT's rows (metric@IoU) {', '.join(f'{n:,}' for n in other)} resamples, each a full "
                 f"rescoring of both outputs (the resamples column gives each row's)")
    return text


def _views(c: Comparison, cls: str) -> list[str]:
    gt, ev_a, ev_b = c.events[cls]
    out = []
    diff = c.differing[cls]
    for r in diff.head(VIEWS_SHOWN).itertuples():
        s = list(gt.sequences).index(r.seq)
        n = int(gt.lengths[s])
        f0, f1 = max(0, r.first - MARGIN), min(n - 1, r.last + MARGIN)
        out += [f"<h3>Sequence {escape(r.seq)}, ground-truth id {r.gt_id}, frames {f0}-{f1}</h3>",
                f"<p>missed {r.missed_a} &rarr; {r.missed_b}, switches {r.switches_a} &rarr; {r.switches_b}, "
                f"fragmentations {r.frags_a} &rarr; {r.frags_b} (A &rarr; B).</p>",
                "<figure>" + timeline_svg(gt, ev_a, s, f0, f1, "A") + timeline_svg(gt, ev_b, s, f0, f1, "B")
                + "</figure>",
                "<figure>" + bev_svg(gt, ev_a, s, f0, f1, "A", extent_of=[ev_b])
                + bev_svg(gt, ev_b, s, f0, f1, "B", extent_of=[ev_a]) + "</figure>"]
    return out


def _whole_sequence(c: Comparison, cls: str) -> list[str]:
    t = c.table
    per = t[(t["class"] == cls) & (t["seq"] != COMBINED) & (t["metric"] == "HOTA")]
    if not len(per):
        return []
    seq = per.loc[per["diff"].abs().idxmax(), "seq"]
    gt, ev_a, ev_b = c.events[cls]
    s = list(gt.sequences).index(seq)
    n = int(gt.lengths[s])
    return [f"<h3>Sequence {escape(seq)}, whole (the largest HOTA move)</h3>",
            f'<figure class="whole" data-seq="{escape(seq)}">' + timeline_svg(gt, ev_a, s, 0, n - 1, "A", most=None)
            + timeline_svg(gt, ev_b, s, 0, n - 1, "B", most=None) + "</figure>"]


def _recall_points(c: Comparison, cls: str) -> list[str]:
    """AB3DMOT's recall points of A and B (their sum's), and the other sum's figures where they differ."""
    if not c.ab3dmot or cls not in c.ab3dmot:
        return []
    a, b = c.ab3dmot[cls]
    both = pd.concat([recall_table(r, tracker=k) for k, r in (("A", a), ("B", b))], ignore_index=True)
    table = both[both["sum"] == a["sum"]]
    others = [line for k, r in (("A", a), ("B", b)) if (line := other_sum_line(r, k)) is not None]
    return [f"<h2>{escape(cls)}: AB3DMOT's recall points</h2>",
            f"<p>Per recall point r of AB3DMOT's evaluator: sMOTA and the matches to ignored ground truth "
            f"(TP_ignored: in the recall that places the points, not in sMOTA's denominator) of A and B, with "
            f"both sums of track scores (solid: compensated, dashed: sequential); a cross marks a pass where the "
            f"sequential sum's drift dropped tracks. Ratios in percent, the recall point too.</p>",
            _figure(recall_points_figure(both)), *(f"<p>{escape(x)}</p>" for x in others),
            f"<details><summary>the table ({len(table)} rows, {escape(a['sum'])} sum): per recall point the "
            f"score threshold chosen, the recall reached, the pass's counts, sMOTA, TP_ignored and the tracks "
            f"dropped by the drift</summary>{_table(table)}</details>"]


def _figure(svg: str) -> str:
    return f"<figure>{svg}</figure>"


def render_compare_html(c: Comparison) -> str:
    """The page of a comparison (:func:`~.compare.compare_outputs`)."""
    pct = int(round(100 * c.level))
    body = [f"<h1>{escape(c.name_a)} vs {escape(c.name_b)}</h1>",
            f'<p class="lead">A = {escape(c.name_a)}; B = {escape(c.name_b)}. Paired bootstrap over sequences: '
            f"{_resamples_text(c)}; {pct} % interval of B &minus; A; P(B better): the share of resamples where B is better (fewer IDSW, "
            f"FP, FN, Frag). dfrmot_jax {escape(__version__)}, {time.strftime('%Y-%m-%d %H:%M')}.</p>"]
    for cls, g in c.table.groupby("class", sort=False):
        comb = g[g["seq"] == COMBINED][["metric", "a", "b", "diff", "ci_low", "ci_high", "p_b_better", "resamples"]]
        per = g[(g["seq"] != COMBINED) & (g["metric"] == "HOTA")][["seq", "a", "b", "diff"]]
        body += [f"<h2>{escape(cls)}: combined</h2>", _table(_combined(comb)),
                 f"<h2>{escape(cls)}: HOTA per sequence</h2>", _table(per),
                 f"<h2>{escape(cls)}: where they differ</h2>",
                 "<p>The ground-truth tracks with the largest differences in missed frames, identity switches and "
                 "fragmentations (CLEAR's matching at IoU 0.5; frames within the sequence).</p>",
                 _table(c.differing[cls].drop(columns=["gid"]))]
        body += _views(c, cls) + _whole_sequence(c, cls) + _recall_points(c, cls)
    return (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>dfrmot compare</title>'
            f"<style>{CSS}</style></head>\n<body>\n" + "\n".join(body) + "\n</body></html>\n")


def write_compare_html(c: Comparison, path) -> None:
    """Write :func:`render_compare_html` of ``c`` to ``path`` (atomically)."""
    write_text_atomic(path, render_compare_html(c))
