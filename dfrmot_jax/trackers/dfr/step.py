"""One frame of the DFR-FastMOT tracker for one setting, as a pure function: ``init`` and ``step``.

``step(params, mem, frame) -> (mem, out)``: de-duplicate the frame's 2D and 3D detections into
objects, associate them with the tracks' predictions, update memory and filters, write, age.
``Frames`` are the per-frame inputs (leading axis T when scanned, ``trackers.dfr.run``). ``Options`` are static.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from .config import Options, Params
from . import associate, filters, memory
from ... import boxes
from .memory import Memory
from ...frames import Frames


class StepOutput(NamedTuple):
    """One frame's output of one lane.

    ids [K] int32: track id written in each output slot, -1 = nothing written. With output
    "detections" the slots are the frame's objects (2D detection slots, then 3D detection slots);
    with "filtered" they are the N track slots.
    boxes [K, 4] float32 the written boxes (``trackers.dfr.run`` keeps them only where a lane's boxes differ
    from the data's, ``trackers.dfr.frames.object_boxes``: [K, 0] otherwise).
    dropped [] int32 births lost for want of a track slot in this frame.
    With ``detail`` (result files): src3 [K] int32 the 3D detection whose values a row carries, as a
    global index ``t * M3 + slot`` into the split's [T, M3] arrays (-1 none): the object's own, or
    for a 2D-only object the last one its track took (the C++'s stale 3D box); own3 [K] bool it is
    the object's own; box3 [K, 6] float32 (output "filtered") the track's filtered 3D corners
    (min, max), meaningful where src3 >= 0. Without: [0], [0], [0, 6].
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
        q, r = kalman_noise(params)
        cov2 = filters.steady_cov(q[0], r[0])
        cov3 = filters.steady_cov(q[-1], r[-1])
        mem = mem._replace(cov0=jnp.where(_IS_2D, cov2[:, None], cov3[:, None]))
    return mem


#: which of the N_COORDS filter coordinates are 2D corners (the others: 3D corners)
_IS_2D = np.arange(memory.N_COORDS) < 4


def kalman_noise(params: Params):
    """(kf_q, kf_r) of each filter coordinate, float64 [N_COORDS] each: the 2D corners' kf_q, kf_r and the
    3D corners' kf_q3, kf_r3, where 0 stands for kf_q, kf_r."""
    q, r = jnp.asarray(params.kf_q, jnp.float64), jnp.asarray(params.kf_r, jnp.float64)
    q3 = jnp.where(params.kf_q3 > 0, params.kf_q3, q)
    r3 = jnp.where(params.kf_r3 > 0, params.kf_r3, r)
    return jnp.where(_IS_2D, q, q3), jnp.where(_IS_2D, r, r3)


class Objects(NamedTuple):
    """A frame's objects after the 2D/3D de-duplication (leading axis T when made for a whole split,
    ``trackers.dfr.run.split_objects``): box [O, 4] float64, z3 [O, 6] float64 (3D min, max corners), has3
    [O] bool, valid [O] bool, slot3 [O] int32 the 3D detection slot of each object (meaningful where
    has3), strong [O] bool it may start a track (not made of weak detections only, ``Params.weak_2d``).
    O: the 2D slots then the 3D slots (fused), or the one modality's slots."""

    box: jnp.ndarray
    z3: jnp.ndarray
    has3: jnp.ndarray
    valid: jnp.ndarray
    slot3: jnp.ndarray
    strong: jnp.ndarray


def objects(params: Params, frame: Frames, options: Options) -> Objects:
    """This frame's :class:`Objects`. They depend on ``score_2d``, ``score_3d``, ``weak_2d``,
    ``weak_3d`` and ``merge_iou`` only (``OBJECT_PARAMS``): lanes sharing those share them
    (``trackers.dfr.run`` then makes them once, outside the scan).

    Scores are compared in float32 (as parsed) with the thresholds and with the weak thresholds
    ``score - weak`` (computed in float64); boxes and corners come out in float64.
    """
    strong2 = frame.valid2 & (frame.score2 >= params.score_2d.astype(jnp.float32))
    strong3 = frame.valid3 & (frame.score3 >= params.score_3d.astype(jnp.float32))
    keep2 = frame.valid2 & (frame.score2 >= (params.score_2d - params.weak_2d).astype(jnp.float32))
    keep3 = frame.valid3 & (frame.score3 >= (params.score_3d - params.weak_3d).astype(jnp.float32))
    box2 = frame.box2.astype(jnp.float64)
    box3 = frame.box3.astype(jnp.float64)
    z3 = jnp.concatenate([frame.lo3, frame.hi3], axis=-1).astype(jnp.float64)
    slots3 = jnp.arange(keep3.shape[0], dtype=jnp.int32)
    if options.modality == "2d":
        return Objects(box2, jnp.zeros((keep2.shape[0], 6), jnp.float64), jnp.zeros_like(keep2), keep2,
                       jnp.zeros(keep2.shape, jnp.int32), strong2)
    if options.modality == "3d":
        return Objects(box3, z3, keep3, keep3, slots3, strong3)
    pair = associate.greedy_max(boxes.iou_matrix(box2, box3),
                                keep2[:, None] & keep3[None, :], params.merge_iou)
    paired2 = jnp.any(pair, axis=1)
    lone3 = keep3 & ~jnp.any(pair, axis=0)
    z3_of_2 = memory.gather_rows(pair.T, z3)                       # [M2, 6], zeros where unpaired
    strong_of_2 = strong2 | jnp.any(pair & strong3[None, :], axis=1)       # a reduction, not a gather
    return Objects(jnp.concatenate([box2, box3]), jnp.concatenate([z3_of_2, z3]),
                   jnp.concatenate([paired2, lone3]), jnp.concatenate([keep2, lone3]),
                   jnp.concatenate([memory.gather_rows(pair.T, slots3), slots3]),
                   jnp.concatenate([strong_of_2, strong3]))


def step(params: Params, mem: Memory, frame: Frames, options: Options, detail: bool = False, t=0,
         stride3: int | None = None, objs: Objects | None = None):
    """One frame: de-duplicate, associate, update memory and filters, write, age. Returns (mem, out).

    detail (static): also the 3D detection each row carries (``StepOutput.src3``); t: the frame's
    global index; stride3 (static): the split's 3D slots per frame M3, the stride of ``src3``'s flat
    index ``t * M3 + slot`` (default: this frame's slots; a frame cut to its first slots passes the
    full count); objs: the frame's :class:`Objects` when made outside (they must be ``objects`` of
    these params and this frame), else made here. Runs under ``jax.enable_x64``: arithmetic and parameters in float64, scores
    compared in float32. (Its phases are plain Python functions, traced inline: one computation.)
    """
    mem = memory.reset(mem, frame.reset)
    box, z3, has3, valid, slot3, strong = objects(params, frame, options) if objs is None else objs
    a = associate_objects(params, mem, box, z3, has3, valid, strong, options)
    u = update_filters(params, mem, a, box, z3, has3, options)
    mem, born_id = next_memory(params, mem, a, u, slot3, frame, detail, t, stride3)
    empty = jnp.zeros((0,), jnp.int32), jnp.zeros((0,), bool), jnp.zeros((0, 6), jnp.float32)
    writable = mem.hits >= params.min_hits
    if options.output == "detections":
        out = write_detections(params, a, mem, born_id, box, has3, valid, detail, empty)
    else:
        out = write_filtered(params, a, u, mem, writable, detail, empty)
    return memory.end_of_frame(mem, params.epsilon), out


class Association(NamedTuple):
    """A frame's O objects matched with the N track slots: match [O, N] (an object takes over a
    live track), birth [O, N] (a newborn object starts a track in a free slot), assign = match |
    birth; newborn [O] (objects matched with no track), rank [O] (their birth order), dropped []
    (births lost for want of a slot); per slot [N]: matched_obj, born, observed = matched_obj | born."""

    match: jnp.ndarray
    birth: jnp.ndarray
    assign: jnp.ndarray
    newborn: jnp.ndarray
    rank: jnp.ndarray
    dropped: jnp.ndarray
    matched_obj: jnp.ndarray
    born: jnp.ndarray
    observed: jnp.ndarray


def associate_objects(params: Params, mem: Memory, box, z3, has3, valid, strong, options: Options) -> Association:
    """Association on the tracks' predictions (fused affinity, greedy or Hungarian), then births of
    the unmatched strong objects (a weak one unmatched is dropped)."""
    f = mem.filt
    iou = boxes.iou_matrix(box, boxes.predicted_boxes(f.p[:, :4], options.truncate))
    dist = associate.centroid_distance(z3, f.p[:, 4:])
    m_f = associate.fused_affinity(iou, mem.age <= params.epsilon, dist, has3[:, None] & mem.has3d[None, :],
                                   params.a_c, params.a_l, params.alpha_c)
    allowed = valid[:, None] & mem.alive[None, :] & (strong[:, None] | (m_f > params.a_weak))
    if options.assign == "hungarian":
        match = associate.hungarian_min(-m_f, allowed, -params.a_f)
    else:
        match = associate.greedy_min(-m_f, allowed, mem.tid, -params.a_f)
    matched_obj = jnp.any(match, axis=0)
    newborn = valid & strong & ~jnp.any(match, axis=1)
    birth, rank, dropped = memory.births(mem.alive, newborn)
    assign = match | birth
    born = jnp.any(birth, axis=0)
    observed = matched_obj | born
    return Association(match, birth, assign, newborn, rank, dropped, matched_obj, born, observed)


class SlotUpdate(NamedTuple):
    """The N track slots' filters after a frame: prior (before it), updated (measured, not yet
    predicted), filt (the next frame's); z [N, 10] the measurement moved into each slot (2D box,
    3D corners), z_has3 [N] it has 3D, had3 [N] the slot's track had a 3D filter, start3 [N] its
    first 3D observation."""

    prior: filters.FilterState
    updated: filters.FilterState
    filt: filters.FilterState
    z: jnp.ndarray
    z_has3: jnp.ndarray
    had3: jnp.ndarray
    start3: jnp.ndarray


def update_filters(params: Params, mem: Memory, a: Association, box, z3, has3, options: Options) -> SlotUpdate:
    """Measurements moved into the slots; the filter modes per slot and coordinate (update, start,
    predict), the filters stepped."""
    kind = options.filter
    f = mem.filt
    z = memory.gather_rows(a.assign, jnp.concatenate([box, z3], axis=1))        # [N, 10]
    z_has3 = memory.gather_rows(a.assign, has3)                                    # [N]
    had3 = mem.has3d & ~a.born
    start3 = z_has3 & ~had3                                                        # first 3D observation
    upd2 = a.matched_obj
    upd3 = a.matched_obj & z_has3 & had3
    pred3 = had3 & mem.alive
    is2d = jnp.arange(memory.N_COORDS) < 4
    do_update = jnp.where(is2d[None, :], upd2[:, None], upd3[:, None])
    do_init = jnp.where(is2d[None, :], a.born[:, None], (a.born | a.matched_obj)[:, None] & start3[:, None])
    do_predict = jnp.where(is2d[None, :], (mem.alive & ~a.born)[:, None], pred3[:, None])

    gains = (params.gain_alpha, params.gain_beta, params.gain_gamma)
    kf_q, kf_r = kalman_noise(params)
    updated = filters.select(do_update, filters.update(f, z, kind, gains, kf_r), f)
    predicted = filters.select(do_predict, filters.predict(updated, kind, kf_q), updated)
    cov0 = mem.cov0 if kind == "kalman" and options.kalman_init == "steady" else None
    filt = filters.select(do_init, filters.init(z, kind, kf_r, params.kf_p0, cov0), predicted)
    return SlotUpdate(f, updated, filt, z, z_has3, had3, start3)


def next_memory(params: Params, mem: Memory, a: Association, u: SlotUpdate, slot3, frame: Frames, detail: bool,
                t, stride3: int | None) -> tuple[Memory, jnp.ndarray]:
    """The memory after the frame (before ageing) and the ids the newborn objects would take [O]."""
    born, observed = a.born, a.observed
    born_id = mem.next_id + a.rank                                                # [O]
    tid = jnp.where(born, memory.gather_rows(a.birth, born_id), mem.tid)
    hits = jnp.where(born, 1, mem.hits + a.matched_obj.astype(jnp.int32))
    age = jnp.where(observed, 0, mem.age)
    alive = mem.alive | born
    last3 = mem.last3
    if detail:
        m3 = frame.valid3.shape[0] if stride3 is None else stride3
        z_src3 = memory.gather_rows(a.assign, t * m3 + slot3)
        last3 = jnp.where(observed & u.z_has3, z_src3, jnp.where(born, -1, last3))
    mem = Memory(alive=alive, tid=tid, age=age, hits=hits, has3d=u.had3 | u.z_has3, filt=u.filt,
                 next_id=mem.next_id + jnp.sum(a.newborn, dtype=jnp.int32), overflow=mem.overflow + a.dropped,
                 peak=jnp.maximum(mem.peak, jnp.sum(alive, dtype=jnp.int32)), cov0=mem.cov0, last3=last3)
    return mem, born_id


def write_detections(params: Params, a: Association, mem: Memory, born_id, box, has3, valid, detail: bool,
                     empty: tuple) -> StepOutput:
    """Output "detections": each object written with its track's id (once the track has
    ``min_hits``) and its own box; ``empty``: the detail fields' empty (src3, own3, box3)."""
    src3, own3, box3 = empty
    match, assign = a.match, a.assign
    obj_id = jnp.sum(jnp.where(match, mem.tid[None, :], 0), axis=1, dtype=jnp.int32) + jnp.where(a.newborn, born_id, 0)
    obj_hits = (jnp.sum(jnp.where(assign, mem.hits[None, :], 0), axis=1, dtype=jnp.int32)
                + jnp.where(a.newborn & ~jnp.any(a.birth, 1), 1, 0))
    ids = jnp.where(valid & (obj_hits >= params.min_hits), obj_id, -1)
    if detail:
        src3 = jnp.where(jnp.any(assign, axis=1), jnp.sum(jnp.where(assign, mem.last3[None, :], 0), axis=1), -1)
        own3 = has3 & valid
    return StepOutput(ids, box.astype(jnp.float32), a.dropped, src3, own3, box3)


def write_filtered(params: Params, a: Association, u: SlotUpdate, mem: Memory, writable, detail: bool,
                   empty: tuple) -> StepOutput:
    """Output "filtered": each writable live track (``writable``: it has ``min_hits``; unobserved
    for at most ``keep_lost`` frames) with its filtered box; ``empty`` as in :func:`write_detections`."""
    src3, own3, box3 = empty
    f, z, updated = u.prior, u.z, u.updated
    shown = jnp.where(a.born[:, None], z[:, :4], jnp.where(a.matched_obj[:, None], updated.p[:, :4], f.p[:, :4]))
    shown = boxes.predicted_boxes(shown, False)  # filter corners may cross: x2 = x1 + |x2 - x1|
    ids = jnp.where(mem.alive & writable & (mem.age <= params.keep_lost), mem.tid, -1)
    if detail:
        src3, own3 = mem.last3, a.observed & u.z_has3
        box3 = jnp.where(u.start3[:, None], z[:, 4:], updated.p[:, 4:]).astype(jnp.float32)
    return StepOutput(ids, shown.astype(jnp.float32), a.dropped, src3, own3, box3)
