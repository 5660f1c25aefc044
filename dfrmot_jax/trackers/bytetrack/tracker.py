"""ByteTrack's ``BYTETracker.update`` as a pure JAX step over fixed-capacity arrays.

Runs under ``jax.enable_x64`` (``batch.run`` sets it): float64 boxes, scores and parameters.

ByteTrack keeps Python lists (tracked, lost, removed); here every track has a slot of ``K`` and
its list is a code (``lst``: 0 none, 1 tracked, 2 lost) with an order key (``key``: a counter
value given when it joined its list, so a list's order is its keys' order). The rules, as the
oracle (``testing.bytetrack_oracle``) states them:

- the pool is the tracked list's activated tracks then the lost list, in list order; it is
  predicted (height velocity 0 for a track not in state Tracked); unconfirmed tracks are not;
- three assignments (``lapjv.assign``): pool x high (fused cost unless ``mot20``, ``match_thresh``),
  the pool's unmatched Tracked tracks x low (0.5), unconfirmed x the high detections left (0.7);
- births for the high detections left with ``score >= track_thresh + det_thresh_margin``, in
  detection order, ids from the lane's counter; activated at once only on frame 1;
- lost tracks past ``max_time_lost`` are marked removed but stay one more frame in the lost list
  (``gone``: the id is in ByteTrack's removed list, from the next frame's bookkeeping on: a lost
  track whose id is there leaves the lost list);
- the list bookkeeping, then ``remove_duplicate_stracks`` (1 - IoU < 0.15; the younger goes, the
  tracked one on a tie).

Capacity: ``K`` track slots; a birth that finds no free slot is dropped and counted (``overflow``).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
from jax import lax

from .config import Options, Params
from .exact import guard, mul, runtime_zero
from .lapjv import shortcut, solve, unique_small

__all__ = ["Frames", "State", "StepOutput", "init", "step", "step_batch", "resolve", "iou_matrix"]

SP = 1.0 / 20
SV = 1.0 / 160
TRACKED, LOST, REMOVED = 1, 2, 3
NONE, IN_TRACKED, IN_LOST = 0, 1, 2


class Frames(NamedTuple):
    """Padded frames: dets [T, D, 5] ``x1, y1, x2, y2, score`` (float64), valid [T, D], reset [T]
    (a new sequence starts: the tracker is made anew)."""
    dets: jnp.ndarray
    valid: jnp.ndarray
    reset: jnp.ndarray


class State(NamedTuple):
    mean: jnp.ndarray      # [K, 8]
    cov: jnp.ndarray       # [K, 4, 4]: per coordinate pp, pv, vp, vv
    tid: jnp.ndarray       # [K] int32
    lst: jnp.ndarray       # [K] int32: NONE / IN_TRACKED / IN_LOST
    state: jnp.ndarray     # [K] int32: TRACKED / LOST / REMOVED
    active: jnp.ndarray    # [K] bool (is_activated)
    score: jnp.ndarray     # [K] float64
    start: jnp.ndarray     # [K] int32 start_frame
    last: jnp.ndarray      # [K] int32 frame_id (end_frame)
    key: jnp.ndarray       # [K] int32 order in its list
    gone: jnp.ndarray      # [K] bool: id in the removed list
    count: jnp.ndarray     # int32 ids given
    frame: jnp.ndarray     # int32 frame_id
    keys: jnp.ndarray      # int32 order keys given
    overflow: jnp.ndarray  # int32 births dropped for want of a slot
    solver: jnp.ndarray    # int32 assignments that ran the full lapjv emulation


class StepOutput(NamedTuple):
    tid: jnp.ndarray       # [K] int32
    tlwh: jnp.ndarray      # [K, 4]
    score: jnp.ndarray     # [K]
    written: jnp.ndarray   # [K] bool
    key: jnp.ndarray       # [K] int32: order in its list (the written tracks' output order: ascending)


def init(k: int) -> State:
    z = jnp.int32(0)
    return State(jnp.zeros((k, 8)), jnp.zeros((k, 4, 4)), jnp.zeros(k, jnp.int32),
                 jnp.zeros(k, jnp.int32), jnp.zeros(k, jnp.int32), jnp.zeros(k, bool), jnp.zeros(k),
                 jnp.zeros(k, jnp.int32), jnp.zeros(k, jnp.int32), jnp.zeros(k, jnp.int32),
                 jnp.zeros(k, bool), z, z, z, z, z)


def _tlwh(mean, zero):
    w = mul(mean[..., 2], mean[..., 3], zero)
    return jnp.stack([mean[..., 0] - w / 2, mean[..., 1] - mean[..., 3] / 2, w, mean[..., 3]], -1)


def _tlbr_of_tlwh(t):
    return jnp.stack([t[..., 0], t[..., 1], t[..., 2] + t[..., 0], t[..., 3] + t[..., 1]], -1)


def iou_matrix(a, b, zero):
    """cython_bbox's ``bbox_overlaps(a, b)`` [len a, len b] (+1-pixel convention, its roundings)."""
    a = a[:, None, :]
    b = b[None, :, :]
    iw = (jnp.minimum(a[..., 2], b[..., 2]) - jnp.maximum(a[..., 0], b[..., 0])) + 1.0
    ih = (jnp.minimum(a[..., 3], b[..., 3]) - jnp.maximum(a[..., 1], b[..., 1])) + 1.0
    area_b = mul((b[..., 2] - b[..., 0]) + 1.0, (b[..., 3] - b[..., 1]) + 1.0, zero)
    area_a = mul((a[..., 2] - a[..., 0]) + 1.0, (a[..., 3] - a[..., 1]) + 1.0, zero)
    inter = mul(iw, ih, zero)
    ua = (area_a + area_b) - inter
    ok = (iw > 0) & (ih > 0)
    return jnp.where(ok, inter / jnp.where(ok, ua, 1.0), 0.0)


