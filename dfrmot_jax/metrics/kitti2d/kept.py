"""Which tracker boxes TrackEval's KITTI preprocessing keeps (``Kitti2DBox.get_preprocessed_seq_data``,
v1.3.0; :mod:`dfrmot_jax.metrics.kitti2d.kitti`'s docstring): per frame, the boxes are matched to the
class and distractor ground truth by ``linear_sum_assignment`` on their IoU where ``IoU >= 0.5 - eps``
(zero elsewhere), pairs above ``0 + eps``; a box matched to a distractor is removed, and so is an
unmatched box ``y2 - y1 <= 25 + eps`` px tall or more than ``0.5 + eps`` inside a DontCare region.

The answer matters only in frames where a distractor or such a fragile box is among the candidates
(elsewhere every box with a candidate stays, matched or not). :func:`kept_boxes` decides every
lane-frame in one compiled pass (:func:`_kept_kernel`); :func:`kept_boxes_numpy`, the same rule
vectorised over the candidate pairs, is the reference it is tested against.
"""

from __future__ import annotations

import numpy as np

from dfrmot_jax.metrics.common.assignment import match_block, workspace
from dfrmot_jax.metrics.common.kernel_cache import cached_njit
from dfrmot_jax.metrics.common.pairs import match_entries, segment_starts
from dfrmot_jax.metrics.kitti2d.box_table import BoxTable, candidate_pairs
from dfrmot_jax.metrics.kitti2d.boxes import EPS

__all__ = ["MIN_HEIGHT", "kept_boxes", "kept_boxes_numpy"]

MIN_HEIGHT = 25


def _fragile(tab: BoxTable, box: np.ndarray) -> np.ndarray:
    """[M] bool: removed if left unmatched (too low, or mostly inside a DontCare region)."""
    return (box[:, 3] - box[:, 1] <= MIN_HEIGHT + EPS) | tab.in_dontcare[tab.value]


def kept_boxes(gt, dets, tab: BoxTable, box: np.ndarray, lf: np.ndarray, g_of_lf: np.ndarray) -> np.ndarray:
    """[M] bool: the tracker boxes the preprocessing keeps (module docstring), in one compiled pass.

    gt: :class:`~dfrmot_jax.metrics.kitti2d.kitti.PreparedGT`; dets: its
    :class:`~dfrmot_jax.metrics.kitti2d.kitti.TrackerDets` (rows sorted by lane-frame); ``tab``: the
    boxes' :func:`~dfrmot_jax.metrics.kitti2d.box_table.box_table`; ``box`` [M, 4] float64; ``lf`` [M]
    lane-frames; ``g_of_lf`` [L*F] the frame of each lane-frame."""
    d_start = segment_starts(np.bincount(lf, minlength=len(g_of_lf)))
    return _kept_kernel(d_start, np.ascontiguousarray(g_of_lf, np.int64), np.ascontiguousarray(gt.row_start, np.int64),
                        np.ascontiguousarray(gt.row_eval, np.bool_), np.ascontiguousarray(tab.value, np.int64),
                        tab.cand_start, tab.cand_row, tab.cand_iou, _fragile(tab, box), EPS)


