"""Box geometry of AB3DMOT's IoU / GIoU (61f3bd7 ``dist_metrics.py`` / ``box.py`` rules) for the
test oracle ``ab3dmot_oracle``: box corners, bottom polygons, Sutherland-Hodgman clipping, convex
hulls and their areas, and the four IoU variants of one pair, in float64 with AB3DMOT's operation
order where its last bits can matter (degenerate, nearly collinear boxes)."""

from __future__ import annotations

import math

import numpy as np


def box_corners(states: np.ndarray) -> np.ndarray:
    """Corners [n, 8, 3] of box states [n, 7]: in the box frame ``x = +-l/2``, ``z = +-w/2``,
    ``y = 0`` (corners 0-3, the bottom: y points down) or ``-h`` (corners 4-7), in the order
    (l,w), (l,-w), (-l,-w), (-l,w); rotated by ``roty(theta) = [[c,0,s],[0,1,0],[-s,0,c]]`` as a
    matrix product [3, 3] x [3, 8], then translated by the centre. The matrix product matters to
    the last bit: BLAS accumulates with fused multiply-adds, ``x' = fma(s, z, c x)``, as it did for
    AB3DMOT (nearly collinear box edges make its IoU depend on those bits)."""
    x, y, z, t, l, w, h = (states[:, i:i + 1] for i in range(7))
    c, s = np.cos(t[:, 0]), np.sin(t[:, 0])
    zero, one = np.zeros_like(c), np.ones_like(c)
    rot = np.stack([np.stack([c, zero, s], 1), np.stack([zero, one, zero], 1),
                    np.stack([-s, zero, c], 1)], 1)                             # [n, 3, 3]
    hl, hw = l / 2, w / 2
    local = np.stack([np.concatenate([hl, hl, -hl, -hl, hl, hl, -hl, -hl], axis=1),
                      np.concatenate([zero[:, None]] * 4 + [-h] * 4, axis=1),
                      np.concatenate([hw, -hw, -hw, hw, hw, -hw, -hw, hw], axis=1)], 1)   # [n, 3, 8]
    corners = np.matmul(rot, local)
    corners[:, 0, :] += x
    corners[:, 1, :] += y
    corners[:, 2, :] += z
    return np.transpose(corners, (0, 2, 1))           # a view: each [8, 3] is column-major, as in AB3DMOT


def bottom_polygon(corners: np.ndarray) -> list[tuple[float, float]]:
    """The bottom face [4] as ``(x, z)`` points in counter-clockwise order: corners 3, 2, 1, 0 of
    one box's corners [8, 3]."""
    return [(float(corners[i, 0]), float(corners[i, 2])) for i in (3, 2, 1, 0)]


def clip_polygon(subject, clip):
    """Sutherland-Hodgman: ``subject`` (any polygon, list of (x, y)) clipped by each edge of the
    convex counter-clockwise ``clip`` polygon in turn, from edge (last, first) on. A point p is
    inside edge (a, b) iff ``(b.x - a.x)(p.y - a.y) > (b.y - a.y)(p.x - a.x)`` (strict); an edge
    crossing adds the intersection of the two lines, ``(n1 dp - n2 dc) / (dc x dp)`` with
    ``dc = a - b``, ``dp = s - e``, ``n1 = a x b``, ``n2 = s x e`` (parallel lines: an infinite
    point, as NumPy's float division gives). Returns the points, or None as soon as a stage leaves
    none."""
    def inside(p):
        return (b[0] - a[0]) * (p[1] - a[1]) > (b[1] - a[1]) * (p[0] - a[0])

    def crossing():
        dc = (a[0] - b[0], a[1] - b[1])
        dp = (s[0] - e[0], s[1] - e[1])
        n1 = a[0] * b[1] - a[1] * b[0]
        n2 = s[0] * e[1] - s[1] * e[0]
        den = dc[0] * dp[1] - dc[1] * dp[0]
        n3 = 1.0 / den if den != 0.0 else math.copysign(math.inf, den)     # IEEE, as NumPy floats
        return ((n1 * dp[0] - n2 * dc[0]) * n3, (n1 * dp[1] - n2 * dc[1]) * n3)

    out = list(subject)
    a = clip[-1]
    for b in clip:
        pts, out = out, []
        s = pts[-1]
        for e in pts:
            if inside(e):
                if not inside(s):
                    out.append(crossing())
                out.append(e)
            elif inside(s):
                out.append(crossing())
            s = e
        a = b
        if not out:
            return None
    return out


