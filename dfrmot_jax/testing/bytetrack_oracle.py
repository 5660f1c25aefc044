"""ByteTrack's tracker (ifzhang/ByteTrack at d1bf019, ``yolox/tracker``) in plain Python floats and
NumPy: the test oracle of ``dfrmot_jax.trackers.bytetrack``.

Written from the published algorithm and the rules of ``reference/bytetrack_tracker/README.md``,
each rule stated where it is implemented; nothing of ``dfrmot_jax.trackers`` is imported (the JAX
side is checked against this, never the reverse). It reproduces the reference runs' files line for
line (ids up to one renaming per sequence; here, as there, the counter starts at 1 per sequence).

One frame (:meth:`Tracker.update`), ByteTrack's ``BYTETracker.update``:

1. the detections are split: *high* ``score > track_thresh``, *low* ``0.1 < score < track_thresh``
   (strict: a score equal to ``track_thresh`` is in neither);
2. the tracked list's activated tracks then the lost list (the *pool*, in list order) are
   predicted (a track not in state Tracked predicts with its height velocity set to 0); the
   unconfirmed tracks (tracked, never activated) are not;
3. pool x high: cost ``1 - IoU`` (+1-pixel IoU), fused with the score (``1 - IoU' * score``) unless
   ``mot20``, assigned by :func:`lapjv` at ``match_thresh``; matched Tracked tracks are updated,
   others re-activated (same id);
4. the pool's unmatched Tracked tracks x low: ``1 - IoU``, 0.5; the rest of them become Lost;
5. unconfirmed x the high detections left: as 3, at 0.7; unmatched unconfirmed tracks are removed;
6. every high detection left with ``score >= track_thresh + margin`` starts a track (a new id;
   activated at once only on the tracker's first frame);
7. lost tracks with ``frame - end_frame > max_time_lost`` are marked removed, but stay in the lost
   list until the next frame's bookkeeping (ByteTrack subtracts the removed list *before* adding the
   frame's removals): such a track can still be found in the next frame, and an id once removed
   makes its track vanish the next time it is lost;
8. the lists are joined / subtracted as ByteTrack does, then ``remove_duplicate_stracks``.

The Kalman filter is ByteTrack's 8-state one written per coordinate (its covariance has four
independent 2x2 blocks: every other entry stays an exact 0), each value rounded as NumPy / OpenBLAS
round ByteTrack's matrix products (products with 0 / 1 entries are exact; ``multi_dot`` of three
equal-cost factors multiplies right first; ``cho_solve`` multiplies by ``1 / sqrt(s)`` twice).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..io.kitti import read_detections_2d, sequence_lengths

__all__ = [
    "PRESETS", "Settings", "Track", "Tracker", "lapjv", "linear_assignment", "iou", "load_frames",
    "run_sequence", "format_line", "demo_filter",
]

SP = 1.0 / 20      # std_weight_position
SV = 1.0 / 160     # std_weight_velocity
LARGE = 1000000.0  # lap's LARGE


@dataclass(frozen=True)
class Settings:
    """One run: ByteTrack's args (``track_thresh``, ``track_buffer``, ``match_thresh``, ``mot20``), the
    frame rate and the births' margin above ``track_thresh`` (ByteTrack: 0.1)."""
    track_thresh: float = 0.5
    track_buffer: int = 30
    match_thresh: float = 0.8
    mot20: bool = False
    frame_rate: int = 10
    det_thresh_margin: float = 0.1
    demo_filter: bool = False

    @property
    def max_time_lost(self) -> int:
        return int(self.frame_rate / 30.0 * self.track_buffer)

    @property
    def det_thresh(self) -> float:
        return self.track_thresh + self.det_thresh_margin


