"""A small synthetic driving scene in KITTI tracking layout, so demos and tests run without KITTI.

:func:`make_scene` simulates cars (and the occasional van) moving in front of a camera car that
drives forward at a constant speed (``U(4, 12)`` m/s, or waits at an intersection, speed 0, in
20 % of the sequences) and writes, for each sequence ``SSSS`` (``0000``, ``0001``,
...)::

    <directory>/label_02/SSSS.txt                 ground truth, KITTI tracking label format
    <directory>/calib/SSSS.txt                    a real KITTI calibration (see below)
    <directory>/detections/synth2d/car/SSSS.txt   2D detections, CSV frame,x1,y1,x2,y2,score
    <directory>/detections/synth3d/car/SSSS.txt   3D detections, CSV
                                                  frame,type,x1,y1,x2,y2,score,h,w,l,x,y,z,rot_y,alpha

The formats are those of the real data under ``kitti/training`` (RRC for 2D, PointRCNN for 3D).

The world (rectified camera-0 coordinates, x right, y down, z forward, 10 frames per second):

* Every frame 0..n_frames-1 has at least one label row: each sequence has a persistent
  ``DontCare`` region near the horizon, plus one more for a stretch of frames.
* ``n_cars`` *slots*: each holds one vehicle at a time; when it leaves the region
  ``x in [-17, 17]``, ``z in [-10, 70]`` a new vehicle (new track id) enters the slot after a
  random delay of 0..2 s. Vehicles are same-direction traffic (lanes ``x = 0, -3.5``), oncoming
  traffic (``x = -7, -10.5``), parked cars (``x = 4.5, -13.5``) or, only while the camera car
  waits, cars crossing the intersection 20..45 m ahead. Lane vehicles faster than 3 m/s change
  lanes now and then (a smooth manoeuvre over 25..40 m, at least 2.5 s: a small turn of the
  heading). Speeds are constant apart from slowing down (at most 6 m/s^2) for a vehicle in the
  corridor ahead and speeding up again (2.5 m/s^2); vehicles in the camera car's lane never
  close in on it.
  Bottom height ``y = 1.65 m`` (camera height), car dims about ``h 1.52, w 1.63, l 3.9``;
  10 % of vehicles are ``Van`` (about ``2.05, 1.9, 4.8``).
* Ground-truth image boxes are the clipped projections
  (:func:`dfrmot_jax.geometry.project_box3d_to_image`) of the ground-truth 3D boxes with ``P2``
  into a 1242 x 375 image; a vehicle is labelled while its clipped box is at least 2 px wide and
  tall. ``truncated`` is 0/1/2 for a fraction of the unclipped box outside the image below 0.15,
  below 0.5, above (2 also when a corner is behind the camera); ``occluded`` is 0/1/2 for a
  fraction of the box covered by the boxes of nearer vehicles below 0.15, below 0.5, above.
  ``alpha = rot_y - arctan2(x, z)``. Track ids count from 0 in order of first appearance.

Detections (class ``car``; a ``Van`` is reported as a car by each detector with probability
``van_detect_prob``, decided once per track). Neither detector reports a vehicle whose box is
covered by nearer vehicles beyond ``occlusion_miss`` (this produces short detection gaps when
vehicles pass each other); otherwise:

* 2D (RRC-like): a vehicle with a box at least ``det2d_min_height`` px tall and 8 px wide is
  missed with probability ``det2d_miss_rate``; otherwise its box is the GT box plus Gaussian
  noise of ``det2d_box_sigma`` times the box width (x1, x2) / height (y1, y2), clipped to the
  image. Scores are ``sigmoid`` of a logit around 3.5 (lower for occluded, small and truncated
  boxes, plus a per-track offset), in ``[0.1, 1]`` (rows below 0.1 are dropped, as in the RRC
  files). False positives: Poisson(``det2d_fp_rate``) per frame, car-shaped boxes near the
  horizon with scores ``U(0.1, 0.45)``.
* 3D (PointRCNN-like, ``type`` 2): a vehicle closer than ``det3d_max_range`` (distance
  ``sqrt(x^2+z^2)``, centre in front of the camera) is missed with probability
  ``det3d_miss_rate``, rising by up to 0.5 over the last 35 % of the range. Its box is the GT box
  with ``x, z`` noise of std ``det3d_pos_sigma * (1 + d / 40)`` (``y``: 0.3 times that), size
  noise of std ``det3d_dim_sigma`` per dimension, heading noise of std ``det3d_rot_sigma`` and a
  heading flip by pi with probability ``det3d_flip_rate``. Values are rounded to 4 decimals and
  the image box is the projection of the *rounded* 3D box (rows whose box is degenerate are
  dropped). Scores ``8 + N(0, 1.2)`` plus a per-track offset, lower when occluded or far, clipped
  to ``[-1, 16]``: about 2..12 for real vehicles. False positives: Poisson(``det3d_fp_rate``)
  per frame, car-sized boxes at random places in the field of view with scores ``U(-1, 3)``.

Everything is drawn from ``numpy.random.default_rng([seed, sequence_index])``: the same seed
gives byte-identical files.
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np

from .geometry import KITTI_IMAGE_SIZE, project_box3d_to_image

__all__ = ["make_scene", "NOISE_DEFAULTS", "IMAGE_SIZE", "DT"]

#: Image size (width, height) of the synthetic camera 02, the most common KITTI size.
IMAGE_SIZE = KITTI_IMAGE_SIZE
#: Seconds between frames (KITTI records at 10 Hz).
DT = 0.1

#: Noise knobs of :func:`make_scene` and their defaults (see the module docstring).
NOISE_DEFAULTS: dict[str, float] = {
    "det2d_miss_rate": 0.08,     # probability a detectable vehicle is missed in a frame (2D)
    "det2d_box_sigma": 0.04,     # std of each 2D box coordinate, as a fraction of box width/height
    "det2d_fp_rate": 0.3,        # mean number of 2D false positives per frame (Poisson)
    "det2d_min_height": 15.0,    # px; smaller GT boxes are never detected in 2D
    "det3d_miss_rate": 0.08,     # base probability a detectable vehicle is missed in a frame (3D)
    "det3d_pos_sigma": 0.15,     # m; std of the x/z position noise, times (1 + distance / 40 m)
    "det3d_dim_sigma": 0.08,     # m; std of the noise of h, w and l
    "det3d_rot_sigma": 0.05,     # rad; std of the heading noise
    "det3d_flip_rate": 0.02,     # probability the detected heading is off by pi
    "det3d_fp_rate": 0.3,        # mean number of 3D false positives per frame (Poisson)
    "det3d_max_range": 60.0,     # m; vehicles farther away are never detected in 3D
    "occlusion_miss": 0.6,       # covered fraction of the box above which both detectors miss
    "van_detect_prob": 0.5,      # probability a Van track is reported by the car detectors
}

# Real KITTI tracking calibrations (public KITTI calib files of training sequences 0000, drive
# 2011_09_26, and 0019, drive 2011_10_03). Even sequences use the first, odd ones the second.
_CALIBS = (
    {
        "P0": (721.5377, 0.0, 609.5593, 0.0, 0.0, 721.5377, 172.854, 0.0, 0.0, 0.0, 1.0, 0.0),
        "P1": (721.5377, 0.0, 609.5593, -387.5744, 0.0, 721.5377, 172.854, 0.0, 0.0, 0.0, 1.0, 0.0),
        "P2": (721.5377, 0.0, 609.5593, 44.85728, 0.0, 721.5377, 172.854, 0.2163791, 0.0, 0.0, 1.0, 0.002745884),
        "P3": (721.5377, 0.0, 609.5593, -339.5242, 0.0, 721.5377, 172.854, 2.199936, 0.0, 0.0, 1.0, 0.002729905),
        "R0_rect": (0.9999239, 0.00983776, -0.007445048, -0.009869795, 0.9999421, -0.004278459,
                    0.007402527, 0.004351614, 0.9999631),
        "Tr_velo_to_cam": (0.007533745, -0.9999714, -0.000616602, -0.004069766, 0.01480249, 0.0007280733,
                           -0.9998902, -0.07631618, 0.9998621, 0.00752379, 0.01480755, -0.2717806),
        "Tr_imu_to_velo": (0.9999976, 0.0007553071, -0.002035826, -0.8086759, -0.0007854027, 0.9998898,
                           -0.01482298, 0.3195559, 0.002024406, 0.01482454, 0.9998881, -0.7997231),
    },
    {
        "P0": (718.3351, 0.0, 600.3891, 0.0, 0.0, 718.3351, 181.5122, 0.0, 0.0, 0.0, 1.0, 0.0),
        "P1": (718.3351, 0.0, 600.3891, -385.8846, 0.0, 718.3351, 181.5122, 0.0, 0.0, 0.0, 1.0, 0.0),
        "P2": (718.3351, 0.0, 600.3891, 44.50382, 0.0, 718.3351, 181.5122, -0.5951107, 0.0, 0.0, 1.0, 0.002616315),
        "P3": (718.3351, 0.0, 600.3891, -336.3147, 0.0, 718.3351, 181.5122, 3.159867, 0.0, 0.0, 1.0, 0.005323834),
        "R0_rect": (0.9999478, 0.009791707, -0.002925305, -0.009806939, 0.9999382, -0.005238719,
                    0.002873828, 0.005267134, 0.999982),
        "Tr_velo_to_cam": (0.007755449, -0.9999694, -0.001014303, -0.007275538, 0.002294056, 0.001032122,
                           -0.9999968, -0.06324057, 0.9999673, 0.007753097, 0.00230199, -0.2670414),
        "Tr_imu_to_velo": (0.9999976, 0.0007553071, -0.002035826, -0.8086759, -0.0007854027, 0.9998898,
                           -0.01482298, 0.3195559, 0.002024406, 0.01482454, 0.9998881, -0.7997231),
    },
)

_GROUND_Y = 1.65
_REGION_X = 17.0
_REGION_Z = (-10.0, 70.0)
_KINDS = ("same", "oncoming", "parked", "crossing")
_KIND_P = (0.35, 0.25, 0.25, 0.15)
_LANES = {"same": (0.0, -3.5), "oncoming": (-7.0, -10.5), "parked": (4.5, -13.5)}


def _wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def _sigmoid(x):
    return 1.0 / (1.0 + np.exp(-x))


class _Vehicle:
    """State of one simulated vehicle (positions relative to the moving camera)."""

    __slots__ = ("uid", "kind", "van", "dims", "x", "y", "z", "lane_x", "dir", "speed", "v_des",
                 "lc_t", "lc_T", "lc_dx", "yaw0", "off2d", "off3d")


def _spawn(rng: np.random.Generator, uid: int, v_ego: float, initial: bool) -> _Vehicle:
    v = _Vehicle()
    v.uid = uid
    # Cross traffic only while the camera car waits at the intersection (v_ego = 0).
    kind_p = np.array(_KIND_P) if v_ego < 0.5 else np.array(_KIND_P[:3] + (0.0,))
    v.kind = _KINDS[rng.choice(len(_KINDS), p=kind_p / kind_p.sum())]
    v.van = bool(rng.random() < 0.1)
    if v.van:
        dims = [rng.normal(2.05, 0.15), rng.normal(1.9, 0.08), rng.normal(4.8, 0.4)]
    else:
        dims = [rng.normal(1.52, 0.08), rng.normal(1.63, 0.07), rng.normal(3.9, 0.3)]
    v.dims = np.clip(np.array(dims), [1.2, 1.4, 3.0], [2.6, 2.1, 6.0])
    v.y = _GROUND_Y + rng.normal(0.0, 0.05)
    v.lc_t, v.lc_T, v.lc_dx, v.yaw0 = 0.0, 0.0, 0.0, 0.0
    v.off2d = rng.normal(0.0, 0.7)
    v.off3d = rng.normal(0.0, 1.0)
    if v.kind == "crossing":
        side = rng.choice([-1.0, 1.0])
        v.dir = np.array([-side, 0.0])                                  # towards the other side
        v.v_des = rng.uniform(5.0, 9.0)
        v.x = rng.uniform(-15.0, 15.0) if initial else side * 16.5
        v.z = rng.uniform(20.0, 45.0)
        v.lane_x = v.x
    else:
        v.lane_x = v.x = float(rng.choice(_LANES[v.kind])) + rng.normal(0.0, 0.15)
        if v.kind == "same":
            v.dir = np.array([0.0, 1.0])
            v.v_des = max(0.0, v_ego + rng.normal(0.0, 2.5))
            if abs(v.lane_x) < 2.0:                                     # ego lane: never closes in
                v.v_des = max(v.v_des, v_ego + 0.5)
        elif v.kind == "oncoming":
            v.dir = np.array([0.0, -1.0])
            v.v_des = rng.uniform(6.0, 14.0)
        else:  # parked, facing either way, slightly askew
            v.dir = np.array([0.0, rng.choice([-1.0, 1.0])])
            v.v_des = 0.0
            v.yaw0 = rng.normal(0.0, 0.05)
        rel_vz = v.dir[1] * v.v_des - v_ego
        if initial:
            v.z = rng.uniform(6.0, 60.0)
        elif rel_vz > 0.3 and v.kind == "same" and abs(v.lane_x) >= 2.0:
            v.z = rng.uniform(-9.0, -6.0)                               # overtakes the camera
        elif rel_vz > 0.3 and v.kind == "same":
            v.z = rng.uniform(8.0, 15.0)                                # pulls in ahead
        else:
            v.z = rng.uniform(58.0, 68.0)
    v.speed = v.v_des
    return v


def _heading(v: _Vehicle) -> np.ndarray:
    """Unit heading (x, z): the lane direction, turned during a lane change.

    A lane change progresses with the distance driven (``lc_t`` is in seconds at the desired
    speed), so the path and hence the heading do not depend on the current speed.
    """
    h = v.dir * max(v.v_des, 1e-6)
    if v.lc_T > 0:
        h = h + np.array([v.lc_dx * np.pi / (2 * v.lc_T) * np.sin(np.pi * v.lc_t / v.lc_T), 0.0])
    return h / np.hypot(*h)


def _velocity(v: _Vehicle) -> np.ndarray:
    """Absolute ground velocity (vx, vz)."""
    return _heading(v) * v.speed


def _rot_y(v: _Vehicle) -> float:
    h = _heading(v)
    return float(_wrap(np.arctan2(-h[1], h[0]) + v.yaw0))


def _target_speed(a: _Vehicle, others: list, v_ego: float) -> float:
    """Desired speed, reduced for anything (incl. the camera car) in a's corridor ahead."""
    target = a.v_des
    obstacles = [(b.x, b.z, _velocity(b)) for b in others if b is not a]
    obstacles.append((0.0, 0.0, np.array([0.0, v_ego])))                 # the camera car
    for bx, bz, bvel in obstacles:
        rel = np.array([bx - a.x, bz - a.z])
        along = float(rel @ a.dir)
        lateral = abs(rel[0] * a.dir[1] - rel[1] * a.dir[0])
        if 0.0 < along < 15.0 and lateral < 2.4:
            target = min(target, 0.0 if along < 7.0 else max(0.0, float(bvel @ a.dir)))
    return target


