"""ByteTrack as a tracker family (:class:`dfrmot_jax.trackers.protocol.TrackerFamily`), the family
``"bytetrack"``: its settings (:mod:`.config`), its tracker (:mod:`.tracker`, the compiled batch
:mod:`.batch`), on the splits every family reads (:class:`dfrmot_jax.data.Split`; ByteTrack reads the
2D detections only, rows of a frame in the order of their file):

- :func:`prepare_frames`: a split's 2D detections as the tracker's ``Frames`` (``x1 y1 x2 y2
  score``, float64 as the file gives them);
- :func:`track`: a batch of settings over a split, in calls of ``lanes_per_call`` lanes, capacity
  from the data and grown where a lane overflows (:mod:`dfrmot_jax.trackers.capacity`), as a
  :class:`~dfrmot_jax.trackers.protocol.TrackResult`: ``ids`` [B, T, K] (ByteTrack's ``track_id``,
  counted from 1 in each sequence), ``boxes`` [B, T, K, 4] the written ``tlwh`` as ``x1 y1 x2 y2``,
  ``score`` [B, T, K] the last matched detection's score;
- :func:`rows`, :func:`write_runs`: the rows as the reference runs' files carry them (``%.6f``) and
  the files, one per sequence, line for line ByteTrack's;
- distortion studies (:func:`distortion_spec`, :func:`distorted_lanes`, ``track(distortion=...)``):
  each lane's 2D detections distorted by the draws DFR-FastMOT's lanes take (``distort``: the same
  seed and level drop the same ground-truth objects' detections), each distinct distortion
  materialised on the host and tracked on its own frames.
"""

from __future__ import annotations

import hashlib
import warnings
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ... import distort
from ...data import CLASS_NAMES, Split
from ...io.columns import as_written_fixed
from ...io.result_writer import write_class_files
from ...rows import KittiRows, Rows, RowSelection, padded_rows
from .. import capacity as slots
from ..lanes import calls_by_key, widen
from ..protocol import TrackerFamily, TrackResult
from . import batch
from .config import FAMILY_CONFIG, Options, Params, as_arrays, validate
from .results import demo_keep
from .tracker import Frames, init, step

__all__ = ["FAMILY", "prepare_frames", "frames_of", "detections_of", "LaneFrames", "distortion_spec", "distorted_lanes",
           "track", "rows", "row_arrays", "class_run", "write_runs", "ByteTrackRun", "lane_keys"]

#: bytes of one output slot of a lane: id, box, score, written
BYTES_PER_SLOT = 4 + 32 + 8 + 1
#: a written line: ``frame id Type 0 0 -10 x1 y1 x2 y2 -1 -1 -1 -1000 -1000 -1000 -10 score``
LINE = "%d %d %s 0 0 -10 %.6f %.6f %.6f %.6f -1 -1 -1 -1000 -1000 -1000 -10 %.6f"
#: the 3D fields of a 2D-only row (``h w l x y z rot_y``), as written
NO_BOX3D = np.array([-1.0, -1.0, -1.0, -1000.0, -1000.0, -1000.0, -10.0])


#: what an empty detection slot holds (``x1 y1 x2 y2 score``)
EMPTY_DET = np.array([0.0, 0.0, 1.0, 1.0, 0.0])


def frames_of(dets: distort.Detections2D, reset) -> Frames:
    """2D detections (file values, float64 [T, M, ...]) as the tracker's frames: dets [T, M, 5]
    ``x1 y1 x2 y2 score`` float64 (empty slots :data:`EMPTY_DET`), valid [T, M], reset [T]."""
    valid = np.asarray(dets.valid, bool)
    d = np.concatenate([np.asarray(dets.box, np.float64), np.asarray(dets.score, np.float64)[..., None]], axis=-1)
    return Frames(np.where(valid[..., None], d, EMPTY_DET), valid, np.asarray(reset, bool))