def _xyah(tlwh):
    return jnp.stack([tlwh[..., 0] + tlwh[..., 2] / 2, tlwh[..., 1] + tlwh[..., 3] / 2,
                      tlwh[..., 2] / tlwh[..., 3], tlwh[..., 3]], -1)


def _initiate(z, zero):
    h = z[..., 3]
    p2 = mul(2 * SP, h, zero)
    v10 = mul(10 * SV, h, zero)
    one = jnp.ones_like(h)
    pos = jnp.stack([p2, p2, 1e-2 * one, p2], -1)
    vel = jnp.stack([v10, v10, 1e-5 * one, v10], -1)
    zz = jnp.zeros_like(pos)
    cov = jnp.stack([mul(pos, pos, zero), zz, zz, mul(vel, vel, zero)], -1)
    mean = jnp.concatenate([z, jnp.zeros_like(z)], -1)
    return mean, cov


def _predict(mean, cov, tracked, zero):
    mean = mean.at[:, 7].set(jnp.where(tracked, mean[:, 7], 0.0))
    h = mean[:, 3:4]
    one = jnp.ones_like(h)
    qp = jnp.concatenate([mul(SP, h, zero), mul(SP, h, zero), 1e-2 * one, mul(SP, h, zero)], -1)
    qv = jnp.concatenate([mul(SV, h, zero), mul(SV, h, zero), 1e-5 * one, mul(SV, h, zero)], -1)
    pp, pv, vp, vv = cov[..., 0], cov[..., 1], cov[..., 2], cov[..., 3]
    npp = guard((pp + vp) + (pv + vv), zero) + mul(qp, qp, zero)
    nvv = vv + mul(qv, qv, zero)
    ncov = jnp.stack([npp, pv + vv, vp + vv, nvv], -1)
    nmean = jnp.concatenate([mean[:, :4] + mean[:, 4:], mean[:, 4:]], -1)
    return nmean, ncov


def _update(mean, cov, z, zero):
    h = mean[:, 3:4]
    one = jnp.ones_like(h)
    r = jnp.concatenate([mul(SP, h, zero), mul(SP, h, zero), 1e-1 * one, mul(SP, h, zero)], -1)
    pp, pv, vp, vv = cov[..., 0], cov[..., 1], cov[..., 2], cov[..., 3]
    s = pp + mul(r, r, zero)
    inv = 1.0 / guard(jnp.sqrt(s), zero)
    kp = mul(mul(pp, inv, zero), inv, zero)
    kv = mul(mul(vp, inv, zero), inv, zero)
    innov = z - mean[:, :4]
    nmean = jnp.concatenate([mean[:, :4] + mul(innov, kp, zero), mean[:, 4:] + mul(innov, kv, zero)], -1)
    skp = mul(s, kp, zero)
    skv = mul(s, kv, zero)
    ncov = jnp.stack([pp - mul(kp, skp, zero), pv - mul(kp, skv, zero),
                      vp - mul(kv, skp, zero), vv - mul(kv, skv, zero)], -1)
    return nmean, ncov


