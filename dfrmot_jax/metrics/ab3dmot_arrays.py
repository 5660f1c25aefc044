"""AB3DMOT's KITTI metrics of many tracker outputs from padded arrays, equal to scoring their files.

:func:`evaluate_ab3dmot_arrays` takes B outputs as ``[B, T, K]`` arrays, the rows a result file
would hold: slot ``k`` of frame ``t`` with ``ids >= 0`` is a row (within a frame, slots in order
``k = 0..K-1``, the order of rows in a file), with its image box, score and, for 3D IoU, its 3D box
``h w l x y z rot_y`` (the values a ``--columns kitti`` file carries: the row's own 3D detection,
or the filtered box with ``output=filtered``; the caller chooses). A row without a 3D box is the
placeholder ``-1 -1 -1 -1000 -1000 -1000`` (any rot_y) or all NaN: unmatched in 3D, as in a file.
Every row is of the evaluated class (no neighbouring-class rows). The 3D rules are the files'
(:mod:`dfrmot_jax.metrics.ab3dmot_prep`): a bad box raises ValueError naming config, sequence,
frame and slot.

The IoU of each (ground-truth object, box) pair is computed once for all outputs (the outputs of a
sweep mostly carry the same detections' boxes); the passes then run per output. Results are the
dicts of :func:`~dfrmot_jax.metrics.ab3dmot.ab3dmot_metrics`, identical to scoring the written
files with :func:`~dfrmot_jax.metrics.ab3dmot.evaluate_ab3dmot_files`.
"""

from __future__ import annotations

import numpy as np

from dfrmot_jax.metrics.ab3dmot import ab3dmot_metrics, iou_2d_pairs, parse_iou, prepare_passes
from dfrmot_jax.metrics.ab3dmot_prep import Ab3dGT, Ab3dTracker
from dfrmot_jax.metrics.box3d import iou_3d
from dfrmot_jax.metrics.fields3d import box3d_problem, no_box_rows
from dfrmot_jax.metrics.pairs import enumerate_pairs, segment_starts
from dfrmot_jax.metrics.similarity import row_ids

__all__ = ["evaluate_ab3dmot_arrays", "tracker_rows_from_arrays"]


def _where(gt: Ab3dGT, b: int, g: int, k: int) -> str:
    s = int(np.searchsorted(gt.offsets, g, side="right") - 1)
    return f"config {b}, sequence {gt.sequences[s]}, frame {g - int(gt.offsets[s])}, slot {k}"


def tracker_rows_from_arrays(gt: Ab3dGT, ids, boxes, scores, box3d=None, seq_offsets=None) -> list[Ab3dTracker]:
    """[B, T, K] padded output -> one :class:`~dfrmot_jax.metrics.ab3dmot_prep.Ab3dTracker` per config.

    ids [B, T, K] int (negative: empty slot; ids per sequence); boxes [B, T, K, 4] image boxes;
    scores [B, T, K]; box3d [B, T, K, 7] or None (2D IoU only); seq_offsets [S] first frame along T
    of each of ``gt.sequences`` (default back to back; other frames of T are ignored)."""
    ids = np.asarray(ids)
    if ids.ndim != 3:
        raise ValueError(f"ids must be [B, T, K], got shape {ids.shape}")
    B, T, K = ids.shape
    boxes = np.asarray(boxes, dtype=np.float64)
    scores = np.asarray(scores, dtype=np.float64)
    for name, a, shape in (("boxes", boxes, (B, T, K, 4)), ("scores", scores, (B, T, K)),
                           ("box3d", None if box3d is None else np.asarray(box3d), (B, T, K, 7))):
        if a is not None and a.shape != shape:
            raise ValueError(f"{name} must have shape {shape}, got {a.shape}")
    S = len(gt.sequences)
    seq_offsets = gt.offsets[:-1] if seq_offsets is None else np.asarray(seq_offsets, dtype=np.int64).reshape(-1)
    if seq_offsets.shape != (S,):
        raise ValueError(f"seq_offsets must have one entry per sequence ({S}), got {seq_offsets.shape}")
    if np.any(seq_offsets < 0) or np.any(seq_offsets + gt.lengths > T):
        raise ValueError(f"seq_offsets + sequence lengths exceed T = {T}")
    gmap = np.full(T, -1, dtype=np.int64)
    for s in range(S):
        gmap[seq_offsets[s]:seq_offsets[s] + gt.lengths[s]] = np.arange(gt.offsets[s], gt.offsets[s + 1])
    out = []
    for b in range(B):
        t, k = np.nonzero((ids[b] >= 0) & (gmap >= 0)[:, None])
        g = gmap[t]
        order = np.lexsort((k, g))
        t, k, g = t[order], k[order], g[order]
        tid = ids[b, t, k].astype(np.int64)
        box, score = boxes[b, t, k], scores[b, t, k]
        bad = ~np.isfinite(box).all(axis=1) | ~np.isfinite(score)
        if bad.any():
            i = int(np.argmax(bad))
            raise ValueError(f"{_where(gt, b, int(g[i]), int(k[i]))}: image box or score not finite")
        seq = np.searchsorted(gt.offsets, g, side="right") - 1
        if len(g):
            o = np.lexsort((tid, g))
            dup = (g[o][1:] == g[o][:-1]) & (tid[o][1:] == tid[o][:-1])
            if dup.any():
                i = int(o[1:][np.argmax(dup)])
                raise ValueError(f"{_where(gt, b, int(g[i]), int(k[i]))}: id {tid[i]} occurs twice in the frame")
        key = seq * (int(tid.max(initial=0)) + 1) + tid
        _, track = np.unique(key, return_inverse=True)
        if box3d is None:
            b3 = np.full((len(t), 7), np.nan)
            has3d = np.zeros(len(t), dtype=bool)
        else:
            b3 = np.asarray(box3d, dtype=np.float64)[b, t, k]
            none = no_box_rows(b3)
            bad = box3d_problem(b3, ~none)
            if bad is not None:
                i = bad[0]
                raise ValueError(f"{_where(gt, b, int(g[i]), int(k[i]))}: 3D box {b3[i].tolist()} is not a box "
                                 f"(finite, h > 0, w and l non-zero and of one sign) nor the 2D-only placeholder")
            has3d = ~none
        out.append(Ab3dTracker(frame=g, track=track.reshape(-1).astype(np.int64), n_tracks=int(track.max(initial=-1)) + 1,
                               neighbour=np.zeros(len(t), dtype=bool), box=box, box3d=b3, has3d=has3d, score=score,
                               source=k.astype(np.int64), seq=seq.astype(np.int64), paths=()))
    return out