#: the reference runs (reference/bytetrack_tracker/README.md): name -> (class, settings)
PRESETS = {
    "car_default": ("car", Settings()),
    "car_mot20": ("car", Settings(mot20=True)),
    "car_low": ("car", Settings(track_thresh=0.3, track_buffer=60, match_thresh=0.9)),
    "car_fps30": ("car", Settings(frame_rate=30)),
    "pedestrian_default": ("pedestrian", Settings()),
    "pedestrian_low": ("pedestrian", Settings(track_thresh=0.3, track_buffer=60, match_thresh=0.9)),
    "car_default_demofilter": ("car", Settings(demo_filter=True)),
}


# ----------------------------------------------------------------------------------------------
# lap.lapjv (lap 0.5.13, _lapjv_cpp/lapjv.cpp), the dense Jonker-Volgenant solver, step by step
# ----------------------------------------------------------------------------------------------

def _column_reduction(n, c, x, y, v):
    """Column reduction and reduction transfer; returns the free rows in ascending order."""
    for j in range(n):
        v[j] = LARGE
        y[j] = 0
    for i in range(n):
        x[i] = -1
    for i in range(n):              # each column's minimum, the first row reaching it
        for j in range(n):
            if c[i][j] < v[j]:
                v[j] = c[i][j]
                y[j] = i
    unique = [True] * n
    for j in range(n - 1, -1, -1):  # a row keeps the last of its columns; the others lose it
        i = y[j]
        if x[i] < 0:
            x[i] = j
        else:
            unique[i] = False
            y[j] = -1
    free = []
    for i in range(n):
        if x[i] < 0:
            free.append(i)
        elif unique[i]:            # transfer: lower v of its column by the second-best reduced cost
            j = x[i]
            best = LARGE
            for j2 in range(n):
                if j2 != j:
                    r = c[i][j2] - v[j2]
                    if r < best:
                        best = r
            v[j] -= best
    return free


def _augmenting_row_reduction(n, c, free, x, y, v):
    """One pass of augmenting row reduction over ``free``; returns the rows still free."""
    current = 0
    new_free = 0
    count = 0
    n_free = len(free)
    free = list(free)
    while current < n_free:
        count += 1
        i = free[current]
        current += 1
        j1, u1 = 0, c[i][0] - v[0]
        j2, u2 = -1, LARGE
        for j in range(1, n):
            r = c[i][j] - v[j]
            if r < u2:
                if r >= u1:
                    u2, j2 = r, j
                else:
                    u2, j2 = u1, j1
                    u1, j1 = r, j
        i0 = y[j1]
        v1_new = v[j1] - (u2 - u1)
        lowers = v1_new < v[j1]
        if count < current * n:
            if lowers:
                v[j1] = v1_new
            elif i0 >= 0 and j2 >= 0:
                j1 = j2
                i0 = y[j2]
            if i0 >= 0:
                if lowers:
                    current -= 1
                    free[current] = i0
                else:
                    free[new_free] = i0
                    new_free += 1
        elif i0 >= 0:
            free[new_free] = i0
            new_free += 1
        x[i] = j1
        y[j1] = i
    return free[:new_free]


def _shortest_path(n, c, start, y, v, pred):
    """The Dijkstra-like search from a free row; returns the free column reached (v updated)."""
    cols = list(range(n))
    d = [c[start][j] - v[j] for j in range(n)]
    for j in range(n):
        pred[j] = start
    lo = hi = 0
    n_ready = 0
    final = -1
    while final == -1:
        if lo == hi:               # collect the columns of minimal d into cols[lo:hi]
            n_ready = lo
            hi = lo + 1
            mind = d[cols[lo]]
            for k in range(hi, n):
                j = cols[k]
                if d[j] <= mind:
                    if d[j] < mind:
                        hi = lo
                        mind = d[j]
                    cols[k] = cols[hi]
                    cols[hi] = j
                    hi += 1
            for k in range(lo, hi):
                if y[cols[k]] < 0:
                    final = cols[k]
        if final == -1:            # scan: relax the columns not yet ready from the scan list
            lo0, hi0 = lo, hi      # lap returns from the scan without storing lo, hi when it finds
            while lo != hi and final == -1:
                j = cols[lo]
                lo += 1
                i = y[j]
                mind = d[j]
                h = c[i][j] - v[j] - mind
                for k in range(hi, n):
                    j = cols[k]
                    r = c[i][j] - v[j] - h
                    if r < d[j]:
                        d[j] = r
                        pred[j] = i
                        if r == mind:
                            if y[j] < 0:
                                final = j
                                break
                            cols[k] = cols[hi]
                            cols[hi] = j
                            hi += 1
            if final != -1:
                lo, hi = lo0, hi0
    mind = d[cols[lo]]
    for k in range(n_ready):
        j = cols[k]
        v[j] += d[j] - mind
    return final


