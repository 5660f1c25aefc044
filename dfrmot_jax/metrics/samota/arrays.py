"""AB3DMOT's KITTI metrics of many tracker outputs from padded arrays, equal to scoring their files.

:func:`evaluate_ab3dmot_arrays` takes B outputs as ``[B, T, K]`` arrays, the rows a result file
would hold: slot ``k`` of frame ``t`` with ``ids >= 0`` is a row (within a frame, slots in order
``k = 0..K-1``, the order of rows in a file), with its image box, score and, for 3D IoU, its 3D box
``h w l x y z rot_y`` (the values a ``--columns kitti`` file carries: the row's own 3D detection,
or the filtered box with ``output=filtered``; the caller chooses). A row without a 3D box is the
placeholder ``-1 -1 -1 -1000 -1000 -1000`` (any rot_y) or all NaN: unmatched in 3D, as in a file.
Every row is of the evaluated class (no neighbouring-class rows). The 3D rules are the files'
(:mod:`dfrmot_jax.metrics.samota.prep`): a bad box raises ValueError naming config, sequence,
frame and slot.

Everything that does not depend on the output's tracks is done once for all outputs: the rows of
every output are flattened together, the distinct (frame, box) values found (the outputs of a sweep
mostly carry the same detections' boxes), their candidate pairs with the ground truth (IoU) and the
static ignore rule computed once each and joined back to every output's rows; track means in one
call (with the chosen sum). The passes then run per output (all its thresholds together,
:mod:`~dfrmot_jax.metrics.samota.passes`). Results are the
dicts of :func:`~dfrmot_jax.metrics.samota.ab3dmot_metrics`, identical to scoring the written
files with :func:`~dfrmot_jax.metrics.samota.evaluate_ab3dmot_files`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

import pandas as pd

from .evaluate import iou_2d_pairs, parse_iou, prepare_passes, static_ignore
from .passes import run_passes_many
from .sums import DEFAULT_SUM
from .prep import Ab3dGT, Ab3dTracker
from dfrmot_jax.metrics.common.box3d import iou_3d
from dfrmot_jax.metrics.common.distinct import distinct_rows
from dfrmot_jax.metrics.common.fields3d import box3d_problem, no_box_rows
from dfrmot_jax.metrics.common.pairs import enumerate_pairs, segment_starts

__all__ = ["evaluate_ab3dmot_arrays", "evaluate_ab3dmot_rows", "tracker_rows_from_arrays"]


def _where(gt: Ab3dGT, b: int, g: int, k: int) -> str:
    s = int(np.searchsorted(gt.offsets, g, side="right") - 1)
    return f"config {b}, sequence {gt.sequences[s]}, frame {g - int(gt.offsets[s])}, slot {k}"


class _Rows(NamedTuple):
    """The rows of B outputs flattened together (R rows by config, frame, slot): ``lane``, ``frame``
    (global), ``slot``, ``track`` (per config from 0), ``box`` [R, 4], ``score``, ``box3d`` [R, 7],
    ``has3d``; ``lane_start`` [B+1], ``n_tracks`` [B], ``track_start`` [B+1] (global track index =
    track_start[lane] + track)."""
    lane: np.ndarray
    frame: np.ndarray
    slot: np.ndarray
    track: np.ndarray
    box: np.ndarray
    score: np.ndarray
    box3d: np.ndarray
    has3d: np.ndarray
    lane_start: np.ndarray
    n_tracks: np.ndarray
    track_start: np.ndarray

    def tracker(self, gt: Ab3dGT, b: int) -> Ab3dTracker:
        i, j = self.lane_start[b], self.lane_start[b + 1]
        frame = self.frame[i:j]
        return Ab3dTracker(frame=frame, track=self.track[i:j], n_tracks=int(self.n_tracks[b]),
                           neighbour=np.zeros(j - i, dtype=bool), box=self.box[i:j], box3d=self.box3d[i:j],
                           has3d=self.has3d[i:j], score=self.score[i:j], source=self.slot[i:j],
                           seq=np.searchsorted(gt.offsets, frame, side="right") - 1, paths=())


def _padded_rows(ids, boxes, scores, box3d=None) -> dict:
    """[B, T, K] padded output -> the keyword arguments of :func:`_flat_rows` (rows in (lane, frame,
    slot) order)."""
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
    b, t, k = np.nonzero(ids >= 0)
    b3 = None if box3d is None else np.asarray(box3d, dtype=np.float64)[b, t, k]
    return dict(lane=b, t=t, slot=k, ids=ids[b, t, k], box=boxes[b, t, k], score=scores[b, t, k], box3d=b3,
                n_lanes=B, n_frames=T)


def _flat_rows(gt: Ab3dGT, lane, t, slot, ids, box, score, box3d, n_lanes: int, n_frames: int, seq_offsets=None,
               box_key=None, box3d_key=None, check_ids: bool = True) -> tuple[_Rows, np.ndarray | None, np.ndarray | None]:
    """Flat rows (in (lane, t, slot) order) -> (:class:`_Rows`, box_key, box3d_key of its rows)
    (checked: finite image boxes and scores, no id twice in a frame (unless ``check_ids`` is False),
    3D boxes or the placeholder; ValueError naming config, sequence, frame, slot). Rows on frames of
    no sequence are dropped."""
    B, T = n_lanes, n_frames
    S = len(gt.sequences)
    seq_offsets = gt.offsets[:-1] if seq_offsets is None else np.asarray(seq_offsets, dtype=np.int64).reshape(-1)
    if seq_offsets.shape != (S,):
        raise ValueError(f"seq_offsets must have one entry per sequence ({S}), got {seq_offsets.shape}")
    if np.any(seq_offsets < 0) or np.any(seq_offsets + gt.lengths > T):
        raise ValueError(f"seq_offsets + sequence lengths exceed T = {T}")
    gmap = np.full(T, -1, dtype=np.int64)
    for s in range(S):
        gmap[seq_offsets[s]:seq_offsets[s] + gt.lengths[s]] = np.arange(gt.offsets[s], gt.offsets[s + 1])
    b, k = np.asarray(lane, np.int64), np.asarray(slot, np.int64)
    g = gmap[np.asarray(t, np.int64)]
    keep = np.flatnonzero(g >= 0)
    if len(keep) == len(g):
        keep = slice(None)
    b, k, g = b[keep], k[keep], g[keep]
    if np.any(np.diff(gmap[gmap >= 0]) < 0):                 # sequences out of order along T
        o = np.lexsort((k, g, b))
        keep = np.arange(len(lane))[keep][o]
        b, k, g = b[o], k[o], g[o]
    tid = np.asarray(ids)[keep].astype(np.int64)
    box, score = np.asarray(box, np.float64)[keep], np.asarray(score, np.float64)[keep]
    box_key = None if box_key is None else np.asarray(box_key)[keep]
    box3d_key = None if box3d_key is None else np.asarray(box3d_key)[keep]
    bad = ~np.isfinite(box).all(axis=1) | ~np.isfinite(score)
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"{_where(gt, int(b[i]), int(g[i]), int(k[i]))}: image box or score not finite")
    R = len(b)
    lane_frame = b * max(gt.n_frames, 1) + g
    top = int(tid.max(initial=0)) + 1
    if not check_ids:
        dup = np.zeros(0, dtype=bool)
    elif B * max(gt.n_frames, 1) * top < 2**62:
        dup = pd.Series(lane_frame * top + tid).duplicated().to_numpy()
    else:
        dup = np.zeros(R, dtype=bool)
        dup[np.unique(np.stack([lane_frame, tid], axis=1), axis=0, return_index=True)[1]] = True
        dup = ~dup
    if dup.any():
        i = int(np.argmax(dup))
        raise ValueError(f"{_where(gt, int(b[i]), int(g[i]), int(k[i]))}: id {tid[i]} occurs twice in the frame")
    seq = np.searchsorted(gt.offsets, g, side="right") - 1
    lane_seq = b * max(S, 1) + seq
    if B * max(S, 1) * top < 2**62:
        codes = pd.factorize(lane_seq * top + tid)[0]
    else:
        codes = np.unique(np.stack([lane_seq, tid], axis=1), axis=0, return_inverse=True)[1].reshape(-1)
    lane_start = segment_starts(np.bincount(b, minlength=B))
    # rows come lane by lane, so each lane's new codes are one contiguous range
    track_start = np.zeros(B + 1, dtype=np.int64)
    n_tracks = np.zeros(B, dtype=np.int64)
    filled = np.flatnonzero(np.diff(lane_start) > 0)
    if R:
        lo = np.minimum.reduceat(codes, lane_start[filled])
        track_start[filled] = lo
        n_tracks[filled] = np.maximum.reduceat(codes, lane_start[filled]) + 1 - lo
    track_start[B] = int(codes.max(initial=-1)) + 1
    track = codes - track_start[b]
    if box3d is None:
        b3 = np.full((R, 7), np.nan)
        has3d = np.zeros(R, dtype=bool)
    else:
        b3 = np.asarray(box3d, dtype=np.float64)[keep]
        none = no_box_rows(b3)
        bad = box3d_problem(b3, ~none)
        if bad is not None:
            i = bad[0]
            raise ValueError(f"{_where(gt, int(b[i]), int(g[i]), int(k[i]))}: 3D box {b3[i].tolist()} is not a box "
                             f"(finite, h > 0, w and l non-zero and of one sign) nor the 2D-only placeholder")
        has3d = ~none
    rows = _Rows(lane=b, frame=g, slot=k, track=track, box=box, score=score, box3d=b3, has3d=has3d,
                 lane_start=lane_start, n_tracks=n_tracks, track_start=track_start)
    return rows, box_key, box3d_key


def tracker_rows_from_arrays(gt: Ab3dGT, ids, boxes, scores, box3d=None, seq_offsets=None) -> list[Ab3dTracker]:
    """[B, T, K] padded output -> one :class:`~dfrmot_jax.metrics.samota.prep.Ab3dTracker` per config.

    ids [B, T, K] int (negative: empty slot; ids per sequence); boxes [B, T, K, 4] image boxes;
    scores [B, T, K]; box3d [B, T, K, 7] or None (2D IoU only); seq_offsets [S] first frame along T
    of each of ``gt.sequences`` (default back to back; other frames of T are ignored)."""
    rows = _flat_rows(gt, **_padded_rows(ids, boxes, scores, box3d), seq_offsets=seq_offsets)[0]
    return [rows.tracker(gt, b) for b in range(len(rows.n_tracks))]


def _pairs(gt: Ab3dGT, rows: _Rows, kind: str, threshold: float, key: np.ndarray | None = None) -> list:
    """Candidate pairs of every output (by frame, object, row within each): the distinct (frame, box)
    values' pairs with the ground truth (IoU once each), joined back to every output's rows.
    ``key`` [R]: the rows' value keys (:func:`~dfrmot_jax.metrics.common.distinct.distinct_rows`), or None."""
    B = len(rows.n_tracks)
    vals, live = (rows.box, np.ones(len(rows.frame), dtype=bool)) if kind == "2d" else (rows.box3d, rows.has3d)
    sel = np.flatnonzero(live)
    first, uid = distinct_rows(rows.frame[sel], vals[sel], None if key is None else key[sel])
    ufr = rows.frame[sel[first]]
    o = np.argsort(ufr, kind="stable")                  # distinct values by frame
    rank = np.empty(len(o), dtype=np.int64)
    rank[o] = np.arange(len(o))
    nu = np.bincount(ufr, minlength=gt.n_frames)
    _, obj, col, _ = enumerate_pairs(np.diff(gt.start), gt.start[:-1], nu, segment_starts(nu)[:-1])
    u = sel[first[o[col]]]                              # a row carrying the value
    if kind == "2d":
        iou = iou_2d_pairs(gt.box[obj], rows.box[u])
    else:
        gb, tb = gt.box3d, rows.box3d
        iou = np.zeros(len(obj))
        reach = 0.5 * (np.hypot(gb[obj, 1], gb[obj, 2]) + np.hypot(tb[u, 1], tb[u, 2]))
        near = np.flatnonzero(np.hypot(gb[obj, 3] - tb[u, 3], gb[obj, 5] - tb[u, 5]) <= reach * (1 + 1e-9))
        iou[near] = iou_3d(gb[obj[near]], tb[u[near]])
    cost = 1.0 - iou
    ok = np.flatnonzero(cost <= 1.0 - threshold)
    ok = ok[np.argsort(col[ok], kind="stable")]          # candidate pairs by distinct value, then object
    obj, cost, ucol = obj[ok], cost[ok], col[ok]
    # join: each live row gets the pairs of its value, then (lane, object, row) order
    cnt = np.bincount(ucol, minlength=len(o))
    cstart = segment_starts(cnt)
    r_rank = rank[uid]
    n_r = cnt[r_rank]
    e_row = np.repeat(sel, n_r)
    e_idx = np.repeat(cstart[r_rank], n_r) + (np.arange(int(n_r.sum())) - np.repeat(segment_starts(n_r)[:-1], n_r))
    e_obj = obj[e_idx]
    e_lane = rows.lane[e_row]
    order = np.argsort(e_lane * max(len(gt.frame), 1) + e_obj, kind="stable")    # rows stay in order per object
    e_row, e_obj, e_cost, e_lane = e_row[order], e_obj[order], cost[e_idx[order]], e_lane[order]
    cut = np.searchsorted(e_lane, np.arange(B + 1))
    return [(e_obj[cut[b]:cut[b + 1]], e_row[cut[b]:cut[b + 1]] - rows.lane_start[b], e_cost[cut[b]:cut[b + 1]])
            for b in range(B)]


