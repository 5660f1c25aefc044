"""Where two outputs differ: the ground-truth tracks they treat most differently, and two views of them.

From CLEAR's own matches of each output (:func:`~dfrmot_jax.metrics.kitti2d.clear.clear_matches`: the
pairs, switches and restarts behind IDSW and Frag):

- :func:`track_events` per output and ground-truth track: frames present, matched, missed, switches,
  fragmentations;
- :func:`differing_tracks`: the ground-truth tracks on which the outputs differ most (missed frames,
  switches and fragmentations, summed as absolute differences), with sequence, the label file's track
  id and frame range, so that a user can go and look;
- :func:`timeline_svg`: ground-truth tracks x frames of one output, each matched frame coloured by the
  tracker id that covers it, misses as grey gaps, switches as red ticks (one ``line.switch`` per IDSW);
- :func:`bev_svg`: the bird's-eye view (x right, z forward, camera coordinates, metres) of the ground
  truth's tracks over a frame range and an output's rows with 3D boxes, coloured by tracker id, switches
  (red crosses, one ``path.switch`` per IDSW) and misses (open circles) marked at the ground truth.

Plain SVG strings (no plotting library: a few hundred shapes whose classes tests count).
"""

from __future__ import annotations

from html import escape
from typing import Mapping, NamedTuple, Sequence

import numpy as np
import pandas as pd

from ..metrics.kitti2d.clear import clear_matches
from ..metrics.kitti2d.kitti import preprocess

__all__ = ["OutputEvents", "output_events", "track_events", "differing_tracks", "timeline_svg", "bev_svg"]

PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#17becf", "#bcbd22", "#7f7f7f",
           "#393b79", "#637939", "#8c6d31", "#843c39", "#7b4173", "#3182bd", "#e6550d", "#31a354", "#756bb1")


class OutputEvents(NamedTuple):
    """One output's CLEAR matches (``clear_matches`` of its lane 0: frame, gid, tid, switch, restart)
    and its rows (``TrackerDets``: frame, track_id, box3d / has3d when read with 3D)."""

    matches: Mapping[str, np.ndarray]
    dets: object


def output_events(gt, dets, batch=None) -> OutputEvents:
    """CLEAR's matches of one output (read by ``read_tracker_files``) against ``gt``; ``batch``: its
    ``preprocess``-ed ``EvalBatch`` when already made."""
    return OutputEvents(clear_matches(preprocess(gt, dets) if batch is None else batch), dets)


def _eval_rows(gt) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The ground truth's evaluated rows: (frame [NE], gid [NE], class-row index [NE])."""
    return np.repeat(np.arange(gt.n_frames), gt.eval_count), np.asarray(gt.eval_gid), np.flatnonzero(gt.row_eval)


def track_events(gt, ev: OutputEvents) -> pd.DataFrame:
    """Per ground-truth track (global id order): present, matched, missed, switches, frags."""
    ng = len(gt.gid_count)
    m = ev.matches
    matched = np.bincount(m["gid"], minlength=ng)
    return pd.DataFrame({"present": gt.gid_count.astype(np.int64), "matched": matched,
                         "missed": gt.gid_count.astype(np.int64) - matched,
                         "switches": np.bincount(m["gid"], weights=m["switch"], minlength=ng).astype(np.int64),
                         "frags": np.bincount(m["gid"], weights=m["restart"], minlength=ng).astype(np.int64)})


def differing_tracks(gt, a: OutputEvents, b: OutputEvents, top: int = 10) -> pd.DataFrame:
    """The ``top`` ground-truth tracks where A and B differ most: columns seq, gt_id (the label
    file's), gid, first, last (frames within the sequence), present, then missed / switches / frags of
    A and B, and ``difference`` (the sum of their absolute differences)."""
    ta, tb = track_events(gt, a), track_events(gt, b)
    frame, gid, _ = _eval_rows(gt)
    ng = len(gt.gid_count)
    first = np.full(ng, np.iinfo(np.int64).max)
    last = np.full(ng, -1)
    np.minimum.at(first, gid, frame)
    np.maximum.at(last, gid, frame)
    seq = gt.gid_seq
    off = np.asarray(gt.offsets)[seq]
    diff = sum(np.abs(ta[c] - tb[c]) for c in ("missed", "switches", "frags"))
    out = pd.DataFrame({"seq": np.asarray(gt.sequences)[seq], "gt_id": gt.gid_label, "gid": np.arange(ng),
                        "first": first - off, "last": last - off, "present": ta["present"],
                        "missed_a": ta["missed"], "missed_b": tb["missed"], "switches_a": ta["switches"],
                        "switches_b": tb["switches"], "frags_a": ta["frags"], "frags_b": tb["frags"],
                        "difference": diff})
    out = out[out["difference"] > 0]
    return out.sort_values(["difference", "gid"], ascending=[False, True], kind="mergesort").head(top) \
        .reset_index(drop=True)


