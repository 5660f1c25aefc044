"""Host side: the detections a distortion lane leaves, as result files carry them.

The tracker families read the same draws (:func:`hook.apply_draws`, keyed by ``(seed, t)``) on the
slots of a ``Frames`` layout: DFR-FastMOT inside its scan, AB3DMOT on 3D-only frames (:func:`frames_3d`,
:func:`distortion_3d`) and ByteTrack on 2D-only frames (:func:`frames_2d`, :func:`distortion_2d`)
materialised here (:meth:`LaneDistortion.lanes`), so one seed and level give every family the same
faults. What a family's rows write of a detection is read back from the distorted frames by one
rule, :func:`read_back` (3D: score, centre, size, heading, image box) and :func:`read_back_2d` (2D:
box, score):

- a value no distortion touched keeps the file's float64 value (level 0 returns the input, bit
  for bit);
- a noisy score (``score_noise_3d`` / ``score_noise_2d > 0``), a jittered image box (``jitter_box3``
  / ``jitter_2d > 0``) and every value of a clutter slot are the distorted frame's float32 values;
- a shifted centre (``jitter_3d > 0``) is the file's centre plus the shift the frame's ``lo3/hi3``
  received, mapped from the convention of ``DistortSpec.centroid`` (a signed permutation of camera
  axes, ``io.columns.invert_box3d_extent``) to camera axes: the same physical shift in every
  family (the float32 shift as DFR-FastMOT's frame received it, exactly);
- a 3D clutter slot is a ``CAR_DIMS`` box at the clutter's pose (``clutter.Placement3D.pose``), its
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


def padded_slots(dets, m: int):
    """``dets`` (a NamedTuple of [T, M, ...] arrays, ``valid`` bool among them) with empty slots
    appended up to ``m`` (invalid, zero)."""
    n = m - dets.valid.shape[1]
    return dets if n <= 0 else type(dets)(*(pad_slots(v, n, False if v.dtype == bool else 0.0) for v in dets))


def packed_slots(dets):
    """``dets`` (as :func:`padded_slots`) with each frame's valid detections first, in slot order
    (what a detection file holding only them lists), the empty slots after them."""
    order = np.argsort(~np.asarray(dets.valid, bool), axis=1, kind="stable")
    return type(dets)(*(np.take_along_axis(v, order.reshape(order.shape + (1,) * (v.ndim - 2)), axis=1)
                        for v in dets))


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
        """The detections with empty slots appended up to ``m`` (:func:`padded_slots`)."""
        return padded_slots(self, m)

    def packed(self) -> "Detections3D":
        """Each frame's valid detections first (:func:`packed_slots`)."""
        return packed_slots(self)


class Detections2D(NamedTuple):
    """One lane's 2D detections [T, M, ...] as a detection file carries them (float64): ``valid``
    (bool), ``score``, ``box`` [.., 4] x1 y1 x2 y2."""

    valid: np.ndarray
    score: np.ndarray
    box: np.ndarray

    def padded(self, m: int) -> "Detections2D":
        """The detections with empty slots appended up to ``m`` (:func:`padded_slots`)."""
        return padded_slots(self, m)

    def packed(self) -> "Detections2D":
        """Each frame's valid detections first (:func:`packed_slots`)."""
        return packed_slots(self)


def split_detections(split: Split) -> Detections3D:
    """The split's own 3D detections (its file values, float64)."""
    f64 = functools.partial(np.asarray, dtype=np.float64)
    return Detections3D(np.asarray(split.valid3d, bool), f64(split.score3d), f64(split.loc3d), f64(split.rot_y3d),
                        f64(split.dims3d), f64(split.alpha3d), f64(split.box3d))


def split_detections_2d(split: Split) -> Detections2D:
    """The split's own 2D detections (its file values, float64)."""
    return Detections2D(np.asarray(split.valid2d, bool), np.asarray(split.score2d, np.float64),
                        np.asarray(split.box2d, np.float64))