def _lapjv_square(c):
    """x, y of lap's ``lapjv_internal`` on a square list-of-lists matrix."""
    n = len(c)
    x = [-1] * n
    y = [0] * n
    v = [0.0] * n
    free = _column_reduction(n, c, x, y, v)
    for _ in range(2):
        if not free:
            break
        free = _augmenting_row_reduction(n, c, free, x, y, v)
    pred = [0] * n
    for f in free:
        j = _shortest_path(n, c, f, y, v, pred)
        i = -1
        while i != f:
            i = pred[j]
            y[j] = i
            x[i], j = j, x[i]
    return x, y


def lapjv(cost, cost_limit):
    """``lap.lapjv(cost, extend_cost=True, cost_limit=cost_limit)``'s ``x, y`` (-1: unmatched): the
    matrix extended to (rows + cols) square, ``cost_limit / 2`` on the dummy entries, 0 on the
    dummy-dummy block."""
    cost = np.asarray(cost, dtype=np.float64)
    nr, nc = cost.shape
    n = nr + nc
    half = cost_limit / 2.0
    c = [[(float(cost[i, j]) if j < nc else half) if i < nr else (half if j < nc else 0.0)
          for j in range(n)] for i in range(n)]
    x, y = _lapjv_square(c)
    xs = [j if j < nc else -1 for j in x[:nr]]
    ys = [i if i < nr else -1 for i in y[:nc]]
    return xs, ys


def linear_assignment(cost, thresh):
    """ByteTrack's ``matching.linear_assignment``: (matches [(row, col)], unmatched rows, unmatched
    cols), rows and columns ascending."""
    cost = np.asarray(cost, dtype=np.float64)
    if cost.size == 0:
        return [], list(range(cost.shape[0])), list(range(cost.shape[1]))
    x, y = lapjv(cost, thresh)
    matches = [(i, j) for i, j in enumerate(x) if j >= 0]
    return matches, [i for i, j in enumerate(x) if j < 0], [j for j, i in enumerate(y) if i < 0]


# ----------------------------------------------------------------------------------------------
# geometry and the Kalman filter
# ----------------------------------------------------------------------------------------------

def iou(a, b):
    """cython_bbox's ``bbox_overlaps`` of one box ``a`` (a track's) and one query box ``b`` (a
    detection's), both ``x1, y1, x2, y2``: the +1-pixel convention, each operation as it is
    written there."""
    iw = (min(a[2], b[2]) - max(a[0], b[0])) + 1.0
    if iw > 0:
        ih = (min(a[3], b[3]) - max(a[1], b[1])) + 1.0
        if ih > 0:
            area_b = ((b[2] - b[0]) + 1.0) * ((b[3] - b[1]) + 1.0)
            area_a = ((a[2] - a[0]) + 1.0) * ((a[3] - a[1]) + 1.0)
            inter = iw * ih
            return inter / ((area_a + area_b) - inter)
    return 0.0