def detections_of(frames: Frames) -> distort.Detections2D:
    """The tracker's frames as ``distort`` reads 2D detections (float64 file values [T, M, ...])."""
    dets = np.asarray(frames.dets, np.float64)
    return distort.Detections2D(np.asarray(frames.valid, bool), dets[..., 4], dets[..., :4])


def prepare_frames(split: Split, options: Options | None = None) -> Frames:
    """``split``'s 2D detections as the tracker's frames (the same for every ``Options``): dets
    [T, M2, 5] ``x1 y1 x2 y2 score`` float64, valid [T, M2], reset [T] (:func:`frames_of`)."""
    return frames_of(distort.split_detections_2d(split), split.reset)


class LaneFrames(NamedTuple):
    """Each lane's frames where lanes track different detections (a distortion study): ``frames``
    the distinct :class:`.tracker.Frames`, ``of`` [B] each lane's; a ``TrackResult``'s ``frames``."""

    frames: tuple
    of: np.ndarray


def distortion_spec(options=None, clutter_slots: int = 0, burst_max: int = 30, burst_dist: str = "fixed",
                    frames: Frames | None = None, dps=None, **kw) -> distort.DistortSpec:
    """The ``DistortSpec`` of ByteTrack's lanes (``TrackerFamily.distortion_spec``; ``options``, its
    own, change nothing): boxes as the detector wrote them (no truncation), the clutter's laws
    measured on ``frames``' 2D detections (:func:`distort.frames_2d`, as DFR-FastMOT measures them
    on its own); only the groups of ``dps``' 2D levels (:func:`distort.only_2d`)."""
    f2 = None if frames is None else distort.frames_2d(detections_of(frames), frames.reset)
    return distort.make_spec(None, clutter_slots=clutter_slots, burst_max=burst_max, burst_dist=burst_dist, frames=f2,
                             dps=None if dps is None else distort.only_2d(dps), **{"truncate": False, **kw})


def distorted_lanes(split: Split, frames: Frames, dps, spec: distort.DistortSpec) -> tuple[LaneFrames,
                                                                                         distort.LaneDistortion]:
    """Each lane's distorted detections (``dps`` leaves [B]): the distinct distortions' frames
    (:meth:`distort.LaneDistortion.lanes` on the 2D detections alone, :func:`distort.distortion_2d`;
    3D levels ignored), each frame's detections packed to its first slots in their order (as a
    detection file holding only them lists them), the clutter after the real ones; a lane whose
    levels are all 0 the undistorted ``frames`` themselves (one entry, whatever their seeds)."""
    lanes = distort.distortion_2d(split, dps, spec)
    b = len(np.asarray(dps.seed))
    of = np.zeros(b, np.int64)
    out, zero_at = [], None
    for d in lanes.lanes(None, np.arange(b), detections_of(frames)):
        if distort.is_zero(distort.lane_params(lanes.params, int(d.which[0]))):      # (whatever the seed)
            zero_at = len(out) if zero_at is None else zero_at
            of[d.which] = zero_at
            if zero_at == len(out):
                out.append(frames)
            continue
        of[d.which] = len(out)
        out.append(frames_of(d.dets2.packed(), frames.reset))
    return LaneFrames(tuple(out), of), lanes


def default_capacity(frames: Frames, params: Params, options: Options, clutter_slots: int = 0) -> int:
    """Track slots from the data (:func:`dfrmot_jax.trackers.capacity.from_data`): two per detection
    of the fullest frame (tracked and lost tracks; births beyond them are counted, the lane grown)."""
    most = int(np.asarray(frames.valid).sum(axis=1).max(initial=0))
    return slots.from_data(most, 2.0, 2 * int(clutter_slots))


def output_slots(options: Options, per_lane: bool) -> tuple[int, int, bool]:
    """(track slots, bytes per slot, whether the slots are the options' own) of a lane's output."""
    return options.capacity or slots.MIN_CAPACITY, BYTES_PER_SLOT, bool(options.capacity)