def _simulate(rng: np.random.Generator, n_frames: int, n_cars: int, v_ego: float, noise: dict):
    """Per frame: list of (uid, is_van, dims[3], loc[3], rot_y); plus per uid
    (reported by 2D, reported by 3D, 2D score offset, 3D score offset)."""
    slots: list[_Vehicle | None] = [None] * n_cars
    delay = np.where(rng.random(n_cars) < 0.8, 0, rng.integers(1, 30, n_cars))
    next_uid = 0
    info: dict[int, tuple[bool, bool, float, float]] = {}
    frames = []
    for t in range(n_frames):
        # Spawn into free slots, away from other vehicles and from the camera.
        for i in range(n_cars):
            if slots[i] is not None:
                continue
            if delay[i] > 0:
                delay[i] -= 1
                continue
            for _attempt in range(5 if t == 0 else 1):
                cand = _spawn(rng, next_uid, v_ego, initial=(t == 0))
                clash = np.hypot(cand.x, cand.z) < 6.0 or any(
                    o is not None and np.hypot(o.x - cand.x, o.z - cand.z) < 9.0 for o in slots)
                if not clash:
                    slots[i] = cand
                    next_uid += 1
                    p = noise["van_detect_prob"]
                    info[cand.uid] = (not cand.van or rng.random() < p, not cand.van or rng.random() < p,
                                      cand.off2d, cand.off3d)
                    break
            else:
                delay[i] = rng.integers(1, 5)
        active = [v for v in slots if v is not None]
        frames.append([(v.uid, v.van, v.dims.copy(), np.array([v.x, v.y, v.z]), _rot_y(v)) for v in active])
        # Speeds: follow / yield, with limited braking (6 m/s^2) and acceleration (2.5 m/s^2).
        targets = [_target_speed(v, active, v_ego) for v in active]
        for v, target in zip(active, targets):
            v.speed = float(np.clip(target, v.speed - 6.0 * DT, v.speed + 2.5 * DT))
        # Lane changes between the two lanes of a direction (a small turn and back).
        for v in active:
            if v.kind in ("same", "oncoming") and v.lc_T == 0 and v.v_des > 3.0 and rng.random() < 0.01:
                other = [l for l in _LANES[v.kind] if abs(l - v.lane_x) > 1.0][0]
                if v.kind == "same" and abs(other) < 2.0 and (v.z < 12.0 or v.v_des < v_ego + 0.5):
                    continue                                            # would block the camera car
                v.lc_dx = other - v.lane_x
                v.lc_T = max(2.5, rng.uniform(25.0, 40.0) / v.v_des)           # over 25..40 m
                v.lc_t = 0.0
        # Move (relative to the camera car, which drives along +z at v_ego).
        for i, v in enumerate(slots):
            if v is None:
                continue
            vel = v.dir * v.speed
            if v.lc_T > 0:
                v.lc_t = min(v.lc_t + DT * v.speed / max(v.v_des, 1e-6), v.lc_T)
                v.x = v.lane_x + v.lc_dx * (1 - np.cos(np.pi * v.lc_t / v.lc_T)) / 2
                if v.lc_t >= v.lc_T:
                    v.lane_x += v.lc_dx
                    v.x = v.lane_x
                    v.lc_T, v.lc_t, v.lc_dx = 0.0, 0.0, 0.0
            else:
                v.x += vel[0] * DT
                v.lane_x = v.x
            v.z += (vel[1] - v_ego) * DT
            if abs(v.x) > _REGION_X or not (_REGION_Z[0] <= v.z <= _REGION_Z[1]):
                slots[i] = None
                delay[i] = rng.integers(0, 21)
    return frames, info