def iou_cost(tracks_tlbr, dets_tlbr, scores=None):
    """``iou_distance`` (1 - IoU), fused with the scores (``fuse_score``) when ``scores`` is given."""
    out = np.zeros((len(tracks_tlbr), len(dets_tlbr)))
    for i, a in enumerate(tracks_tlbr):
        for j, b in enumerate(dets_tlbr):
            cost = 1.0 - iou(a, b)
            if scores is not None:
                cost = 1.0 - (1.0 - cost) * scores[j]
            out[i, j] = cost
    return out


def _initiate(z):
    """Mean (8) and covariance blocks [4][pp, pv, vp, vv] of a new track from ``z = x, y, a, h``."""
    h = z[3]
    sp2, sv10 = 2 * SP, 10 * SV
    pos = [sp2 * h, sp2 * h, 1e-2, sp2 * h]
    vel = [sv10 * h, sv10 * h, 1e-5, sv10 * h]
    mean = [z[0], z[1], z[2], z[3], 0.0, 0.0, 0.0, 0.0]
    cov = [[pos[c] * pos[c], 0.0, 0.0, vel[c] * vel[c]] for c in range(4)]
    return mean, cov


def _predict(mean, cov, tracked):
    """Constant-velocity prediction (``multi_predict``); a track not Tracked has ``vh`` set to 0."""
    mean = list(mean)
    if not tracked:
        mean[7] = 0.0
    h = mean[3]
    qp = [SP * h, SP * h, 1e-2, SP * h]
    qv = [SV * h, SV * h, 1e-5, SV * h]
    new_cov = []
    for c in range(4):
        pp, pv, vp, vv = cov[c]
        new_cov.append([((pp + vp) + (pv + vv)) + qp[c] * qp[c], pv + vv, vp + vv, vv + qv[c] * qv[c]])
    new_mean = [mean[c] + mean[c + 4] for c in range(4)] + mean[4:]
    return new_mean, new_cov


def _update(mean, cov, z):
    """Kalman correction with the measurement ``z = x, y, a, h`` (``KalmanFilter.update``)."""
    h = mean[3]
    r = [SP * h, SP * h, 1e-1, SP * h]
    new_mean = list(mean)
    new_cov = []
    for c in range(4):
        pp, pv, vp, vv = cov[c]
        s = pp + r[c] * r[c]
        inv = 1.0 / math.sqrt(s)
        kp = (pp * inv) * inv
        kv = (vp * inv) * inv
        innov = z[c] - mean[c]
        new_mean[c] = mean[c] + innov * kp
        new_mean[c + 4] = mean[c + 4] + innov * kv
        new_cov.append([pp - kp * (s * kp), pv - kp * (s * kv), vp - kv * (s * kp), vv - kv * (s * kv)])
    return new_mean, new_cov


def tlwh_of_mean(mean):
    """``STrack.tlwh`` of a Kalman mean: ``x - a h / 2, y - h / 2, a h, h``."""
    w = mean[2] * mean[3]
    return [mean[0] - w / 2, mean[1] - mean[3] / 2, w, mean[3]]


def tlbr_of_mean(mean):
    x1, y1, w, h = tlwh_of_mean(mean)
    return [x1, y1, w + x1, h + y1]


def xyah_of_tlwh(t):
    """``tlwh_to_xyah``: centre, aspect ``w / h``, height."""
    return [t[0] + t[2] / 2, t[1] + t[3] / 2, t[2] / t[3], t[3]]


# ----------------------------------------------------------------------------------------------
# the tracker
# ----------------------------------------------------------------------------------------------

TRACKED, LOST, REMOVED = 1, 2, 3


@dataclass(eq=False)
class Track:
    """One track (``STrack``); a detection before it starts has ``mean is None``."""
    tlwh: list
    score: float
    mean: list | None = None
    cov: list | None = None
    track_id: int = 0
    state: int = 0
    is_activated: bool = False
    start_frame: int = 0
    frame_id: int = 0

    def box_tlbr(self):
        if self.mean is None:
            x1, y1, w, h = self.tlwh
            return [x1, y1, w + x1, h + y1]
        return tlbr_of_mean(self.mean)

    def box_tlwh(self):
        return list(self.tlwh) if self.mean is None else tlwh_of_mean(self.mean)