def compact_split(split: Split, params: Params) -> Split:
    """``split`` as it is (every detection above 0.1 takes part whatever the settings)."""
    return split


def _lanes(params: Params) -> Params:
    p = as_arrays(params)
    b = max([np.size(v) for v in p] + [1])
    return Params(*(np.broadcast_to(v, (b,)).copy() for v in p))


def _track_on(frames: Frames, p: Params, lanes: np.ndarray, options: Options, per: int, grow: bool, cap0: int,
              got: dict, overflow: np.ndarray, capacity: np.ndarray, progress) -> None:
    """Lanes ``lanes`` (indices into ``p``'s leaves [B]) over ``frames``, in calls of ``per`` lanes
    from ``cap0`` track slots, a lane that overflowed run again with twice as many (``grow``): their
    ids, boxes and scores written into ``got`` ([B, T, K] arrays, widened as the calls need),
    ``overflow`` and ``capacity`` [B]."""
    b = len(p.track_thresh)
    todo, cap = np.asarray(lanes, np.int64), cap0
    while todo.size:
        for at, _ in calls_by_key(todo, per, None):
            out = batch.run(Params(*(v[at] for v in p)), options._replace(capacity=0), frames, capacity=cap)
            keep = out.written & demo_keep(out.tlwh) if options.demo_filter else out.written
            # each frame's written tracks first, in ByteTrack's output order (their list order)
            order = np.argsort(np.where(keep, out.key, np.iinfo(np.int32).max), axis=2, kind="stable")
            def take(a, order=order):
                return np.take_along_axis(np.asarray(a), order.reshape(order.shape + (1,) * (np.ndim(a) - 3)), axis=2)
            tlwh = take(out.tlwh)
            part = {"ids": take(np.where(keep, out.tid, -1)).astype(np.int32),
                    "boxes": np.concatenate([tlwh[..., :2], tlwh[..., :2] + tlwh[..., 2:]], axis=-1),
                    "score": take(np.asarray(out.score, np.float64))}
            for name, v in part.items():
                fill = -1 if name == "ids" else 0.0
                if name not in got:
                    got[name] = np.full((b,) + v.shape[1:], fill, v.dtype)
                got[name] = widen(got[name], v.shape[2], fill)
                got[name][at, :, :v.shape[2]] = v
                got[name][at, :, v.shape[2]:] = fill
            overflow[at] = out.overflow
            capacity[at] = cap
            if progress is not None and cap == cap0:
                progress(len(at))
        todo = todo[overflow[todo] > 0]
        more = slots.grown(cap) if todo.size and grow else None
        if more is None:
            break
        cap = more


