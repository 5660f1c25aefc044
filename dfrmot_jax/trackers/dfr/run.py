"""The tracker over a split: ``run`` scans ``step`` over the frames of one lane; ``run_batch`` vmaps
it over a ``Params`` batch ``[B]`` and shards the batch over the host's devices, one compilation
per static setting (``Options``, capacity, devices, hook, detail, small-frame sizes).

Small frames: most frames hold few detections, but every step pays for the [objects, tracks]
work of the largest frame. Frames whose valid detections all sit in the first ``m2`` 2D and ``m3``
3D slots of one of up to three sizes (a per-frame size index, the same for every lane) run a copy
of the step on those slots only (``lax.switch`` on an unbatched index keeps its branches under
``vmap``); its output slots are padded back to the full layout. The result is the same: the slots left out hold no valid
detection, and every order (greedy ties, births) follows the slot order, which is kept.
"""

from __future__ import annotations

import contextlib
import functools
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh
from jax.sharding import PartitionSpec as P

from .config import Options, Params
from ...devices import batch_devices, call_compiled, chosen_platform, platform_of
from ...frames import Frames
from .step import Objects, init, objects, step


class FrameHook(NamedTuple):
    """A per-frame input transform applied inside the scan before each step (e.g. a distortion).

    fn(frame, lane, x, t) -> frame: static and hashable (it is part of the compilation key);
    lane: this lane's own values (a pytree, batched [B] in ``run_batch`` like the params);
    xs: per-frame values shared by every lane (a pytree with leading axis T).
    """
    fn: Any
    lane: Any = None
    xs: Any = None


#: run frames with few detections on a smaller copy of the step (``small_frames``) on splits of at
#: least this many frames (each smaller copy of the step costs its compilation); the default of
#: ``run_batch(small_frames_min=...)`` and ``track(small_frames_min=...)``, where None turns it off
SMALL_FRAMES_MIN_T = 2000


#: the most smaller copies of the step (``small_frames``): each costs its compilation (~0.9 s on a
#: 2-core CPU); calls of fewer than ``WIDE_CALL_LANES`` lanes take at most two (KITTI car, B = 1: the
#: third size bought 2-3 % for 1.2 s more compilation; B = 64: 4-10 %)
MAX_SMALL_SIZES = 3
WIDE_CALL_LANES = 8


