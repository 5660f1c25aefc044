"""The tracker over a split: ``run`` scans ``step`` over the frames of one lane; ``run_batch`` vmaps
it over a ``Params`` batch ``[B]`` and shards the batch over the host's devices, one compilation
per static setting (``Options``, capacity, devices, hook, detail).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..config import Options, Params
from .devices import setup_host_devices
from .step import Frames, init, step


class FrameHook(NamedTuple):
    """A per-frame input transform applied inside the scan before each step (e.g. a distortion).

    fn(frame, lane, x, t) -> frame: static and hashable (it is part of the compilation key);
    lane: this lane's own values (a pytree, batched [B] in ``run_batch`` like the params);
    xs: per-frame values shared by every lane (a pytree with leading axis T).
    """

    fn: Any
    lane: Any = None
    xs: Any = None


def run(params: Params, frames: Frames, options: Options, capacity: int, hook: FrameHook | None = None,
        detail: bool = False):
    """One lane over all frames: (final Memory, StepOutput stacked [T, ...]).

    hook: each frame is first transformed by ``hook.fn``; the written boxes are then the lane's own
    (``StepOutput.boxes`` [K, 4]), else [K, 0] (output "detections": the data's, ``data.object_boxes``).
    detail: see ``step``.
    """
    t = jnp.arange(frames.reset.shape[0], dtype=jnp.int32)
    xs = None if hook is None else hook.xs

    def body(m, inputs):
        frame, x, ti = inputs
        if hook is not None:
            frame = hook.fn(frame, hook.lane, x, ti)
        m, out = step(params, m, frame, options, detail=detail, t=ti)
        if hook is None and options.output == "detections":
            out = out._replace(boxes=out.boxes[:, :0])    # the data's boxes: not computed per lane
        return m, out

    return jax.lax.scan(body, init(options, capacity, params), (frames, xs, t))


class BatchOutput(NamedTuple):
    """ids [B, T, K] int32; boxes [B, T, K, 4] float32 (a lane's own boxes) or [B, T, K, 0];
    dropped [B, T] int32; overflow [B] int32 (births dropped in total); peak [B] int32 (most live
    tracks); with ``detail``: src3 [B, T, K] int32, own3 [B, T, K] bool, box3 [B, T, K, 6] float32
    (output "filtered"), else their K axis is empty."""

    ids: np.ndarray
    boxes: np.ndarray
    dropped: np.ndarray
    overflow: np.ndarray
    peak: np.ndarray
    src3: np.ndarray
    own3: np.ndarray
    box3: np.ndarray


_PROGRAMS: dict[tuple, Any] = {}


def compiled(options: Options, capacity: int, n_devices: int, hook_fn=None, detail: bool = False):
    """The jitted batch program of one static setting, built once and kept (``_PROGRAMS``).

    Called with (params [B], frames, hook lanes [B] or None, hook xs or None).
    """
    key = (options, capacity, n_devices, hook_fn, detail)
    if key not in _PROGRAMS:
        _PROGRAMS[key] = _build(*key)
    return _PROGRAMS[key]


def compilations() -> int:
    """XLA compilations of the batch programs so far (a program not yet called counts once):
    ``testing.recompile.no_recompile`` guards against this growing."""
    return sum(max(1, fn._cache_size()) for fn in _PROGRAMS.values())


def _build(options: Options, capacity: int, n_devices: int, hook_fn, detail: bool):
    def lane(params, frames, hook_lane, hook_xs):
        hook = None if hook_fn is None else FrameHook(hook_fn, hook_lane, hook_xs)
        mem, out = run(params, frames, options, capacity, hook, detail)
        return out, mem.overflow, mem.peak

    batched = jax.vmap(lane, in_axes=(0, None, 0, None))
    if n_devices == 1:
        return jax.jit(batched)
    from jax.sharding import Mesh, PartitionSpec as P

    mesh = Mesh(np.array(jax.devices()[:n_devices]), ("b",))
    sharded = jax.shard_map(batched, mesh=mesh, in_specs=(P("b"), P(), P("b"), P()), out_specs=P("b"),
                            check_vma=False)
    return jax.jit(sharded)


def device_count() -> int:
    """Devices a batch is split over (the first call asks JAX for one per core: ``core.devices``)."""
    return setup_host_devices()


def _lanes(tree, b: int, pad: int, float_dtype):
    """Leaves broadcast to [b] and padded with copies of the last lane to b + pad: integers as int32,
    floats as ``float_dtype`` (float64 ``Params`` need the caller's ``jax.enable_x64`` scope)."""
    out = []
    for v in tree:
        v = np.broadcast_to(np.atleast_1d(np.asarray(v)), (b,))
        v = np.concatenate([v, np.repeat(v[-1:], pad)])
        out.append(jnp.asarray(v, jnp.int32 if v.dtype.kind in "iub" else float_dtype))
    return type(tree)(*out)


def run_batch(params: Params, frames: Frames, options: Options, capacity: int, n_devices: int | None = None,
              hook: FrameHook | None = None, detail: bool = False) -> BatchOutput:
    """All lanes of a ``Params`` batch [B] over the split; the batch is split over ``n_devices``.

    hook: a ``FrameHook`` whose ``lane`` leaves are [B] (float leaves as float32) and ``xs`` leaves
    [T, ...]; detail: also the rows' 3D detections (``StepOutput.src3``; for result files).
    Returns BatchOutput (numpy). Lanes are padded to a multiple of the device count and trimmed.
    """
    b = max(np.atleast_1d(np.asarray(v)).shape[0] for v in params)
    n_dev = device_count() if n_devices is None else n_devices
    n_dev = max(1, min(n_dev, b))
    pad = (-b) % n_dev
    with jax.enable_x64(True):
        p = _lanes(params, b, pad, jnp.float64)
        if hook is None:
            fn, lanes, xs = None, jnp.zeros(b + pad, jnp.int32), None
        else:
            fn, lanes, xs = hook.fn, _lanes(hook.lane, b, pad, jnp.float32), jax.tree.map(jnp.asarray, hook.xs)
        program = compiled(options, capacity, n_dev, fn, detail)
        out, overflow, peak = program(p, Frames(*(jnp.asarray(x) for x in frames)), lanes, xs)
    out = jax.tree.map(lambda x: np.asarray(x)[:b], out)
    return BatchOutput(out.ids, out.boxes, out.dropped, np.asarray(overflow)[:b], np.asarray(peak)[:b],
                       out.src3, out.own3, out.box3)
