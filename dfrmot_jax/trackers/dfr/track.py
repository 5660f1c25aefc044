"""High-level tracking: a ``Params`` batch over a split, with capacity chosen from the data.

``track(split, params, options)`` runs the batch in compiled calls of ``lanes_per_call`` lanes,
picks the track capacity from the data when ``options.capacity`` is 0, and re-runs any lane whose
memory overflowed with twice the capacity (``grow=True``), so that no track is dropped silently.
Lanes that still overflow are reported in ``TrackResult.overflow`` and with a warning.
"""

from __future__ import annotations

import warnings
from collections import namedtuple

import numpy as np

from ... import distort
from ...devices import default_lanes_per_call, setup_host_devices
from ...frames import Frames
from ...data import Split
from .frames import compact_frames, image_box_3d, object_slots, prepare_frames
from .config import (MAX_CAPACITY, OBJECT_PARAMS, Options, Params, as_arrays, batch_size, keep_thresholds,
                     validate_params)
from .results import output_boxes
from ...rows import Rows, row_starts
from .. import capacity
from ..lanes import calls_by_key, widen
from ..protocol import TrackResult
from .associate import MAX_ROWS
from .run import SMALL_FRAMES_MIN_T, BatchOutput, FrameHook, run_batch, split_objects

#: objects (detection slots) per frame the greedy order keys can tell apart (core.associate.MAX_ROWS)
MAX_OBJECTS = MAX_ROWS


def default_capacity(frames: Frames, params: Params, options: Options, clutter_slots: int = 0) -> int:
    """Track slots from the data: 1.5 x the most objects any frame keeps at the batch's loosest
    score thresholds, rounded up to a multiple of 8 (at least 16). Every [objects, tracks] operation
    of a step scales with it, so it is tight on purpose: a lane that overflows is re-run by ``track``
    with twice the slots. ``clutter_slots``: a distortion's clutter slots per frame (not in
    ``frames``), room for their births: 3 x as many slots more, a multiple of 8."""
    s2, s3 = (np.min(s) for s in keep_thresholds(params))
    n2 = np.sum(frames.valid2 & (frames.score2 >= s2), axis=1)
    n3 = np.sum(frames.valid3 & (frames.score3 >= s3), axis=1)
    if options.modality == "2d":
        n = n2
    elif options.modality == "3d":
        n = n3
    else:
        n = n2 + n3
    extra = 8 * int(np.ceil(3 * clutter_slots / 8)) if clutter_slots else 0
    return capacity.from_data(int(n.max(initial=0)), 1.5, extra)


def _take(tree, idx: np.ndarray):
    """Lanes idx of a Params / DistortParams batch."""
    b = batch_size(tree)
    return type(tree)(*(np.broadcast_to(np.asarray(v), (b,))[idx] for v in tree))


def prepare_distortion(split: Split, frames: Frames, options: Options, dps: distort.DistortParams,
                       spec: distort.DistortSpec | None = None, clutter_slots: int = 0):
    """Host side of a distortion study: (padded frames, (spec, gid2, gid3)).

    The spec defaults to ``distort.make_spec`` with exactly the groups ``dps`` uses; ground-truth
    identities come from ``split.root``'s labels.
    """
    if spec is None:
        spec = distort.make_spec(options, clutter_slots=clutter_slots, frames=frames, dps=dps)
    distort.check_params(dps, spec)
    if not split.root:
        raise ValueError("a distortion study needs the split's KITTI root (load it with load_split)")
    gid2, gid3 = distort.pad_identity(*distort.gt_identity(split, split.root, image_box_3d(split.box3d, split.proj3d, options)), spec)
    return distort.pad_for_clutter(frames, spec), (spec, gid2, gid3)