def _coverage(boxes: np.ndarray, order_dist: np.ndarray, n_grid: int = 12) -> np.ndarray:
    """Fraction of each box covered by the boxes of nearer objects (grid sampling)."""
    n = len(boxes)
    cov = np.zeros(n)
    if n < 2:
        return cov
    g = (np.arange(n_grid) + 0.5) / n_grid
    for i in range(n):
        nearer = order_dist < order_dist[i]
        if not nearer.any():
            continue
        x1, y1, x2, y2 = boxes[i]
        px = (x1 + g * (x2 - x1))[:, None]                                  # [G, 1]
        py = (y1 + g * (y2 - y1))[None, :]                                  # [1, G]
        covered = np.zeros((n_grid, n_grid), dtype=bool)
        for b in boxes[nearer]:
            covered |= (px >= b[0]) & (px <= b[2]) & (py >= b[1]) & (py <= b[3])
        cov[i] = covered.mean()
    return cov


def _level(frac, lo=0.15, hi=0.5):
    return np.where(frac < lo, 0, np.where(frac < hi, 1, 2))


def _fmt_calib(calib: dict) -> str:
    return "".join(f"{k}: " + " ".join(f"{v:.12e}" for v in vals) + "\n" for k, vals in calib.items())


def _make_sequence(rng: np.random.Generator, n_frames: int, n_cars: int, P2: np.ndarray, noise: dict):
    """One sequence: (label lines, 2D detections, 3D detections). Every random draw is taken in a
    fixed order (the scene, its DontCare regions, then per frame the 2D detector, the 3D detector and
    the false positives), so a seed gives one scene."""
    v_ego = float(rng.choice([0.0, rng.uniform(4.0, 12.0)], p=[0.2, 0.8]))
    frames, info = _simulate(rng, n_frames, n_cars, v_ego, noise)
    dontcare = _dontcare_regions(rng, n_frames)
    uid_to_track: dict[int, int] = {}
    labels, det2d, det3d = [], [], []
    for t, objs in enumerate(frames):
        for (a, b), box in dontcare:
            if a <= t <= b:
                labels.append(f"{t} -1 DontCare -1 -1 -10.000000 {box[0]:.6f} {box[1]:.6f} {box[2]:.6f} "
                              f"{box[3]:.6f} -1000.000000 -1000.000000 -1000.000000 -10.000000 -1.000000 "
                              f"-1.000000 -1.000000")
        seen = _visible(objs, P2)
        if seen is not None:
            labels.extend(_label_rows(t, seen, uid_to_track))
            _detect_2d(rng, t, seen, info, noise, det2d)
            _detect_3d(rng, t, seen, info, noise, P2, det3d)
        _false_positives(rng, t, noise, P2, det2d, det3d)
    return labels, det2d, det3d


