"""AB3DMOT's affinity matrix ``A[det, trk]`` (float32; 61f3bd7 ``matching.compute_affinity`` with
``dist_metrics``) of detection and predicted track boxes, every metric, every pair at once.

Boxes are states ``[x, y, z, theta, l, w, h]`` (KITTI camera coordinates, y the bottom, pointing
down). Each value is computed in float64 with AB3DMOT's roundings (``exact``: products rounded on
their own; the corners' rotation fused as its BLAS product fuses) and rounded once to float32:

- corners: ``x' = fma(s, dz, c dx) + x``, ``z' = fma(c, dz, -s dx) + z`` for the box-frame offsets
  ``dx = +-l/2``, ``dz = +-w/2`` (corners (l, w), (l, -w), (-l, -w), (-l, w), bottom then top);
  the footprint is corners 3, 2, 1, 0 as (x, z) points;
- ``iou_2d``, ``giou_2d``, ``iou_3d``, ``giou_3d``: I = the hull area of the detection's footprint
  clipped by the track's (0 when the footprints' circumcircles are apart, centre distance >
  radii + 1e-6), U = ``w_a l_a + w_b l_b - I``, C (GIoU) = the hull area of both footprints;
  IoU ``I / U``, GIoU ``I / U - (C - U) / C``; 3D: I, U and C times the overlap height
  ``max(0, min(y_a, y_b) - max(y_a - h_a, y_b - h_b))`` (C: the union height
  ``max(0, max(y_a, y_b) - min(y_a - h_a, y_b - h_b))``), U as ``w l h + w l h - I3``;
- ``dist_2d``: ``-sqrt(dx dx + dz dz)`` of the states; ``dist_3d``: the same over the 8 corners'
  means (pairwise sums ``((c0 + c1) + (c2 + c3)) + ((c4 + c5) + (c6 + c7))``, then / 8) in x, y, z;
- ``m_dis``: ``-sqrt(sum_j d_j (d_j / s_j))`` (each ``d_j / s_j`` as ``d_j * (1 / s_j)``, summed
  in order), d = det - trk with the heading difference shifted once by -pi (if > pi/2), then +pi
  (if < -pi/2), s the diagonal of the track's innovation covariance (``kalman.innovation``).

Pairs where AB3DMOT's geometry raises (a degenerate hull) are reported by ``bad`` [N, K].
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from . import polygon
from .config import DISTANCE_METRICS, METRICS
from .exact import fma, mul

__all__ = ["affinity", "footprint", "circle", "circles_apart", "pair_apart", "pair_intersection", "pair_hull",
           "footprint_intersection", "footprint_hull", "combine", "distance",
           "compact", "METRICS", "DISTANCE_METRICS"]


_SX = np.array([1.0, 1.0, -1.0, -1.0])                # the 4 corners' signs of l/2 and w/2
_SZ = np.array([1.0, -1.0, -1.0, 1.0])


def _corners_xz(boxes, zero):
    """(x, z [..., 4]) of the bottom corners 0..3 of boxes [..., 7]."""
    x, z, t = boxes[..., 0:1], boxes[..., 2:3], boxes[..., 3:4]
    c, s = jnp.cos(t), jnp.sin(t)
    dx, dz = (boxes[..., 4:5] / 2) * _SX, (boxes[..., 5:6] / 2) * _SZ           # exact (halves, signs)
    return fma(s, dz, mul(c, dx, zero), zero) + x, fma(c, dz, mul(-s, dx, zero), zero) + z


def footprint(boxes, zero):
    """The counter-clockwise footprint (x, z [..., 4]) of boxes [..., 7]: corners 3, 2, 1, 0."""
    x, z = _corners_xz(boxes, zero)
    return x[..., ::-1], z[..., ::-1]


def circle(boxes, zero):
    """(cx, cz, r [...]): the centre of the footprint of boxes [..., 7] (its corners' mean) and
    its circumradius (the farthest corner)."""
    px, pz = footprint(boxes, zero)
    cx = (((px[..., 0] + px[..., 1]) + px[..., 2]) + px[..., 3]) / 4
    cz = (((pz[..., 0] + pz[..., 1]) + pz[..., 2]) + pz[..., 3]) / 4
    dx, dz = px - cx[..., None], pz - cz[..., None]
    return cx, cz, jnp.max(jnp.sqrt(mul(dx, dx, zero) + mul(dz, dz, zero)), -1)


def circles_apart(a, b, zero):
    """Footprints surely apart [...] from their circles (``circle``) a, b (broadcast)."""
    (acx, acz, ra), (bcx, bcz, rb) = a, b
    dx, dz = acx - bcx, acz - bcz
    return jnp.sqrt(mul(dx, dx, zero) + mul(dz, dz, zero)) > (ra + rb) + 1e-6


def pair_apart(det, trk, zero):
    """Footprints surely apart [...]: their centres farther than the sum of their circumradii +
    1e-6 (then the clip is empty), for paired boxes det, trk [..., 7] (broadcast)."""
    return circles_apart(circle(det, zero), circle(trk, zero), zero)


def footprint_intersection(d, t, zero):
    """``pair_intersection`` of the footprints d, t (x, z [..., 4] each, ``footprint``)."""
    px, py, n, over = polygon.clip(d[0], d[1], t[0], t[1], zero)
    area, bad = polygon.hull_area(px, py, n, zero)
    return jnp.where(n > 0, area, 0.0), ((bad & (n > 0)) | over)


def pair_intersection(det, trk, zero):
    """(I [...], degenerate [...]) of paired boxes det, trk [..., 7]: the hull area of the
    detection's footprint clipped by the track's, 0 where the clip is empty."""
    return footprint_intersection(footprint(det, zero), footprint(trk, zero), zero)


def footprint_hull(d, t, zero):
    """``pair_hull`` of the footprints d, t (x, z [..., 4] each, ``footprint``)."""
    (dx, dz), (tx, tz) = d, t
    shape = jnp.broadcast_shapes(dx.shape, tx.shape)
    hx = jnp.concatenate([jnp.broadcast_to(dx, shape), jnp.broadcast_to(tx, shape)], -1)
    hz = jnp.concatenate([jnp.broadcast_to(dz, shape), jnp.broadcast_to(tz, shape)], -1)
    return polygon.hull_area(hx, hz, jnp.full(shape[:-1], 8, jnp.int32), zero)


def pair_hull(det, trk, zero):
    """(C [...], degenerate [...]): the hull area of both footprints of paired boxes [..., 7]."""
    return footprint_hull(footprint(det, zero), footprint(trk, zero), zero)


def combine(det, trk, metric: str, inter, hull, zero):
    """The IoU / GIoU value (float64 [...]) of paired boxes det, trk [..., 7] (broadcast) from
    their intersection I and (GIoU) hull area C."""
    d, t = det, trk
    area_d, area_t = mul(d[..., 5], d[..., 4], zero), mul(t[..., 5], t[..., 4], zero)
    if metric.endswith("2d"):
        union = (area_d + area_t) - inter
        if metric == "iou_2d":
            return inter / union
        return inter / union - (hull - union) / hull
    ya, yb = d[..., 1], t[..., 1]
    ta, tb = ya - d[..., 6], yb - t[..., 6]
    low = jnp.where(yb < ya, yb, ya) - jnp.where(tb > ta, tb, ta)
    inter3 = mul(inter, jnp.where(low > 0, low, 0.0), zero)
    union3 = (mul(area_d, d[..., 6], zero) + mul(area_t, t[..., 6], zero)) - inter3
    if metric == "iou_3d":
        return inter3 / union3
    high = jnp.where(yb > ya, yb, ya) - jnp.where(tb < ta, tb, ta)
    hull3 = mul(hull, jnp.where(high > 0, high, 0.0), zero)
    return inter3 / union3 - (hull3 - union3) / hull3


def compact(mask, capacity: int, start=0):
    """The flat positions [capacity] of the True entries of ``mask`` (any shape) ranked ``start``
    to ``start + capacity - 1`` in flat order (``start`` an int or traced scalar; positions of
    ranks beyond the last point past the end), and each entry's rank among them (mask's shape)."""
    flat = mask.reshape(-1)
    incl = jnp.cumsum(flat.astype(jnp.int32))
    sel = jnp.searchsorted(incl, start + jnp.arange(capacity) + 1, side="left")
    return sel, (incl - 1).reshape(mask.shape)


def _intersections(det, trk, cand, capacity: int, zero):
    """Footprint intersections [N, K] of the candidate pairs ``cand`` [N, K] (the rest 0), clipped
    for the first ``capacity`` candidates in (det, trk) order: (I, degenerate, candidates left)."""
    n_det, n_trk = cand.shape
    sel, rank = compact(cand, capacity)
    sel = jnp.minimum(sel, n_det * n_trk - 1)
    area, bad = pair_intersection(det[sel // n_trk], trk[sel % n_trk], zero)
    got = cand & (rank < capacity)
    rank = jnp.clip(rank, 0, capacity - 1)
    return jnp.where(got, area[rank], 0.0), got & bad[rank], jnp.maximum(jnp.sum(cand) - capacity, 0)


def _ious(det, trk, metric, valid, capacity, zero):
    """IoU / GIoU [N, K] float64, the degenerate pairs and the candidates left out, for boxes
    det [N, 7], trk [K, 7] and the valid pairs ``valid`` [N, K]."""
    d, t = det[:, None], trk[None]
    cand = valid & ~pair_apart(d, t, zero)
    inter, bad, left = _intersections(det, trk, cand, capacity, zero)
    hull = None
    if metric.startswith("giou"):
        hull, hull_bad = pair_hull(d, t, zero)
        bad = bad | (hull_bad & valid)
    return combine(d, t, metric, inter, hull, zero), bad, left


def _centres(boxes, zero):
    """[..., 3] the means of boxes' 8 corners (bottom 4, then top 4 at y - h), pairwise summed."""
    x, z = _corners_xz(boxes, zero)
    y = boxes[..., 1:2]
    ys = jnp.concatenate([jnp.broadcast_to(y, x.shape), jnp.broadcast_to(y - boxes[..., 6:7], x.shape)], -1)

    def mean8(v):
        low, high = (v[..., 0] + v[..., 1]) + (v[..., 2] + v[..., 3]), (v[..., 4] + v[..., 5]) + (v[..., 6] + v[..., 7])
        return (low + high) / 8
    return jnp.stack([mean8(jnp.concatenate([x, x], -1)), mean8(ys), mean8(jnp.concatenate([z, z], -1))], -1)


