"""DFR-FastMOT for one configuration, in plain NumPy and Python loops: the test oracle.

Written for clarity, following ``docs/dfr-fastmot-spec.md`` step by step. Detections and scores
are float32 as parsed; parameters are float64 (score thresholds compared in float32 with the
scores); arithmetic (IoU, distances, costs, filters) is float64, as in the JAX tracker and the
authors' C++, so that the two can be compared id for id.

It shares no code with the tracker: it imports nothing that imports ``dfrmot_jax.trackers.dfr`` (checked
by ``tests/house/test_oracle_independent.py``) and keeps its own copies of the box rules the tracker
takes from ``core.boxes`` (IoU, the loaders' integer truncation), written from the C++ code.
"""

from __future__ import annotations

import functools
import math

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

from ..geometry import box3d_extent, project_box3d_to_image
from ..io.sequence import SequenceDets
from ..trackers.dfr.config import Options, Params

F32 = np.float32
F64 = np.float64


def p64(x) -> F64:
    """A parameter as the JAX tracker sees it: float64."""
    return F64(x)


# White-noise-jerk process noise of a constant-acceleration model, dt = 1 frame (position, velocity, acceleration).
Q_JERK = np.array([[1 / 20, 1 / 8, 1 / 6], [1 / 8, 1 / 3, 1 / 2], [1 / 6, 1 / 2, 1.0]], dtype=np.float64)


@dataclass
class Obj:
    """One object of the current frame: a 2D box, and maybe a 3D box."""

    box: np.ndarray               # [4] float64 (float32 values) x1, y1, x2, y2
    lo3: np.ndarray | None        # [3] float64 (float32 values) internal 3D box min corner
    hi3: np.ndarray | None        # [3] max corner
    kind: str                     # "2d" (row of the 2D file) or "3d" (unmatched 3D detection)
    index: int                    # file row of the detection it came from
    row3: int = -1                # file row (in seq.det3d) of its 3D detection (paired or lone), -1 = none
    strong: bool = True           # it may start a track (not only weak detections: Params.weak_2d, weak_3d)


@dataclass
class CoordFilter:
    """Per-coordinate constant-acceleration filter state: p, v, a [K] and, for the Kalman filter,
    the covariance entries P00, P01, P02, P11, P12, P22 [6, K]."""

    p: np.ndarray
    v: np.ndarray
    a: np.ndarray
    cov: np.ndarray | None = None


@dataclass
class Track:
    id: int
    f2: CoordFilter                   # 4 coords: top-left x, y; bottom-right x, y
    f3: CoordFilter | None            # 6 coords: min corner, max corner (None until a 3D observation)
    age: int = 0                      # frames since the last match
    hits: int = 1
    out_box: np.ndarray = field(default_factory=lambda: np.zeros(4, F64))
    row3: int = -1                    # file row of the last 3D detection it took (kept by 2D-only matches)
    own3: bool = False                # this frame's matched object had its own 3D detection
    out_box3: np.ndarray | None = None  # [6] 3D filter position taken with out_box (None: no 3D filter)


def iou_matrix(a, b) -> np.ndarray:
    """IoU [n, m] of x1, y1, x2, y2 boxes a [n, 4] and b [m, 4] in float64 (0 when the union is empty)."""
    a = np.asarray(a, F64).reshape(-1, 4)[:, None, :]
    b = np.asarray(b, F64).reshape(-1, 4)[None, :, :]
    iw = np.maximum(0.0, np.minimum(a[..., 2], b[..., 2]) - np.maximum(a[..., 0], b[..., 0]))
    ih = np.maximum(0.0, np.minimum(a[..., 3], b[..., 3]) - np.maximum(a[..., 1], b[..., 1]))
    inter = iw * ih
    union = (a[..., 2] - a[..., 0]) * (a[..., 3] - a[..., 1]) + (b[..., 2] - b[..., 0]) * (b[..., 3] - b[..., 1]) - inter
    return np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)


def iou(a, b) -> float:
    """IoU of two x1, y1, x2, y2 boxes."""
    return float(iou_matrix(a, b)[0, 0])