def frames_2d(dets: Detections2D, reset) -> Frames:
    """``Frames`` [T, ...] holding 2D detections only (no 3D slot) for the distortion of a family
    that reads 2D detections alone: ``box2`` the detector's box (float32, untruncated), ``score2``
    float32, ``valid2`` the detections' (as ``trackers.dfr.frames.prepare_frames`` has them: the
    same slots, the same draws)."""
    t = np.asarray(reset).shape[0]
    return Frames(reset=np.asarray(reset, bool), box2=np.asarray(dets.box).astype(np.float32),
                  score2=np.asarray(dets.score).astype(np.float32), valid2=np.asarray(dets.valid, bool),
                  box3=np.zeros((t, 0, 4), np.float32), score3=np.zeros((t, 0), np.float32),
                  valid3=np.zeros((t, 0), bool), lo3=np.zeros((t, 0, 3), np.float32),
                  hi3=np.zeros((t, 0, 3), np.float32))


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


def _drawn(base: np.ndarray, after, touched: np.ndarray) -> np.ndarray:
    """The module's rule for one value [T, M, ...]: the distorted frame's float32 value (as float64)
    where ``touched`` [T, M], the file's float64 ``base`` elsewhere."""
    after = np.asarray(after)
    return np.where(touched.reshape(touched.shape + (1,) * (after.ndim - 2)), after.astype(np.float64), base)


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
    score = _drawn(base.score, after.score3, was & (float(dp.score_noise_3d) > 0) | fake)
    image = _drawn(base.image, after.box3, was & (float(dp.jitter_box3) > 0) | fake)
    _, c0 = invert_box3d_extent(before.lo3, before.hi3, spec.centroid)
    _, c1 = invert_box3d_extent(after.lo3, after.hi3, spec.centroid)
    loc = np.where((was & (float(dp.jitter_3d) > 0))[..., None], base.loc + (c1 - c0), base.loc)
    rot_y, dims, alpha = base.rot_y, base.dims, base.alpha
    if fake.any():
        where = np.zeros(loc.shape[:2] + (4,))
        where[:, m - s:] = np.asarray(pose, np.float64)
        loc = np.where(fake[..., None], where[..., :3], loc)
        rot_y = np.where(fake, where[..., 3], rot_y)
        dims = np.where(fake[..., None], np.asarray(CAR_DIMS, np.float32).astype(np.float64), dims)
        alpha = np.where(fake, _wrap(where[..., 3] - np.arctan2(where[..., 0], where[..., 2])), alpha)
    return Detections3D(valid, score, loc, rot_y, dims, alpha, image)


def read_back_2d(base: Detections2D, before: Frames, after: Frames, dp: DistortParams) -> Detections2D:
    """One lane's distorted 2D detections by the module's rule (:func:`read_back`'s, on the 2D
    slots): ``base`` the file values [T, M', ...] (padded to the frames' slots), ``before`` /
    ``after`` the frames the distortion read and wrote; a noisy score (``score_noise_2d > 0``), a
    jittered box (``jitter_2d > 0``) and every value of a clutter slot are the distorted frame's
    float32 values, every other value the file's."""
    was = np.asarray(before.valid2, bool)
    valid = np.asarray(after.valid2, bool)
    fake = valid & ~was
    return Detections2D(valid, _drawn(base.score, after.score2, was & (float(dp.score_noise_2d) > 0) | fake),
                        _drawn(base.box, after.box2, was & (float(dp.jitter_2d) > 0) | fake))


#: the levels of ``DistortParams`` that act on 2D detections only (nothing of a 3D detection moves)
LEVELS_2D = ("drop_2d", "jitter_2d", "score_noise_2d", "clutter_2d")
#: the levels of ``DistortParams`` that act on 3D detections only (their image boxes included:
#: nothing of a 2D detection moves)
LEVELS_3D = ("drop_3d", "jitter_box3", "jitter_3d", "score_noise_3d", "clutter_3d")


def _zeroed(dp: DistortParams, names) -> DistortParams:
    return dp._replace(**{n: np.zeros_like(np.asarray(getattr(dp, n))) for n in names})


def only_3d(dp: DistortParams) -> DistortParams:
    """``dp`` (scalars or [B]) with its 2D-only levels (:data:`LEVELS_2D`) zeroed: what a family
    reading 3D detections alone applies."""
    return _zeroed(dp, LEVELS_2D)


