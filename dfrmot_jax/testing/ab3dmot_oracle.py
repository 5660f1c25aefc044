"""AB3DMOT's 3D multi-object tracker (xinshuoweng/AB3DMOT at 61f3bd7, ``main.py`` with ego-motion
compensation off) in plain NumPy / SciPy / Python floats: the test oracle for its output files.

Written from the published algorithm, step by step, with each rule stated where it is implemented.
Nothing in the package imports this module. It reproduces the per-sequence files
``results/KITTI/pointrcnn_<Cat>_val_H1/data_0/SSSS.txt`` that AB3DMOT writes, line for line
(``reference/ab3dmot_tracker/README.md`` describes the reference runs; ``PRESETS`` holds their
settings).

One frame (``SequenceTracker.step``):

1. every live track is predicted with a constant-velocity Kalman filter (10 states
   ``[x, y, z, theta, l, w, h, dx, dy, dz]``), its heading wrapped to ``[-pi, pi)``;
2. the affinity ``A[det, trk]`` (float32) is computed with the run's metric;
3. Hungarian (``scipy.optimize.linear_sum_assignment`` on ``-A``) or greedy assignment over all
   pairs; assigned pairs with ``A < thres`` (float64 comparison) are rejected;
4. matched tracks are updated (heading first turned by pi / 2 pi to lie within 90 degrees of the
   detection's wrapped heading; Joseph-form covariance update), then wrapped again;
5. every unmatched detection starts a track (ids from one counter that runs across sequences);
6. tracks are written newest first when ``time_since_update < max_age`` and
   ``hits >= min_hits`` or the frame is one of the first ``min_hits`` frames; tracks with
   ``time_since_update >= max_age`` are deleted.

Array conventions: a box *state* is ``[x, y, z, theta, l, w, h]`` (KITTI camera coordinates,
bottom centre); a detection's *raw* box is ``[h, w, l, x, y, z, theta]`` as in the detection CSV;
*info* is ``[alpha, type, x1, y1, x2, y2, score]``.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment

PI = np.pi
TWO_PI = np.pi * 2

#: class code in the detection files -> name written in the output (AB3DMOT's KITTI ``det_id2str``)
TYPE_NAMES = {1: "Pedestrian", 2: "Car", 3: "Cyclist"}
#: category name -> detection folder name under ``detections/pointrcnn``
CATEGORY_FOLDERS = {"Car": "car", "Pedestrian": "pedestrian", "Cyclist": "cyclist"}
#: the line format of AB3DMOT's ``save_results`` for the evaluation files
LINE_FORMAT = "%d %d %s 0 0 %f %f %f %f %f %f %f %f %f %f %f %f %f"
METRICS = ("iou_2d", "iou_3d", "giou_2d", "giou_3d", "dist_2d", "dist_3d", "m_dis")
#: metrics whose affinity is a negated distance (``get_param`` negates their threshold)
DISTANCE_METRICS = ("dist_2d", "dist_3d", "m_dis")


@dataclass(frozen=True)
class Settings:
    """One AB3DMOT run: the category and ``get_param``'s five values, the threshold as written there
    (a positive distance for the distance metrics; ``affinity_threshold`` gives the one compared)."""

    category: str = "Car"
    algorithm: str = "hungar"          # 'hungar' | 'greedy'
    metric: str = "giou_3d"            # one of METRICS
    threshold: float = -0.2
    min_hits: int = 3
    max_age: int = 2

    @property
    def affinity_threshold(self) -> float:
        """The threshold compared with the affinity: ``-threshold`` for the distance metrics."""
        return -self.threshold if self.metric in DISTANCE_METRICS else self.threshold


#: the seven reference runs (folder name without ``head61f3bd7_``); ``car_noaffipro`` changes only
#: AB3DMOT's saved affinity matrices, so its tracks are those of ``car_default``
PRESETS = {
    "car_default": Settings("Car", "hungar", "giou_3d", -0.2, 3, 2),
    "ped_default": Settings("Pedestrian", "greedy", "giou_3d", -0.4, 1, 4),
    "car_greedy": Settings("Car", "greedy", "giou_3d", -0.2, 3, 2),
    "car_iou3d": Settings("Car", "hungar", "iou_3d", 0.01, 3, 2),
    "car_dist3d": Settings("Car", "hungar", "dist_3d", 6, 3, 2),
    "car_mdis": Settings("Car", "hungar", "m_dis", 6, 3, 2),
    "car_noaffipro": Settings("Car", "hungar", "giou_3d", -0.2, 3, 2),
}


# ----------------------------------------------------------------------------------------------
# input

@dataclass
class FrameDets:
    """The detections of one frame in file order: ``raw`` [n, 7] ``[h, w, l, x, y, z, theta]``,
    ``info`` [n, 7] ``[alpha, type, x1, y1, x2, y2, score]`` (float64 as parsed)."""

    raw: np.ndarray
    info: np.ndarray


def read_detections(path) -> dict[int, FrameDets]:
    """Parse a PointRCNN detection CSV (``frame,type,x1,y1,x2,y2,score,h,w,l,x,y,z,rot_y,alpha``)
    into ``{frame: FrameDets}``. Rows keep their order within a frame: that is the detection
    index. Frames without a row are absent."""
    rows: dict[int, list[list[float]]] = {}
    for line in Path(path).read_text().splitlines():
        if not line.strip():
            continue
        v = [float(s) for s in line.split(",")]
        rows.setdefault(int(v[0]), []).append(v)
    out = {}
    for frame, r in rows.items():
        a = np.array(r, dtype=np.float64)                             # [n, 15]
        out[frame] = FrameDets(raw=a[:, 7:14].copy(),
                               info=np.concatenate([a[:, 14:15], a[:, 1:7]], axis=1))
    return out


def sequence_length(label_path) -> int:
    """Frames of a sequence: the last frame in its ``label_02`` file plus one."""
    last = 0
    for line in Path(label_path).read_text().splitlines():
        if line.strip():
            last = max(last, int(line.split(" ", 1)[0]))
    return last + 1


EMPTY = FrameDets(raw=np.zeros((0, 7)), info=np.zeros((0, 7)))


# ----------------------------------------------------------------------------------------------
# angles

def wrap_angle(theta: float) -> float:
    """AB3DMOT's ``within_range``: subtract 2 pi once if ``theta >= pi``, then add 2 pi once if
    ``theta < -pi`` (one shift each way, not a modulo)."""
    if theta >= PI:
        theta = theta - TWO_PI
    if theta < -PI:
        theta = theta + TWO_PI
    return theta


def orientation_correction(theta_pre: float, theta_obs: float) -> tuple[float, float]:
    """Both headings wrapped; then the predicted one is turned by pi (and wrapped) when the two are
    more than 90 and less than 270 degrees apart; then, if they are still >= 270 degrees apart, the
    predicted one is moved by 2 pi towards the detection (+2 pi if ``theta_obs > 0``, else -2 pi).
    Returns ``(theta_pre, theta_obs)``; the Kalman update uses both (state and measurement)."""
    theta_pre, theta_obs = wrap_angle(theta_pre), wrap_angle(theta_obs)
    d = abs(theta_obs - theta_pre)
    if PI / 2.0 < d < PI * 3 / 2.0:
        theta_pre = wrap_angle(theta_pre + PI)
    if abs(theta_obs - theta_pre) >= PI * 3 / 2.0:
        theta_pre = theta_pre + TWO_PI if theta_obs > 0 else theta_pre - TWO_PI
    return theta_pre, theta_obs


def yaw_difference(diff: float) -> float:
    """m_dis's heading difference ``det - trk``, shifted once: -pi if > pi/2, then +pi if < -pi/2."""
    if diff > PI / 2:
        diff = diff - PI
    if diff < -PI / 2:
        diff = diff + PI
    return diff