def evaluate_ab3dmot_arrays(gt: Ab3dGT, ids, boxes, scores, box3d=None, seq_offsets=None,
                            iou="3d:0.25", sum_mode: str = DEFAULT_SUM, other: bool = False) -> list[dict]:
    """AB3DMOT's figures of B padded outputs (module docstring) -> a list of B result dicts.

    gt: :func:`~dfrmot_jax.metrics.samota.prep.prepare_ab3dmot_gt`; ids [B, T, K]; boxes
    [B, T, K, 4]; scores [B, T, K]; box3d [B, T, K, 7] (needed for ``3d`` IoU); iou ``'3d:0.25'``,
    ``'2d:0.5'``, ...; seq_offsets as in :func:`tracker_rows_from_arrays`; sum_mode, other:
    :func:`~dfrmot_jax.metrics.samota.evaluate.ab3dmot_metrics`'s."""
    kind, _ = parse_iou(iou)
    if kind == "3d" and box3d is None:
        raise ValueError("3D IoU needs box3d [B, T, K, 7] (h w l x y z rot_y per slot)")
    return evaluate_ab3dmot_rows(gt, **_padded_rows(ids, boxes, scores, box3d if kind == "3d" else None),
                                 seq_offsets=seq_offsets, iou=iou, sum_mode=sum_mode, other=other)