def only_2d(dp: DistortParams) -> DistortParams:
    """``dp`` (scalars or [B]) with its 3D-only levels (:data:`LEVELS_3D`) zeroed: what a family
    reading 2D detections alone applies (bursts occlude both)."""
    return _zeroed(dp, LEVELS_3D)


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

    def lanes(self, base: Detections3D | None, lanes, base2: Detections2D | None = None) -> list["DistortedLane"]:
        """Each distinct distortion of ``lanes`` (lane indices), one at a time, as a
        :class:`DistortedLane`: its 3D detections read back from ``base`` (the file values,
        :func:`read_back`) and its 2D detections from ``base2`` (:func:`read_back_2d`), each when
        given; a lane whose levels are all 0 gets the file values as they are (padded)."""
        lanes = np.asarray(lanes, np.int64)
        sub = DistortParams(*(np.asarray(v)[lanes] for v in self.params))
        first, of = distinct_lanes(sub)
        frames = self.frames
        base = None if base is None else base.padded(frames.valid3.shape[1])
        base2 = None if base2 is None else base2.padded(frames.valid2.shape[1])
        out = []
        for d, i in enumerate(first):
            dp = lane_params(sub, int(i))
            which = np.flatnonzero(of == d)
            if is_zero(dp):
                out.append(DistortedLane(which, base, base2))
                continue
            after, pose = distort_split(frames, self.gid2, self.gid3, dp, self.spec, pose=True)
            after = Frames(*(np.asarray(v) for v in after))
            out.append(DistortedLane(which, None if base is None else read_back(base, frames, after, np.asarray(pose),
                                                                                dp, self.spec),
                                     None if base2 is None else read_back_2d(base2, frames, after, dp)))
        return out


class DistortedLane(NamedTuple):
    """One distinct distortion of :meth:`LaneDistortion.lanes`: ``which`` the positions among the
    lanes asked for it serves, ``dets`` its :class:`Detections3D` and ``dets2`` its
    :class:`Detections2D` (each None when not asked for)."""

    which: np.ndarray
    dets: Detections3D | None
    dets2: Detections2D | None


def _labelled(split: Split) -> None:
    if not split.root:
        raise ValueError("a distortion study needs the split's KITTI root (load it with load_split)")


def distortion_3d(split: Split, dets: Detections3D, dp: DistortParams, spec: DistortSpec) -> LaneDistortion:
    """The :class:`LaneDistortion` of a family reading 3D detections alone: its 3D-only frames
    (:func:`frames_3d` of ``dets``, the split's detections as that family holds them, padded for
    the clutter), the ground-truth ids of their slots (``split.root``'s labels; the detector's image
    box, as DFR-FastMOT's default options read it) and the levels with the 2D ones zeroed
    (:func:`only_3d`)."""
    _labelled(split)
    _, gid3 = gt_identity(split, split.root)
    frames = pad_for_clutter(frames_3d(dets, split.reset, spec.centroid), spec)
    gid2, gid3 = pad_identity(np.zeros((gid3.shape[0], 0), np.int32), gid3, spec)
    return LaneDistortion(only_3d(dp), spec, frames, gid2, gid3)


def distortion_2d(split: Split, dp: DistortParams, spec: DistortSpec) -> LaneDistortion:
    """The :class:`LaneDistortion` of a family reading 2D detections alone: the 2D-only frames of
    the split's own 2D detections (:func:`frames_2d`, padded for the clutter), the ground-truth ids
    of their slots (``split.root``'s labels, the detector's box: DFR-FastMOT's ``gid2``) and the
    levels with the 3D ones zeroed (:func:`only_2d`)."""
    _labelled(split)
    gid2, _ = gt_identity(split, split.root)
    frames = pad_for_clutter(frames_2d(split_detections_2d(split), split.reset), spec)
    gid2, gid3 = pad_identity(gid2, np.zeros((gid2.shape[0], 0), np.int32), spec)
    return LaneDistortion(only_2d(dp), spec, frames, gid2, gid3)