def _onehot_rows(match, d):
    """[K, D] bool: slot k matched detection d."""
    return match[:, None] == jnp.arange(d)[None, :]


def _pick(onehot, values):
    """values[match] per slot via a masked sum (exact: one term)."""
    return jnp.sum(jnp.where(onehot[..., None], values[None, :, :], 0.0), axis=1)


def _begin(params: Params, options: Options, st: State, dets, valid, reset):
    """A frame up to its associations: (the state after ``reset``, the frame's context)."""
    k = st.tid.shape[0]
    st = State(*[jnp.where(reset, a, b) for a, b in zip(init(k), st)])
    frame = st.frame + 1
    zero = runtime_zero(frame)
    tt = params.track_thresh
    sc = dets[:, 4]
    high = valid & (sc > tt)
    low = valid & (sc > 0.1) & (sc < tt)
    dtlwh = jnp.stack([dets[:, 0], dets[:, 1], dets[:, 2] - dets[:, 0], dets[:, 3] - dets[:, 1]], -1)
    dtlbr = _tlbr_of_tlwh(dtlwh)
    intr = st.lst == IN_TRACKED
    inlost = st.lst == IN_LOST
    unconf = intr & ~st.active
    pool = (intr & st.active) | inlost
    pkey = jnp.where(intr, st.key, st.key + (1 << 29))
    # predict the pool
    pmean, pcov = _predict(st.mean, st.cov, st.state == TRACKED, zero)
    mean = jnp.where(pool[:, None], pmean, st.mean)
    cov = jnp.where(pool[:, None, None], pcov, st.cov)
    tlbr = _tlbr_of_tlwh(_tlwh(mean, zero))
    iou = iou_matrix(tlbr, dtlbr, zero)
    cost = 1.0 - iou
    fused = 1.0 - mul(1.0 - cost, sc[None, :], zero) if options.fuse_score else cost
    ctx = dict(frame=frame, zero=zero, sc=sc, high=high, low=low, dxyah=_xyah(dtlwh), intr=intr,
               inlost=inlost, unconf=unconf, pool=pool, pkey=pkey, mean=mean, cov=cov, cost=cost,
               fused=fused, match_thresh=jnp.asarray(params.match_thresh, jnp.float64))
    return st, ctx


def _problem(st: State, ctx, s, m1):
    """The association ``s`` (0: pool x high, 1: the pool's unmatched Tracked tracks x low, 2:
    unconfirmed x the high detections left) given the first one's matches ``m1``: (cost, rows,
    row order keys, columns, limit)."""
    dn = ctx["sc"].shape[0]
    hit1 = m1 >= 0
    rest = ctx["pool"] & ~hit1 & (st.state == TRACKED)
    left = ctx["high"] & ~jnp.any(_onehot_rows(m1, dn), axis=0)
    first, second = s == 0, s == 1
    cost = jnp.where(second, ctx["cost"], ctx["fused"])
    rmask = jnp.where(first, ctx["pool"], jnp.where(second, rest, ctx["unconf"]))
    rkey = jnp.where(s == 2, st.key, ctx["pkey"])
    cmask = jnp.where(first, ctx["high"], jnp.where(second, ctx["low"], left))
    limit = jnp.where(first, ctx["match_thresh"], jnp.where(second, 0.5, 0.7))
    return cost, rmask, rkey, cmask, limit


def resolve(problem, ok, quick):
    """The matches of a batch [B] of associations: ``quick`` where ``ok``, the full emulation
    (:func:`lapjv.solve`, unbatched: one lane at a time) for the other lanes."""
    def body(c):
        res, todo = c
        i = jnp.argmax(todo)
        x = solve(*(a[i] for a in problem))
        return res.at[i].set(x), todo.at[i].set(False)
    return lax.while_loop(lambda c: jnp.any(c[1]), body, (quick, ~ok))[0]


