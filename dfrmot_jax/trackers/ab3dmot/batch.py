"""AB3DMOT over a split for a batch of settings: ``lax.scan`` over the frames of ``tracker.step``
vmapped over a ``Params`` batch [B], jitted once per ``Options`` (and frame shape), under
``jax.enable_x64``. Each frame's affinity matrices are computed for the pairs that exist (valid
detection, live track) of all lanes together, in fixed-size blocks of the packed list of pairs (a
loop of as many trips as the frame needs, one copy of the geometry's code: :func:`blockwise`);
with ``Options.buckets`` > 1 its assignment runs on the smallest of a few slot counts that holds
its detections and every lane's live tracks (``lax.switch`` on an index shared by the lanes).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import numpy as np
from jax import lax

from ...devices import call_compiled, setup_host_devices
from .config import AUTO_BUCKETS_MIN_T, Options, Params, as_arrays, validate
import jax.numpy as jnp

from . import kalman
from .. import capacity as slots
from .affinity import (circle, circles_apart, combine, compact, distance, footprint, footprint_hull, footprint_intersection)
from .exact import runtime_zero
from .tracker import Frames, State, StepOutput, decide, finish, init, predict, step

__all__ = ["RunOutput", "run", "run_lane", "run_lanes", "pooled_affinity", "affinity_sizes", "blockwise", "PAIR_BLOCK",
           "CLIP_BLOCK", "clear_programs",
           "data_capacity", "broadcast_lanes", "tracking_lanes", "frame_counts",
           "written_lines", "own_frames"]


class RunOutput(NamedTuple):
    """A batch's output (NumPy): ``ids`` [B, T, K] (-1: not written), ``src`` [B, T, K], ``boxes``
    [B, T, K, 7] (``StepOutput``'s fields per frame), ``next_id`` [B, T] (the id counter after
    each frame), ``dropped`` [B, T] (births dropped per frame), and per lane [B]: ``overflow``
    (births dropped), ``peak`` (most slots needed),
    ``pairs_left``, ``degenerate``, ``fallback`` (see ``tracker.State``): a lane is AB3DMOT's exactly
    when all of ``overflow``, ``pairs_left``, ``degenerate`` and ``fallback`` are 0; ``options``:
    the ``Options`` of the run (capacities grown, buckets chosen); ``capacity`` [B] the track
    slots each lane alone would have grown to (None: ``options.capacity``)."""

    ids: np.ndarray
    src: np.ndarray
    boxes: np.ndarray
    next_id: np.ndarray
    dropped: np.ndarray
    overflow: np.ndarray
    peak: np.ndarray
    pairs_left: np.ndarray
    degenerate: np.ndarray
    fallback: np.ndarray
    options: Options | None = None
    capacity: np.ndarray | None = None


def run_lane(params: Params, frames: Frames, state: State, options: Options) -> tuple[State, StepOutput]:
    """One lane over frames [T, ...] from ``state``: (final state, outputs [T, ...]). Traceable."""
    return lax.scan(lambda s, f: step(params, s, f, options), state, frames)


def affinity_sizes(n_det: int, tracks: int, buckets: int) -> tuple[tuple[int, int], ...]:
    """The (detection, track) slot counts a frame's assignment may run on, smallest first:
    ``ceil(N / 2^s), ceil(K / 2^s)`` for s = buckets - 1 .. 0 (0 buckets: one, the full size)."""
    out = []
    for s in range(max(buckets, 1) - 1, -1, -1):
        size = (max(1, -(-n_det // (1 << s))), max(1, -(-tracks // (1 << s))))
        if size not in out:
            out.append(size)
    return tuple(out)


#: ``pooled_affinity``'s block sizes, pairs per lane of the call: the loop over the existing pairs
#: (distances; the IoU metrics' circle test and GIoU hull) and the one over the pairs clipped.
#: The results do not depend on them; smaller blocks cost more trips, larger ones more padding.
#: Chosen on KITTI car (21 sequences, buckets 3, 2 busy cores, giou_3d Hungarian): clip blocks of
#: 8, 16, 24 per lane ran B = 1 in 2.5-2.9 s, 64 in 4.2 s, 190 in 7.0 s; B = 8 ran in 10-14 s
#: for 4-16 per lane, 14.7 s for 24; pair blocks of 16, 48, 128 per lane: B = 1 2.5, 2.1, 2.2 s,
#: B = 8 8.5, 8.2, 9.6 s (dist_3d: 48 and 128 alike).
PAIR_BLOCK = 48
CLIP_BLOCK = 8
#: lanes per block unit of the shared-detection path (``_shared_affinity``): its blocks hold
#: ``PAIR_BLOCK * ceil(B / SHARED_LANES)`` pairs, the lanes' tracks being mostly the same ones
SHARED_LANES = 8
#: whether lanes sharing detections pair each distinct track once (``_shared_affinity``; read when a
#: program is traced: the same values either way, a switch for benchmarks)
SHARE_TRACKS = True


def blockwise(mask, block: int, values):
    """``values(sel)`` of every pair ``mask`` holds (any shape; ``sel`` [block] the flat positions
    of ``block`` of them, :func:`affinity.compact`, positions past the end padding), computed block
    by block over the pairs in flat order (a loop of ceil(count / block) trips: one copy of
    ``values``' code whatever the count) and written back: a tuple of mask-shaped arrays, 0 (False)
    where ``mask`` is not set. ``values`` computes each pair's values alone (elementwise), so they
    do not depend on ``block``."""
    def at(start):
        sel, _ = compact(mask, block, start)
        return sel, values(sel)

    def body(i, outs):
        sel, vals = at(i * block)
        return tuple(o.at[sel].set(v, mode="drop") for o, v in zip(outs, vals))

    init = tuple(jnp.zeros(mask.size, v.dtype) for v in jax.eval_shape(lambda: at(0)[1]))
    outs = lax.fori_loop(0, (jnp.sum(mask) + block - 1) // block, body, init)
    return tuple(o.reshape(mask.shape) for o in outs)


_HASH = np.array([0x9E3779B97F4A7C15, 0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9, 0xD6E8FEB86659FD93,
                  0xFF51AFD7ED558CCD, 0xC4CEB9FE1A85EC53, 0x94D049BB133111EB, 0xBF58476D1CE4E5B9,
                  0x2545F4914F6CDD1D, 0x9FB21C651E98DF25, 0x85EBCA77C2B2AE63, 0x27D4EB2F165667C5,
                  0xA0761D6478BD642F, 0xE7037ED1A0B428DB], np.uint64).view(np.int64)


def distinct_rows(rows, live):
    """The distinct rows of ``rows`` [M, W] (float64, compared bit for bit) among the ``live`` [M]
    ones: (group [M] int32: each row's group, rep [M] int32: each group's first row in sort order
    (groups 0 .. count - 1; the rest point at row 0), group_live [M]: the groups of live rows).
    Dead rows form groups of their own after the live ones. One sort by a hash of the row's bits;
    rows of equal hash but different bits (a collision) start groups of their own: each group holds
    equal rows only, whatever the hash."""
    m, w = rows.shape
    words = jax.lax.bitcast_convert_type(rows, jnp.int64)
    h = jnp.sum(words * jnp.asarray(_HASH[:w]), -1)                             # (wrapping int64)
    h = h ^ (h >> 29)
    idx = jnp.arange(m, dtype=jnp.int32)
    dead = (~live).astype(jnp.int32)
    _, _, order = lax.sort((dead, h, idx), num_keys=2)
    sw, sl = words[order], live[order]
    new = jnp.concatenate([jnp.ones(1, bool), jnp.any(sw[1:] != sw[:-1], -1) | (sl[1:] != sl[:-1])])
    gid = (jnp.cumsum(new) - 1).astype(jnp.int32)
    group = jnp.zeros(m, jnp.int32).at[order].set(gid)
    rep = jnp.zeros(m, jnp.int32).at[jnp.where(new, gid, m)].set(order, mode="drop")
    group_live = jnp.zeros(m, bool).at[jnp.where(new, gid, m)].set(sl, mode="drop")
    return group, rep, group_live


def pooled_affinity(frame: Frames, pred, options: Options):
    """Every lane's affinity matrix (A [B, N, K] float32, degenerate [B, N, K]) of ``frame``'s
    detections (boxes [N, 7], shared by the lanes, or each lane's own [B, N, 7]) from the pairs
    that exist (valid detection, live track) of all lanes, packed into one list and computed in
    blocks of ``PAIR_BLOCK`` pairs per lane (:func:`blockwise`); IoU metrics clip only the pairs
    whose footprints may overlap, packed again, in blocks of ``CLIP_BLOCK`` per lane.
    The same values as ``affinity.affinity`` lane by lane (the same elementwise functions)."""
    metric = options.metric
    b, k = pred.count.shape[0], pred.age.shape[1]
    n = frame.valid.shape[-1]
    full = b * n * k
    trk = pred.filt.x[..., :7]                                                  # [B, K, 7]
    det = frame.boxes                                                           # [N, 7] or per lane [B, N, 7]
    own = det.ndim == 3
    zero = runtime_zero(jnp.max(pred.frame_count))
    valid = frame.valid[:, :, None] if own else frame.valid[None, :, None]
    mask = valid & (jnp.arange(k)[None, None, :] < pred.count[:, None, None])

    def take_det(v, lane, i):
        """A detection value per pair: the lane's own detections, or the shared ones."""
        return v[lane, i] if own else v[i]

    def pair(sel):
        """(lane, detection, track slot) of each listed pair (flat index into [B, N, K])."""
        sel = jnp.minimum(sel, full - 1)
        return sel // (n * k), (sel // k) % n, sel % k

    if not own and b > 1 and SHARE_TRACKS and "iou" in metric:      # (distances: cheaper than the sort)
        return _shared_affinity(frame, pred, options, zero)

    if "iou" not in metric:
        def dist(sel):
            lane, i, j = pair(sel)
            inn = kalman.innovation(jax.tree.map(lambda v: v[lane, j], pred.filt)) if metric == "m_dis" else None
            return (distance(take_det(det, lane, i), trk[lane, j], metric, zero, inn),)

        value, = blockwise(mask, PAIR_BLOCK * b, dist)
        return value.astype(jnp.float32), jnp.zeros_like(mask)

    # each box's footprint and circle once (the same values as per pair), gathered per pair
    det_fp, trk_fp = footprint(det, zero), footprint(trk, zero)                 # x, z [N, 4], [B, K, 4]
    det_c, trk_c = circle(det, zero), circle(trk, zero)

    def geometry(sel):
        lane, i, j = pair(sel)
        take_d = lambda v: take_det(v, lane, i)                                 # noqa: E731
        take_t = lambda v: v[lane, j]                                           # noqa: E731
        return (tuple(map(take_d, det_fp)), tuple(map(take_t, trk_fp)), tuple(map(take_d, det_c)),
                tuple(map(take_t, trk_c)))

    def near(sel):
        """(apart, and for GIoU: the hull's degenerate pairs, the hull area C) of listed pairs."""
        dfp, tfp, dc, tc = geometry(sel)
        apart = circles_apart(dc, tc, zero)
        if not metric.startswith("giou"):
            return (apart,)
        hull, bad = footprint_hull(dfp, tfp, zero)
        return apart, bad, hull

    def clip(sel):
        """(I, degenerate) of listed pairs."""
        dfp, tfp, _, _ = geometry(sel)
        return footprint_intersection(dfp, tfp, zero)

    apart, *rest = blockwise(mask, PAIR_BLOCK * b, near)
    bad, hull = rest if rest else (jnp.zeros_like(mask), None)
    inter, clip_bad = blockwise(mask & ~apart, CLIP_BLOCK * b, clip)
    value = combine(det[:, :, None] if own else det[None, :, None], trk[:, None, :], metric, inter, hull, zero)
    return value.astype(jnp.float32), (bad | clip_bad) & mask


def _shared_affinity(frame: Frames, pred, options: Options, zero):
    """``pooled_affinity`` for detections shared by the lanes: each distinct live track (its box,
    and for ``m_dis`` its innovation, bit for bit: lanes mostly hold the same tracks) paired with
    the frame's detections once, its values given to every lane holding it. The same elementwise
    functions on the same bits: the same values."""
    metric = options.metric
    b, k = pred.count.shape[0], pred.age.shape[1]
    n = frame.valid.shape[-1]
    m = b * k
    trk = pred.filt.x[..., :7].reshape(m, 7)
    det = frame.boxes                                                           # [N, 7]
    live = (jnp.arange(k)[None, :] < pred.count[:, None]).reshape(m)
    inn = kalman.innovation(pred.filt).reshape(m, 7) if metric == "m_dis" else None
    group, rep, group_live = distinct_rows(trk if inn is None else jnp.concatenate([trk, inn], -1), live)
    trk_u = trk[rep]                                                            # [M, 7] (the first U distinct)
    inn_u = None if inn is None else inn[rep]
    mask = frame.valid[:, None] & group_live[None, :]                           # [N, M]
    shared = -(-b // SHARED_LANES)                      # (blocks for the distinct tracks: fewer than B K)

    def pair(sel):
        sel = jnp.minimum(sel, n * m - 1)
        return sel // m, sel % m

    def back(v):
        """[N, M] per distinct track -> [B, N, K] per lane."""
        return jnp.moveaxis(v[:, group].reshape(n, b, k), 1, 0)

    if "iou" not in metric:
        def dist(sel):
            i, u = pair(sel)
            return (distance(det[i], trk_u[u], metric, zero, None if inn_u is None else inn_u[u]),)

        value, = blockwise(mask, PAIR_BLOCK * shared, dist)
        return back(value).astype(jnp.float32), jnp.zeros((b, n, k), bool)

    det_fp, trk_fp = footprint(det, zero), footprint(trk_u, zero)               # x, z [N, 4], [M, 4]
    det_c, trk_c = circle(det, zero), circle(trk_u, zero)

    def geometry(sel):
        i, u = pair(sel)
        return (tuple(v[i] for v in det_fp), tuple(v[u] for v in trk_fp), tuple(v[i] for v in det_c),
                tuple(v[u] for v in trk_c))

    def near(sel):
        dfp, tfp, dc, tc = geometry(sel)
        apart = circles_apart(dc, tc, zero)
        if not metric.startswith("giou"):
            return (apart,)
        hull, bad = footprint_hull(dfp, tfp, zero)
        return apart, bad, hull

    def clip(sel):
        dfp, tfp, _, _ = geometry(sel)
        return footprint_intersection(dfp, tfp, zero)

    apart, *rest = blockwise(mask, PAIR_BLOCK * shared, near)
    bad, hull = rest if rest else (jnp.zeros_like(mask), None)
    inter, clip_bad = blockwise(mask & ~apart, CLIP_BLOCK * shared, clip)
    inter, bad = back(inter), back(bad | clip_bad)
    hull = None if hull is None else back(hull)
    lanes = (jnp.arange(k)[None, :] < pred.count[:, None])[:, None, :] & frame.valid[None, :, None]
    value = combine(det[None, :, None], pred.filt.x[..., :7][:, None, :], metric, inter, hull, zero)
    return value.astype(jnp.float32), bad & lanes


def run_lanes(params: Params, frames: Frames, states: State, options: Options) -> tuple[State, StepOutput]:
    """Every lane (``params``, ``states`` leaves [B]) over frames [T, ...]: a scan over frames of
    the step vmapped over the lanes, its affinity matrices from ``pooled_affinity`` (no pair left
    out: ``Options.pairs`` does not apply) and its assignment on the smallest of
    ``affinity_sizes`` holding the frame's valid detections and every lane's live tracks (the same
    result: slots beyond hold nothing). ``frames``: shared by the lanes (boxes [T, N, 7]) or each
    lane's own (:func:`own_frames`: boxes [T, B, N, 7], valid and score [T, B, N], reset [T]).
    Outputs [T, B, ...]. Traceable."""
    n_det = frames.valid.shape[-1]
    fax = Frames(0, 0, 0, None) if own_frames(frames) else None     # (the frame's vmap axes)
    sizes = affinity_sizes(n_det, options.capacity, options.buckets)

    def body(s, f):
        pred = jax.vmap(predict, in_axes=(0, None))(s, f)
        a32, bad = pooled_affinity(f, pred, options)
        none = jnp.zeros(a32.shape[0], jnp.int32)

        def at(size):
            def lanes(p, pr, a, bd, lf):
                return jax.vmap(lambda q, r, fr, a, bd, lf: decide(q, r, fr, options, size, (a, bd, lf)),
                                in_axes=(0, 0, fax, 0, 0, 0))(p, pr, f, a, bd, lf)
            return lanes

        need_n = jnp.max(jnp.where(f.valid, jnp.arange(n_det) + 1, 0))
        need_k = jnp.max(pred.count)
        if len(sizes) == 1:
            dec = at(sizes[0])(params, pred, a32, bad, none)
        else:
            fits = jnp.array([(need_n <= nb) & (need_k <= kb) for nb, kb in sizes])
            dec = lax.switch(jnp.argmax(fits), [at(size) for size in sizes], params, pred, a32, bad, none)
        return jax.vmap(finish, in_axes=(0, 0, fax, None, 0, 0))(params, s, f, options, pred, dec)

    return lax.scan(body, states, frames)


def own_frames(frames: Frames) -> bool:
    """Whether ``frames`` are each lane's own (valid [T, B, N]) rather than shared (valid [T, N])."""
    return np.ndim(frames.valid) == 3


_PROGRAMS: dict = {}


def data_capacity(frames: Frames) -> int:
    """Track slots for ``Options.capacity = 0`` (:func:`dfrmot_jax.trackers.capacity.from_data`): four
    per detection slot of the fullest frame, a multiple of 8, at least 16 (``run`` grows them where a lane needs more)."""
    return slots.from_data(int(np.max(np.sum(np.asarray(frames.valid), axis=-1), initial=0)), 4)


def _program(options: Options):
    fn = _PROGRAMS.get(options)
    if fn is None:
        def lanes(params, frames, states):
            last, out = run_lanes(params, frames, states, options)
            out = jax.tree.map(lambda v: jnp.swapaxes(v, 0, 1), out)
            return out, (last.overflow, last.peak, last.pairs_left, last.degenerate, last.fallback)
        fn = _PROGRAMS[options] = jax.jit(lanes)
    return fn


def clear_programs() -> None:
    """Forget the compiled programs."""
    _PROGRAMS.clear()


def broadcast_lanes(params: Params) -> Params:
    """``params`` as lanes: every leaf [B] (``as_arrays``' dtypes; scalars broadcast, one lane when
    all are)."""
    p = as_arrays(params)
    b = max([np.shape(v)[0] for v in p if np.ndim(v)] or [1])
    return Params(*(np.broadcast_to(np.atleast_1d(v), (b,)) for v in p))


def tracking_lanes(params: Params, frame_of=None) -> tuple[Params, np.ndarray]:
    """The lanes that track differently, and which of them each lane is: ``min_hits`` and
    ``score_threshold`` choose the written lines only (a track's life depends on ``threshold`` and
    ``max_age``), so lanes equal in those two track alike. Returns (their ``Params`` [C], with
    ``min_hits`` 0 and ``score_threshold`` -inf: every track ``max_age`` keeps is written; ``of``
    [B] int the tracking lane of each lane). ``params``: leaves [B] (``as_arrays``); ``frame_of``
    [B] int (optional): the frames each lane reads (lanes on different frames never track alike)."""
    cols = [np.asarray(params.threshold, np.float64).view(np.int64), np.asarray(params.max_age, np.int64)]
    if frame_of is not None:
        cols.append(np.asarray(frame_of, np.int64).reshape(-1))
    key = np.stack(cols, axis=1)
    _, first, of = np.unique(key, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")                # the tracking lanes in first-appearance order
    rank = np.empty(len(order), np.int64)
    rank[order] = np.arange(len(order))
    first, of = first[order], rank[np.asarray(of).reshape(-1)]
    c = len(first)
    core = Params(np.asarray(params.threshold)[first], np.zeros(c, np.int32), np.asarray(params.max_age)[first],
                  np.full(c, -np.inf))
    return core, of


def frame_counts(reset: np.ndarray) -> np.ndarray:
    """[T] int: each frame's count in its sequence, from 1 (``State.frame_count`` after its step)."""
    t = np.arange(len(reset))
    start = np.maximum.accumulate(np.where(np.asarray(reset, bool), t, 0))
    return t - start + 1


def written_lines(ids, hits, src, score, fc, min_hits, score_threshold) -> np.ndarray:
    """[B, T, K] the ids of lanes' written lines (-1 elsewhere) from their tracking lanes' output:
    ``ids`` [B, T, K] every track kept (``min_hits`` 0, ``score_threshold`` -inf), ``hits`` [B, T, K],
    ``src`` [B, T, K] each track's last detection (``t * N + slot``), ``score`` [T * N] the
    detections' scores (or each lane's own, [B, T * N]), ``fc`` [T] frame counts, ``min_hits`` /
    ``score_threshold`` [B]: the step's rule (``tracker.finish``), applied afterwards."""
    mh = np.asarray(min_hits, np.int64)[:, None, None]
    st = np.asarray(score_threshold, np.float64)[:, None, None]
    score = np.asarray(score, np.float64)
    if score.ndim == 2:
        last = score[np.arange(len(score))[:, None, None], np.maximum(src, 0)]
    else:
        last = score[np.maximum(src, 0)]
    keep = (ids >= 0) & ((hits >= mh) | (fc[None, :, None] <= mh)) & (last >= st)
    return np.where(keep, ids, -1).astype(np.int32)


def run(params: Params, frames: Frames, options: Options, first_id: int = 1, grow: bool = True,
        frame_of=None, lanes: int = 0) -> RunOutput:
    """Every lane of ``params`` (scalars: one lane; leaves [B]) over ``frames`` [T, N, ...], ids
    from ``first_id``. Validates the setting first (ValueError with every problem). Lanes that
    track alike (:func:`tracking_lanes`: the same ``threshold`` and ``max_age``) are tracked once,
    and each lane's lines chosen from that run by its ``min_hits`` and ``score_threshold``
    (:func:`written_lines`): the same output as each lane tracked alone. ``grow``: where a lane ran
    out of track slots (``overflow``), every lane runs again with twice as many (up to
    ``MAX_CAPACITY``, :func:`dfrmot_jax.trackers.capacity.grown`); the output says which ``options`` it ran with, and ``capacity`` [B] the slots
    each lane would have grown to alone (the first it did not overflow). Every pair is clipped
    (``pooled_affinity``): ``pairs_left`` is 0.

    ``frame_of`` [B] int: lanes on frames of their own: ``frames`` then hold D distinct frame sets
    (boxes [T, D, N, 7], valid and score [T, D, N], reset [T] shared) and lane b reads set
    ``frame_of[b]``; each tracking lane runs on its own (``src`` indexes its set's ``t * N + slot``),
    all in one compiled call: the same output as each lane run alone on its frames.
    ``lanes``: the call holds at least this many tracking lanes (the last repeated; its output
    dropped): calls of different lane counts share one compiled program."""
    validate(params, options)
    setup_host_devices()        # before the first JAX operation; the compile cache DFR-FastMOT's runs use
    p = broadcast_lanes(params)
    b = len(p.threshold)
    if frame_of is not None:
        frame_of = np.broadcast_to(np.asarray(frame_of, np.int64).reshape(-1), (b,))
    core, of = tracking_lanes(p, frame_of)
    t = np.shape(frames.valid)[0]
    if options.buckets == 0:
        options = options._replace(buckets=3 if t >= AUTO_BUCKETS_MIN_T else 1)
    if options.capacity == 0:
        options = options._replace(capacity=data_capacity(frames))
    c = core.threshold.shape[0]
    run_c = max(c, int(lanes))
    fill = np.minimum(np.arange(run_c), c - 1)               # (the tracking lanes, the last repeated)
    core = Params(*(np.asarray(v)[fill] for v in core))
    with jax.enable_x64(True):
        f = Frames(np.asarray(frames.boxes, np.float64), np.asarray(frames.valid, bool),
                   np.asarray(frames.score, np.float64), np.asarray(frames.reset, bool))
        if frame_of is not None:        # each tracking lane its own frames [T, C, N, ...]
            _, first = np.unique(of, return_index=True)    # (a lane of each tracking lane)
            own = frame_of[first][fill]
            f = Frames(f.boxes[:, own], f.valid[:, own], f.score[:, own], f.reset)
        capacity = np.zeros(run_c, np.int64)            # (each tracking lane's own: the first it fits)
        while True:
            states = jax.tree.map(lambda v: np.repeat(np.asarray(v)[None], run_c, 0), init(options, first_id))
            out, counters = call_compiled(lambda: _program(options)(core, f, states))
            out = jax.tree.map(np.asarray, out)
            counters = [np.asarray(v) for v in counters]        # overflow first
            capacity[(capacity == 0) & (counters[0] == 0)] = options.capacity
            more = slots.grown(options.capacity) if grow and counters[0].any() else None
            if more is None:
                break
            options = options._replace(capacity=more)
    capacity[capacity == 0] = options.capacity
    score = f.score.reshape(-1) if frame_of is None else np.moveaxis(f.score, 1, 0).reshape(run_c, -1)[of]
    ids = written_lines(out.ids[of], out.hits[of], out.src[of], score, frame_counts(f.reset),
                        p.min_hits, p.score_threshold)
    return RunOutput(ids, out.src[of], out.boxes[of], out.next_id[of], out.dropped[of],
                     *(c[of] for c in counters), options, capacity[of])
