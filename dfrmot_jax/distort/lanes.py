"""Host side: the 3D detections a distortion lane leaves, as result files carry them.

The tracker families read the same draws (:func:`hook.apply_draws`, keyed by ``(seed, t)``) on the
3D slots of a ``Frames`` layout: DFR-FastMOT inside its scan, AB3DMOT on frames materialised here
(:func:`distorted_detections`), so one seed and level give both the same faults. What a family's
rows write of a 3D detection (its score, centre, size, heading, image box) is read back from the
distorted frames by one rule, :func:`read_back`:

- a value no distortion touched keeps the file's float64 value (level 0 returns the input, bit
  for bit);
- a noisy score (``score_noise_3d > 0``), a jittered image box (``jitter_box3 > 0``) and every
  value of a clutter slot are the distorted frame's float32 values;
- a shifted centre (``jitter_3d > 0``) is the file's centre plus the shift the frame's ``lo3/hi3``
  received, mapped from the convention of ``DistortSpec.centroid`` (a signed permutation of camera
  axes, ``io.columns.invert_box3d_extent``) to camera axes: the same physical shift in every
  family (the float32 shift as DFR-FastMOT's frame received it, exactly);
- a clutter slot is a ``CAR_DIMS`` box at the clutter's pose (``clutter.Placement3D.pose``), its
  observation angle ``alpha = rot_y - atan2(x, z)`` wrapped to [-pi, pi).
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import numpy as np

from ..frames import Frames
from ..data import Split
from ..geometry import box3d_extent
from ..io.columns import invert_box3d_extent
from .clutter import pad_for_clutter, pad_slots
from .hook import distort_split
from .identity import gt_identity, pad_identity
from .spec import CAR_DIMS, GROUPS, DistortParams, DistortSpec


class Detections3D(NamedTuple):
    """One lane's 3D detections [T, M, ...] as a result file carries them (float64): ``valid``
    (bool), ``score``, ``loc`` [.., 3] x y z (camera axes, bottom centre), ``rot_y``, ``dims``
    [.., 3] h w l, ``alpha``, ``image`` [.., 4] the detector's image box x1 y1 x2 y2."""

    valid: np.ndarray
    score: np.ndarray
    loc: np.ndarray
    rot_y: np.ndarray
    dims: np.ndarray
    alpha: np.ndarray
    image: np.ndarray

    def padded(self, m: int) -> "Detections3D":
        """The detections with empty slots appended up to ``m`` (invalid, zero)."""
        n = m - self.valid.shape[1]
        return self if n <= 0 else Detections3D(*(pad_slots(v, n, False if v.dtype == bool else 0.0) for v in self))


    def packed(self) -> "Detections3D":
        """Each frame's valid detections first, in slot order (what a detection file holding only
        them lists), the empty slots after them."""
        order = np.argsort(~np.asarray(self.valid, bool), axis=1, kind="stable")
        return Detections3D(*(np.take_along_axis(v, order.reshape(order.shape + (1,) * (v.ndim - 2)), axis=1)
                              for v in self))


def split_detections(split: Split) -> Detections3D:
    """The split's own 3D detections (its file values, float64)."""
    f64 = functools.partial(np.asarray, dtype=np.float64)
    return Detections3D(np.asarray(split.valid3d, bool), f64(split.score3d), f64(split.loc3d), f64(split.rot_y3d),
                        f64(split.dims3d), f64(split.alpha3d), f64(split.box3d))


def frames_3d(dets: Detections3D, reset, centroid: str) -> Frames:
    """``Frames`` [T, ...] holding 3D detections only (no 2D slot) for the distortion of a family
    that reads 3D detections alone: ``box3`` the detector's image box (float32, untruncated),
    ``score3`` float32, ``lo3/hi3`` ``geometry.box3d_extent`` for ``centroid`` (the corners
    DFR-FastMOT's frames hold for that ``Options.centroid``: the same bits), ``valid3`` as
    ``trackers.dfr.frames.prepare_frames`` has it (a detection with a finite image box)."""
    image = np.asarray(dets.image, np.float64)
    finite = np.all(np.isfinite(image), axis=-1)
    lo3, hi3 = box3d_extent(dets.dims, dets.loc, centroid)
    t = np.asarray(reset).shape[0]
    return Frames(reset=np.asarray(reset, bool), box2=np.zeros((t, 0, 4), np.float32),
                  score2=np.zeros((t, 0), np.float32), valid2=np.zeros((t, 0), bool),
                  box3=np.where(finite[..., None], image, 0.0).astype(np.float32),
                  score3=np.asarray(dets.score).astype(np.float32), valid3=np.asarray(dets.valid, bool) & finite,
                  lo3=lo3, hi3=hi3)