def small_frames(frames: Frames, options: Options, min_frames: int | None = SMALL_FRAMES_MIN_T,
                 max_sizes: int = MAX_SMALL_SIZES):
    """(sizes, bucket [T] int32) for the small-frame steps, or None when they would not pay (fewer
    than ``min_frames`` frames (None: never), or less than 15 % fewer slots per step).

    ``sizes``: one or more (m2, m3), each slot count smaller than the last's in at least one of its
    two, at most ``max_sizes``; ``bucket[t]``: the first size whose first m2 2D / m3 3D slots hold all
    of frame t's valid detections, ``len(sizes)`` for none (the full step). The sizes minimise the
    expected slots per step (from the frames' last valid slots; a further size must buy another 10 %);
    they depend on the data only (``valid2``, ``valid3``), so every batch on the same frames shares
    one compilation. Not with the Hungarian assignment (its choice among equal optima depends on
    the matrix size). With ``detail`` too: the 3D sources keep the full layout's flat index
    (``step``'s ``stride3``) and a small frame's rows are padded back like its ids.
    """
    v2, v3 = np.asarray(frames.valid2), np.asarray(frames.valid3)
    if min_frames is None or options.assign == "hungarian" or v2.shape[0] < min_frames:
        return None
    big2, big3 = v2.shape[1], v3.shape[1]

    def last(v):
        return np.where(v.any(axis=1), v.shape[1] - np.argmax(v[:, ::-1], axis=1), 0)

    l2, l3 = last(v2), last(v3)
    full = big2 + big3
    # cov[s]: the share of frames whose detections sit in the first a2[s] 2D and a3[s] 3D slots
    hist = np.zeros((big2 + 1, big3 + 1))
    np.add.at(hist, (l2, l3), 1.0 / l2.size)
    # candidate counts: every count up to 24 slots, else the frames' 5 % quantiles (at most 21 x 21 sizes)
    c2, c3 = ((np.arange(1, big + 1) if big <= 24 else
               np.unique(np.clip(np.ceil(np.percentile(last_, np.arange(0, 101, 5))), 1, big).astype(int)))
              for big, last_ in ((big2, l2), (big3, l3)))
    a2, a3 = (g.ravel() for g in np.meshgrid(c2, c3, indexing="ij"))
    ok = (a2 < big2) | (a3 < big3)
    a2, a3 = a2[ok], a3[ok]
    if a2.size == 0:            # one slot of each kind: nothing smaller
        return None
    cov = hist.cumsum(0).cumsum(1)[a2, a3]
    slots = (a2 + a3).astype(np.float64)
    # cost[k][s]: the least expected slots of the frames in sizes 0..s's share with k + 1 nested sizes,
    # the last s (each size holds the frames the one before it does not: larger in a count, none smaller)
    inside = (a2[:, None] <= a2[None, :]) & (a3[:, None] <= a3[None, :]) & (cov[:, None] < cov[None, :])
    cost, back = [cov * slots], []
    for _ in range(1, max_sizes):
        via = np.where(inside, cost[-1][:, None] + (cov[None, :] - cov[:, None]) * slots[None, :], np.inf)
        back.append(np.argmin(via, axis=0))
        cost.append(via[back[-1], np.arange(cov.size)])
    sizes, best = None, float(full)
    for k, c in enumerate(cost):          # each further size (one compilation more) must buy 10 %
        total = c + (1 - cov) * full
        s = int(np.argmin(total))
        if total[s] < (0.85 if k == 0 else 0.9) * best:
            chain = [s]
            for b in reversed(back[:k]):
                chain.append(int(b[chain[-1]]))
            sizes, best = tuple((int(a2[i]), int(a3[i])) for i in reversed(chain)), float(total[s])
        else:
            break
    if sizes is None:         # a second program must buy at least 15 %
        return None
    bucket = np.full(l2.shape, len(sizes), np.int32)
    for k in reversed(range(len(sizes))):
        bucket[(l2 <= sizes[k][0]) & (l3 <= sizes[k][1])] = k
    return sizes, bucket


def _slots(frame: Frames, m2: int, m3: int) -> Frames:
    """The frame's first m2 2D and m3 3D detection slots."""
    return Frames(frame.reset, frame.box2[:m2], frame.score2[:m2], frame.valid2[:m2], frame.box3[:m3],
                  frame.score3[:m3], frame.valid3[:m3], frame.lo3[:m3], frame.hi3[:m3])


def _object_slots(objs: Objects | None, options: Options, m2: int, m3: int, big2: int) -> Objects | None:
    """The objects of a frame's first m2 2D and m3 3D slots (the objects ``step`` makes of ``_slots``)."""
    if objs is None:
        return None
    if options.modality == "2d":
        return Objects(*(x[:m2] for x in objs))
    if options.modality == "3d":
        return Objects(*(x[:m3] for x in objs))
    return Objects(*(jnp.concatenate([x[:m2], x[big2:big2 + m3]]) for x in objs))


def split_objects(params: Params, frames: Frames, options: Options) -> Objects:
    """The :class:`~dfrmot_jax.trackers.dfr.step.Objects` of every frame ([T, O, ...]) for one setting of
    ``trackers.dfr.config.OBJECT_PARAMS`` (``params``: scalars or [1] leaves; the other fields
    are not read), made in one vmapped call outside the scan, once for every lane that shares them."""
    fn = _OBJECT_PROGRAMS.get(options)
    if fn is None:
        fn = _OBJECT_PROGRAMS[options] = jax.jit(jax.vmap(lambda p, f: objects(p, f, options), in_axes=(None, 0)))
    with jax.enable_x64(True):
        p = Params(*(v[0] for v in _lanes(params, 1, 0, jnp.float64)))      # the step's dtypes, as scalars
        f = Frames(*(jnp.asarray(x) for x in frames))
        return call_compiled(lambda: fn(p, f))