# ----------------------------------------------------------------------------------------------
# Kalman filter (filterpy's KalmanFilter arithmetic, float64 matrices)

def _kf_matrices():
    F = np.eye(10)
    F[0, 7] = F[1, 8] = F[2, 9] = 1.0                                 # x += dx, y += dy, z += dz
    H = np.eye(7, 10)                                                 # the first 7 states measured
    P0 = np.eye(10)
    P0[7:, 7:] *= 1000.0                                              # unknown velocity
    P0 *= 10.0
    Q = np.eye(10)
    Q[7:, 7:] *= 0.01
    R = np.eye(7)
    return F, H, P0, Q, R


KF_F, KF_H, KF_P0, KF_Q, KF_R = _kf_matrices()
KF_I = np.eye(10)


class Track:
    """One track: state ``x`` [10, 1], covariance ``P`` [10, 10], ``id``, ``hits`` (1 at birth),
    ``time_since_update`` and ``info`` (its last detection's info row, [7])."""

    __slots__ = ("x", "P", "id", "hits", "time_since_update", "info")

    def __init__(self, state: np.ndarray, info: np.ndarray, track_id: int):
        """Birth: ``x[:7]`` = the detection's state (heading not wrapped), velocity 0, ``P = P0``."""
        self.x = np.zeros((10, 1))
        self.x[:7, 0] = state
        self.P = KF_P0.copy()
        self.id = track_id
        self.hits = 1
        self.time_since_update = 0
        self.info = info

    def predict(self) -> None:
        """``x = F x``; ``P = (F P) F' + Q``; heading wrapped; ``time_since_update += 1``."""
        self.x = KF_F @ self.x
        self.P = (KF_F @ self.P) @ KF_F.T + KF_Q
        self.x[3, 0] = wrap_angle(self.x[3, 0])
        self.time_since_update += 1

    def innovation(self) -> np.ndarray:
        """``S = (H P) H' + R`` [7, 7] (m_dis uses its inverse)."""
        return (KF_H @ self.P) @ KF_H.T + KF_R

    def update(self, z: np.ndarray) -> None:
        """filterpy's update with measurement ``z`` [7]: ``y = z - H x``; ``PHt = P H'``;
        ``S = H PHt + R``; ``K = PHt inv(S)``; ``x = x + K y``; Joseph form
        ``P = ((I - K H) P) (I - K H)' + (K R) K'``. Then the heading is wrapped."""
        y = z.reshape(7, 1) - KF_H @ self.x
        pht = self.P @ KF_H.T
        S = KF_H @ pht + KF_R
        K = pht @ np.linalg.inv(S)
        self.x = self.x + K @ y
        i_kh = KF_I - K @ KF_H
        self.P = (i_kh @ self.P) @ i_kh.T + (K @ KF_R) @ K.T
        self.x[3, 0] = wrap_angle(self.x[3, 0])

    def state(self) -> np.ndarray:
        """The box state ``[x, y, z, theta, l, w, h]`` [7] (a copy)."""
        return self.x[:7, 0].copy()