@cached_njit(nogil=True, calls=("dfrmot_jax.metrics.common.assignment",))
def _kept_kernel(d_start, g_of_lf, row_start, row_eval, value, cand_start, cand_row, cand_iou, fragile, eps):
    """Every lane-frame (its boxes ``d_start[lf]:d_start[lf + 1]``, frame ``g_of_lf[lf]``'s class rows):
    each box's candidates (the box table's: its value ``value[box]``'s class rows ``cand_row`` of
    ``IoU >= 0.5 - eps``, ``cand_iou``, from ``cand_start``); where a distractor row or a ``fragile``
    box is among them, the frame's match on its candidate matrix (zero elsewhere;
    :func:`~dfrmot_jax.metrics.common.assignment.match_block`, pairs above ``0 + eps``): a box matched
    to a distractor is removed, an unmatched fragile one too. Returns [M] bool kept."""
    M = len(fragile)
    keep = np.ones(M, np.bool_)
    side, block = np.int64(1), np.int64(1)       # (typed: assignment's docstring)
    for lf in range(len(g_of_lf)):
        nc = d_start[lf + 1] - d_start[lf]
        if nc:
            nr = row_start[g_of_lf[lf] + 1] - row_start[g_of_lf[lf]]
            side = max(side, nr, nc)
            block = max(block, nr * nc)
    vals = np.empty(block)
    rows, cols = np.empty(side, np.int64), np.empty(side, np.int64)
    matched = np.zeros(side, np.bool_)
    ws = workspace(side, block)
    for lf in range(len(g_of_lf)):
        d0, nc = d_start[lf], d_start[lf + 1] - d_start[lf]
        if nc == 0:
            continue
        needed = False
        for j in range(nc):
            v = value[d0 + j]
            for k in range(cand_start[v], cand_start[v + 1]):
                needed = needed or fragile[d0 + j] or not row_eval[cand_row[k]]
        if not needed:                            # a fragile box has no candidate here: unmatched
            for j in range(nc):
                keep[d0 + j] = not fragile[d0 + j]
            continue
        r0 = row_start[g_of_lf[lf]]
        nr = row_start[g_of_lf[lf] + 1] - r0
        vals[:nr * nc] = 0.0
        for j in range(nc):
            v = value[d0 + j]
            for k in range(cand_start[v], cand_start[v + 1]):
                vals[(cand_row[k] - r0) * nc + j] = cand_iou[k]
        n = match_block(vals, nr, nc, eps, rows, cols, ws)
        matched[:nc] = False
        for k in range(n):
            matched[cols[k]] = True
            if not row_eval[r0 + rows[k]]:
                keep[d0 + cols[k]] = False
        for j in range(nc):
            if fragile[d0 + j] and not matched[j]:
                keep[d0 + j] = False
    return keep


def kept_boxes_numpy(gt, dets, tab: BoxTable, box: np.ndarray, lf: np.ndarray, g_of_lf: np.ndarray) -> np.ndarray:
    """:func:`kept_boxes` vectorised over the candidate pairs (the frames that need it matched by
    :func:`~dfrmot_jax.metrics.common.pairs.match_entries`): the reference the compiled pass is tested
    against."""
    L = int(dets.n_lanes)
    F = gt.n_frames
    M = len(dets.lane)
    nd = np.bincount(lf, minlength=L * F).astype(np.int64)
    d_start = segment_starts(nd)
    fragile = _fragile(tab, box)
    # --- step 2: match to class + distractor GT, drop boxes matched to distractors. Only pairs with
    # IoU >= 0.5 - eps score (TrackEval's matrix is [class rows, boxes], zeros elsewhere); the answer
    # matters only where a distractor or a fragile box is among a frame's candidates (else every box
    # stays either way)
    c_det, c_row, c_iou = candidate_pairs(tab)
    c_lf = lf[c_det]
    needed = np.zeros(len(nd), dtype=bool)
    needed[c_lf[~gt.row_eval[c_row] | fragile[c_det]]] = True
    matched = match_entries(c_lf, dets.lane[c_det] * max(len(gt.row_eval), 1) + c_row, c_det, c_iou, needed,
                            np.diff(gt.row_start)[g_of_lf], nd, c_row - gt.row_start[dets.frame[c_det]],
                            c_det - d_start[c_lf], 0 + EPS)
    det_matched = np.zeros(M, dtype=bool)
    det_matched[c_det[matched]] = True
    to_remove = np.zeros(M, dtype=bool)
    to_remove[c_det[matched & ~gt.row_eval[c_row]]] = True
    # --- step 3: unmatched fragile boxes
    to_remove |= ~det_matched & fragile
    return ~to_remove