def c_int(v: float) -> float:
    """C++ ``(int)`` / ``stoi`` of a coordinate, as a float: towards zero (Python ``int`` of a float
    truncates the same way); a NaN or infinite value is kept (it has no integer)."""
    v = float(v)
    return float(int(v)) if math.isfinite(v) else v


def truncate_2d(box) -> np.ndarray:
    """The authors' 2D loader: each corner read as an integer, x = (int) x1, w = |x - (int) x2|;
    returned as (x, y, x + w, y + h) float64."""
    x1, y1, x2, y2 = (float(v) for v in box)
    x, y = c_int(x1), c_int(y1)
    w, h = abs(x - c_int(x2)), abs(y - c_int(y2))
    return np.array([x, y, x + w, y + h], F64)


def truncate_3d(box) -> np.ndarray:
    """The authors' 3D loader (and a track's truncated box): x = (int) x1, w = (int) |x - x2|, the
    far corner as read; returned as (x, y, x + w, y + h) float64."""
    x1, y1, x2, y2 = (float(v) for v in box)
    x, y = c_int(x1), c_int(y1)
    w, h = c_int(abs(x - x2)), c_int(abs(y - y2))
    return np.array([x, y, x + w, y + h], F64)


def predicted_box(p: np.ndarray, truncate: bool) -> np.ndarray:
    """A track's 2D box from its filter (top-left, bottom-right); truncated as the code does."""
    if truncate:
        return truncate_3d(p)
    return np.array([p[0], p[1], p[0] + np.abs(p[2] - p[0]), p[1] + np.abs(p[3] - p[1])], F64)


# ---------------------------------------------------------------------------------------------
# Filters


def steady_cov(params: Params, options: Options, iters: int = 500) -> np.ndarray:
    """Steady-state predicted covariance [6] by Riccati iteration (the "steady" Kalman start)."""
    return _steady_cov(float(params.kf_q), float(params.kf_r), options, iters).copy()


@functools.lru_cache(maxsize=64)
def _steady_cov(kf_q: float, kf_r: float, options: Options, iters: int) -> np.ndarray:
    params = Params(kf_q=kf_q, kf_r=kf_r)
    f = CoordFilter(np.zeros(1), np.zeros(1), np.zeros(1), np.array([[1e3], [0], [0], [1e3], [0], [1e3]], F64))
    for _ in range(iters):
        filter_update(f, f.p, params, options)
        filter_predict(f, params, options)
    return f.cov[:, 0]


def params_3d(params: Params) -> Params:
    """The parameters the 3D corners' filter runs with: kf_q, kf_r replaced by kf_q3, kf_r3 unless
    those are 0 (the default: the same noise as the 2D corners)."""
    return params._replace(kf_q=params.kf_q3 if params.kf_q3 != 0 else params.kf_q,
                           kf_r=params.kf_r3 if params.kf_r3 != 0 else params.kf_r)


def filter_init(z: np.ndarray, params: Params, options: Options) -> CoordFilter:
    k = z.shape[0]
    cov = None
    if options.filter == "kalman":
        cov = np.zeros((6, k), F64)
        if options.kalman_init == "steady":
            cov[:] = steady_cov(params, options)[:, None]
        else:
            cov[0] = p64(params.kf_r); cov[3] = p64(params.kf_p0); cov[5] = p64(params.kf_p0)
    return CoordFilter(z.astype(F64).copy(), np.zeros(k, F64), np.zeros(k, F64), cov)


def filter_update(f: CoordFilter, z: np.ndarray, params: Params, options: Options) -> None:
    r = z.astype(F64) - f.p
    if options.filter == "fixed_gain":
        ka, kb, kc = p64(params.gain_alpha), p64(params.gain_beta), F64(2) * p64(params.gain_gamma)
        f.p = f.p + ka * r
        f.v = f.v + kb * r
        f.a = f.a + kc * r
        return
    p00, p01, p02, p11, p12, p22 = f.cov
    s = p00 + p64(params.kf_r)
    k0, k1, k2 = p00 / s, p01 / s, p02 / s
    f.p = f.p + k0 * r
    f.v = f.v + k1 * r
    f.a = f.a + k2 * r
    f.cov = np.stack([p00 - k0 * p00, p01 - k0 * p01, p02 - k0 * p02,
                      p11 - k1 * p01, p12 - k1 * p02, p22 - k2 * p02])