def evaluate_ab3dmot_rows(gt: Ab3dGT, lane, t, slot, ids, box, score, box3d, n_lanes: int, n_frames: int,
                          seq_offsets=None, iou="3d:0.25", box_key=None, box3d_key=None,
                          check_ids: bool = True, sum_mode: str = DEFAULT_SUM, other: bool = False) -> list[dict]:
    """:func:`evaluate_ab3dmot_arrays` of B outputs given as their rows, flat, in (lane, t, slot)
    order (the fields of :class:`dfrmot_jax.rows.KittiRows`): lane, t (frame along the T frames),
    slot, ids [R]; box [R, 4]; score [R]; box3d [R, 7] or None; n_lanes B; n_frames T. box_key /
    box3d_key [R] int64 or None: equal keys within a frame mean equal image / 3D boxes (the distinct
    values are then taken from the keys); any key of a row without a 3D box. check_ids: refuse an id
    twice in a lane's frame (False: the caller vouches for it, as the tracker's own rows do);
    sum_mode, other: :func:`~dfrmot_jax.metrics.samota.evaluate.ab3dmot_metrics`'s."""
    kind, thr = parse_iou(iou)
    if kind == "3d" and box3d is None:
        raise ValueError("3D IoU needs box3d [R, 7] (h w l x y z rot_y per row)")
    rows, box_key, box3d_key = _flat_rows(gt, lane, t, slot, ids, box, score, box3d if kind == "3d" else None,
                                          n_lanes, n_frames, seq_offsets, box_key, box3d_key, check_ids)
    B = len(rows.n_tracks)
    if not B:
        return []
    pairs = _pairs(gt, rows, kind, thr, box_key if kind == "2d" else box3d_key)
    # the static ignore rule once per distinct (frame, image box); track means in one call (run_passes_many)
    first, bid = distinct_rows(rows.frame, rows.box, box_key)
    static = static_ignore(gt, rows.frame[first], rows.box[first], np.zeros(len(first), dtype=bool))[bid]
    preps = []
    for b in range(B):
        i, j = rows.lane_start[b], rows.lane_start[b + 1]
        preps.append(prepare_passes(gt, rows.tracker(gt, b), kind, thr, pairs=pairs[b], static=static[i:j]))
    return run_passes_many(preps, sum_mode, other)
