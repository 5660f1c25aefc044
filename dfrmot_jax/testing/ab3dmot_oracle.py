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

import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment

from ..io.kitti import sequence_lengths
from .ab3dmot_geometry import bottom_polygon, box_corners, box_dict, iou_pair

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
    """``parse_detections`` of a file."""
    return parse_detections(Path(path).read_text())


def parse_detections(text: str) -> dict[int, FrameDets]:
    """Parse a PointRCNN detection CSV (``frame,type,x1,y1,x2,y2,score,h,w,l,x,y,z,rot_y,alpha``)
    into ``{frame: FrameDets}``. Rows keep their order within a frame: that is the detection
    index. Frames without a row are absent."""
    rows: dict[int, list[list[float]]] = {}
    for line in text.splitlines():
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
# affinities (box geometry in ab3dmot_geometry; its DegenerateGeometry propagates)


def affinity_matrix(det_states: np.ndarray, trk_states: np.ndarray, metric: str,
                    trk_inv_innovations: np.ndarray | None = None) -> np.ndarray:
    """Affinity [n_det, n_trk], float32 (each float64 value rounded once), of detection and
    predicted track states ([n, 7], [m, 7]):

    - ``iou_2d``/``iou_3d``/``giou_2d``/``giou_3d``: ``iou_pair``;
    - ``dist_2d``: ``-|(dx, dz)|`` of the states (bottom centres on the ground; ``np.linalg.norm``);
    - ``dist_3d``: ``-|c_det - c_trk|``, c the mean of a box's 8 corners (summed row by row, then
      divided by 8: ``np.average`` over corners stored column-major, i.e. NumPy's summation along
      a contiguous axis, as for AB3DMOT's transposed corner array; the norm as ``np.linalg.norm``;
      boxes with the same centre give 0 or a few 1e-15 depending on these orders);
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
        dbox = [box_dict(s) for s in det_states]
        tbox = [box_dict(s) for s in trk_states]
        for i in range(n):
            for j in range(m):
                out[i, j] = iou_pair(dbox[i], tbox[j], metric, dpoly[i], tpoly[j])
    elif metric == "dist_2d":
        for i in range(n):
            for j in range(m):
                out[i, j] = -np.linalg.norm(det_states[i, [0, 2]] - trk_states[j, [0, 2]])
    elif metric == "dist_3d":
        cd = [np.average(c, axis=0) for c in box_corners(det_states)]     # [3] each
        ct = [np.average(c, axis=0) for c in box_corners(trk_states)]
        for i in range(n):
            for j in range(m):
                out[i, j] = -np.linalg.norm(cd[i] - ct[j])
    else:                                                             # m_dis
        for i in range(n):
            for j in range(m):
                d = (det_states[i] - trk_states[j]).reshape(7, 1)
                d[3, 0] = yaw_difference(d[3, 0])
                out[i, j] = -np.sqrt(((d.T @ trk_inv_innovations[j]) @ d)[0, 0])
    return out


# ----------------------------------------------------------------------------------------------
# association

def _less(a, b) -> bool:
    """NumPy's float order for sorting: NaN after everything."""
    return a < b or (b != b and a == a)


def _argheapsort(v, idx, lo: int, n: int) -> None:
    """NumPy's indirect heapsort of ``idx[lo:lo+n]`` by ``v`` (the introsort's fallback), in place."""
    a = lambda k: idx[lo + k - 1]                                     # noqa: E731 (1-based heap)

    def put(k, val):
        idx[lo + k - 1] = val

    def sift(tmp, i, size):
        j = 2 * i
        while j <= size:
            if j < size and _less(v[a(j)], v[a(j + 1)]):
                j += 1
            if _less(v[tmp], v[a(j)]):
                put(i, a(j))
                i, j = j, 2 * j
            else:
                break
        put(i, tmp)

    for l in range(n >> 1, 0, -1):
        sift(a(l), l, n)
    while n > 1:
        tmp = a(n)
        put(n, a(1))
        n -= 1
        sift(tmp, 1, n)


def numpy_argsort(values) -> list[int]:
    """``np.argsort(values)`` with NumPy 1.23's default ``kind='quicksort'`` for floats, tie order
    included (NumPy 2 may dispatch to SIMD sorts that order ties otherwise): introsort on an index
    array, median-of-3 pivot moved to ``pr - 1``, both scans stopping at equal keys, the larger
    part pushed, insertion sort for parts of at most 16 items, heapsort past depth
    ``2 * floor(log2(n))``."""
    v = [float(x) for x in values]
    n = len(v)
    idx = list(range(n))
    stack = []
    pl, pr = 0, n - 1
    cdepth = 2 * (n.bit_length() - 1) if n else 0
    while True:
        if cdepth < 0:
            _argheapsort(v, idx, pl, pr - pl + 1)
        else:
            while pr - pl > 15:
                pm = pl + ((pr - pl) >> 1)
                if _less(v[idx[pm]], v[idx[pl]]):
                    idx[pm], idx[pl] = idx[pl], idx[pm]
                if _less(v[idx[pr]], v[idx[pm]]):
                    idx[pr], idx[pm] = idx[pm], idx[pr]
                if _less(v[idx[pm]], v[idx[pl]]):
                    idx[pm], idx[pl] = idx[pl], idx[pm]
                vp = v[idx[pm]]
                pi, pj = pl, pr - 1
                idx[pm], idx[pj] = idx[pj], idx[pm]
                while True:
                    pi += 1
                    while _less(v[idx[pi]], vp):
                        pi += 1
                    pj -= 1
                    while _less(vp, v[idx[pj]]):
                        pj -= 1
                    if pi >= pj:
                        break
                    idx[pi], idx[pj] = idx[pj], idx[pi]
                idx[pi], idx[pr - 1] = idx[pr - 1], idx[pi]
                if pi - pl < pr - pi:
                    stack.append((pi + 1, pr, cdepth - 1))
                    pr = pi - 1
                else:
                    stack.append((pl, pi - 1, cdepth - 1))
                    pl = pi + 1
                cdepth -= 1                                           # checked only for popped parts
            for i in range(pl + 1, pr + 1):                           # insertion sort
                vi = idx[i]
                key = v[vi]
                j = i
                while j > pl and _less(key, v[idx[j - 1]]):
                    idx[j] = idx[j - 1]
                    j -= 1
                idx[j] = vi
        if not stack:
            break
        pl, pr, cdepth = stack.pop()
    return idx


def greedy_assignment(cost: np.ndarray) -> np.ndarray:
    """Pairs [k, 2] (det, trk): all pairs visited by ascending cost (``numpy_argsort`` of the
    flattened row-major [n, m] matrix: NumPy 1.23's introsort, whose order of equal costs matters,
    e.g. the many zero IoUs), each taken when both its detection and its track are still free.
    Rows come in the order taken."""
    n, m = cost.shape
    order = numpy_argsort(cost.reshape(-1))
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
        lines, next_id = track_sequence(dets, max(sequence_lengths(root, [seq])[seq], 1), settings, next_id)
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