def _dontcare_regions(rng: np.random.Generator, n_frames: int) -> list:
    """DontCare regions ((first, last frame), box): one for the whole sequence (guarantees a label
    row in every frame), one for a stretch of frames."""
    W, _ = IMAGE_SIZE
    dontcare = []
    for k in range(2):
        w, h = rng.uniform(40, 120), rng.uniform(18, 40)
        x1 = rng.uniform(0, 150) if rng.random() < 0.5 else rng.uniform(W - 150 - w, W - 1 - w)
        y1 = rng.uniform(160, 190)
        if k == 0:
            span = (0, n_frames - 1)
        else:
            a = int(rng.integers(0, max(1, n_frames - 10)))
            span = (a, min(n_frames - 1, a + int(rng.integers(10, 31))))
        dontcare.append((span, (x1, y1, x1 + w, y1 + h)))
    return dontcare


class _Seen(NamedTuple):
    """A frame's visible vehicles (image box at least 2 x 2 px): ids, van flags, 3D boxes, image
    boxes and their width and height, truncation, distance, occlusion (coverage by nearer boxes)."""
    uids: np.ndarray
    vans: np.ndarray
    dims: np.ndarray
    loc: np.ndarray
    rot: np.ndarray
    box: np.ndarray
    bw: np.ndarray
    bh: np.ndarray
    trunc: np.ndarray
    dist: np.ndarray
    occ: np.ndarray