def _associate(st: State, ctx, batched: bool):
    """The three associations, one after the other through ONE solver site: (m1, m2, m3, the
    number that ran the full emulation). Batched: ``st`` and ``ctx`` carry a leading lane axis."""
    lane = (lambda f, *ax: jax.vmap(f, in_axes=ax)) if batched else (lambda f, *ax: f)
    k = st.tid.shape[-1]
    shape = st.tid.shape

    def stage(s, carry):
        ms, ns = carry
        prob = lane(_problem, 0, 0, None, 0)(st, ctx, s, ms[0])
        args = (prob[0], prob[1], prob[3], prob[4])
        ok0, quick0 = lane(shortcut, 0, 0, 0, 0)(*args)
        # the blocks only where some lane's shortcut fails (B = 1: a real branch)
        ok, quick = lax.cond(jnp.all(ok0), lambda: (ok0, quick0), lambda: lane(unique_small, 0, 0, 0, 0)(*args))
        if batched:
            res = resolve(prob, ok, quick)
        else:
            res = lax.cond(ok, lambda: quick, lambda: solve(*prob))
        return ms.at[s].set(res), ns + (~ok).astype(jnp.int32)

    ms0 = jnp.full((3,) + shape, -1, jnp.int32)
    ms, ns = lax.fori_loop(0, 3, stage, (ms0, jnp.zeros(shape[:-1], jnp.int32)))
    del k
    return ms[0], ms[1], ms[2], ns


def step(params: Params, options: Options, st: State, dets, valid, reset):
    """One frame (``BYTETracker.update``). Returns (state, output)."""
    st, ctx = _begin(params, options, st, dets, valid, reset)
    m1, m2, m3, ns = _associate(st, ctx, False)
    return _finish(params, options, st, ctx, m1, m2, m3, ns)


def step_batch(params: Params, options: Options, st: State, dets, valid, reset):
    """One frame of every lane: ``params`` and ``st`` [B] (leading lane axis), the frame shared."""
    st, ctx = jax.vmap(lambda p, s: _begin(p, options, s, dets, valid, reset))(params, st)
    m1, m2, m3, ns = _associate(st, ctx, True)
    return jax.vmap(lambda p, *a: _finish(p, options, *a))(params, st, ctx, m1, m2, m3, ns)