def filter_predict(f: CoordFilter, params: Params, options: Options) -> None:
    half = F64(0.5)
    f.p = f.p + f.v + half * f.a
    f.v = f.v + f.a
    if options.filter == "kalman":
        a, b, c, d, e, g = f.cov
        # F P F^T for F = [[1, 1, 1/2], [0, 1, 1], [0, 0, 1]], plus q * Q_JERK
        r00 = a + b + half * c; r01 = b + d + half * e; r02 = c + e + half * g
        r11 = d + e; r12 = e + g
        q = p64(params.kf_q)
        qj = Q_JERK
        f.cov = np.stack([
            r00 + r01 + half * r02 + q * qj[0, 0],
            r01 + r02 + q * qj[0, 1],
            r02 + q * qj[0, 2],
            r11 + r12 + q * qj[1, 1],
            r12 + q * qj[1, 2],
            g + q * qj[2, 2],
        ])


# ---------------------------------------------------------------------------------------------
# One frame


def frame_objects(seq: SequenceDets, t: int, params: Params, options: Options, image_size) -> list[Obj]:
    """Kept detections of frame t, de-duplicated: 2D objects (file order), then unmatched 3D ones."""
    d2, d3 = seq.det2d, seq.det3d
    low2 = F32(p64(params.score_2d) - p64(params.weak_2d))      # weak thresholds: float64 difference, float32
    low3 = F32(p64(params.score_3d) - p64(params.weak_3d))
    rows2 = [i for i in np.flatnonzero(d2.frame == t) if F32(d2.score[i]) >= low2]
    rows3 = [j for j in np.flatnonzero(d3.frame == t) if F32(d3.score[j]) >= low3]
    if options.modality == "2d":
        rows3 = []
    if options.modality == "3d":
        rows2 = []

    def box2(i):
        b = d2.box[i]
        return (truncate_2d(b) if options.truncate else b).astype(F32).astype(F64)

    def box3(j):
        if options.merge == "calib_projection" or options.modality == "3d":
            b = project_box3d_to_image(d3.dims[j], d3.loc[j], d3.rot_y[j], seq.calib.P2, image_size)
        else:
            b = d3.box[j]
        return (truncate_3d(b) if options.truncate else b).astype(F32).astype(F64)

    def extent3(j):
        lo, hi = box3d_extent(d3.dims[j], d3.loc[j], options.centroid)
        return lo.astype(F64), hi.astype(F64)

    b2 = [box2(i) for i in rows2]
    b3 = [box3(j) for j in rows3]
    finite = [bool(np.all(np.isfinite(b))) for b in b3]  # a projected box behind the camera is NaN
    rows3 = [j for j, ok in zip(rows3, finite) if ok]
    b3 = [b for b, ok in zip(b3, finite) if ok]

    # Greedy de-duplication: first strict maximum in row-major order, while IoU > merge_iou.
    pair_of_2 = [-1] * len(rows2)
    taken3 = [False] * len(rows3)
    m = iou_matrix(b2, b3)
    for bi, bj in greedy_match(-m, list(range(len(b3))), -p64(params.merge_iou)):
        pair_of_2[bi] = bj
        taken3[bj] = True

    objects = []
    for i, r in enumerate(rows2):
        j = pair_of_2[i]
        lo = hi = None
        if j >= 0:
            lo, hi = extent3(rows3[j])
        strong = F32(d2.score[r]) >= F32(params.score_2d) or (j >= 0 and F32(d3.score[rows3[j]]) >= F32(params.score_3d))
        objects.append(Obj(b2[i], lo, hi, "2d", int(r), int(rows3[j]) if j >= 0 else -1, strong))
    for j, r in enumerate(rows3):
        if not taken3[j]:
            lo, hi = extent3(r)
            objects.append(Obj(b3[j], lo, hi, "3d", int(r), int(r), F32(d3.score[r]) >= F32(params.score_3d)))
    return objects