# ----------------------------------------------------------------------------------------------
# boxes and affinities

def box_corners(states: np.ndarray) -> np.ndarray:
    """Corners [n, 8, 3] of box states [n, 7]: in the box frame ``x = +-l/2``, ``z = +-w/2``,
    ``y = 0`` (corners 0-3, the bottom: y points down) or ``-h`` (corners 4-7), in the order
    (l,w), (l,-w), (-l,-w), (-l,w); rotated by ``roty(theta) = [[c,0,s],[0,1,0],[-s,0,c]]``, then
    translated by the centre."""
    x, y, z, t, l, w, h = (states[:, i:i + 1] for i in range(7))
    c, s = np.cos(t), np.sin(t)
    hl, hw = l / 2, w / 2
    xc = np.concatenate([hl, hl, -hl, -hl, hl, hl, -hl, -hl], axis=1)         # [n, 8]
    zc = np.concatenate([hw, -hw, -hw, hw, hw, -hw, -hw, hw], axis=1)
    zero = np.zeros_like(h)
    yc = np.concatenate([zero] * 4 + [-h] * 4, axis=1)
    return np.stack([c * xc + s * zc + x, yc + y, -s * xc + c * zc + z], axis=2)


def bottom_polygon(corners: np.ndarray) -> list[tuple[float, float]]:
    """The bottom face [4] as ``(x, z)`` points in counter-clockwise order: corners 3, 2, 1, 0 of
    one box's corners [8, 3]."""
    return [(float(corners[i, 0]), float(corners[i, 2])) for i in (3, 2, 1, 0)]