def _all_pairs(gt: Ab3dGT, trks: list, kind: str, threshold: float) -> list:
    """Candidate pairs of every output, each pair's IoU computed once per distinct (object, box)."""
    F = gt.n_frames
    B = len(trks)
    frame = np.concatenate([t.frame + b * F for b, t in enumerate(trks)]) if B else np.zeros(0, np.int64)
    lane_start = segment_starts(np.array([len(t.frame) for t in trks], dtype=np.int64))
    nt = np.bincount(frame, minlength=B * F)
    t_start = segment_starts(nt)
    g_of = np.tile(np.arange(F), B)
    _, row, col, _ = enumerate_pairs(np.diff(gt.start)[g_of], gt.start[g_of], nt, t_start[:-1])
    if kind == "2d":
        vals = np.concatenate([t.box for t in trks])
        live = np.ones(len(vals), dtype=bool)
    else:
        vals = np.concatenate([t.box3d for t in trks])
        live = np.concatenate([t.has3d for t in trks])
    iou = np.zeros(len(row))
    if kind == "2d":
        iou = iou_2d_pairs(gt.box[row], vals[col])
    else:
        # pairs whose ground circles overlap (others have IoU 0), each distinct (object, box) once
        gb, tb = gt.box3d, vals
        reach = 0.5 * (np.hypot(gb[row, 1], gb[row, 2]) + np.hypot(tb[col, 1], tb[col, 2]))
        near = np.hypot(gb[row, 3] - tb[col, 3], gb[row, 5] - tb[col, 5]) <= reach * (1 + 1e-9)
        sel = np.flatnonzero(live[col] & near)
        if sel.size:
            box_id = row_ids(vals)
            key = row[sel] * (int(box_id.max()) + 1) + box_id[col[sel]]
            _, first, inv = np.unique(key, return_index=True, return_inverse=True)
            r, c = row[sel][first], col[sel][first]
            iou[sel] = iou_3d(gt.box3d[r], vals[c])[inv.reshape(-1)]
    cost = 1.0 - iou
    ok = np.flatnonzero(cost <= 1.0 - threshold)
    row, col, cost = row[ok], col[ok], cost[ok]
    lane = np.searchsorted(lane_start, col, side="right") - 1
    cut = np.searchsorted(lane, np.arange(B + 1))
    return [(row[cut[b]:cut[b + 1]], col[cut[b]:cut[b + 1]] - lane_start[b], cost[cut[b]:cut[b + 1]])
            for b in range(B)]


def evaluate_ab3dmot_arrays(gt: Ab3dGT, ids, boxes, scores, box3d=None, seq_offsets=None,
                            iou="3d:0.25") -> list[dict]:
    """AB3DMOT's figures of B padded outputs (module docstring) -> a list of B result dicts.

    gt: :func:`~dfrmot_jax.metrics.ab3dmot_prep.prepare_ab3dmot_gt`; ids [B, T, K]; boxes
    [B, T, K, 4]; scores [B, T, K]; box3d [B, T, K, 7] (needed for ``3d`` IoU); iou ``'3d:0.25'``,
    ``'2d:0.5'``, ...; seq_offsets as in :func:`tracker_rows_from_arrays`."""
    kind, thr = parse_iou(iou)
    if kind == "3d" and box3d is None:
        raise ValueError("3D IoU needs box3d [B, T, K, 7] (h w l x y z rot_y per slot)")
    trks = tracker_rows_from_arrays(gt, ids, boxes, scores, box3d if kind == "3d" else None, seq_offsets)
    if not trks:
        return []
    pairs = _all_pairs(gt, trks, kind, thr)
    return [ab3dmot_metrics(prepare_passes(gt, t, kind, thr, pairs=p)) for t, p in zip(trks, pairs)]