def _visible(objs: list, P2: np.ndarray) -> _Seen | None:
    """The frame's visible vehicles of ``objs`` (``_simulate``'s), or None when none is."""
    if not objs:
        return None
    uids = np.array([o[0] for o in objs])
    vans = np.array([o[1] for o in objs])
    dims = np.stack([o[2] for o in objs])
    loc = np.stack([o[3] for o in objs])
    rot = np.array([o[4] for o in objs])
    box = project_box3d_to_image(dims, loc, rot, P2, IMAGE_SIZE)
    raw = project_box3d_to_image(dims, loc, rot, P2, IMAGE_SIZE, clip=False)
    finite = np.all(np.isfinite(box), axis=1)
    bw = np.where(finite, box[:, 2] - box[:, 0], 0.0)
    bh = np.where(finite, box[:, 3] - box[:, 1], 0.0)
    idx = np.flatnonzero(finite & (bw >= 2.0) & (bh >= 2.0))
    if not len(idx):
        return None
    uids, vans, dims, loc, rot = uids[idx], vans[idx], dims[idx], loc[idx], rot[idx]
    box, raw, bw, bh = box[idx], raw[idx], bw[idx], bh[idx]
    area = bw * bh
    raw_area = (raw[:, 2] - raw[:, 0]) * (raw[:, 3] - raw[:, 1])
    trunc = 1.0 - area / np.maximum(raw_area, 1e-9)
    all_front = np.all(np.isfinite(raw), axis=1) & (loc[:, 2] - 0.5 * np.hypot(dims[:, 1], dims[:, 2]) > 0.1)
    trunc = np.where(all_front, trunc, np.maximum(trunc, 0.5))
    dist = np.hypot(loc[:, 0], loc[:, 2])
    return _Seen(uids, vans, dims, loc, rot, box, bw, bh, trunc, dist, _coverage(box, dist))