def track(split: Split | Frames, params: Params, options: Options = Options(), *, lanes_per_call: int | None = None,
          grow: bool = True, progress=None, distortion: distort.DistortParams | None = None,
          spec: distort.DistortSpec | None = None, clutter_slots: int = 0, detail: bool = False,
          small_frames_min: int | None = SMALL_FRAMES_MIN_T, compact: bool = True,
          chunk: int | None = None, rows_only: bool = False) -> TrackResult:
    """Track every lane of ``params`` (leaves scalar or [B]) over the split.

    lanes_per_call: lanes per compiled call (memory: lanes_per_call x T x K int32 ids; default
    ``devices.default_lanes_per_call()``: 64 on the CPU, 1024 on a GPU); progress: a
    callable(n) told how many lanes finished, e.g. a tqdm bar's ``update``.
    distortion: ``DistortParams`` with leaves [B] (or scalars): lane b's detections are distorted by
    its own levels and seed inside the scan (``dfrmot_jax.distort``); needs a ``Split`` (ground truth).
    spec / clutter_slots: the static ``DistortSpec`` (default from the data and the levels used).
    detail: also return the 3D detection each written row carries (``TrackResult.src3``), for
    result files with 3D fields; costs memory per lane, so sweeps leave it off.
    small_frames_min: frames with few detections run on a smaller copy of the step on splits of at
    least this many frames (None: one size); the results are the same, only the speed differs.
    compact: track a ``Split`` compacted to the batch's loosest score thresholds
    (:func:`dfrmot_jax.trackers.dfr.frames.compact_frames`: the detections no lane keeps dropped, the rest packed to
    the front) and give the output back in the split's own slot layout: the same result, fewer dead
    slots per step (not with a distortion or the Hungarian assignment).
    chunk: deprecated name of ``lanes_per_call`` (kept for one release, with a ``DeprecationWarning``).
    rows_only: a lane's own boxes (output "filtered", or a distortion) and ``box3`` come back as
    :class:`dfrmot_jax.rows.Rows`, their values at the rows (ids >= 0) only, read from each call's
    output without a dense copy: what every reader of the rows gets, in a fraction of the memory
    (sweeps; a filtered slot is a track and most hold no row).
    """
    if chunk is not None:
        warnings.warn("track(chunk=...) is deprecated: use track(lanes_per_call=...) (a sweep's chunk is "
                      "its unit of configs)", DeprecationWarning, stacklevel=2)
        lanes_per_call = chunk
    setup_host_devices()          # before this call's first JAX operation
    if lanes_per_call is None:
        lanes_per_call = default_lanes_per_call()
    options = options.validate()
    validate_params(params)
    params = as_arrays(params)
    if options.output == "detections" and np.any(np.asarray(params.keep_lost) > 0):
        raise ValueError("parameter keep_lost > 0 writes lost tracks' predicted boxes: it needs output='filtered'")
    b = batch_size(params)
    inputs = _inputs(split, params, options, compact, distortion, spec, clutter_slots)
    frames, extra, distortion = inputs.frames, inputs.extra, inputs.distortion
    per_lane_boxes = options.output == "filtered" or extra is not None
    cap0 = options.capacity or default_capacity(frames, params, options)
    per_slot = ["ids"] + (["boxes"] if per_lane_boxes else []) + (["src3", "own3"] if detail else []) \
        + (["box3"] if detail and options.output == "filtered" else [])
    outputs = _Outputs(b, cap0, per_slot, {"boxes", "box3"} & set(per_slot) if rows_only else set())
    todo = np.arange(b)
    cap = cap0
    keys = None if extra is not None else merge_keys(params)
    objs: dict = {}
    while todo.size:
        for lanes, key in calls_by_key(todo, lanes_per_call, keys):
            hook = None if extra is None else FrameHook(distort.FrameDistortion(extra[0]), _take(distortion, lanes),
                                                        extra[1:])
            if key is not None and key not in objs:
                objs[key] = split_objects(_take(params, lanes[:1]), frames, options)
            out = run_batch(_take(params, lanes), frames, options, cap, hook=hook, detail=detail,
                            small_frames_min=small_frames_min, objs=None if key is None else objs[key],
                            rows_only=bool(outputs.packed))
            outputs.put(lanes, out, cap)
            if progress is not None and cap == cap0:
                progress(len(lanes))
        todo = todo[outputs.overflow[todo] > 0]
        cap = capacity.grown(cap) if todo.size and grow else None
        if cap is None:
            break
    return outputs.result(inputs, options, per_lane_boxes)


class _Inputs(namedtuple("_Inputs", "frames full_frames packed distortion extra")):
    """What ``track`` runs on: ``frames`` (prepared; compacted, or padded for a distortion's clutter),
    ``full_frames`` (the split's own, the output's layout), ``packed`` (a compaction's (frames,
    order2, order3), or None), ``distortion`` ([B] leaves, or None) and ``extra`` (the distortion
    hook's (spec, gid2, gid3), or None)."""

    __slots__ = ()