_OBJECT_PROGRAMS: dict = {}


def _padded(out, options: Options, m2: int, m3: int, big2: int, big3: int):
    """A small frame's output in the full object-slot layout (output "detections"; the padding is
    what an empty slot writes: no id, no 3D source)."""
    if options.output != "detections":
        return out

    def pad(x, fill):
        if x.shape[0] == 0:
            return x
        gap = lambda n: jnp.full((n,) + x.shape[1:], fill, x.dtype)   # noqa: E731
        if options.modality == "2d":
            return jnp.concatenate([x, gap(big2 - m2)])
        if options.modality == "3d":
            return jnp.concatenate([x, gap(big3 - m3)])
        return jnp.concatenate([x[:m2], gap(big2 - m2), x[m2:], gap(big3 - m3)])

    return out._replace(ids=pad(out.ids, -1), boxes=pad(out.boxes, 0), src3=pad(out.src3, -1),
                        own3=pad(out.own3, False))


def run(params: Params, frames: Frames, options: Options, capacity: int, hook: FrameHook | None = None,
        detail: bool = False, small=None, small_bucket=None, objs: Objects | None = None):
    """One lane over all frames: (final Memory, StepOutput stacked [T, ...]).

    hook: each frame is first transformed by ``hook.fn``; the written boxes are then the lane's own
    (``StepOutput.boxes`` [K, 4]), else [K, 0] (output "detections": the data's, ``trackers.dfr.frames.object_boxes``).
    detail: see ``step``. small: the sizes ((m2, m3), ...) static and small_bucket [T] int32
    (``small_frames``; not with a hook): frame t runs on its first m2 / m3 detection slots of size
    ``small_bucket[t]``, or on all of them where that is ``len(small)``.
    """
    t = jnp.arange(frames.reset.shape[0], dtype=jnp.int32)
    xs = None if hook is None else hook.xs
    big2, big3 = frames.valid2.shape[1], frames.valid3.shape[1]

    def one(m, frame, ti, obj):
        m, out = step(params, m, frame, options, detail=detail, t=ti, stride3=big3, objs=obj)
        if hook is None and options.output == "detections":
            out = out._replace(boxes=out.boxes[:, :0])    # the data's boxes: not computed per lane
        return m, out

    def body(m, inputs):
        frame, x, ti, bucket, obj = inputs
        if hook is not None:
            frame = hook.fn(frame, hook.lane, x, ti)
        if small is None:
            return one(m, frame, ti, obj)

        def on_first_slots(mm, m2, m3):
            mm, out = one(mm, _slots(frame, m2, m3), ti, _object_slots(obj, options, m2, m3, big2))
            return mm, _padded(out, options, m2, m3, big2, big3)

        branches = [functools.partial(on_first_slots, m2=m2, m3=m3) for m2, m3 in small]
        return jax.lax.switch(bucket, branches + [lambda mm: one(mm, frame, ti, obj)], m)

    return jax.lax.scan(body, init(options, capacity, params), (frames, xs, t, small_bucket, objs))


class BatchOutput(NamedTuple):
    """ids [B, T, K] int32; boxes [B, T, K, 4] float32 (a lane's own boxes) or [B, T, K, 0];
    dropped [B, T] int32; overflow [B] int32 (births dropped in total); peak [B] int32 (most live
    tracks); with ``detail``: src3 [B, T, K] int32, own3 [B, T, K] bool, box3 [B, T, K, 6] float32
    (output "filtered"), else their K axis is empty. ``run_batch(rows_only=True)``: boxes (a lane's
    own) and box3 are their rows' values, [R, 4] and [R, 6] (ids >= 0, in (lane, frame, slot) order)."""
    ids: np.ndarray
    boxes: np.ndarray
    dropped: np.ndarray
    overflow: np.ndarray
    peak: np.ndarray
    src3: np.ndarray
    own3: np.ndarray
    box3: np.ndarray


_PROGRAMS: dict[tuple, Any] = {}