def _wrap(a: np.ndarray) -> np.ndarray:
    """Angles wrapped to [-pi, pi)."""
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def read_back(base: Detections3D, before: Frames, after: Frames, pose: np.ndarray, dp: DistortParams,
              spec: DistortSpec) -> Detections3D:
    """One lane's distorted 3D detections (the module's rule): ``base`` the file values [T, M', ...]
    (padded to the frames' slots), ``before`` / ``after`` the frames the distortion read and wrote
    [T, M', ...], ``pose`` [T, S, 4] its clutter's poses, ``dp`` the lane's levels (scalars)."""
    was = np.asarray(before.valid3, bool)
    valid = np.asarray(after.valid3, bool)
    fake = valid & ~was                                     # clutter: only reserved empty slots switch on
    s = int(spec.clutter_slots)
    m = was.shape[1]

    def changed(level) -> np.ndarray:
        return was & (float(level) > 0)

    score = np.where(changed(dp.score_noise_3d) | fake, np.asarray(after.score3, np.float64), base.score)
    image = np.where((changed(dp.jitter_box3) | fake)[..., None], np.asarray(after.box3, np.float64), base.image)
    _, c0 = invert_box3d_extent(before.lo3, before.hi3, spec.centroid)
    _, c1 = invert_box3d_extent(after.lo3, after.hi3, spec.centroid)
    loc = np.where(changed(dp.jitter_3d)[..., None], base.loc + (c1 - c0), base.loc)
    rot_y, dims, alpha = base.rot_y, base.dims, base.alpha
    if fake.any():
        where = np.zeros(loc.shape[:2] + (4,))
        where[:, m - s:] = np.asarray(pose, np.float64)
        loc = np.where(fake[..., None], where[..., :3], loc)
        rot_y = np.where(fake, where[..., 3], rot_y)
        dims = np.where(fake[..., None], np.asarray(CAR_DIMS, np.float32).astype(np.float64), dims)
        alpha = np.where(fake, _wrap(where[..., 3] - np.arctan2(where[..., 0], where[..., 2])), alpha)
    return Detections3D(valid, score, loc, rot_y, dims, alpha, image)


#: the levels of ``DistortParams`` that act on 2D detections only (nothing of a 3D detection moves)
LEVELS_2D = ("drop_2d", "jitter_2d", "score_noise_2d", "clutter_2d")


def only_3d(dp: DistortParams) -> DistortParams:
    """``dp`` (scalars or [B]) with its 2D-only levels (:data:`LEVELS_2D`) zeroed: what a family
    reading 3D detections alone applies."""
    return dp._replace(**{n: np.zeros_like(np.asarray(getattr(dp, n))) for n in LEVELS_2D})