def clip_polygon(subject, clip):
    """Sutherland-Hodgman: ``subject`` (any polygon, list of (x, y)) clipped by each edge of the
    convex counter-clockwise ``clip`` polygon in turn, from edge (last, first) on. A point p is
    inside edge (a, b) iff ``(b.x - a.x)(p.y - a.y) > (b.y - a.y)(p.x - a.x)`` (strict); an edge
    crossing adds the intersection of the two lines, ``(n1 dp - n2 dc) / (dc x dp)`` with
    ``dc = a - b``, ``dp = s - e``, ``n1 = a x b``, ``n2 = s x e``. Returns the points, or None as
    soon as a stage leaves none."""
    def inside(p):
        return (b[0] - a[0]) * (p[1] - a[1]) > (b[1] - a[1]) * (p[0] - a[0])

    def crossing():
        dc = (a[0] - b[0], a[1] - b[1])
        dp = (s[0] - e[0], s[1] - e[1])
        n1 = a[0] * b[1] - a[1] * b[0]
        n2 = s[0] * e[1] - s[1] * e[0]
        n3 = 1.0 / (dc[0] * dp[1] - dc[1] * dp[0])
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

    - ``I_2D``: area of the detection's bottom clipped by the track's (0 when the clip is empty);
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
            inter = polygon_area(clipped)
    hull = polygon_area(convex_hull(det_poly + trk_poly)) if metric.startswith("giou") else None
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


def _box_dict(state) -> dict:
    return dict(zip(("x", "y", "z", "theta", "l", "w", "h"), (float(v) for v in state)))


def affinity_matrix(det_states: np.ndarray, trk_states: np.ndarray, metric: str,
                    trk_inv_innovations: np.ndarray | None = None) -> np.ndarray:
    """Affinity [n_det, n_trk], float32 (each float64 value rounded once), of detection and
    predicted track states ([n, 7], [m, 7]):

    - ``iou_2d``/``iou_3d``/``giou_2d``/``giou_3d``: ``iou_pair``;
    - ``dist_2d``: ``-|(dx, dz)|`` of the states (bottom centres on the ground);
    - ``dist_3d``: ``-|c_det - c_trk|``, c the mean of a box's 8 corners;
    - ``m_dis``: ``-sqrt(d' S^-1 d)``, ``d = det - trk`` [7] with the heading difference through
      ``yaw_difference``, ``S^-1`` [m, 7, 7] the inverse innovation of each track.
    """
    n, m = len(det_states), len(trk_states)
    if metric not in METRICS:
        raise ValueError(f"unknown metric {metric!r}")
    out = np.zeros((n, m), dtype=np.float32)
    if n == 0 or m == 0:
        return out
    if "iou" in metric:
        dc, tc = box_corners(det_states), box_corners(trk_states)
        dpoly = [bottom_polygon(c) for c in dc]
        tpoly = [bottom_polygon(c) for c in tc]
        dbox = [_box_dict(s) for s in det_states]
        tbox = [_box_dict(s) for s in trk_states]
        for i in range(n):
            for j in range(m):
                out[i, j] = iou_pair(dbox[i], tbox[j], metric, dpoly[i], tpoly[j])
    elif metric == "dist_2d":
        d = det_states[:, None, [0, 2]] - trk_states[None, :, [0, 2]]
        out[:] = -np.sqrt(np.sum(d * d, axis=-1))
    elif metric == "dist_3d":
        cd = box_corners(det_states).mean(axis=1)                     # [n, 3]
        ct = box_corners(trk_states).mean(axis=1)                     # [m, 3]
        d = cd[:, None, :] - ct[None, :, :]
        out[:] = -np.sqrt(np.sum(d * d, axis=-1))
    else:                                                             # m_dis
        for i in range(n):
            for j in range(m):
                d = (det_states[i] - trk_states[j]).reshape(7, 1)
                d[3, 0] = yaw_difference(d[3, 0])
                out[i, j] = -np.sqrt(((d.T @ trk_inv_innovations[j]) @ d)[0, 0])
    return out


