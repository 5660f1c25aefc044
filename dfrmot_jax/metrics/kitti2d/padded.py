"""Padded tracker output ([B, T, K] ids and their boxes, as the tracker and a sweep hold it) flattened
into the preprocessing's :class:`~dfrmot_jax.metrics.kitti2d.kitti.TrackerDets`: :func:`check_arrays`,
:func:`tracker_dets_from_arrays` (the rows in (lane, frame, slot) order, one compiled pass over the ids).
"""

from __future__ import annotations

import numpy as np

from dfrmot_jax.metrics.common.fields3d import FIELDS_3D, box3d_problem, no_box_rows
from dfrmot_jax.metrics.common.kernel_cache import cached_njit
from dfrmot_jax.metrics.kitti2d.kitti import PreparedGT, TrackerDets
from dfrmot_jax.rows import Rows

__all__ = ["check_arrays", "frames_aligned", "tracker_dets_from_arrays"]


def check_arrays(gt: PreparedGT, ids: np.ndarray, boxes: np.ndarray, seq_offsets) -> np.ndarray:
    """ValueError unless ``ids`` is [B, T, K], ``boxes`` [B, T, K, 4] and ``seq_offsets`` [S] puts every
    sequence of ``gt`` inside T (``boxes`` may be a :class:`~dfrmot_jax.rows.Rows` of ``ids``: the
    rows' [R, 4]); returns ``seq_offsets`` as int64."""
    ids = np.asarray(ids)
    if ids.ndim != 3:
        raise ValueError(f"ids must be [B, T, K], got shape {ids.shape}")
    B, T, K = ids.shape
    if isinstance(boxes, Rows):
        if boxes.values.shape[1:] != (4,) or boxes.start.shape != (B * T + 1,) or boxes.start[-1] != boxes.values.shape[0]:
            raise ValueError(f"boxes kept as rows must be the [R, 4] rows of ids {ids.shape}, got "
                             f"{boxes.values.shape} with {boxes.start.shape[0] - 1} (lane, frame) starts")
    elif np.shape(boxes) != (B, T, K, 4):
        raise ValueError(f"boxes must be [B, T, K, 4] = {(B, T, K, 4)}, got {boxes.shape}")
    seq_offsets = np.asarray(seq_offsets, dtype=np.int64).reshape(-1)
    S = len(gt.sequences)
    if seq_offsets.shape != (S,):
        raise ValueError(f"seq_offsets must have one entry per sequence ({S}), got {seq_offsets.shape}")
    if np.any(seq_offsets < 0) or np.any(seq_offsets + gt.lengths > T):
        raise ValueError(f"seq_offsets + sequence lengths exceed T = {T}")
    return seq_offsets


def frames_aligned(gt: PreparedGT, n_frames: int, seq_offsets) -> bool:
    """Whether padded output's ``n_frames`` frames are the ground truth's sequences back to back
    (``seq_offsets`` their starts): its frame t is the ground truth's global frame t."""
    return n_frames == gt.n_frames and np.array_equal(seq_offsets, gt.offsets[:-1])