def _joint(a, b):
    ids = {t.track_id for t in a}
    out = list(a)
    for t in b:
        if t.track_id not in ids:
            ids.add(t.track_id)
            out.append(t)
    return out


def _sub(a, b):
    gone = {t.track_id for t in b}
    out, seen = [], {}
    for t in a:                 # a dict keyed by id in ByteTrack: the last of equal ids, first place
        if t.track_id in seen:
            out[seen[t.track_id]] = t
        else:
            seen[t.track_id] = len(out)
            out.append(t)
    return [t for t in out if t.track_id not in gone]


class Tracker:
    """``BYTETracker`` for one sequence; ids from 1 (``next_id`` counter owned by the tracker)."""

    def __init__(self, settings: Settings):
        self.s = settings
        self.frame_id = 0
        self.count = 0
        self.tracked: list[Track] = []
        self.lost: list[Track] = []
        self.removed: list[Track] = []

    def _activate(self, t: Track):
        self.count += 1
        t.track_id = self.count
        t.mean, t.cov = _initiate(xyah_of_tlwh(t.tlwh))
        t.state = TRACKED
        t.is_activated = self.frame_id == 1
        t.frame_id = t.start_frame = self.frame_id

    def _update(self, t: Track, det: Track):
        t.mean, t.cov = _update(t.mean, t.cov, xyah_of_tlwh(det.tlwh))
        t.state = TRACKED
        t.is_activated = True
        t.frame_id = self.frame_id
        t.score = det.score

    def update(self, dets: np.ndarray) -> list[Track]:
        """One frame: ``dets`` [n, 5] ``x1, y1, x2, y2, score`` (float64). Returns the written tracks."""
        s = self.s
        self.frame_id += 1
        dets = np.asarray(dets, dtype=np.float64).reshape(-1, 5)
        sc = dets[:, 4]
        high = [Track([b[0], b[1], b[2] - b[0], b[3] - b[1]], float(q)) for b, q in zip(dets[sc > s.track_thresh, :4].tolist(), sc[sc > s.track_thresh])]
        lmask = (sc > 0.1) & (sc < s.track_thresh)
        low = [Track([b[0], b[1], b[2] - b[0], b[3] - b[1]], float(q)) for b, q in zip(dets[lmask, :4].tolist(), sc[lmask])]
        activated, refound, lost_now, removed_now = [], [], [], []

        unconfirmed = [t for t in self.tracked if not t.is_activated]
        confirmed = [t for t in self.tracked if t.is_activated]
        pool = _joint(confirmed, self.lost)
        for t in pool:
            t.mean, t.cov = _predict(t.mean, t.cov, t.state == TRACKED)

        # first association: pool x high
        cost = iou_cost([t.box_tlbr() for t in pool], [d.box_tlbr() for d in high],
                        None if s.mot20 else [d.score for d in high])
        matches, u_track, u_det = linear_assignment(cost, s.match_thresh)
        for i, j in matches:
            t = pool[i]
            if t.state == TRACKED:
                self._update(t, high[j])
                activated.append(t)
            else:                  # re_activate: the same update, found again with its id
                self._update(t, high[j])
                refound.append(t)

        # second association: the pool's unmatched Tracked tracks x low, plain IoU, 0.5
        rest = [pool[i] for i in u_track if pool[i].state == TRACKED]
        cost = iou_cost([t.box_tlbr() for t in rest], [d.box_tlbr() for d in low])
        matches, u_rest, _ = linear_assignment(cost, 0.5)
        for i, j in matches:
            self._update(rest[i], low[j])
            activated.append(rest[i])
        for i in u_rest:
            t = rest[i]
            if t.state != LOST:
                t.state = LOST
                lost_now.append(t)

        # unconfirmed x the high detections left, 0.7
        left = [high[j] for j in u_det]
        cost = iou_cost([t.box_tlbr() for t in unconfirmed], [d.box_tlbr() for d in left],
                        None if s.mot20 else [d.score for d in left])
        matches, u_unc, u_left = linear_assignment(cost, 0.7)
        for i, j in matches:
            self._update(unconfirmed[i], left[j])
            activated.append(unconfirmed[i])
        for i in u_unc:
            unconfirmed[i].state = REMOVED
            removed_now.append(unconfirmed[i])

        # births
        for j in u_left:
            d = left[j]
            if d.score < s.det_thresh:
                continue
            self._activate(d)
            activated.append(d)

        # lost tracks past max_time_lost
        for t in self.lost:
            if self.frame_id - t.frame_id > s.max_time_lost:
                t.state = REMOVED
                removed_now.append(t)

        # the lists, in ByteTrack's order of operations
        self.tracked = [t for t in self.tracked if t.state == TRACKED]
        self.tracked = _joint(self.tracked, activated)
        self.tracked = _joint(self.tracked, refound)
        self.lost = _sub(self.lost, self.tracked)
        self.lost.extend(lost_now)
        self.lost = _sub(self.lost, self.removed)     # the removed list before this frame's
        self.removed.extend(removed_now)
        self.tracked, self.lost = self._remove_duplicates(self.tracked, self.lost)
        return [t for t in self.tracked if t.is_activated]

    def _remove_duplicates(self, a, b):
        """Pairs tracked x lost with ``1 - IoU < 0.15``: the younger (``frame_id - start_frame``)
        goes, the tracked one on a tie."""
        if not a or not b:
            return a, b
        cost = iou_cost([t.box_tlbr() for t in a], [t.box_tlbr() for t in b])
        drop_a, drop_b = set(), set()
        for p, q in zip(*np.nonzero(cost < 0.15)):
            if a[p].frame_id - a[p].start_frame > b[q].frame_id - b[q].start_frame:
                drop_b.add(int(q))
            else:
                drop_a.add(int(p))
        return ([t for i, t in enumerate(a) if i not in drop_a], [t for i, t in enumerate(b) if i not in drop_b])