def compiled(options: Options, capacity: int, n_devices: int, hook_fn=None, detail: bool = False, small=None,
             shared_objects: bool = False, platform: str = "cpu"):
    """The jitted batch program of one static setting, built once and kept (``_PROGRAMS``): keyed on
    every argument (the program is built from nothing else; the devices are the process's first
    ``n_devices`` of ``platform``, fixed once JAX runs), while shapes and dtypes of the inputs select among its
    traces in ``jax.jit``'s own cache.

    Called with (params [B], frames, hook lanes [B] or None, hook xs or None, small-frame size index [T]
    or None, the lanes' shared objects [T, O, ...] or None (``shared_objects``)).
    """
    key = (options, capacity, n_devices, hook_fn, detail, small, shared_objects, platform)
    if key not in _PROGRAMS:
        _PROGRAMS[key] = _build(*key)
    return _PROGRAMS[key]


def clear_programs() -> None:
    """Forget every compiled batch program and object program, and JAX's own caches: their memory
    is given back, at the cost of compiling again. Each compiled program holds memory mappings of
    its own; a process that compiles hundreds of static settings (a test suite) would otherwise
    reach the kernel's limit on them (``vm.max_map_count``, 65,530 by default) and crash."""
    _PROGRAMS.clear()
    _OBJECT_PROGRAMS.clear()
    jax.clear_caches()


def compilations() -> int:
    """XLA compilations of the batch programs so far (a program not yet called counts once):
    ``testing.recompile.no_recompile`` guards against this growing."""
    return sum(max(1, fn._cache_size()) for fn in _PROGRAMS.values())


def _build(options: Options, capacity: int, n_devices: int, hook_fn, detail: bool, small, shared_objects: bool,
           platform: str):
    def lane(params, frames, hook_lane, hook_xs, bucket, objs):
        hook = None if hook_fn is None else FrameHook(hook_fn, hook_lane, hook_xs)
        mem, out = run(params, frames, options, capacity, hook, detail, small, bucket, objs)
        return out, mem.overflow, mem.peak

    batched = jax.vmap(lane, in_axes=(0, None, 0, None, None, None))
    if n_devices == 1:
        return jax.jit(batched)

    mesh = Mesh(np.array(batch_devices(platform)[:n_devices]), ("b",))
    sharded = jax.shard_map(batched, mesh=mesh, in_specs=(P("b"), P(), P("b"), P(), P(), P()), out_specs=P("b"),
                            check_vma=False)
    return jax.jit(sharded)


def _lanes(tree, b: int, pad: int, float_dtype):
    """Leaves broadcast to [b] and padded with copies of the last lane to b + pad: integers as int32,
    floats as ``float_dtype`` (float64 ``Params`` need the caller's ``jax.enable_x64`` scope); made on
    the host and placed in one transfer."""
    out = []
    for v in tree:
        v = np.broadcast_to(np.atleast_1d(np.asarray(v)), (b,))
        v = np.concatenate([v, np.repeat(v[-1:], pad)])
        out.append(v.astype(np.int32 if v.dtype.kind in "iub" else np.dtype(float_dtype)))
    return type(tree)(*jax.device_put(out))


def _shards(x: jax.Array, b: int):
    """(first lane, its lanes' data as NumPy, a view where the platform allows) of each device's shard
    of a program output, in lane order, cut to the first b lanes."""
    for shard in sorted(x.addressable_shards, key=lambda s: (s.index[0].start or 0) if s.index else 0):
        start = (shard.index[0].start or 0) if shard.index else 0
        if start < b:
            data = np.asarray(shard.data)
            yield start, data[:min(b - start, data.shape[0])]


def _to_host(x: jax.Array, b: int) -> np.ndarray:
    """The first b lanes of a program output as a NumPy array of its own (writeable): each device's
    shard copied once into place (``np.asarray`` of a sharded array assembles a read-only copy)."""
    out = np.empty((b,) + x.shape[1:], x.dtype)
    for start, data in _shards(x, b):
        out[start:start + len(data)] = data
    return out