def polygon_area(pts) -> float:
    """Shoelace area ``|sum(x_i y_i+1 - y_i x_i+1)| / 2`` of a simple polygon (list of (x, y))."""
    acc = 0.0
    n = len(pts)
    for i in range(n):
        x0, y0 = pts[i]
        x1, y1 = pts[(i + 1) % n]
        acc += x0 * y1 - y0 * x1
    return abs(acc) * 0.5


def convex_hull(pts):
    """Andrew's monotone chain: the convex hull (counter-clockwise, collinear points dropped) of a
    list of (x, y) points."""
    p = sorted(set(pts))
    if len(p) <= 2:
        return p

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower, upper = [], []
    for q in p:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], q) <= 0:
            lower.pop()
        lower.append(q)
    for q in reversed(p):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], q) <= 0:
            upper.pop()
        upper.append(q)
    return lower[:-1] + upper[:-1]


class DegenerateGeometry(ValueError):
    """A convex hull AB3DMOT cannot take (its ``scipy.spatial.ConvexHull`` raises ``QhullError``):
    non-finite points (a clip against a parallel edge), or fewer than 3 points not on one line.
    AB3DMOT stops there, so the oracle does too."""


def hull_area(pts) -> float:
    """Area of the convex hull of points (list of (x, y)); ``DegenerateGeometry`` where AB3DMOT's
    qhull call fails."""
    if not all(math.isfinite(c) for q in pts for c in q):
        raise DegenerateGeometry("non-finite point in a convex hull")
    hull = convex_hull(pts)
    if len(hull) < 3:
        raise DegenerateGeometry("convex hull of fewer than 3 points off one line")
    return polygon_area(hull)


def _overlap_possible(pa, pb) -> bool:
    """False when two bottom polygons (lists of 4 (x, z) points) are surely apart: centre distance
    above the sum of their circumradii (with 1e-6 slack). Then the clip is empty (area 0)."""
    ca = (sum(q[0] for q in pa) / 4, sum(q[1] for q in pa) / 4)
    cb = (sum(q[0] for q in pb) / 4, sum(q[1] for q in pb) / 4)
    ra = max(math.hypot(q[0] - ca[0], q[1] - ca[1]) for q in pa)
    rb = max(math.hypot(q[0] - cb[0], q[1] - cb[1]) for q in pb)
    return math.hypot(ca[0] - cb[0], ca[1] - cb[1]) <= ra + rb + 1e-6


def iou_pair(det, trk, metric: str, det_poly, trk_poly) -> float:
    """IoU / GIoU of a detection and a track (boxes as dicts of floats x y z theta l w h; bottom
    polygons from ``bottom_polygon``), in float64:

    - ``I_2D``: area of the convex hull of the detection's bottom clipped by the track's (0 when
      the clip is empty). Boxes with (nearly) collinear edges, e.g. identical boxes, give garbage
      points here (intersections of near-parallel lines), as in AB3DMOT, or ``DegenerateGeometry``;
    - ``C_2D`` (GIoU only): area of the convex hull of both bottoms' 8 points;
    - 2D: ``U = w_a l_a + w_b l_b - I``; IoU ``I / U``; GIoU ``I / U - (C - U) / C``;
    - 3D: overlap height ``max(0, min(y_a, y_b) - max(y_a - h_a, y_b - h_b))`` (y is the bottom),
      ``I3 = I_2D * overlap``, ``U3 = w_a l_a h_a + w_b l_b h_b - I3``; IoU ``I3 / U3``; GIoU uses
      the union height ``max(0, max(y_a, y_b) - min(y_a - h_a, y_b - h_b))``, ``C3 = C_2D * union``
      and ``I3 / U3 - (C3 - U3) / C3``.
    """
    inter = 0.0
    if _overlap_possible(det_poly, trk_poly):
        clipped = clip_polygon(det_poly, trk_poly)
        if clipped is not None:
            inter = hull_area(clipped)
    hull = hull_area(det_poly + trk_poly) if metric.startswith("giou") else None
    if metric.endswith("2d"):
        union = det["w"] * det["l"] + trk["w"] * trk["l"] - inter
        if metric == "iou_2d":
            return inter / union
        return inter / union - (hull - union) / hull
    ya, yb = det["y"], trk["y"]
    ta, tb = ya - det["h"], yb - trk["h"]
    overlap = max(0.0, min(ya, yb) - max(ta, tb))
    inter3 = inter * overlap
    union3 = det["w"] * det["l"] * det["h"] + trk["w"] * trk["l"] * trk["h"] - inter3
    if metric == "iou_3d":
        return inter3 / union3
    hull3 = hull * max(0.0, max(ya, yb) - min(ta, tb))
    return inter3 / union3 - (hull3 - union3) / hull3


def box_dict(state) -> dict:
    return dict(zip(("x", "y", "z", "theta", "l", "w", "h"), (float(v) for v in state)))