def _label_rows(t: int, v: _Seen, uid_to_track: dict) -> list[str]:
    """Frame ``t``'s label lines of its visible vehicles, by id (a new vehicle takes the next track id)."""
    alpha = _wrap(v.rot - np.arctan2(v.loc[:, 0], v.loc[:, 2]))
    trunc_lvl, occ_lvl = _level(v.trunc), _level(v.occ)
    box, dims, loc, rot = v.box, v.dims, v.loc, v.rot
    rows = []
    for j in np.argsort(v.uids, kind="stable"):
        u = int(v.uids[j])
        if u not in uid_to_track:
            uid_to_track[u] = len(uid_to_track)
        rows.append(
            f"{t} {uid_to_track[u]} {'Van' if v.vans[j] else 'Car'} {trunc_lvl[j]} {occ_lvl[j]} "
            f"{alpha[j]:.6f} {box[j, 0]:.6f} {box[j, 1]:.6f} {box[j, 2]:.6f} {box[j, 3]:.6f} "
            f"{dims[j, 0]:.6f} {dims[j, 1]:.6f} {dims[j, 2]:.6f} "
            f"{loc[j, 0]:.6f} {loc[j, 1]:.6f} {loc[j, 2]:.6f} {rot[j]:.6f}"
        )
    return rows