def _colour(tid: int) -> str:
    return PALETTE[int(tid) % len(PALETTE)]


def timeline_svg(gt, ev: OutputEvents, seq: int, f0: int, f1: int, title: str, gids=None, width: int = 900,
                 most: int | None = 40) -> str:
    """Ground-truth tracks (rows; ``gids`` or every track present in frames f0..f1 of sequence index
    ``seq``, the first ``most``, None: all) x frames of one output: matched frames coloured by tracker
    id, missed frames grey, switches as red ticks (``line.switch``, one per IDSW of the rows drawn)."""
    frame, gid, _ = _eval_rows(gt)
    g0 = int(gt.offsets[seq])
    lo, hi = g0 + f0, g0 + f1
    inside = (frame >= lo) & (frame <= hi)
    rows = np.unique(gid[inside]) if gids is None else np.asarray(gids)
    rows = rows if most is None else rows[:most]
    n_frames = max(1, f1 - f0 + 1)
    left, top, row_h = 70, 28, 12
    x = lambda f: left + (f - lo) * (width - left - 10) / n_frames          # noqa: E731
    cell = max(1.0, (width - left - 10) / n_frames)
    height = top + row_h * max(1, len(rows)) + 24
    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" class="timeline" data-seq="{escape(gt.sequences[seq])}" '
             f'data-output="{escape(title)}" viewBox="0 0 {width} {height}" width="{width}" height="{height}">',
             f'<text x="4" y="16" font-size="12">{escape(title)}: sequence {escape(gt.sequences[seq])}, frames '
             f'{f0}-{f1}</text>']
    m = ev.matches
    for r, g in enumerate(rows):
        y = top + r * row_h
        parts.append(f'<text x="4" y="{y + 9}" font-size="9">gt {int(gt.gid_label[g])}</text>')
        present = frame[(gid == g) & inside]
        for f in present:
            parts.append(f'<rect class="miss" x="{x(f):.1f}" y="{y}" width="{cell:.1f}" height="{row_h - 2}" '
                         f'fill="#e4e4e4"/>')
        sel = np.flatnonzero((m["gid"] == g) & (m["frame"] >= lo) & (m["frame"] <= hi))
        for i in sel:
            parts.append(f'<rect class="hit" x="{x(m["frame"][i]):.1f}" y="{y}" width="{cell:.1f}" '
                         f'height="{row_h - 2}" fill="{_colour(m["tid"][i])}"/>')
        for i in sel[m["switch"][sel]]:
            xs = x(m["frame"][i])
            parts.append(f'<line class="switch" x1="{xs:.1f}" y1="{y - 2}" x2="{xs:.1f}" y2="{y + row_h}" '
                         f'stroke="#d62728" stroke-width="2"/>')
    parts.append(f'<text x="{left}" y="{height - 6}" font-size="10" fill="#555">grey: ground truth not matched '
                 f'(missed); colour: the tracker id covering it; red tick: an identity switch</text></svg>')
    return "".join(parts)


def _bev_rows(ev: OutputEvents, lo: int, hi: int) -> np.ndarray:
    """The rows of an output with a 3D box in (global) frames lo..hi."""
    d = ev.dets
    if d is None or d.box3d is None:
        return np.zeros(0, np.int64)
    return np.flatnonzero((d.frame >= lo) & (d.frame <= hi) & d.has3d)


