"""The DFR-FastMOT tracker as pure functions: ``init``, ``step``, ``run`` (lax.scan), batched ``run_batch``.

``step(params, mem, frame) -> (mem, out)`` processes one frame for one parameter setting; ``run``
scans it over all frames of a packed split; ``run_batch`` vmaps ``run`` over a ``Params`` batch
``[B]`` and shards the batch over the host's devices. ``Options`` are static.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from . import associate, distort, kalman, memory
from .data import Frames
from .memory import Memory
from .params import Options, Params


class StepOutput(NamedTuple):
    """One frame's output of one lane.

    ids [K] int32: track id written in each output slot, -1 = nothing written. With output
    "detections" the slots are the frame's objects (2D detection slots, then 3D detection slots:
    boxes come from the data, ``data.object_boxes``, unless the lane distorts them); with
    "filtered" they are the N track slots.
    boxes [K, 4] float32 (output "filtered", or "detections" with a distortion) or [0].
    dropped [] int32 births lost for want of a track slot in this frame.
    With ``detail`` (result files), else [0]: src3 [K] int32 the 3D detection whose values a row
    carries, as a global index ``t * M3 + slot`` into the split's [T, M3] arrays (-1 none): the
    object's own, or for a 2D-only object the last one its track took (the C++'s stale 3D box);
    own3 [K] bool it is the object's own; box3 [K, 6] float32 (output "filtered") the track's
    filtered 3D corners (min, max), meaningful where src3 >= 0.
    """

    ids: jnp.ndarray
    boxes: jnp.ndarray
    dropped: jnp.ndarray
    src3: jnp.ndarray
    own3: jnp.ndarray
    box3: jnp.ndarray


def init(options: Options, capacity: int, params: Params | None = None) -> Memory:
    """Empty memory; with the steady Kalman start, its covariance is solved here once per lane."""
    mem = memory.empty(capacity, options.filter == "kalman")
    if options.filter == "kalman" and options.kalman_init == "steady":
        mem = mem._replace(cov0=kalman.steady_cov(jnp.asarray(params.kf_q, jnp.float64),
                                                  jnp.asarray(params.kf_r, jnp.float64)))
    return mem


def _f64(params: Params) -> Params:
    return Params(*(v.astype(jnp.float64) if jnp.issubdtype(v.dtype, jnp.floating) else v for v in params))


def _objects(params: Params, frame: Frames, options: Options):
    """This frame's objects: box [O, 4], z3 [O, 6] (3D min, max corners), has3d [O], valid [O],
    slot3 [O] int32 the 3D detection slot of each object (meaningful where has3d).

    Scores are compared in float32 (as parsed); boxes and corners come out in float64.
    """
    keep2 = frame.valid2 & (frame.score2 >= params.score_2d.astype(jnp.float32))
    keep3 = frame.valid3 & (frame.score3 >= params.score_3d.astype(jnp.float32))
    box2 = frame.box2.astype(jnp.float64)
    box3 = frame.box3.astype(jnp.float64)
    z3 = jnp.concatenate([frame.lo3, frame.hi3], axis=-1).astype(jnp.float64)
    slots3 = jnp.arange(keep3.shape[0], dtype=jnp.int32)
    if options.modality == "2d":
        return (box2, jnp.zeros((keep2.shape[0], 6), jnp.float64), jnp.zeros_like(keep2), keep2,
                jnp.zeros(keep2.shape, jnp.int32))
    if options.modality == "3d":
        return box3, z3, keep3, keep3, slots3
    pair = associate.greedy_max(associate.iou_matrix(box2, box3),
                                keep2[:, None] & keep3[None, :], params.merge_iou)
    paired2 = jnp.any(pair, axis=1)
    lone3 = keep3 & ~jnp.any(pair, axis=0)
    z3_of_2 = memory.gather_rows(pair.T, z3)                       # [M2, 6], zeros where unpaired
    return (jnp.concatenate([box2, box3]), jnp.concatenate([z3_of_2, z3]),
            jnp.concatenate([paired2, lone3]), jnp.concatenate([keep2, lone3]),
            jnp.concatenate([memory.gather_rows(pair.T, slots3), slots3]))


def step(params: Params, mem: Memory, frame: Frames, options: Options, emit_boxes: bool = False,
         detail: bool = False, t=0):
    """One frame: de-duplicate, associate, update memory and filters, write, age. Returns (mem, out).

    detail (static): also the 3D detection each row carries (``StepOutput.src3``); t: the frame's
    global index. Runs under ``jax.enable_x64``: arithmetic and parameters in float64, scores
    compared in float32.
    """
    kind = options.filter
    mem = memory.reset(mem, frame.reset)
    box, z3, has3, valid, slot3 = _objects(params, frame, options)
    params = _f64(params)

    # Association on the tracks' predictions.
    f = mem.filt
    iou = associate.iou_matrix(box, associate.predicted_boxes(f.p[:, :4], options.truncate))
    dist = associate.centroid_distance(z3, f.p[:, 4:])
    m_f = associate.fused_affinity(iou, mem.age <= params.epsilon, dist, has3[:, None] & mem.has3d[None, :],
                                   params.a_c, params.a_l, params.alpha_c)
    match = associate.greedy_min(-m_f, valid[:, None] & mem.alive[None, :], mem.tid, -params.a_f)
    matched_obj = jnp.any(match, axis=0)
    newborn = valid & ~jnp.any(match, axis=1)
    birth, rank, dropped = memory.births(mem.alive, newborn)
    assign = match | birth
    born = jnp.any(birth, axis=0)
    observed = matched_obj | born

    # Measurements moved into the slots; filter modes per slot.
    z = memory.gather_rows(assign, jnp.concatenate([box, z3], axis=1))        # [N, 10]
    z_has3 = memory.gather_rows(assign, has3)                                    # [N]
    had3 = mem.has3d & ~born
    start3 = z_has3 & ~had3                                                      # first 3D observation
    upd2 = matched_obj
    upd3 = matched_obj & z_has3 & had3
    pred3 = had3 & mem.alive
    is2d = jnp.arange(memory.N_COORDS) < 4
    do_update = jnp.where(is2d[None, :], upd2[:, None], upd3[:, None])
    do_init = jnp.where(is2d[None, :], born[:, None], (born | matched_obj)[:, None] & start3[:, None])
    do_predict = jnp.where(is2d[None, :], (mem.alive & ~born)[:, None], pred3[:, None])

    gains = (params.gain_alpha, params.gain_beta, params.gain_gamma)
    updated = kalman.select(do_update, kalman.update(f, z, kind, gains, params.kf_r), f)
    predicted = kalman.select(do_predict, kalman.predict(updated, kind, params.kf_q), updated)
    cov0 = mem.cov0 if kind == "kalman" and options.kalman_init == "steady" else None
    filt = kalman.select(do_init, kalman.init(z, kind, params.kf_r, params.kf_p0, cov0), predicted)

    born_id = mem.next_id + rank                                                  # [O]
    tid = jnp.where(born, memory.gather_rows(birth, born_id), mem.tid)
    hits = jnp.where(born, 1, mem.hits + matched_obj.astype(jnp.int32))
    age = jnp.where(observed, 0, mem.age)
    alive = mem.alive | born
    last3 = mem.last3
    if detail:
        z_src3 = memory.gather_rows(assign, t * frame.valid3.shape[0] + slot3)
        last3 = jnp.where(observed & z_has3, z_src3, jnp.where(born, -1, last3))
    mem = Memory(alive=alive, tid=tid, age=age, hits=hits, has3d=had3 | z_has3, filt=filt,
                 next_id=mem.next_id + jnp.sum(newborn, dtype=jnp.int32), overflow=mem.overflow + dropped,
                 peak=jnp.maximum(mem.peak, jnp.sum(alive, dtype=jnp.int32)), cov0=mem.cov0, last3=last3)
    none = jnp.zeros((0,), jnp.int32)
    src3, own3, box3 = none, none.astype(bool), none.astype(jnp.float32)

    writable = hits >= params.min_hits
    if options.output == "detections":
        obj_id = jnp.sum(jnp.where(match, tid[None, :], 0), axis=1, dtype=jnp.int32) + jnp.where(newborn, born_id, 0)
        obj_hits = (jnp.sum(jnp.where(assign, hits[None, :], 0), axis=1, dtype=jnp.int32)
                    + jnp.where(newborn & ~jnp.any(birth, 1), 1, 0))
        ids = jnp.where(valid & (obj_hits >= params.min_hits), obj_id, -1)
        if detail:
            src3 = jnp.where(jnp.any(assign, axis=1), jnp.sum(jnp.where(assign, last3[None, :], 0), axis=1), -1)
            own3 = has3 & valid
        out = StepOutput(ids, box.astype(jnp.float32) if emit_boxes else jnp.zeros((0,), jnp.float32), dropped,
                         src3, own3, box3)
    else:
        shown = jnp.where(born[:, None], z[:, :4], jnp.where(matched_obj[:, None], updated.p[:, :4], f.p[:, :4]))
        shown = associate.predicted_boxes(shown, False)  # filter corners may cross: x2 = x1 + |x2 - x1|
        ids = jnp.where(alive & writable & (age <= params.keep_lost), tid, -1)
        if detail:
            src3, own3 = last3, observed & z_has3
            box3 = jnp.where(start3[:, None], z[:, 4:], updated.p[:, 4:]).astype(jnp.float32)
        out = StepOutput(ids, shown.astype(jnp.float32), dropped, src3, own3, box3)
    return memory.end_of_frame(mem, params.epsilon), out


def run(params: Params, frames: Frames, options: Options, capacity: int, distortion=None, detail: bool = False):
    """One lane over all frames: (final Memory, StepOutput stacked [T, ...]).

    distortion: None, or (dp, spec, gid2 [T, M2], gid3 [T, M3]): each frame is first distorted by
    ``distort.distort_frame`` with this lane's ``DistortParams`` dp (static ``DistortSpec`` spec).
    detail: see ``step``.
    """
    t = jnp.arange(frames.reset.shape[0], dtype=jnp.int32)
    mem0 = init(options, capacity, params)
    if distortion is None:
        return jax.lax.scan(lambda m, xs: step(params, m, xs[0], options, detail=detail, t=xs[1]), mem0, (frames, t))
    dp, spec, gid2, gid3 = distortion

    def body(m, xs):
        fr, g2, g3, ti = xs
        return step(params, m, distort.distort_frame(fr, g2, g3, ti, dp, spec), options, emit_boxes=True,
                    detail=detail, t=ti)

    return jax.lax.scan(body, mem0, (frames, gid2, gid3, t))


class BatchOutput(NamedTuple):
    """ids [B, T, K] int32; boxes [B, T, K, 4] float32 or [B, T, 0]; dropped [B, T] int32;
    overflow [B] int32 (births dropped in total); peak [B] int32 (most live tracks);
    src3 [B, T, K], own3 [B, T, K], box3 [B, T, K, 6] with ``detail`` (else [B, T, 0])."""

    ids: np.ndarray
    boxes: np.ndarray
    dropped: np.ndarray
    overflow: np.ndarray
    peak: np.ndarray
    src3: np.ndarray
    own3: np.ndarray
    box3: np.ndarray


@functools.lru_cache(maxsize=None)
def _compiled(options: Options, capacity: int, n_devices: int, spec=None, detail: bool = False):
    def lane(params, frames, dp, gid2, gid3):
        mem, out = run(params, frames, options, capacity, None if spec is None else (dp, spec, gid2, gid3), detail)
        return out, mem.overflow, mem.peak

    batched = jax.vmap(lane, in_axes=(0, None, 0, None, None))
    if n_devices == 1:
        return jax.jit(batched)
    from jax.sharding import Mesh, PartitionSpec as P

    mesh = Mesh(np.array(jax.devices()[:n_devices]), ("b",))
    sharded = jax.shard_map(batched, mesh=mesh, in_specs=(P("b"), P(), P("b"), P(), P()), out_specs=P("b"),
                            check_vma=False)
    return jax.jit(sharded)


def device_count() -> int:
    return jax.local_device_count()


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
              distortion=None, detail: bool = False):
    """All lanes of a ``Params`` batch [B] over the split; the batch is split over ``n_devices``.

    distortion: None, or (dp, spec, gid2, gid3) with ``DistortParams`` dp [B] (one per lane), a
    static ``DistortSpec``, and ground-truth ids [T, M2], [T, M3] of the (clutter-padded) frames.
    detail: also the rows' 3D detections (``StepOutput.src3``; for result files).
    Returns BatchOutput (numpy). Lanes are padded to a multiple of the device count and trimmed.
    """
    b = max(np.atleast_1d(np.asarray(v)).shape[0] for v in params)
    n_dev = device_count() if n_devices is None else n_devices
    n_dev = max(1, min(n_dev, b))
    pad = (-b) % n_dev
    with jax.enable_x64(True):
        p = _lanes(params, b, pad, jnp.float64)
        if distortion is None:
            spec, dp, gid2, gid3 = None, jnp.zeros(b + pad, jnp.int32), jnp.zeros((), jnp.int32), jnp.zeros((), jnp.int32)
        else:
            dpb, spec, gid2, gid3 = distortion
            dp = _lanes(dpb, b, pad, jnp.float32)
        fn = _compiled(options, capacity, n_dev, spec, detail)
        out, overflow, peak = fn(p, Frames(*(jnp.asarray(x) for x in frames)), dp, jnp.asarray(gid2), jnp.asarray(gid3))
    out = jax.tree.map(lambda x: np.asarray(x)[:b], out)
    return BatchOutput(out.ids, out.boxes, out.dropped, np.asarray(overflow)[:b], np.asarray(peak)[:b],
                       out.src3, out.own3, out.box3)