def _detect_2d(rng: np.random.Generator, t: int, v: _Seen, info: dict, noise: dict, det2d: list) -> None:
    """The 2D detector on frame ``t``'s visible vehicles: misses, box noise, scores."""
    W, H = IMAGE_SIZE
    for j in range(len(v.uids)):
        u = int(v.uids[j])
        if not info[u][0] or v.occ[j] > noise["occlusion_miss"]:
            continue
        if v.bh[j] < noise["det2d_min_height"] or v.bw[j] < 8.0:
            continue
        if rng.random() < noise["det2d_miss_rate"]:
            continue
        s = noise["det2d_box_sigma"]
        d = v.box[j] + rng.normal(0.0, s, 4) * np.array([v.bw[j], v.bh[j], v.bw[j], v.bh[j]])
        d = np.array([min(d[0], d[2]), min(d[1], d[3]), max(d[0], d[2]), max(d[1], d[3])])
        d = np.clip(d, 0.0, [W - 1, H - 1, W - 1, H - 1])
        logit = (3.5 + info[u][2] + rng.normal(0.0, 0.8) - 4.0 * v.occ[j]
                 - 1.5 * (v.bh[j] < 30) - 1.0 * (v.trunc[j] > 0.3))
        score = float(_sigmoid(logit))
        if score < 0.1 or d[2] - d[0] < 1 or d[3] - d[1] < 1:
            continue
        det2d.append((t, d, score))


def _detect_3d(rng: np.random.Generator, t: int, v: _Seen, info: dict, noise: dict, P2: np.ndarray,
               det3d: list) -> None:
    """The 3D detector on frame ``t``'s visible vehicles: range, misses, position / size / heading
    noise, flips, scores."""
    R = noise["det3d_max_range"]
    dist, loc, dims, rot, occ = v.dist, v.loc, v.dims, v.rot, v.occ
    for j in range(len(v.uids)):
        u = int(v.uids[j])
        if not info[u][1] or occ[j] > noise["occlusion_miss"]:
            continue
        if dist[j] > R or loc[j, 2] < 1.0:
            continue
        p_miss = noise["det3d_miss_rate"] + 0.5 * np.clip((dist[j] - 0.65 * R) / (0.35 * R), 0.0, 1.0)
        if rng.random() < p_miss:
            continue
        sp = noise["det3d_pos_sigma"] * (1.0 + dist[j] / 40.0)
        l3 = loc[j] + rng.normal(0.0, 1.0, 3) * np.array([sp, 0.3 * sp, sp])
        d3 = np.maximum(dims[j] + rng.normal(0.0, noise["det3d_dim_sigma"], 3), 0.5)
        r3 = rot[j] + rng.normal(0.0, noise["det3d_rot_sigma"])
        if rng.random() < noise["det3d_flip_rate"]:
            r3 += np.pi
        score = (8.0 + info[u][3] + rng.normal(0.0, 1.2) - 6.0 * occ[j]
                 - 4.0 * np.clip((dist[j] - 30.0) / 30.0, 0.0, 1.0))
        _add_det3d(det3d, t, d3, l3, float(_wrap(r3)), float(np.clip(score, -1.0, 16.0)), P2)


def _false_positives(rng: np.random.Generator, t: int, noise: dict, P2: np.ndarray, det2d: list, det3d: list) -> None:
    """Frame ``t``'s false positives: 2D boxes on the road, then 3D boxes on the ground."""
    W, H = IMAGE_SIZE
    for _ in range(rng.poisson(noise["det2d_fp_rate"])):
        h = rng.uniform(20.0, 90.0)
        w = h * rng.uniform(1.0, 2.0)
        cx, y2 = rng.uniform(0, W - 1), rng.uniform(180.0, 260.0)
        d = np.clip([cx - w / 2, y2 - h, cx + w / 2, y2], 0.0, [W - 1, H - 1, W - 1, H - 1])
        if d[2] - d[0] >= 1 and d[3] - d[1] >= 1:
            det2d.append((t, d, float(rng.uniform(0.1, 0.45))))
    for _ in range(rng.poisson(noise["det3d_fp_rate"])):
        z = rng.uniform(5.0, 50.0)
        x = z * np.tan(rng.uniform(-0.6, 0.6))
        l3 = np.array([x, _GROUND_Y + rng.normal(0.0, 0.1), z])
        d3 = np.array([rng.normal(1.5, 0.15), rng.normal(1.6, 0.15), rng.normal(3.8, 0.5)]).clip(0.5)
        _add_det3d(det3d, t, d3, l3, float(rng.uniform(-np.pi, np.pi)), float(rng.uniform(-1.0, 3.0)), P2)


def _add_det3d(out: list, t: int, dims, loc, rot: float, score: float, P2) -> None:
    dims = np.round(np.asarray(dims, float), 4)
    loc = np.round(np.asarray(loc, float), 4)
    rot = round(rot, 4)
    box = project_box3d_to_image(dims, loc, rot, P2, IMAGE_SIZE)
    if not np.all(np.isfinite(box)) or box[2] - box[0] < 1 or box[3] - box[1] < 1:
        return
    alpha = float(_wrap(rot - np.arctan2(loc[0], loc[2])))
    out.append((t, box, score, dims, loc, rot, alpha))