# ----------------------------------------------------------------------------------------------
# association

def greedy_assignment(cost: np.ndarray) -> np.ndarray:
    """Pairs [k, 2] (det, trk): all pairs visited by ascending cost (``np.argsort`` of the
    flattened row-major [n, m] matrix; ties keep the flat order), each taken when both its
    detection and its track are still free. Rows come in the order taken."""
    n, m = cost.shape
    order = np.argsort(cost.reshape(-1), kind="stable")
    det_free, trk_free = [True] * n, [True] * m
    pairs = []
    for k in order:
        i, j = divmod(int(k), m)
        if det_free[i] and trk_free[j]:
            det_free[i] = trk_free[j] = False
            pairs.append((i, j))
    return np.array(pairs, dtype=int).reshape(-1, 2)


def associate(affinity: np.ndarray, algorithm: str, threshold: float):
    """Assignment on ``-affinity`` over all pairs, then rejection of pairs with
    ``affinity < threshold`` (in float64). Returns ``(matches [k, 2], unmatched_dets,
    unmatched_trks)``: unmatched detections are those the assignment left out (ascending), then
    the rejected ones in assignment order (Hungarian: ascending detection; greedy: ascending
    cost); this order is the order of births."""
    n, m = affinity.shape
    if m == 0:
        return np.zeros((0, 2), dtype=int), list(range(n)), []
    if n == 0:
        return np.zeros((0, 2), dtype=int), [], list(range(m))
    if algorithm == "hungar":
        rows, cols = linear_sum_assignment(-affinity)
        pairs = np.stack([rows, cols], axis=1)
    elif algorithm == "greedy":
        pairs = greedy_assignment(-affinity)
    else:
        raise ValueError(f"unknown algorithm {algorithm!r}")
    unmatched_dets = [i for i in range(n) if i not in set(pairs[:, 0].tolist())]
    unmatched_trks = [j for j in range(m) if j not in set(pairs[:, 1].tolist())]
    matches = []
    for i, j in pairs.tolist():
        if float(affinity[i, j]) < float(threshold):
            unmatched_dets.append(i)
            unmatched_trks.append(j)
        else:
            matches.append((i, j))
    return np.array(matches, dtype=int).reshape(-1, 2), unmatched_dets, unmatched_trks


# ----------------------------------------------------------------------------------------------
# tracking

def raw_to_state(raw: np.ndarray) -> np.ndarray:
    """``[h, w, l, x, y, z, theta]`` [..., 7] -> ``[x, y, z, theta, l, w, h]`` [..., 7]."""
    return raw[..., [3, 4, 5, 6, 2, 1, 0]]