def track(split: Split | Frames, params: Params, options: Options = Options(), *, lanes_per_call: int | None = None,
          grow: bool = True, detail: bool = False, rows_only: bool = False, distortion=None, spec=None,
          clutter_slots: int = 0, progress=None) -> TrackResult:
    """Every lane of ``params`` (leaves scalar or [B]) over the split (or its prepared frames).

    lanes_per_call: lanes per compiled call (default all); grow: a lane that overflowed its track
    slots runs again with twice as many (``trackers.capacity``); rows_only: the boxes and scores as
    :class:`dfrmot_jax.rows.Rows`. ``detail`` changes nothing (the rows carry no 3D detection).
    The result's slots are ByteTrack's output order within a frame; ``options.demo_filter`` drops
    the rows ``tools/demo_track.py`` would not write (a writer's filter, the tracking unchanged).

    ``distortion``: ``distort.DistortParams`` (scalars or leaves [B]; needs the ``Split``, whose
    labels give the bursts' identities): lane b tracks its 2D detections distorted by its own levels
    and seed, the draws DFR-FastMOT's lanes take (:func:`distorted_lanes`; 3D levels change nothing
    here), on its distortion's materialised frames, each distinct distortion's lanes in calls of
    their own; ``spec`` / ``clutter_slots``: the static ``DistortSpec`` (default
    :func:`distortion_spec` of the data and the levels). The result's ``frames`` are then a
    :class:`LaneFrames` and its ``distortion`` the ``distort.LaneDistortion``."""
    p = _lanes(params)
    b = len(p.track_thresh)
    validate(Params(*(v[0] for v in p)), options)
    frames = split if isinstance(split, Frames) else prepare_frames(split, options)
    per = max(1, int(lanes_per_call or b))
    groups, lanes = [(frames, np.arange(b))], None
    if distortion is not None:
        if not isinstance(split, Split):
            raise ValueError("track(distortion=...) needs the Split (its ground truth), not prepared frames")
        dps = distort.DistortParams(*(np.broadcast_to(np.asarray(v), (b,)) for v in distortion))
        if spec is None:
            spec = distortion_spec(clutter_slots=clutter_slots, frames=frames, dps=dps)
        distort.check_params(distort.only_2d(dps), spec)
        frames, lanes = distorted_lanes(split, frames, dps, spec)
        groups = [(f, np.flatnonzero(frames.of == d)) for d, f in enumerate(frames.frames)]
    got: dict[str, np.ndarray] = {}
    overflow = np.zeros(b, np.int64)
    capacity = np.zeros(b, np.int64)
    for f, at in groups:
        cap0 = options.capacity or default_capacity(f, p, options)
        _track_on(f, p, at, options, per, grow, cap0, got, overflow, capacity, progress)
    if np.any(overflow > 0):
        bad = np.flatnonzero(overflow > 0)
        warnings.warn(f"ByteTrack: track memory overflow in {bad.size} lane(s) (e.g. lane {bad[0]}: {overflow[bad[0]]} "
                      f"births dropped at capacity {capacity[bad[0]]}); raise Options.capacity", RuntimeWarning,
                      stacklevel=2)
    ids = got["ids"]
    boxes, score = got["boxes"], got["score"]
    if rows_only:
        boxes, score = Rows.of(ids, boxes), Rows.of(ids, score)
    t = ids.shape[1]
    peak = (ids >= 0).sum(axis=2).max(axis=1, initial=0).astype(np.int32)
    return TrackResult(ids, boxes, np.zeros((b, t), np.int32), overflow.astype(np.int32), peak, None, None, None,
                       capacity, frames, options, lanes, score)


def rows(split: Split, res: TrackResult, columns: str = "kitti", lanes=None) -> KittiRows:
    """The rows of ``res``' lanes (``lanes``: only these, renumbered 0..len-1; default all) as the
    reference runs' files carry them (:class:`dfrmot_jax.rows.KittiRows`): the Kalman box and the
    last matched detection's score, as ``%.6f`` reads back; no 3D box (KITTI's placeholders)."""
    ids = np.asarray(res.ids)
    sel = RowSelection.of(ids, lanes)
    box = as_written_fixed(np.asarray(sel.values(res.boxes), np.float64))
    score = as_written_fixed(np.asarray(sel.values(res.score), np.float64))
    box3d = np.broadcast_to(NO_BOX3D, (box.shape[0], 7)).copy()
    return KittiRows(sel.lane, sel.t, sel.slot, sel.values(ids).astype(np.int64), box, score, box3d,
                     len(sel.chosen), ids.shape[1])


