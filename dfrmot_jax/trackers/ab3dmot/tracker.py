"""One frame of AB3DMOT's tracker (61f3bd7 ``AB3DMOT.track``, ego-motion compensation off) as a pure
function on padded arrays: ``init`` makes the empty ``State``, ``step(params, state, frame,
options)`` returns the next state and the frame's ``StepOutput``.

Layout: the frame's detections fill slots ``0 .. n - 1`` of N in file order (``valid``); the live
tracks fill slots ``0 .. count - 1`` of K in creation order (AB3DMOT's list), births are appended,
and the dead are removed at the end of each step, keeping that order. Every choice follows these
orders, so a padded slot changes nothing.

One step, AB3DMOT's order:

1. a frame with ``reset`` starts a sequence: no tracks, frame counter 0 (the id counter runs on);
2. every live track is predicted (``kalman.predict``), ``time_since_update`` += 1;
3. ``A[det, trk]`` (float32, ``affinity``); Hungarian (``hungarian.assign``) or greedy
   (``greedy.greedy``) assignment over all pairs; an assigned pair is rejected when its affinity
   is below the threshold (float64; ``config.compared_threshold``);
4. matched tracks: heading corrected towards the detection's (``kalman.orientation_correction``),
   Kalman update, hits += 1, ``time_since_update`` = 0, their detection remembered (``src``);
5. births: first the detections the assignment left out (ascending), then the rejected ones in
   assignment order (Hungarian: ascending detection; greedy: the order pairs were taken); each
   takes the next id; births beyond the capacity K are dropped and counted (``overflow``);
6. output: a track is written when ``time_since_update < max_age`` and ``hits >= min_hits`` or
   the frame is one of the sequence's first ``min_hits``, and its detection's score is
   ``>= score_threshold``; then tracks with ``time_since_update >= max_age`` are deleted.

Runs under ``jax.enable_x64`` (float64 boxes and parameters; ``batch.run`` sets it).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from . import kalman
from .affinity import affinity
from .config import Options, Params, compared_threshold
from .exact import runtime_zero
from .greedy import greedy
from .hungarian import assign

__all__ = ["Frames", "State", "StepOutput", "Predicted", "Decision", "init", "step", "predict", "decide", "finish",
           "finite_affinity", "NON_FINITE_STAND_IN"]


class Frames(NamedTuple):
    """Padded frames, [T, ...] (one frame: without T).

    boxes:  [T, N, 7] float64 detection states ``[x, y, z, theta, l, w, h]`` (the CSV's
            ``h, w, l, x, y, z, rot_y`` reordered), valid ones first in file order.
    valid:  [T, N] bool.
    score:  [T, N] float64 detection scores.
    reset:  [T] bool: the frame is the first of a sequence.
    """

    boxes: np.ndarray
    valid: np.ndarray
    score: np.ndarray
    reset: np.ndarray


class State(NamedTuple):
    """The tracker between frames (per lane; K = ``Options.capacity``).

    filt:        the tracks' Kalman filters (``kalman.Gauss``, [K, ...]).
    ids, hits, age:  [K] int32 track id, matches (birth included), frames since the last match.
    src:         [K] int32 the last matched detection as ``t * N + slot`` (t: the step's index).
    score:       [K] float64 that detection's score.
    count:       live tracks (slots ``0 .. count - 1``, in creation order).
    next_id:     the id of the next birth (one counter across sequences, as AB3DMOT's).
    frame_count: frames of the current sequence so far; t: steps taken.
    overflow:    births dropped for want of a slot (results differ from AB3DMOT's from there on).
    peak:        the most slots a frame needed (live tracks plus births).
    pairs_left:  IoU metrics: pairs beyond ``Options.pairs`` taken as apart (not AB3DMOT's).
    degenerate:  pairs where AB3DMOT's geometry raises or whose affinity is not finite (its run would have
                 stopped there).
    fallback:    greedy sorts that reached NumPy's heapsort, not reproduced.
    """

    filt: kalman.Gauss
    ids: np.ndarray
    hits: np.ndarray
    age: np.ndarray
    src: np.ndarray
    score: np.ndarray
    count: np.ndarray
    next_id: np.ndarray
    frame_count: np.ndarray
    t: np.ndarray
    overflow: np.ndarray
    peak: np.ndarray
    pairs_left: np.ndarray
    degenerate: np.ndarray
    fallback: np.ndarray


class StepOutput(NamedTuple):
    """One frame's output, by track slot (creation order; AB3DMOT writes newest first).

    ids:      [K] int32 the written tracks' ids, -1 elsewhere.
    src:      [K] int32 their last detection (``t * N + slot``): alpha, type, 2D box and score.
    boxes:    [K, 7] float64 their 3D boxes, the Kalman state ``[x, y, z, theta, l, w, h]``
              ([K, 0] without ``Options.boxes``).
    next_id:  the id counter after the frame.
    dropped:  births dropped for want of a slot in the frame (``State.overflow``'s increment).
    hits:     [K] int32 every slot's matches so far (birth included): with ``min_hits`` 0 and
              ``score_threshold`` -inf, ``ids`` are every track ``max_age`` keeps, and the lines of
              any other ``min_hits`` / ``score_threshold`` follow from ``hits``, the frame's count
              in its sequence and the detections' scores (``batch.run`` shares lanes so).
    """

    ids: np.ndarray
    src: np.ndarray
    boxes: np.ndarray
    next_id: np.ndarray
    dropped: np.ndarray
    hits: np.ndarray


def init(options: Options, first_id: int = 1) -> State:
    """The empty state (NumPy arrays: float64 whatever JAX's x64 setting); ids start at first_id."""
    k = options.capacity
    if k < 1:
        raise ValueError(f"Options.capacity {k}: a lane's state needs track slots (batch.run chooses them for 0)")
    i32 = lambda v=0: np.int32(v)                                          # noqa: E731
    filt = kalman.Gauss(np.zeros((k, 10)), np.zeros((k, 3)), np.zeros((k, 3)), np.zeros((k, 3)),
                        np.zeros((k, 3)), np.zeros((k, 4)))
    ints = np.zeros(k, np.int32)
    return State(filt, ints - 1, ints, ints, ints - 1, np.zeros(k), i32(), i32(first_id), i32(), i32(),
                 i32(), i32(), i32(), i32(), i32())


def _pick(mask, new, old):
    """``new`` where ``mask`` [K], else ``old`` (leaves [K, ...])."""
    return jax.tree.map(lambda a, b: jnp.where(mask.reshape(mask.shape + (1,) * (a.ndim - 1)), a, b), new, old)


def _associate(a32, n, m, params: Params, options: Options):
    """(det_track [N], kept [N], order key [N], greedy fallback) of the assignment and threshold."""
    n_det = a32.shape[0]
    if options.algorithm == "hungarian":
        det_track, key, fallback = assign(a32, n, m), jnp.arange(n_det, dtype=jnp.int32), jnp.zeros((), bool)
    else:
        det_track, key, fallback = greedy(a32, n, m)
    assigned = det_track >= 0
    value = a32[jnp.arange(n_det), jnp.maximum(det_track, 0)].astype(jnp.float64)
    threshold = compared_threshold(jnp.asarray(params.threshold, jnp.float64), options.metric)
    return det_track, assigned & ~(value < threshold), key, fallback


def _births(state_ids, filt, hits, age, src, score, frame, det_track, kept, key, count, next_id, t):
    """New tracks for the unmatched detections at slots count, count + 1, ... (ids from next_id):
    the updated per-slot arrays, slots used, births (placed or not)."""
    n_det, k = frame.valid.shape[0], state_ids.shape[0]
    det_i, slot = jnp.arange(n_det), jnp.arange(k)
    unassigned = frame.valid & (det_track < 0)
    born = frame.valid & ~kept
    bkey = jnp.where(unassigned, det_i, n_det + key)
    rank = jnp.sum(born[None, :] & (bkey[None, :] < bkey[:, None]), 1)
    placed = born & (rank < k - count)
    onto = placed[None, :] & ((count + rank)[None, :] == slot[:, None])          # [K, N]
    new, d = jnp.any(onto, 1), jnp.argmax(onto, 1)
    filt = _pick(new, kalman.birth(frame.boxes[d]), filt)
    ids = jnp.where(new, next_id + rank[d], state_ids).astype(jnp.int32)
    hits, age = jnp.where(new, 1, hits), jnp.where(new, 0, age)
    src = jnp.where(new, t * n_det + d, src).astype(jnp.int32)
    score = jnp.where(new, frame.score[d], score)
    return (filt, ids, hits, age, src, score), count + jnp.sum(placed), jnp.sum(born)


class Predicted(NamedTuple):
    """A lane after the prediction of a frame (``predict``): live tracks, frame counter, filters
    [K, ...] and ``time_since_update`` [K]."""

    count: jnp.ndarray
    frame_count: jnp.ndarray
    filt: kalman.Gauss
    age: jnp.ndarray


class Decision(NamedTuple):
    """The association of a frame (``decide``): per detection [N] its assigned track (-1: none),
    whether the pair passed the threshold and its assignment order key; the greedy sort's
    fallback, the degenerate pairs and the pairs beyond ``Options.pairs``."""

    det_track: jnp.ndarray
    kept: jnp.ndarray
    key: jnp.ndarray
    fallback: jnp.ndarray
    degenerate: jnp.ndarray
    pairs_left: jnp.ndarray


def predict(state: State, frame: Frames) -> Predicted:
    """Steps 1-2: a reset, then every track predicted."""
    return Predicted(jnp.where(frame.reset, 0, state.count), jnp.where(frame.reset, 0, state.frame_count) + 1,
                     kalman.predict(state.filt), state.age + 1)


#: what a non-finite affinity is replaced by before the assignment (its pair counted as degenerate)
NON_FINITE_STAND_IN = float(np.finfo(np.float32).min)


def finite_affinity(a32, bad):
    """(A, degenerate) with every non-finite affinity (NaN: 0 / 0 of zero-size or zero-height
    boxes; -inf: a distance beyond float32) replaced by ``NON_FINITE_STAND_IN`` and marked
    degenerate: AB3DMOT's scipy raises on such a matrix (its run stops), and the assignments'
    loops need finite costs to end (a NaN cost never enters Hungarian's shortest-path tree, whose
    augmenting walk then never reaches its root; NaN keys unsettle the greedy introsort)."""
    ok = jnp.isfinite(a32)
    return jnp.where(ok, a32, jnp.float32(NON_FINITE_STAND_IN)), bad | ~ok


def decide(params: Params, pred: Predicted, frame: Frames, options: Options, size=None, matrix=None) -> Decision:
    """Step 3 on the first ``size = (n, k)`` detection and track slots (default all; every valid
    detection and live track must lie there): the decision, padded back to N detections.
    ``matrix``: (A [N, K] float32, degenerate [N, K], pairs left) computed elsewhere (``batch``);
    default: ``affinity`` here."""
    n_det = frame.valid.shape[0]
    nb, kb = size or (n_det, pred.age.shape[0])
    valid = frame.valid[:nb]
    pairs = valid[:, None] & (jnp.arange(kb) < pred.count)[None]
    if matrix is None:
        filt = jax.tree.map(lambda v: v[:kb], pred.filt)
        a32, bad, left = affinity(frame.boxes[:nb], filt.x[:, :7], options.metric, runtime_zero(pred.frame_count),
                                  kalman.innovation(filt), pairs, options.pairs or None)
    else:
        a32, bad, left = matrix[0][:nb, :kb], matrix[1][:nb, :kb], matrix[2]
    a32, bad = finite_affinity(a32, bad)
    n = jnp.sum(valid).astype(jnp.int32)
    det_track, kept, key, fallback = _associate(a32, n, pred.count, params, options)
    pad = lambda v, fill: jnp.concatenate([v, jnp.full((n_det - nb,), fill, v.dtype)])    # noqa: E731
    return Decision(pad(det_track, -1), pad(kept, False), pad(key, 0), fallback,
                    jnp.sum(bad & pairs).astype(jnp.int32), jnp.asarray(left, jnp.int32))


def step(params: Params, state: State, frame: Frames, options: Options) -> tuple[State, StepOutput]:
    """One frame (see the module's docstring): (next state, output)."""
    pred = predict(state, frame)
    return finish(params, state, frame, options, pred, decide(params, pred, frame, options))


def finish(params: Params, state: State, frame: Frames, options: Options, pred: Predicted,
           dec: Decision) -> tuple[State, StepOutput]:
    """Steps 4-6: updates, births, output, deletion."""
    n_det, k = frame.valid.shape[0], options.capacity
    slot = jnp.arange(k)
    count, fc, filt, age = pred
    zero = runtime_zero(fc)
    det_track, kept, key = dec.det_track, dec.kept, dec.key
    match = (det_track[:, None] == slot[None]) & kept[:, None]                    # [N, K]
    has, d = jnp.any(match, 0), jnp.argmax(match, 0)
    z = frame.boxes[d]
    pre, obs = kalman.orientation_correction(filt.x[:, 3], z[:, 3], zero)
    turned = filt._replace(x=filt.x.at[:, 3].set(pre))
    filt = _pick(has, kalman.update(turned, z.at[:, 3].set(obs), zero), filt)
    hits = state.hits + has
    age = jnp.where(has, 0, age)
    src = jnp.where(has, state.t * n_det + d, state.src).astype(jnp.int32)
    score = jnp.where(has, frame.score[d], state.score)
    slots, total, n_born = _births(state.ids, filt, hits, age, src, score, frame, det_track, kept, key, count,
                                   state.next_id, state.t)
    filt, ids, hits, age, src, score = slots
    exists = slot < total
    written = exists & (age < params.max_age) & ((hits >= params.min_hits) | (fc <= params.min_hits)) \
        & (score >= params.score_threshold)
    next_id = state.next_id + n_born
    dropped = jnp.asarray(n_born - (total - count), jnp.int32)
    out = StepOutput(jnp.where(written, ids, -1), src, filt.x[:, :7] if options.boxes else filt.x[:, :0], next_id,
                     dropped, hits.astype(jnp.int32))
    alive = exists & (age < params.max_age)
    onto = alive[None, :] & ((jnp.cumsum(alive) - 1)[None, :] == slot[:, None])  # [new slot, old slot]
    take = jnp.argmax(onto, 1)
    filt, ids, hits, age, src, score = jax.tree.map(lambda v: v[take], (filt, ids, hits, age, src, score))
    i32 = lambda v: jnp.asarray(v, jnp.int32)                                      # noqa: E731
    new = State(filt, ids, hits, age, src, score, i32(jnp.sum(alive)), i32(next_id), i32(fc), i32(state.t + 1),
                i32(state.overflow + dropped), i32(jnp.maximum(state.peak, count + n_born)),
                i32(state.pairs_left + dec.pairs_left), i32(state.degenerate + dec.degenerate),
                i32(state.fallback + dec.fallback))
    return new, out
