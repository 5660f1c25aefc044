"""Box overlap formulas, bit-identical to TrackEval's ``_BaseDataset._calculate_box_ious``.

TrackEval computes a dense ``[N1, N2]`` matrix per frame; here the same float64 operations are
applied elementwise to *pairs* ``(a[k], b[k])`` so that many frames (and many tracker configs) are
handled in one vectorised call. Every value equals TrackEval's bit for bit, which matters because
ties in the later optimal assignments must resolve the same way.
"""

from __future__ import annotations

import numpy as np

EPS = np.finfo("float").eps  # TrackEval's tolerance, 2.22e-16


def _intersection(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    # TrackEval: min_ = minimum(b1, b2); max_ = maximum(b1, b2)
    #            inter = maximum(min_[2] - max_[0], 0) * maximum(min_[3] - max_[1], 0)
    w = np.minimum(a[:, 2], b[:, 2]) - np.maximum(a[:, 0], b[:, 0])
    h = np.minimum(a[:, 3], b[:, 3]) - np.maximum(a[:, 1], b[:, 1])
    return np.maximum(w, 0) * np.maximum(h, 0)


def _area(a: np.ndarray) -> np.ndarray:
    return (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])


def pair_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU of box pairs ``a[k]``, ``b[k]`` (``x0, y0, x1, y1``), exactly as TrackEval.

    a, b: [P, 4] float64 (``a`` plays TrackEval's ``bboxes1``, the ground truth). Returns [P] float64.
    Degenerate boxes (area <= eps) and unions <= eps give 0.
    """
    inter = _intersection(a, b)
    area1 = _area(a)
    area2 = _area(b)
    union = area1 + area2 - inter
    bad = (area1 <= 0 + EPS) | (area2 <= 0 + EPS) | (union <= 0 + EPS)
    inter = np.where(bad, 0.0, inter)
    union = np.where(union <= 0 + EPS, 1.0, union)
    return inter / union


def columns(boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """[N, 4] boxes -> four contiguous [N] float64 columns (fast gathers for :func:`gather_iou`)."""
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    return tuple(np.ascontiguousarray(boxes[:, i]) for i in range(4))


def gather_iou(a_cols, ia: np.ndarray, b_cols, ib: np.ndarray) -> np.ndarray:
    """``pair_iou(A[ia], B[ib])`` from column arrays (see :func:`columns`), bit-identical, faster.

    a_cols, b_cols: 4-tuples of [N] / [M] float64; ia, ib: [P] int indices. Returns [P] float64.
    """
    ax1, ay1, ax2, ay2 = (c[ia] for c in a_cols)
    bx1, by1, bx2, by2 = (c[ib] for c in b_cols)
    w = np.minimum(ax2, bx2)
    w -= np.maximum(ax1, bx1)
    h = np.minimum(ay2, by2)
    h -= np.maximum(ay1, by1)
    np.maximum(w, 0, out=w)
    np.maximum(h, 0, out=h)
    inter = w
    inter *= h
    ax2 -= ax1
    ay2 -= ay1
    area1 = ax2
    area1 *= ay2
    bx2 -= bx1
    by2 -= by1
    area2 = bx2
    area2 *= by2
    union = area1 + area2
    union -= inter
    bad = area1 <= 0 + EPS
    bad |= area2 <= 0 + EPS
    small = union <= 0 + EPS
    bad |= small
    inter[bad] = 0.0
    union[small] = 1.0
    inter /= union
    return inter


def pair_ioa(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Intersection over the area of ``a`` for pairs (TrackEval's ``do_ioa=True``).

    a: [P, 4] tracker boxes, b: [P, 4] ignore regions, both ``x0, y0, x1, y1`` float64.
    Returns [P] float64; 0 where ``area(a) <= eps``.
    """
    inter = _intersection(a, b)
    area1 = _area(a)
    valid = area1 > 0 + EPS
    out = np.zeros_like(inter)
    np.divide(inter, area1, out=out, where=valid)
    return out