class SequenceTracker:
    """AB3DMOT's tracker for one sequence. ``step`` takes one frame's detections and returns its
    output rows; ``next_id`` is the id the next birth gets."""

    def __init__(self, settings: Settings, first_id: int = 1):
        self.settings = settings
        self.tracks: list[Track] = []
        self.frame_count = 0
        self.next_id = first_id

    def step(self, dets: FrameDets) -> list[tuple]:
        """One frame; returns rows ``(id, info [7], state [7])``, newest track first."""
        st = self.settings
        self.frame_count += 1
        det_states = raw_to_state(dets.raw)                           # [n, 7]
        for t in self.tracks:
            t.predict()
        trk_states = np.array([t.state() for t in self.tracks]).reshape(-1, 7)
        inv_s = None
        if st.metric == "m_dis" and self.tracks:
            inv_s = np.stack([np.linalg.inv(t.innovation()) for t in self.tracks])
        aff = affinity_matrix(det_states, trk_states, st.metric, inv_s)
        matches, unmatched_dets, _ = associate(aff, st.algorithm, st.affinity_threshold)

        for i, j in matches.tolist():                                 # update (any order: independent)
            t = self.tracks[j]
            t.time_since_update = 0
            t.hits += 1
            z = det_states[i].copy()
            t.x[3, 0], z[3] = orientation_correction(t.x[3, 0], z[3])
            t.update(z)
            t.info = dets.info[i]

        for i in unmatched_dets:                                      # birth
            self.tracks.append(Track(det_states[i], dets.info[i], self.next_id))
            self.next_id += 1

        rows, alive = [], []
        for t in reversed(self.tracks):                               # output, newest first
            if t.time_since_update < st.max_age and (t.hits >= st.min_hits or self.frame_count <= st.min_hits):
                rows.append((t.id, t.info, t.state()))
            if t.time_since_update < st.max_age:
                alive.append(t)
        self.tracks = alive[::-1]
        return rows


def format_line(frame: int, row) -> str:
    """One output line in AB3DMOT's evaluation format (no newline): frame, id, type, ``0 0``,
    alpha, 2D box, h w l, x y z, theta, score."""
    tid, info, s = row
    return LINE_FORMAT % (frame, tid, TYPE_NAMES[int(info[1])], info[0], info[2], info[3], info[4], info[5],
                          s[6], s[5], s[4], s[0], s[1], s[2], s[3], info[6])


def track_sequence(dets: dict[int, FrameDets], n_frames: int, settings: Settings,
                   first_id: int = 1) -> tuple[list[str], int]:
    """Track frames ``0 .. n_frames-1``; returns ``(lines, next_id)``."""
    tracker = SequenceTracker(settings, first_id)
    lines = []
    for frame in range(n_frames):
        for row in tracker.step(dets.get(frame, EMPTY)):
            lines.append(format_line(frame, row))
    return lines, tracker.next_id


def track_sequences(kitti_root, settings: Settings, sequences=None, first_id: int = 1,
                    out_dir=None) -> dict[str, list[str]]:
    """Track ``sequences`` (default 0000..0020) in order with one id counter (starting at
    ``first_id``) from ``kitti_root/detections/pointrcnn/<cat>/SSSS.txt``, each over the frames of
    ``kitti_root/label_02/SSSS.txt``. A sequence whose detection file is empty is skipped (AB3DMOT
    writes nothing for it). Returns ``{seq: lines}``; writes ``out_dir/SSSS.txt`` if given."""
    root = Path(kitti_root)
    sequences = [f"{i:04d}" for i in range(21)] if sequences is None else list(sequences)
    folder = root / "detections" / "pointrcnn" / CATEGORY_FOLDERS[settings.category]
    out, next_id = {}, first_id
    for seq in sequences:
        dets = read_detections(folder / f"{seq}.txt")
        if not dets:
            continue
        lines, next_id = track_sequence(dets, sequence_length(root / "label_02" / f"{seq}.txt"), settings, next_id)
        out[seq] = lines
        if out_dir is not None:
            Path(out_dir).mkdir(parents=True, exist_ok=True)
            (Path(out_dir) / f"{seq}.txt").write_text("".join(s + "\n" for s in lines))
    return out


def main(argv=None):
    """``python -m dfrmot_jax.testing.ab3dmot_oracle KITTI_ROOT PRESET OUT_DIR [SEQ ...]``."""
    args = sys.argv[1:] if argv is None else argv
    root, preset, out_dir, seqs = args[0], args[1], args[2], args[3:] or None
    t0 = time.perf_counter()
    res = track_sequences(root, PRESETS[preset], seqs, out_dir=out_dir)
    print(f"{preset}: {sum(map(len, res.values()))} lines in {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