def affinity_matrix(objects: list[Obj], tracks: list[Track], params: Params, options: Options) -> np.ndarray:
    """[O, N] fused affinity M_f = alpha_c IoU' + alpha_l (1 - min(d, a_l) / a_l), float64.

    IoU' = IoU (against the track's predicted box) when >= a_c and the track is at most epsilon
    frames old, else 0; the LiDAR term counts only when both have a 3D box (d = centroid distance).
    """
    ac, a_c, a_l = p64(params.alpha_c), p64(params.a_c), p64(params.a_l)
    iou_ = iou_matrix([o.box for o in objects], [predicted_box(t.f2.p, options.truncate) for t in tracks])
    young = np.array([t.age <= params.epsilon for t in tracks])
    iou_c = np.where((iou_ >= a_c) & young[None, :], iou_, 0.0)

    def centres(items, lo_hi):
        has = np.array([lh is not None for lh in map(lo_hi, items)])
        c = np.array([(lh[0] + lh[1]) / F64(2) if lh is not None else np.zeros(3) for lh in map(lo_hi, items)], F64)
        return has, c.reshape(-1, 3)

    has_o, oc = centres(objects, lambda o: None if o.lo3 is None else (o.lo3, o.hi3))
    has_t, tc = centres(tracks, lambda t: None if t.f3 is None else (t.f3.p[:3], t.f3.p[3:]))
    dx, dy, dz = (oc[:, None, k] - tc[None, :, k] for k in range(3))
    d = np.sqrt(dx * dx + dy * dy + dz * dz)
    m_l = np.where(has_o[:, None] & has_t[None, :] & (d < a_l), d / a_l, 1.0)
    return ac * iou_c + (F64(1) - ac) * (1.0 - m_l)


TIE_BITS = 28


def order_key(cost: F64, col_key: int, row: int, row_bits: int = 6) -> int:
    """The entry's place in the greedy order: (cost to 2^-24 relative, column key, row).

    The cost's float64 bits, made order-preserving, with the lowest TIE_BITS replaced by the
    tie-break, exactly as ``associate.order_key``.
    """
    bits = int(np.array(F64(cost) + F64(0.0), F64).view(np.int64))
    if bits < 0:
        bits ^= 0x7FFFFFFFFFFFFFFF
    return ((bits >> TIE_BITS) << TIE_BITS) | (col_key << row_bits) | row


def greedy_match(cost: np.ndarray, track_ids: list[int], limit: F64) -> list[tuple[int, int]]:
    """Repeatedly take the first entry in greedy order (smallest cost; ties: smaller track id,
    then smaller row) while its cost < limit.

    The tracker calls it with cost = -M_f and limit = -a_f: the largest affinity first, while M_f > a_f.
    """
    rb = max(6, (cost.shape[0] - 1).bit_length())     # rows never spill into the track-id bits
    entries = sorted((order_key(cost[i, j], track_ids[j], i, rb), i, j) for i, j in zip(*np.nonzero(cost < limit)))
    used_rows, used_cols, pairs = set(), set(), []
    for _, i, j in entries:
        if i not in used_rows and j not in used_cols:
            pairs.append((i, j))
            used_rows.add(i)
            used_cols.add(j)
    return pairs


def hungarian_match(cost: np.ndarray, limit: F64) -> list[tuple[int, int]]:
    """The matching of the largest total limit - cost over entries with cost < limit (SciPy's
    ``linear_sum_assignment``), as (row, column) pairs in row order.

    The tracker calls it with cost = -M_f and limit = -a_f: the largest total M_f - a_f. Where several
    matchings reach the same total, SciPy's choice may differ from the tracker's solver.
    """
    ok = cost < limit
    rows, cols = linear_sum_assignment(np.where(ok, limit - cost, 0.0), maximize=True)
    return [(int(i), int(j)) for i, j in zip(rows, cols) if ok[i, j]]