def bev_svg(gt, ev: OutputEvents, seq: int, f0: int, f1: int, title: str, size: int = 420,
            extent_of: Sequence[OutputEvents] = ()) -> str:
    """Bird's-eye view (x, z camera coordinates) of sequence index ``seq``, frames f0..f1: the ground
    truth's tracks (grey lines), the output's rows with a 3D box (dots coloured by tracker id; rows
    without one are not drawn), switches (``path.switch``, one per IDSW) and misses (open circles)
    at the ground truth's position. The view's extent holds the ground truth and the rows of ``ev``
    and of every output of ``extent_of`` (both outputs of a comparison: one extent for the pair, so
    that the two views read side by side)."""
    frame, gid, crow = _eval_rows(gt)
    g0 = int(gt.offsets[seq])
    lo, hi = g0 + f0, g0 + f1
    inside = (frame >= lo) & (frame <= hi)
    gx, gz = gt.row_box3d[crow, 3], gt.row_box3d[crow, 5]
    ok = inside & gt.row_has3d[crow]
    d = ev.dets
    rows = _bev_rows(ev, lo, hi)
    placed = [(o.dets, _bev_rows(o, lo, hi)) for o in (ev, *extent_of)]
    xs = np.concatenate([gx[ok]] + [o.box3d[r, 3] for o, r in placed if r.size])
    zs = np.concatenate([gz[ok]] + [o.box3d[r, 5] for o, r in placed if r.size])
    if not xs.size:
        xs, zs = np.array([-10.0, 10.0]), np.array([0.0, 40.0])
    x0, x1 = float(xs.min()) - 2, float(xs.max()) + 2
    z0, z1 = float(zs.min()) - 2, float(zs.max()) + 2
    span = max(x1 - x0, z1 - z0, 1.0)
    sx = lambda v: 10 + (v - x0) * (size - 20) / span                     # noqa: E731
    sz = lambda v: size - 30 - (v - z0) * (size - 50) / span              # noqa: E731
    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" class="bev" data-seq="{escape(gt.sequences[seq])}" '
             f'data-output="{escape(title)}" viewBox="0 0 {size} {size}" width="{size}" height="{size}">',
             f'<text x="4" y="14" font-size="12">{escape(title)}: bird\'s-eye view, frames {f0}-{f1} '
             f'(x right, z forward, m)</text>']
    for g in np.unique(gid[ok]):
        sel = ok & (gid == g)
        pts = " ".join(f"{sx(a):.1f},{sz(b):.1f}" for a, b in zip(gx[sel], gz[sel]))
        parts.append(f'<polyline class="gt" points="{pts}" fill="none" stroke="#bbb" stroke-width="3"/>')
    for i in rows:
        parts.append(f'<circle class="row" cx="{sx(d.box3d[i, 3]):.1f}" cy="{sz(d.box3d[i, 5]):.1f}" r="1.6" '
                     f'fill="{_colour(d.track_id[i])}"/>')
    m = ev.matches
    pos = {(int(f), int(g)): (a, b) for f, g, a, b in zip(frame[ok], gid[ok], gx[ok], gz[ok])}
    hit = set(zip(m["frame"].tolist(), m["gid"].tolist()))
    for (f, g), (a, b) in pos.items():
        if (f, g) not in hit:
            parts.append(f'<circle class="miss" cx="{sx(a):.1f}" cy="{sz(b):.1f}" r="3" fill="none" '
                         f'stroke="#555"/>')
    sw = np.flatnonzero(m["switch"] & (m["frame"] >= lo) & (m["frame"] <= hi))
    for i in sw:
        a, b = pos.get((int(m["frame"][i]), int(m["gid"][i])), (None, None))
        if a is None:               # a ground truth without a 3D box: marked at the view's corner
            a, b = x0 + 1, z0 + 1
        cx, cy = sx(a), sz(b)
        parts.append(f'<path class="switch" d="M{cx - 5:.1f},{cy - 5:.1f}L{cx + 5:.1f},{cy + 5:.1f}M{cx - 5:.1f},'
                     f'{cy + 5:.1f}L{cx + 5:.1f},{cy - 5:.1f}" stroke="#d62728" stroke-width="2"/>')
    parts.append(f'<text x="4" y="{size - 8}" font-size="10" fill="#555">grey: truth; dots: rows by id; '
                 f'circles: missed; red x: switch</text></svg>')
    return "".join(parts)