def tracker_dets_from_arrays(gt: PreparedGT, ids: np.ndarray, boxes: np.ndarray, seq_offsets,
                             box3d: np.ndarray | None = None) -> TrackerDets:
    """Flatten padded tracker output into :class:`TrackerDets`.

    ids: [B, T, K] int (negative = empty slot); boxes: [B, T, K, 4] float ``x1, y1, x2, y2``;
    seq_offsets: [S] first frame (along T) of each of ``gt.sequences``; sequence s uses frames
    ``seq_offsets[s] : seq_offsets[s] + gt.lengths[s]``; other frames of T are ignored.
    boxes may be a :class:`~dfrmot_jax.rows.Rows` of ``ids`` (their values at the rows only).
    box3d: [B, T, K, 7] ``h w l x y z rot_y`` per slot, or None (3D fields not needed). A slot
    without a 3D box holds the placeholder or all NaN; any other value that is no box
    (:mod:`dfrmot_jax.metrics.common.fields3d`) raises ValueError naming config, frame, slot and field.
    """
    seq_offsets = check_arrays(gt, ids, boxes, seq_offsets)
    ids = np.asarray(ids)
    B, T, K = ids.shape
    S = len(gt.sequences)
    aligned = frames_aligned(gt, T, seq_offsets)
    if isinstance(boxes, Rows) and not aligned:
        boxes = boxes.dense(ids)        # (frames taken apart from the rows: gathered from the padded form)
    boxes = boxes if isinstance(boxes, Rows) else np.asarray(boxes)
    tid = None
    if aligned:
        flat, b, t, k, tid = _flat_rows(np.ascontiguousarray(ids))     # (b, t, k) in order
        tk = flat - b * (T * K)
        g = t
    else:
        # map array frames to global GT frames; frames outside every sequence are ignored
        gmap = np.full(T, -1, dtype=np.int64)
        for s in range(S):
            gmap[seq_offsets[s]:seq_offsets[s] + gt.lengths[s]] = np.arange(gt.offsets[s], gt.offsets[s + 1])
        b, t, k = np.nonzero((ids >= 0) & (gmap >= 0)[None, :, None])
        g = gmap[t]
        order = np.lexsort((k, g, b))
        b, t, k, g = b[order], t[order], k[order], g[order]
    if isinstance(boxes, Rows):             # (g is t: every row, in the order of flat)
        box = boxes.values
    elif g is t and boxes.flags.c_contiguous:
        box = np.take(boxes.reshape(-1, 4), flat, axis=0)
    elif g is t and boxes.strides[0] == 0 and boxes[0].flags.c_contiguous:    # one box array for all lanes
        box = np.take(boxes[0].reshape(-1, 4), tk, axis=0)
    else:
        box = boxes[b, t, k]
    box = box if box.dtype == np.float32 else box.astype(np.float64)   # float32 kept: widened per batch
    if box.size and not np.all(np.isfinite(box)):
        bad = int(np.flatnonzero(~np.all(np.isfinite(box), axis=1))[0])
        raise ValueError(f"non-finite box in config {b[bad]}, frame {t[bad]}, slot {k[bad]}")
    b3 = h3 = None
    if box3d is not None:
        box3d = np.asarray(box3d)
        if box3d.shape != (B, T, K, 7):
            raise ValueError(f"box3d must be [B, T, K, 7] = {(B, T, K, 7)}, got {box3d.shape}")
        b3 = box3d[b, t, k].astype(np.float64)
        h3 = ~no_box_rows(b3)
        bad = box3d_problem(b3, h3)
        if bad is not None:
            i, j, msg = bad
            raise ValueError(f"3D box of config {b[i]}, frame {t[i]}, slot {k[i]}, field {FIELDS_3D[j]}: "
                             + msg.format(repr(float(b3[i, j])), repr(float(b3[i, 2]))))
    tid = ids[b, t, k] if tid is None else tid
    return TrackerDets(B, b.astype(np.int64, copy=False), g.astype(np.int64, copy=False),
                       tid.astype(np.int64, copy=False), box, k.astype(np.int64, copy=False), (), b3, h3)


@cached_njit(nogil=True)
def _flat_rows(ids):
    """The rows (ids >= 0) of ``ids`` [B, T, K] in (b, t, k) order, one pass: (flat index, b, t, k,
    id), each [M] int64."""
    B, T, K = ids.shape
    n = 0
    for b in range(B):
        for t in range(T):
            for k in range(K):
                if ids[b, t, k] >= 0:
                    n += 1
    flat = np.empty(n, np.int64)
    lane = np.empty(n, np.int64)
    frame = np.empty(n, np.int64)
    slot = np.empty(n, np.int64)
    tid = np.empty(n, np.int64)
    i = 0
    for b in range(B):
        for t in range(T):
            for k in range(K):
                v = ids[b, t, k]
                if v >= 0:
                    flat[i] = (b * T + t) * K + k
                    lane[i] = b
                    frame[i] = t
                    slot[i] = k
                    tid[i] = v
                    i += 1
    return flat, lane, frame, slot, tid