# Whole on purpose (over 80 lines): the oracle reads straight through, one frame as the spec states it.
def track_sequence(seq: SequenceDets, params: Params, options: Options,
                   image_size=(1242, 375)) -> list[tuple]:
    """Run one sequence; returns output rows ``(frame, id, x1, y1, x2, y2, kind, index, row3, own3, box3)``.

    kind/index name the detection written ("2d"/"3d", file row) with output="detections";
    with output="filtered" kind is "track" and index -1.
    row3 / own3 name the 3D detection whose values the row carries (its file row in ``seq.det3d``,
    -1 = none): with output="detections" the object's own 3D detection (own3 True) or, for an
    object without 3D matched to a track with 3D, the track's stale last one (own3 False, spec
    section 5); with "filtered" the track's last 3D detection (own3 True when this frame's matched
    object had its own). box3: output "filtered" only, [6] float64 the track's 3D filter position
    (min corner, max corner) taken with the 2D box, None without a 3D filter; None for "detections".
    """
    options.validate()
    tracks: list[Track] = []
    next_id = 0
    rows = []
    limit = -p64(params.a_f)
    p3 = params_3d(params)
    for t in range(seq.n_frames):
        objects = frame_objects(seq, t, params, options, image_size)
        pairs = []
        if tracks and objects:
            affinity = affinity_matrix(objects, tracks, params, options)
            for i, obj in enumerate(objects):          # a weak object needs M_f > a_weak as well
                if not obj.strong:
                    affinity[i, affinity[i] <= p64(params.a_weak)] = -np.inf
            if options.assign == "hungarian":
                pairs = hungarian_match(-affinity, limit)
            else:
                pairs = greedy_match(-affinity, [trk.id for trk in tracks], limit)

        # Memory: matched objects take over their track; the others are born, in row order.
        obj_track: dict[int, Track] = {}
        matched_tracks = set()
        for i, j in pairs:
            trk, obj = tracks[j], objects[i]
            trk.age = 0
            trk.hits += 1
            filter_update(trk.f2, obj.box, params, options)
            trk.out_box = trk.f2.p.copy()
            filter_predict(trk.f2, params, options)
            trk.own3 = obj.lo3 is not None
            if obj.lo3 is not None:
                trk.row3 = obj.row3
                z3 = np.concatenate([obj.lo3, obj.hi3])
                if trk.f3 is None:
                    trk.f3 = filter_init(z3, p3, options)
                    trk.out_box3 = trk.f3.p.copy()
                else:
                    filter_update(trk.f3, z3, p3, options)
                    trk.out_box3 = trk.f3.p.copy()
                    filter_predict(trk.f3, p3, options)
            elif trk.f3 is not None:
                trk.out_box3 = trk.f3.p.copy()
                filter_predict(trk.f3, p3, options)
            obj_track[i] = trk
            matched_tracks.add(id(trk))
        for trk in tracks:
            if id(trk) not in matched_tracks:
                trk.out_box = trk.f2.p.copy()
                trk.own3 = False
                filter_predict(trk.f2, params, options)
                if trk.f3 is not None:
                    trk.out_box3 = trk.f3.p.copy()
                    filter_predict(trk.f3, p3, options)
        for i, obj in enumerate(objects):
            if i in obj_track or not obj.strong:       # a weak object continues a track, never starts one
                continue
            f3 = filter_init(np.concatenate([obj.lo3, obj.hi3]), p3, options) if obj.lo3 is not None else None
            trk = Track(id=next_id, f2=filter_init(obj.box, params, options), f3=f3,
                        row3=obj.row3, own3=f3 is not None, out_box3=None if f3 is None else f3.p.copy())
            trk.out_box = trk.f2.p.copy()
            next_id += 1
            tracks.append(trk)
            obj_track[i] = trk

        if options.output == "detections":
            for i, obj in enumerate(objects):
                if i not in obj_track:
                    continue
                trk = obj_track[i]
                if trk.hits >= params.min_hits:
                    own3 = obj.lo3 is not None
                    row3 = obj.row3 if own3 else trk.row3
                    rows.append((t, trk.id, *[float(v) for v in obj.box], obj.kind, obj.index, row3, own3, None))
        else:
            for trk in sorted(tracks, key=lambda k: k.id):
                if trk.hits >= params.min_hits and trk.age <= params.keep_lost:
                    box = predicted_box(trk.out_box, truncate=False)  # corners may cross
                    box3 = None if trk.out_box3 is None else trk.out_box3.astype(F64).copy()
                    rows.append((t, trk.id, *[float(F32(v)) for v in box], "track", -1, trk.row3, trk.own3, box3))

        # End of frame: forget tracks unmatched for more than epsilon frames, age the others.
        tracks = [trk for trk in tracks if trk.age <= params.epsilon]
        for trk in tracks:
            trk.age += 1
    return rows