def _norm(d, zero):
    """sqrt of the sequential sum of squares over the last axis (NumPy's norm of a short vector)."""
    acc = mul(d[..., 0], d[..., 0], zero)
    for i in range(1, d.shape[-1]):
        acc = acc + mul(d[..., i], d[..., i], zero)
    return jnp.sqrt(acc)


def _yaw_difference(d):
    d = jnp.where(d > np.pi / 2, d - np.pi, d)
    return jnp.where(d < -np.pi / 2, d + np.pi, d)


def distance(det, trk, metric: str, zero, innovation=None):
    """``dist_2d`` / ``dist_3d`` / ``m_dis`` affinity (float64 [...], the negated distance) of
    paired boxes det, trk [..., 7] (broadcast); ``innovation`` [..., 7] the tracks' (``m_dis``)."""
    if metric == "dist_2d":
        d = det - trk
        return -_norm(jnp.stack([d[..., 0], d[..., 2]], -1), zero)
    if metric == "dist_3d":
        return -_norm(_centres(det, zero) - _centres(trk, zero), zero)
    d = det - trk
    d = jnp.concatenate([d[..., :3], _yaw_difference(d[..., 3:4]), d[..., 4:]], -1)
    inv = 1.0 / innovation
    acc = None
    for j in range(7):
        term = mul(mul(d[..., j], inv[..., j], zero), d[..., j], zero)
        acc = term if acc is None else acc + term
    return -jnp.sqrt(acc)