def make_scene(directory, n_sequences: int = 2, n_frames: int = 80, n_cars: int = 5, seed: int = 0,
               **noise) -> Path:
    """Write a synthetic KITTI-layout tracking root (see the module docstring for the model).

    Args:
        directory: where to write; created if missing. Existing files of the same names are
            overwritten.
        n_sequences: number of sequences ``0000``, ``0001``, ...
        n_frames: frames per sequence (frames ``0..n_frames-1`` all have label rows).
        n_cars: number of vehicle slots, i.e. vehicles present at a time (a leaving vehicle is
            replaced by a new one, with a new track id, after 0..2 s).
        seed: non-negative integer; the output is a deterministic function of all arguments.
        **noise: detector noise knobs, any of :data:`NOISE_DEFAULTS`:

            * ``det2d_miss_rate`` (0.08): per-frame probability a detectable vehicle is missed (2D).
            * ``det2d_box_sigma`` (0.04): std of each 2D box coordinate as a fraction of the GT box
              width (x1, x2) or height (y1, y2).
            * ``det2d_fp_rate`` (0.3): mean number of 2D false positives per frame (scores 0.1..0.45).
            * ``det2d_min_height`` (15): GT boxes less tall (px) are never detected in 2D.
            * ``det3d_miss_rate`` (0.08): base per-frame miss probability (3D), rising by up to
              0.5 towards ``det3d_max_range``.
            * ``det3d_pos_sigma`` (0.15): std (m) of the x/z error, times ``1 + distance / 40 m``.
            * ``det3d_dim_sigma`` (0.08): std (m) of the error of each of h, w, l.
            * ``det3d_rot_sigma`` (0.05): std (rad) of the heading error.
            * ``det3d_flip_rate`` (0.02): probability the detected heading is off by pi.
            * ``det3d_fp_rate`` (0.3): mean number of 3D false positives per frame (scores -1..3).
            * ``det3d_max_range`` (60): vehicles farther away (m) are never detected in 3D.
            * ``occlusion_miss`` (0.6): a vehicle whose box is covered by nearer vehicles beyond
              this fraction is missed by both detectors.
            * ``van_detect_prob`` (0.5): probability a Van track is reported by each car detector.

    Returns:
        ``Path(directory)``, the tracking root (holding ``label_02``, ``calib``, ``detections``).
    """
    unknown = set(noise) - set(NOISE_DEFAULTS)
    if unknown:
        raise TypeError(f"unknown noise knob(s) {sorted(unknown)}; valid: {sorted(NOISE_DEFAULTS)}")
    if n_sequences < 0 or n_frames < 1 or n_cars < 0 or seed < 0:
        raise ValueError("need n_sequences >= 0, n_frames >= 1, n_cars >= 0, seed >= 0")
    knobs = {**NOISE_DEFAULTS, **{k: float(v) for k, v in noise.items()}}
    root = Path(directory)
    dirs = {
        "label": root / "label_02",
        "calib": root / "calib",
        "d2": root / "detections" / "synth2d" / "car",
        "d3": root / "detections" / "synth3d" / "car",
    }
    for d in dirs.values():
        d.mkdir(parents=True, exist_ok=True)
    for s in range(n_sequences):
        name = f"{s:04d}.txt"
        rng = np.random.default_rng([seed, s])
        calib = _CALIBS[s % len(_CALIBS)]
        P2 = np.array(calib["P2"]).reshape(3, 4)
        labels, det2d, det3d = _make_sequence(rng, n_frames, n_cars, P2, knobs)
        (dirs["calib"] / name).write_text(_fmt_calib(calib))
        (dirs["label"] / name).write_text("".join(line + "\n" for line in labels))
        (dirs["d2"] / name).write_text("".join(
            f"{t},{b[0]:.6f},{b[1]:.6f},{b[2]:.6f},{b[3]:.6f},{sc:.6f}\n" for t, b, sc in det2d))
        (dirs["d3"] / name).write_text("".join(
            f"{t},2,{b[0]:.4f},{b[1]:.4f},{b[2]:.4f},{b[3]:.4f},{sc:.4f},"
            f"{dm[0]:.4f},{dm[1]:.4f},{dm[2]:.4f},{lc[0]:.4f},{lc[1]:.4f},{lc[2]:.4f},{r:.4f},{al:.4f}\n"
            for t, b, sc, dm, lc, r, al in det3d))
    return root