# ----------------------------------------------------------------------------------------------
# files
# ----------------------------------------------------------------------------------------------

def load_frames(root, cls: str, seq: str) -> list[np.ndarray]:
    """The frames of one sequence: [n, 5] float64 per frame (file order), frames 0..N-1 with N from
    ``label_02`` (the reference's driver)."""
    root = Path(root)
    n = sequence_lengths(root, [seq])[seq]
    d = read_detections_2d(root / "detections" / "rrc" / cls / f"{seq}.txt")
    rows = np.concatenate([d.box, d.score[:, None]], axis=1).astype(np.float64)
    return [rows[d.frame == f] for f in range(n)]


def demo_filter(tlwh) -> bool:
    """``tools/demo_track.py``'s writer filter: kept if ``w * h > 10`` and not ``w / h > 1.6``."""
    w, h = tlwh[2], tlwh[3]
    return w * h > 10 and not w / h > 1.6


def format_line(frame: int, tid: int, typ: str, tlwh, score: float) -> str:
    x1, y1, w, h = tlwh
    return (f"{frame} {tid} {typ} 0 0 -10 {x1:.6f} {y1:.6f} {x1 + w:.6f} {y1 + h:.6f} "
            f"-1 -1 -1 -1000 -1000 -1000 -10 {score:.6f}")


def run_sequence(frames, settings: Settings, typ: str = "Car") -> list[str]:
    """The result lines of one sequence (the reference's writer)."""
    tr = Tracker(settings)
    out = []
    for k, d in enumerate(frames):
        for t in tr.update(d):
            tlwh = t.box_tlwh()
            if settings.demo_filter and not demo_filter(tlwh):
                continue
            out.append(format_line(k, t.track_id, typ, tlwh, t.score))
    return out