def _inputs(split: Split | Frames, params: Params, options: Options, compact: bool,
            distortion: distort.DistortParams | None, spec: distort.DistortSpec | None, clutter_slots: int) -> _Inputs:
    """The frames ``track`` runs the lanes on (checked to fit ``MAX_OBJECTS``), and its distortion."""
    frames = prepare_frames(split, options) if isinstance(split, Split) else split
    b = batch_size(params)
    packed = None
    if compact and isinstance(split, Split) and distortion is None and options.assign != "hungarian":
        packed = _compacted(split, frames, params, options)
    full_frames = frames
    if packed is not None:
        frames = packed[0]
    extra = None
    if distortion is not None:
        if not isinstance(split, Split):
            raise ValueError("track(distortion=...) needs the Split, not prepared Frames")
        nd = batch_size(distortion)
        if nd not in (1, b):
            raise ValueError(f"distortion has {nd} lanes, params {b}")
        distortion = distort.DistortParams(*(np.broadcast_to(np.asarray(v), (b,)) for v in distortion))
        frames, extra = prepare_distortion(split, frames, options, distortion, spec, clutter_slots)
    n_objects = object_slots(options, frames.valid2[:1], frames.valid3[:1]).shape[1]
    if n_objects > MAX_OBJECTS:
        raise ValueError(f"a frame holds up to {frames.box2.shape[1]} 2D and {frames.box3.shape[1]} 3D detection slots "
                         f"({n_objects} objects with modality {options.modality!r}, clutter slots included): at most "
                         f"{MAX_OBJECTS} objects per frame are supported")
    return _Inputs(frames, full_frames, packed, distortion, extra)


class _Outputs:
    """A batch's outputs gathered over its compiled calls: per-slot arrays (``names`` of
    ``trackers.dfr.run.BatchOutput``) and per-lane counts; a lane re-run with more track slots overwrites
    its first run. ``packed``: the names kept as rows only (``run_batch(rows_only=True)``' values,
    held per lane until :meth:`result` joins them into a :class:`~dfrmot_jax.rows.Rows`)."""

    FILL = {"ids": -1, "src3": -1}

    def __init__(self, b: int, cap0: int, names: list[str], packed=frozenset()):
        self.b, self.names, self.packed = b, names, frozenset(packed)
        self.got: dict[str, np.ndarray] = {}
        self.lane_rows: dict[str, list] = {name: [None] * b for name in self.packed}
        self.dropped: np.ndarray | None = None
        self.overflow = np.zeros(b, np.int64)
        self.peak = np.zeros(b, np.int64)
        self.capacity = np.full(b, cap0, np.int64)

    def put(self, lanes: np.ndarray, out: BatchOutput, cap: int) -> None:
        """The output of one call on ``lanes`` with ``cap`` track slots."""
        b, got = self.b, self.got
        if self.dropped is None:
            self.dropped = np.empty((b,) + out.dropped.shape[1:], np.int32)
        # contiguous lanes (every first pass) are written through a slice: no fancy-index copy
        at = slice(lanes[0], lanes[-1] + 1) if lanes[-1] - lanes[0] + 1 == lanes.size else lanes
        if self.packed:         # each lane's rows: a re-run lane's replace its first run's
            per_lane = np.cumsum((out.ids >= 0).sum(axis=(1, 2), dtype=np.int64))[:-1]
            for name in self.packed:
                for lane, part in zip(lanes, np.split(getattr(out, name), per_lane)):
                    self.lane_rows[name][lane] = part
        for name in self.names:
            if name in self.packed:
                continue
            v = getattr(out, name)
            fill = self.FILL.get(name, 0)
            if name not in got and lanes.size == b:
                got[name] = v                     # the whole batch in one call: run_batch's own arrays
                continue
            if name not in got:
                got[name] = np.empty((b,) + v.shape[1:], v.dtype)
            # a lane re-run with more track slots ("filtered": slots are tracks) widens axis 2
            got[name] = widen(got[name], v.shape[2], fill)
            k = v.shape[2]
            got[name][at, :, :k] = v
            if got[name].shape[2] > k:
                got[name][at, :, k:] = fill
        self.dropped[lanes] = out.dropped; self.overflow[lanes] = out.overflow; self.peak[lanes] = out.peak
        self.capacity[lanes] = cap

    def result(self, inputs: _Inputs, options: Options, per_lane_boxes: bool) -> TrackResult:
        """The ``TrackResult`` (in the split's own slot layout), with a warning if a lane overflowed."""
        overflow, capacity = self.overflow, self.capacity
        if np.any(overflow > 0):
            bad = np.flatnonzero(overflow > 0)
            warnings.warn(f"track memory overflow in {bad.size} lane(s) (e.g. lane {bad[0]}: {overflow[bad[0]]} births "
                          f"dropped at capacity {capacity[bad[0]]}); raise Options.capacity", RuntimeWarning,
                          stacklevel=3)
        got, frames = self.got, inputs.frames
        if inputs.packed is not None:
            got = _full_layout(got, inputs.packed[1], inputs.packed[2], inputs.full_frames, options)
            frames = inputs.full_frames
        if self.packed:
            if inputs.packed is not None and options.output == "detections":
                raise RuntimeError("rows kept alone cannot follow the compaction's slot moves")
            got = dict(got)
            start = row_starts(got["ids"])       # (one for the boxes and the 3D detail: the same rows)
            for name in self.packed:
                got[name] = Rows(np.concatenate(self.lane_rows[name]), start, got["ids"].shape[1])
        boxes = got["boxes"] if per_lane_boxes else output_boxes(frames, options)
        lanes = None
        if inputs.extra is not None:
            spec, gid2, gid3 = inputs.extra
            lanes = distort.LaneDistortion(inputs.distortion, spec, frames, gid2, gid3)
        return TrackResult(ids=got["ids"], boxes=boxes, dropped=self.dropped, overflow=overflow, peak=self.peak,
                           src3=got.get("src3"), own3=got.get("own3"), box3=got.get("box3"), capacity=capacity,
                           frames=frames, options=options, distortion=lanes)


