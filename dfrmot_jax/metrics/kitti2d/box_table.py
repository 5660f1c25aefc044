"""Image IoU of the distinct tracker boxes with the ground truth, computed once and looked up.

The outputs of a sweep (and the lanes of one batch) mostly carry the same boxes: the detector's,
frame by frame. :func:`box_table` finds the distinct (frame, box) values of the tracker rows
(:func:`~dfrmot_jax.metrics.common.distinct.distinct_rows`), computes their IoU with every class row of
the frame's ground truth once (TrackEval's formula bit for bit, :func:`~dfrmot_jax.metrics.kitti2d.boxes.gather_iou`),
and keeps, per distinct value, its candidate rows (IoU >= 0.5 - eps, the preprocessing's matching
threshold) and whether it lies mostly inside a DontCare region (intersection over its own area
> 0.5 + eps with any, :func:`~dfrmot_jax.metrics.kitti2d.boxes.pair_ioa`). :func:`pair_iou` looks pairs
up; :func:`candidate_pairs` joins the candidates back to the rows.

Arrays: ``F`` frames, ``M`` tracker rows, ``U`` distinct values (sorted by frame), class rows of
the ground truth as in :class:`~dfrmot_jax.metrics.kitti2d.kitti.PreparedGT` (``row_start`` [F+1]).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from dfrmot_jax.metrics.common.distinct import distinct_rows
from dfrmot_jax.metrics.common.kernel_cache import cached_njit
from dfrmot_jax.metrics.common.pairs import enumerate_pairs, segment_starts
from dfrmot_jax.metrics.kitti2d.boxes import EPS, columns, gather_iou, pair_ioa

__all__ = ["BoxTable", "MATCH_IOU", "box_table", "box_table_numpy", "pair_iou", "candidate_pairs", "metric_pairs"]

MATCH_IOU = 0.5  # the preprocessing's distractor matching: IoU >= 0.5 - eps


class BoxTable(NamedTuple):
    """IoU of distinct (frame, box) values with the frame's class ground-truth rows.

    value: [M] distinct value of each tracker row (0..U-1, values sorted by frame); local: [M] its
    rank among its frame's values; n_values: [F]; iou_start: [F+1] (frame f's table is
    ``iou[iou_start[f]:iou_start[f+1]]``, [n class rows of f, n_values[f]] row-major);
    iou: float64 table; cand_start: [U+1], cand_row: [Q] class row (global), cand_iou: [Q]: each
    value's rows with IoU >= 0.5 - eps, in row order; in_dontcare: [U] bool.
    """
    value: np.ndarray
    local: np.ndarray
    n_values: np.ndarray
    iou_start: np.ndarray
    iou: np.ndarray
    cand_start: np.ndarray
    cand_row: np.ndarray
    cand_iou: np.ndarray
    in_dontcare: np.ndarray


def box_table(row_start: np.ndarray, row_cols: tuple, dc_start: np.ndarray, dc_box: np.ndarray, frame: np.ndarray,
              box: np.ndarray) -> BoxTable:
    """The :class:`BoxTable` of tracker rows ``frame`` [M] (global frame) and ``box`` [M, 4] float64.

    row_start: [F+1] class rows of each frame; row_cols: the class rows' boxes as four columns
    (:func:`~dfrmot_jax.metrics.kitti2d.boxes.columns`); dc_start [F+1], dc_box [D, 4]: DontCare regions."""
    first, order, value, n_values, vstart, local = _values(len(row_start) - 1, frame, box)
    ubox = np.ascontiguousarray(box[first[order]], dtype=np.float64).reshape(-1, 4)
    iou_start = segment_starts(np.diff(row_start) * n_values)
    iou, cand_start, cand_row, cand_iou, in_dc = _table(
        np.asarray(row_start, np.int64), *(np.asarray(c, np.float64) for c in row_cols), vstart, ubox, iou_start,
        np.asarray(dc_start, np.int64), np.ascontiguousarray(dc_box, dtype=np.float64).reshape(-1, 4), EPS, MATCH_IOU)
    return BoxTable(value=value, local=local, n_values=n_values, iou_start=iou_start, iou=iou,
                    cand_start=cand_start, cand_row=cand_row, cand_iou=cand_iou, in_dontcare=in_dc)


def _values(F: int, frame: np.ndarray, box: np.ndarray) -> tuple:
    """The distinct (frame, box) values of the rows, numbered by frame: (first row of each [U], the
    values in frame order [U], each row's value [M], values per frame [F], their starts [F+1], each
    row's rank among its frame's values [M])."""
    first, ids = distinct_rows(frame, box)
    ufr = frame[first]
    order = np.argsort(ufr, kind="stable")               # distinct values by frame
    value = np.empty(len(order), dtype=np.int64)
    value[order] = np.arange(len(order))
    value = value[ids]
    n_values = np.bincount(ufr, minlength=F).astype(np.int64)
    vstart = segment_starts(n_values)
    return first, order, value, n_values, vstart, value - vstart[frame]


def box_table_numpy(row_start: np.ndarray, row_cols: tuple, dc_start: np.ndarray, dc_box: np.ndarray,
                    frame: np.ndarray, box: np.ndarray) -> BoxTable:
    """:func:`box_table` in NumPy (every pair's IoU vectorised, :func:`~dfrmot_jax.metrics.kitti2d.boxes.
    gather_iou`): the reference the compiled table is tested against."""
    F = len(row_start) - 1
    first, order, value, n_values, vstart, local = _values(F, frame, box)
    n_rows = np.diff(row_start)
    _, row, col, iou_start = enumerate_pairs(n_rows, row_start[:-1], n_values, vstart[:-1])
    iou = gather_iou(row_cols, row, columns(box[first[order]]), col)
    ubox = box[first[order]]
    n_dc = np.diff(dc_start)[np.repeat(np.arange(F), n_values)]
    d_val = np.repeat(np.arange(len(order)), n_dc)
    d_reg = np.repeat(dc_start[:-1][np.repeat(np.arange(F), n_values)], n_dc) + (
        np.arange(len(d_val)) - np.repeat(segment_starts(n_dc)[:-1], n_dc))
    in_dc = np.zeros(len(order), dtype=bool)
    in_dc[d_val[pair_ioa(ubox[d_val], dc_box[d_reg]) > 0.5 + EPS]] = True
    cand = np.flatnonzero(iou >= MATCH_IOU - EPS)
    cand = cand[np.argsort(col[cand], kind="stable")]    # by value, rows in order
    return BoxTable(value=value, local=local, n_values=n_values, iou_start=iou_start, iou=iou,
                    cand_start=segment_starts(np.bincount(col[cand], minlength=len(order))),
                    cand_row=row[cand], cand_iou=iou[cand], in_dontcare=in_dc)


@cached_njit(nogil=True)
def _table(row_start, rx1, ry1, rx2, ry2, vstart, ubox, iou_start, dc_start, dc_box, eps, match_iou):
    """The table's IoU, candidates and DontCare flags in one pass per frame: each pair's IoU by the
    operations of :func:`~dfrmot_jax.metrics.kitti2d.boxes.gather_iou` in the same order (so bit for
    bit TrackEval's), each value's intersection over its own area with the frame's DontCare regions
    as :func:`~dfrmot_jax.metrics.kitti2d.boxes.pair_ioa`. ``eps`` and ``match_iou`` come in as arguments
    (the tolerance is another module's): numba keys a cached function on its own file only, and would
    keep an imported global's old value."""
    F = row_start.shape[0] - 1
    U = ubox.shape[0]
    iou = np.empty(iou_start[F], np.float64)
    n_cand = np.zeros(U, np.int64)
    in_dc = np.zeros(U, np.bool_)
    for f in range(F):
        r0, r1, v0, v1 = row_start[f], row_start[f + 1], vstart[f], vstart[f + 1]
        nv = v1 - v0
        for r in range(r0, r1):
            ax1, ay1, ax2, ay2 = rx1[r], ry1[r], rx2[r], ry2[r]
            area1 = (ax2 - ax1) * (ay2 - ay1)
            base = iou_start[f] + (r - r0) * nv
            for v in range(v0, v1):
                bx1, by1, bx2, by2 = ubox[v, 0], ubox[v, 1], ubox[v, 2], ubox[v, 3]
                w = min(ax2, bx2) - max(ax1, bx1)
                h = min(ay2, by2) - max(ay1, by1)
                inter = max(w, 0.0) * max(h, 0.0)
                area2 = (bx2 - bx1) * (by2 - by1)
                union = area1 + area2 - inter
                small = union <= 0 + eps
                if area1 <= 0 + eps or area2 <= 0 + eps or small:
                    inter = 0.0
                if small:
                    union = 1.0
                x = inter / union
                iou[base + v - v0] = x
                if x >= match_iou - eps:
                    n_cand[v] += 1
        for v in range(v0, v1):
            bx1, by1, bx2, by2 = ubox[v, 0], ubox[v, 1], ubox[v, 2], ubox[v, 3]
            area = (bx2 - bx1) * (by2 - by1)
            if not area > 0 + eps:
                continue
            for d in range(dc_start[f], dc_start[f + 1]):
                w = min(bx2, dc_box[d, 2]) - max(bx1, dc_box[d, 0])
                h = min(by2, dc_box[d, 3]) - max(by1, dc_box[d, 1])
                if max(w, 0.0) * max(h, 0.0) / area > 0.5 + eps:
                    in_dc[v] = True
                    break
    cand_start = np.zeros(U + 1, np.int64)
    for v in range(U):
        cand_start[v + 1] = cand_start[v] + n_cand[v]
    cand_row = np.empty(cand_start[U], np.int64)
    cand_iou = np.empty(cand_start[U], np.float64)
    for f in range(F):
        r0, r1, v0, v1 = row_start[f], row_start[f + 1], vstart[f], vstart[f + 1]
        nv = v1 - v0
        for v in range(v0, v1):
            k = cand_start[v]
            for r in range(r0, r1):
                x = iou[iou_start[f] + (r - r0) * nv + v - v0]
                if x >= match_iou - eps:
                    cand_row[k] = r
                    cand_iou[k] = x
                    k += 1
    return iou, cand_start, cand_row, cand_iou, in_dc


def pair_iou(t: BoxTable, row_start: np.ndarray, rows: np.ndarray, p_row: np.ndarray, dets: np.ndarray,
             p_det: np.ndarray) -> np.ndarray:
    """IoU of pairs (class row ``rows[p_row]``, tracker row ``dets[p_det]``) -> [P] float64.

    rows: [R] class rows, dets: [D] tracker rows (each pair's row and box in the same frame);
    p_row, p_det: [P] indices into them. Looked up as one base per row plus one offset per box."""
    frame = np.searchsorted(row_start, rows, side="right") - 1
    base = t.iou_start[frame] + (rows - row_start[frame]) * t.n_values[frame]
    return t.iou[base[p_row] + t.local[dets][p_det]]


def candidate_pairs(t: BoxTable) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every tracker row's candidate class rows: (det [Q], row [Q], iou [Q]), by tracker row then class row."""
    a = t.cand_start[t.value]
    n = t.cand_start[t.value + 1] - a
    det = np.repeat(np.arange(len(t.value), dtype=np.int64), n)
    idx = np.repeat(a, n) + (np.arange(int(n.sum()), dtype=np.int64) - np.repeat(segment_starts(n)[:-1], n))
    return det, t.cand_row[idx], t.cand_iou[idx]


def metric_pairs(t: BoxTable, row_start: np.ndarray, eval_start: np.ndarray, eval_count: np.ndarray,
                 ev_rows: np.ndarray, g_of_lf: np.ndarray, nk: np.ndarray, kidx: np.ndarray) -> tuple:
    """Every lane-frame's metric pairs (its eval GT rows x its kept boxes, row-major) and their IoU, in one
    compiled pass: ``(p_lf, p_e, p_k, sim, pair_start)``, what
    :func:`~dfrmot_jax.metrics.common.pairs.enumerate_pairs` of the eval rows and kept boxes and
    :func:`pair_iou` give, bit for bit. eval_start [F+1] / eval_count [F]: each frame's eval rows;
    ev_rows [NE]: each eval row's class row; g_of_lf [L*F]; nk [L*F] kept boxes per lane-frame (in
    order); kidx [KD] each kept box's row in the table's rows."""
    pair_start = segment_starts(eval_count[g_of_lf] * nk)
    return _metric_pairs(np.ascontiguousarray(g_of_lf, np.int64), np.ascontiguousarray(eval_start, np.int64),
                         np.ascontiguousarray(eval_count, np.int64), np.ascontiguousarray(ev_rows, np.int64),
                         np.ascontiguousarray(row_start, np.int64), segment_starts(nk), pair_start, t.iou_start,
                         t.n_values, t.iou, np.ascontiguousarray(t.local[kidx], np.int64)) + (pair_start,)


@cached_njit(nogil=True)
def _metric_pairs(g_of_lf, eval_start, eval_count, ev_rows, row_start, k_start, pair_start, iou_start, n_values, iou,
                  k_local):
    """The body of :func:`metric_pairs`: each pair's lane-frame, eval row, kept box and IoU."""
    P = pair_start[len(g_of_lf)]
    p_lf, p_e, p_k = np.empty(P, np.int64), np.empty(P, np.int64), np.empty(P, np.int64)
    sim = np.empty(P)
    for lf in range(len(g_of_lf)):
        f = g_of_lf[lf]
        k0, nc = k_start[lf], k_start[lf + 1] - k_start[lf]
        q = pair_start[lf]
        for i in range(eval_count[f] if nc else 0):
            e = eval_start[f] + i
            base = iou_start[f] + (ev_rows[e] - row_start[f]) * n_values[f]
            for j in range(nc):
                p_lf[q], p_e[q], p_k[q] = lf, e, k0 + j
                sim[q] = iou[base + k_local[k0 + j]]
                q += 1
    return p_lf, p_e, p_k, sim