def _rows_to_host(x: jax.Array, ids: np.ndarray) -> np.ndarray:
    """[R, ...] the values of a program output [B', T, K, ...] at the rows ``ids [B, T, K] >= 0`` of
    its first B lanes, in (lane, frame, slot) order, read from each device's shard without a dense
    host copy."""
    parts = [data[ids[start:start + len(data)] >= 0] for start, data in _shards(x, ids.shape[0])]
    return np.concatenate(parts) if parts else np.zeros((0,) + x.shape[3:], x.dtype)


def run_batch(params: Params, frames: Frames, options: Options, capacity: int, n_devices: int | None = None,
              hook: FrameHook | None = None, detail: bool = False,
              small_frames_min: int | None = SMALL_FRAMES_MIN_T, objs: Objects | None = None,
              rows_only: bool = False) -> BatchOutput:
    """All lanes of a ``Params`` batch [B] over the split; the batch is split over ``n_devices``.

    hook: a ``FrameHook`` whose ``lane`` leaves are [B] (float leaves as float32) and ``xs`` leaves
    [T, ...]; detail: also the rows' 3D detections (``StepOutput.src3``; for result files).
    small_frames_min: run frames with few detections on smaller copies of the step on splits of at
    least this many frames (``small_frames``: up to :data:`MAX_SMALL_SIZES` sizes, two for calls of
    fewer than :data:`WIDE_CALL_LANES` lanes; None: one size; the results are the same).
    objs: every lane's objects, made once outside the scan (``split_objects``; the lanes must share
    ``trackers.dfr.config.OBJECT_PARAMS``; not with a hook); None: each step makes them.
    rows_only: a lane's own boxes and ``box3`` come back as their rows' values only, [R, 4] and
    [R, 6] at ``ids >= 0`` in (lane, frame, slot) order (read from the device without a dense copy).
    Returns BatchOutput (numpy). Lanes are padded to a multiple of the device count and trimmed.
    The platform is ``devices.chosen_platform()`` (``$DFRMOT_DEVICE``): its devices run the batch.
    """
    b = max(np.atleast_1d(np.asarray(v)).shape[0] for v in params)
    platform = chosen_platform()
    devices = batch_devices(platform)
    # a platform other than JAX's default (the CPU where JAX defaults to a GPU): one of its devices,
    # the inputs placed there (JAX_PLATFORMS=cpu gives the CPU all its cores)
    elsewhere = platform != platform_of(jax.default_backend())
    n_dev = 1 if elsewhere else len(devices) if n_devices is None else n_devices
    n_dev = max(1, min(n_dev, b))
    pad = (-b) % n_dev
    place = jax.default_device(devices[0]) if elsewhere else contextlib.nullcontext()
    if objs is not None and elsewhere:
        objs = jax.device_put(objs, devices[0])
    with jax.enable_x64(True), place:
        p = _lanes(params, b, pad, jnp.float64)
        small = bucket = None
        if hook is None:
            fn, lanes, xs = None, jnp.zeros(b + pad, jnp.int32), None
            found = small_frames(frames, options, small_frames_min,
                                 MAX_SMALL_SIZES if b >= WIDE_CALL_LANES else min(2, MAX_SMALL_SIZES))
            if found is not None:
                small, bucket = found[0], jnp.asarray(found[1])
        else:
            fn, lanes, xs = hook.fn, _lanes(hook.lane, b, pad, jnp.float32), jax.tree.map(jnp.asarray, hook.xs)
        if objs is not None and hook is not None:
            raise ValueError("objects made outside the scan cannot follow a frame hook")
        program = compiled(options, capacity, n_dev, fn, detail, small, objs is not None, platform)
        f = Frames(*jax.device_put(tuple(np.asarray(x) for x in frames)))
        out, overflow, peak = call_compiled(lambda: program(p, f, lanes, xs, bucket, objs))
    ids = _to_host(out.ids, b)
    packed = {"boxes", "box3"} if rows_only else set()
    out = out._replace(**{f: (_rows_to_host(v, ids) if f in packed and v.shape[2] else ids if f == "ids" else _to_host(v, b))
                          for f, v in zip(out._fields, out)})
    return BatchOutput(out.ids, out.boxes, out.dropped, np.asarray(overflow)[:b], np.asarray(peak)[:b],
                       out.src3, out.own3, out.box3)