def _compacted(split: Split, frames: Frames, params: Params, options: Options):
    """(frames of the split compacted to the lanes' loosest thresholds, order2, order3), or None
    when that saves no slot (:func:`dfrmot_jax.trackers.dfr.frames.compact_frames`; ``frames``: the split's own)."""
    s2, s3 = (float(np.min(s)) for s in keep_thresholds(params))
    packed, order2, order3 = compact_frames(split, frames, options, s2, s3)
    if order2.shape[1] + order3.shape[1] >= split.valid2d.shape[1] + split.valid3d.shape[1]:
        return None
    return packed, order2, order3


def _full_layout(got: dict, order2: np.ndarray, order3: np.ndarray, frames: Frames, options: Options) -> dict:
    """Outputs of a compacted split (``got``: ids, src3, own3 [B, T, K'], ...) in the layout of the
    split's own ``frames``: object slots moved back to their original slots (output "detections";
    slots no lane keeps hold nothing), 3D sources renumbered to the original [T, M3] index."""
    out = dict(got)
    T, m3c = order3.shape
    m2, m3 = frames.valid2.shape[1], frames.valid3.shape[1]
    if "src3" in out:
        src = out["src3"]
        t, j = np.divmod(np.maximum(src, 0), m3c)
        out["src3"] = np.where(src >= 0, t * m3 + order3[t, j], -1).astype(src.dtype)
    if options.output == "detections":
        # [T, K'] the original object slot of each (fused: the 2D slots, then the 3D slots)
        omap = object_slots(options, order2, order3 + (m2 if options.modality == "fused" else 0))
        k = object_slots(options, frames.valid2[:1], frames.valid3[:1]).shape[1]
        rows = np.arange(T)[:, None]
        for name, fill in (("ids", -1), ("src3", -1), ("own3", False)):
            if name in out:
                a = out[name]
                full = np.full(a.shape[:2] + (k,) + a.shape[3:], fill, a.dtype)
                full[:, rows, omap] = a
                out[name] = full
    return out


#: a batch's lanes share objects made once outside the scan (``trackers.dfr.run.split_objects``) when its
#: distinct settings of ``trackers.dfr.config.OBJECT_PARAMS`` have this many lanes each on average (or there
#: is one): fewer lanes per setting would mean many small compiled calls
SHARED_OBJECTS_MIN_LANES = 8


def merge_keys(params: Params) -> np.ndarray | None:
    """[B] ids of the lanes' distinct ``trackers.dfr.config.OBJECT_PARAMS`` (score_2d, score_3d, merge_iou, weak_2d,
    weak_3d), the settings a frame's objects depend on (``trackers.dfr.step.objects``), or None when objects are better made in the scan
    (too few lanes per setting, ``SHARED_OBJECTS_MIN_LANES``)."""
    b = batch_size(params)
    triple = np.stack([np.broadcast_to(np.asarray(v, np.float64), (b,))
                       for v in (getattr(params, name) for name in OBJECT_PARAMS)], axis=1)
    _, first, inv = np.unique(triple, axis=0, return_index=True, return_inverse=True)
    n = len(first)
    if n > 1 and b < SHARED_OBJECTS_MIN_LANES * n:
        return None
    return first[inv.reshape(-1)]            # the first lane of each setting names it