def row_arrays(split: Split, res: TrackResult, columns: str = "kitti") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`rows` as padded arrays (:func:`dfrmot_jax.rows.padded_rows`)."""
    return padded_rows(rows(split, res, columns), np.asarray(res.ids).shape)


class ByteTrackRun(NamedTuple):
    """One class's lane to write (:func:`write_runs`): its split, ids [T, K], boxes [T, K, 4]
    ``x1 y1 x2 y2``, scores [T, K]."""

    split: Split
    ids: np.ndarray
    boxes: np.ndarray
    score: np.ndarray


def class_run(split: Split, res: TrackResult, lane: int = 0) -> ByteTrackRun:
    """Lane ``lane`` of a :func:`track` result on ``split`` as :func:`write_runs` takes it."""
    ids = np.asarray(res.ids)
    dense = [a.lane_dense(lane, ids[lane], 0.0) if isinstance(a, Rows) else np.asarray(a)[lane]
             for a in (res.boxes, res.score)]
    return ByteTrackRun(split, ids[lane], *dense)


def write_runs(out_dir, runs: list[ByteTrackRun], *, columns: str = "kitti") -> list[Path]:
    """One result file per sequence of any run, the reference runs' lines (``frame id Type 0 0 -10
    x1 y1 x2 y2 -1 -1 -1 -1000 -1000 -1000 -10 score``, ``%.6f``; a frame's targets in ByteTrack's
    output order). Several classes (one run each) share a sequence's file, frame by frame in the
    order of ``runs``, each later class's ids offset past the largest id written before it in that
    sequence. ``columns``: "kitti" (the only layout; "kitti-stale" is the same)."""
    if columns not in ("kitti", "kitti-stale"):
        raise ValueError(f"columns={columns!r}: ByteTrack writes KITTI lines only (kitti)")
    per_seq: dict[str, list[tuple[np.ndarray, list[str]]]] = {}
    top: dict[str, int] = {}
    for run in runs:
        s = run.split
        name_of = CLASS_NAMES[s.cls]
        for k, name in enumerate(s.names):
            sl = s.sequence_slice(k)
            ids = run.ids[sl]
            t, slot = np.nonzero(ids >= 0)
            offset = top.get(name, 0) if name in per_seq else 0
            tid = ids[t, slot].astype(np.int64) + offset
            frame = np.asarray(s.frame)[sl][t]
            box = run.boxes[sl][t, slot]
            score = run.score[sl][t, slot]
            lines = [LINE % (frame[i], tid[i], name_of, *box[i], score[i]) for i in range(len(t))]
            per_seq.setdefault(name, []).append((frame, lines))
            top[name] = max(top.get(name, 0), int(tid.max(initial=offset)))
    return write_class_files(out_dir, per_seq)


def table_problem(table) -> tuple[str, str] | None:
    """None: ByteTrack runs every valid setting."""
    return None


def failing_rows(table) -> np.ndarray:
    """[C] False: no ByteTrack setting is known to fail without a run."""
    return np.zeros(len(table), bool)


def setting_problem(what: str, params: Params, options: Options) -> str | None:
    """None: every valid ByteTrack setting runs (``TrackerFamily.setting_problem``)."""
    return None


def lane_keys(res: TrackResult, base) -> list[bytes]:
    """One digest per lane of what its rows carry beyond ``base`` (its ids and image boxes): the
    options and the rows' scores (``TrackerFamily.lane_keys``); with a distortion, the lane's levels
    and seed (which detections it tracked)."""
    ids = np.asarray(res.ids)
    out = []
    for b in range(ids.shape[0]):
        h = hashlib.sha1(repr(res.options).encode())
        h.update(base[b])
        if res.distortion is not None:
            h.update(res.distortion.key(b))
        sel = RowSelection.of(ids, [b])
        h.update(np.ascontiguousarray(sel.values(res.score), np.float64).tobytes())
        out.append(h.digest())
    return out


#: ByteTrack, the family ``"bytetrack"``
FAMILY = TrackerFamily(
    config=FAMILY_CONFIG, init=init, step=step, run_batch=batch.run, track=track, prepare_frames=prepare_frames,
    compact_split=compact_split, default_capacity=default_capacity, output_slots=output_slots, rows=rows,
    row_arrays=row_arrays, class_run=class_run, write_runs=write_runs, table_problem=table_problem,
    failing_rows=failing_rows, setting_problem=setting_problem, lane_keys=lane_keys, box_format="f6",
    oracle="dfrmot_jax.testing.bytetrack_oracle", distortion_spec=distortion_spec)