def affinity(det, trk, metric: str, zero, innovation=None, valid=None, capacity: int | None = None):
    """(A [N, K] float32, bad [N, K] bool, left int) of detection boxes det [N, 7] and predicted
    track boxes trk [K, 7] (states). innovation [K, 7]: the tracks' innovation diagonals (``m_dis``);
    valid [N, K]: the pairs that exist (default all; the others' values are meaningless); capacity:
    the most pairs whose footprints may overlap that are clipped (IoU metrics; default N K);
    ``left``: how many such pairs went beyond it (their intersection taken as 0: not AB3DMOT's);
    ``bad``: pairs where AB3DMOT's geometry raises (their values are not AB3DMOT's)."""
    if metric not in METRICS:
        raise ValueError(f"unknown metric {metric!r}; one of {METRICS}")
    shape = (det.shape[0], trk.shape[0])
    valid = jnp.ones(shape, bool) if valid is None else valid
    if "iou" in metric:
        cap = max(1, min(shape[0] * shape[1], capacity or shape[0] * shape[1]))
        value, bad, left = _ious(det, trk, metric, valid, cap, zero)
        return value.astype(jnp.float32), bad, left
    inn = None if innovation is None else innovation[None]
    value = distance(det[:, None], trk[None], metric, zero, inn)
    return value.astype(jnp.float32), jnp.zeros(shape, bool), jnp.zeros((), jnp.int32)