def distinct_lanes(dp: DistortParams) -> tuple[np.ndarray, np.ndarray]:
    """(the distinct lanes of ``dp`` (leaves [B]): their index of first appearance [D], and each lane's
    distinct lane [B]), in order of first appearance."""
    key = np.stack([np.asarray(v, np.float64).reshape(-1) for v in dp], axis=1)
    _, first, of = np.unique(key, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty(len(order), np.int64)
    rank[order] = np.arange(len(order))
    return first[order], rank[np.asarray(of).reshape(-1)]


def lane_params(dp: DistortParams, b: int) -> DistortParams:
    """Lane ``b`` of a batch (scalars)."""
    return DistortParams(*(np.asarray(v).reshape(-1)[b] if np.ndim(v) else np.asarray(v) for v in dp))


def is_zero(dp: DistortParams) -> bool:
    """Every level of a lane is 0 (the undistorted lane, whatever its seed)."""
    return all(float(getattr(dp, n)) == 0.0 for names in GROUPS.values() for n in names)


class LaneDistortion(NamedTuple):
    """What a distorted batch's rows need to read each lane's own detections back: ``params``
    ``DistortParams`` [B] (leaves [B]), ``spec``, ``frames`` (the undistorted frames the distortion read, padded
    for the clutter), ``gid2`` / ``gid3`` (their ground-truth ids, padded). A ``TrackResult``'s
    ``distortion``; its families' rows and lane keys read it."""

    params: DistortParams
    spec: DistortSpec
    frames: Frames
    gid2: np.ndarray
    gid3: np.ndarray

    def key(self, b: int) -> bytes:
        """Lane ``b``'s levels and seed and the static spec they were drawn under (part of the key of
        the metrics' memo of its rows: the detections a lane reads follow from these and the split)."""
        return (np.asarray([float(v) for v in lane_params(self.params, b)], np.float64).tobytes()
                + repr(self.spec).encode())

    def lanes(self, base: Detections3D, lanes, score2=None) -> list["DistortedLane"]:
        """Each distinct distortion of ``lanes`` (lane indices), one at a time, as a
        :class:`DistortedLane`: its 3D detections read back from ``base`` (the file values) and,
        with ``score2`` ([T, M2] the 2D detections' file scores), its 2D scores by the same rule; a
        lane whose levels are all 0 gets the file values as they are."""
        lanes = np.asarray(lanes, np.int64)
        sub = DistortParams(*(np.asarray(v)[lanes] for v in self.params))
        first, of = distinct_lanes(sub)
        frames = self.frames
        base = base.padded(frames.valid3.shape[1])
        if score2 is not None:
            score2 = pad_slots(np.asarray(score2, np.float64), frames.valid2.shape[1] - np.shape(score2)[1], 0.0)
        out = []
        for d, i in enumerate(first):
            dp = lane_params(sub, int(i))
            which = np.flatnonzero(of == d)
            if is_zero(dp):
                out.append(DistortedLane(which, base, score2, np.asarray(frames.valid2, bool)))
                continue
            after, pose = distort_split(frames, self.gid2, self.gid3, dp, self.spec, pose=True)
            after = Frames(*(np.asarray(v) for v in after))
            s2 = None
            if score2 is not None:
                was = np.asarray(frames.valid2, bool)
                new = was & (float(dp.score_noise_2d) > 0) | (np.asarray(after.valid2) & ~was)
                s2 = np.where(new, np.asarray(after.score2, np.float64), score2)
            out.append(DistortedLane(which, read_back(base, frames, after, np.asarray(pose), dp, self.spec), s2,
                                     np.asarray(after.valid2, bool)))
        return out


class DistortedLane(NamedTuple):
    """One distinct distortion of :meth:`LaneDistortion.lanes`: ``which`` the positions among the
    lanes asked for it serves, ``dets`` its :class:`Detections3D`, ``score2`` / ``valid2`` [T, M2']
    its 2D detections' scores (float64; None when not asked for) and validity."""

    which: np.ndarray
    dets: Detections3D
    score2: np.ndarray | None
    valid2: np.ndarray


def distortion_3d(split: Split, dets: Detections3D, dp: DistortParams, spec: DistortSpec) -> LaneDistortion:
    """The :class:`LaneDistortion` of a family reading 3D detections alone: its 3D-only frames
    (:func:`frames_3d` of ``dets``, the split's detections as that family holds them, padded for
    the clutter), the ground-truth ids of their slots (``split.root``'s labels; the detector's image
    box, as DFR-FastMOT's default options read it) and the levels with the 2D ones zeroed
    (:func:`only_3d`)."""
    if not split.root:
        raise ValueError("a distortion study needs the split's KITTI root (load it with load_split)")
    _, gid3 = gt_identity(split, split.root)
    frames = pad_for_clutter(frames_3d(dets, split.reset, spec.centroid), spec)
    gid2, gid3 = pad_identity(np.zeros((gid3.shape[0], 0), np.int32), gid3, spec)
    return LaneDistortion(only_3d(dp), spec, frames, gid2, gid3)