# Whole on purpose (over 80 lines): BYTETracker.update after its associations, read straight through.
def _finish(params: Params, options: Options, st: State, ctx, m1, m2, m3, nsolved):
    """The frame after its associations. Returns (state, output)."""
    k = st.tid.shape[0]
    dn = ctx["sc"].shape[0]
    frame, zero, sc, high, dxyah = ctx["frame"], ctx["zero"], ctx["sc"], ctx["high"], ctx["dxyah"]
    intr, inlost, unconf, pool, pkey = ctx["intr"], ctx["inlost"], ctx["unconf"], ctx["pool"], ctx["pkey"]
    mean, cov = ctx["mean"], ctx["cov"]
    tt = params.track_thresh
    det_thresh = tt + params.det_thresh_margin
    max_lost = jnp.floor((options.frame_rate / 30.0) * params.track_buffer.astype(jnp.float64)).astype(jnp.int32)
    hit1 = m1 >= 0
    refound = hit1 & (st.state != TRACKED)
    rest = pool & ~hit1 & (st.state == TRACKED)
    hit2 = m2 >= 0
    lost_now = rest & ~hit2
    used1 = jnp.any(_onehot_rows(m1, dn), axis=0)
    left = high & ~used1
    hit3 = m3 >= 0
    unc_removed = unconf & ~hit3
    used3 = jnp.any(_onehot_rows(m3, dn), axis=0)

    # updates of every matched track (one detection each)
    match = jnp.where(hit1, m1, jnp.where(hit2, m2, m3))
    hit = hit1 | hit2 | hit3
    oh = _onehot_rows(jnp.where(hit, match, -1), dn)
    z = _pick(oh, dxyah)
    dsc = jnp.sum(jnp.where(oh, sc[None, :], 0.0), axis=1)
    umean, ucov = _update(mean, cov, z, zero)
    mean = jnp.where(hit[:, None], umean, mean)
    cov = jnp.where(hit[:, None, None], ucov, cov)
    state = jnp.where(hit, TRACKED, st.state)
    state = jnp.where(lost_now, LOST, state)
    state = jnp.where(unc_removed, REMOVED, state)
    active = st.active | hit
    score = jnp.where(hit, dsc, st.score)
    last = jnp.where(hit, frame, st.last)

    # lost tracks past max_time_lost (the lost list as the frame found it)
    timeout = inlost & (frame - last > max_lost)
    state = jnp.where(timeout, REMOVED, state)

    # list bookkeeping (births come after the old tracked list, refound tracks after them)
    keep_tr = intr & (state == TRACKED)
    births = left & ~used3 & (sc >= det_thresh)
    lst = jnp.where(intr & ~keep_tr, NONE, st.lst)
    lst = jnp.where(refound, IN_TRACKED, lst)
    nb = jnp.sum(births).astype(jnp.int32)
    brank = (jnp.cumsum(births) - 1).astype(jnp.int32)                                 # births in detection order
    prank = jnp.sum((pkey[None, :] < pkey[:, None]) & pool[None, :], axis=1).astype(jnp.int32)  # pool positions
    key = jnp.where(refound, st.keys + nb + prank, st.key)
    lost_key = st.keys + nb + k + prank
    lst = jnp.where(lost_now, IN_LOST, lst)
    key = jnp.where(lost_now, lost_key, key)
    # sub(lost, removed before this frame): a lost track whose id was removed leaves
    lst = jnp.where((lst == IN_LOST) & st.gone, NONE, lst)
    gone = st.gone | timeout | unc_removed

    # births into free slots, in detection order
    free = lst == NONE
    frank = (jnp.cumsum(free) - 1).astype(jnp.int32)
    slot_b = (frank[:, None] == brank[None, :]) & free[:, None] & births[None, :]   # [K, D]
    born = jnp.any(slot_b, axis=1)
    overflow = st.overflow + nb - jnp.sum(born).astype(jnp.int32)
    bz = _pick(slot_b, dxyah)
    bmean, bcov = _initiate(bz, zero)
    bidx = jnp.sum(jnp.where(slot_b, brank[None, :], 0), axis=1).astype(jnp.int32)
    mean = jnp.where(born[:, None], bmean, mean)
    cov = jnp.where(born[:, None, None], bcov, cov)
    tid = jnp.where(born, st.count + 1 + bidx, st.tid).astype(jnp.int32)
    lst = jnp.where(born, IN_TRACKED, lst)
    state = jnp.where(born, TRACKED, state)
    active = jnp.where(born, frame == 1, active)
    score = jnp.where(born, jnp.sum(jnp.where(slot_b, sc[None, :], 0.0), axis=1), score)
    start = jnp.where(born, frame, st.start)
    last = jnp.where(born, frame, last)
    key = jnp.where(born, st.keys + bidx, key)
    gone = jnp.where(born, False, gone)
    count = st.count + nb
    keys = st.keys + nb + 2 * k

    # remove_duplicate_stracks(tracked, lost)
    tb = _tlbr_of_tlwh(_tlwh(mean, zero))
    dist = 1.0 - iou_matrix(tb, tb, zero)
    a = lst == IN_TRACKED
    b = lst == IN_LOST
    age = last - start
    pair = (dist < 0.15) & a[:, None] & b[None, :]
    older = age[:, None] > age[None, :]
    drop_a = jnp.any(pair & ~older, axis=1)
    drop_b = jnp.any(pair & older, axis=0)
    lst = jnp.where(drop_a | drop_b, NONE, lst)

    key = key.astype(jnp.int32)
    lst = lst.astype(jnp.int32)
    state = state.astype(jnp.int32)
    written = (lst == IN_TRACKED) & active
    solver = st.solver + nsolved
    new = State(mean, cov, tid, lst, state, active, score, start, last, key, gone, count, frame, keys,
                overflow, solver)
    return new, StepOutput(tid, _tlwh(mean, zero), score, written, key)
