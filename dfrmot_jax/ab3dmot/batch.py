"""AB3DMOT over a split for a batch of settings: ``lax.scan`` over the frames of ``tracker.step``
vmapped over a ``Params`` batch [B], jitted once per ``Options`` (and frame shape), under
``jax.enable_x64``. With ``Options.buckets`` > 1 each frame's association (the affinity matrix,
where the time goes) runs on the smallest of a few slot counts that holds its detections and every
lane's live tracks (``lax.switch`` on an index shared by the lanes).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import numpy as np
from jax import lax

from .config import AUTO_BUCKETS_MIN_T, Options, Params, as_arrays, validate
import jax.numpy as jnp

from .tracker import Frames, State, StepOutput, decide, finish, init, predict, step

__all__ = ["RunOutput", "run", "run_lane", "run_lanes", "affinity_sizes", "clear_programs", "MAX_TRACKS"]


class RunOutput(NamedTuple):
    """A batch's output (NumPy): ``ids`` [B, T, K] (-1: not written), ``src`` [B, T, K], ``boxes``
    [B, T, K, 7] (``StepOutput``'s fields per frame), ``next_id`` [B, T] (the id counter after
    each frame), and per lane [B]: ``overflow`` (births dropped), ``peak`` (most slots needed),
    ``pairs_left``, ``degenerate``, ``fallback`` (see ``tracker.State``): a lane is AB3DMOT's exactly
    when all of ``overflow``, ``pairs_left``, ``degenerate`` and ``fallback`` are 0; ``options``:
    the ``Options`` of the run (capacities grown, buckets chosen)."""

    ids: np.ndarray
    src: np.ndarray
    boxes: np.ndarray
    next_id: np.ndarray
    overflow: np.ndarray
    peak: np.ndarray
    pairs_left: np.ndarray
    degenerate: np.ndarray
    fallback: np.ndarray
    options: Options | None = None


def run_lane(params: Params, frames: Frames, state: State, options: Options) -> tuple[State, StepOutput]:
    """One lane over frames [T, ...] from ``state``: (final state, outputs [T, ...]). Traceable."""
    return lax.scan(lambda s, f: step(params, s, f, options), state, frames)


def affinity_sizes(n_det: int, tracks: int, buckets: int) -> tuple[tuple[int, int], ...]:
    """The (detection, track) slot counts a frame's association may run on, smallest first:
    ``ceil(N / 2^s), ceil(K / 2^s)`` for s = buckets - 1 .. 0 (0 buckets: one, the full size)."""
    out = []
    for s in range(max(buckets, 1) - 1, -1, -1):
        size = (max(1, -(-n_det // (1 << s))), max(1, -(-tracks // (1 << s))))
        if size not in out:
            out.append(size)
    return tuple(out)


def run_lanes(params: Params, frames: Frames, states: State, options: Options) -> tuple[State, StepOutput]:
    """Every lane (``params``, ``states`` leaves [B]) over frames [T, ...]: the scan over frames of
    the vmapped step, whose association runs on the smallest of ``affinity_sizes`` holding the
    frame's valid detections and every lane's live tracks (the same result: slots beyond hold
    nothing). Outputs [T, B, ...]. Traceable."""
    n_det = frames.valid.shape[1]
    sizes = affinity_sizes(n_det, options.tracks, options.buckets)

    def body(s, f):
        pred = jax.vmap(predict, in_axes=(0, None))(s, f)

        def at(size):
            return lambda p, pr: jax.vmap(lambda q, r: decide(q, r, f, options, size))(p, pr)

        if len(sizes) == 1:
            dec = at(None)(params, pred)
        else:
            need_n = jnp.max(jnp.where(f.valid, jnp.arange(n_det) + 1, 0))
            need_k = jnp.max(pred.count)
            fits = jnp.array([(need_n <= nb) & (need_k <= kb) for nb, kb in sizes])
            dec = lax.switch(jnp.argmax(fits), [at(size) for size in sizes], params, pred)
        return jax.vmap(finish, in_axes=(0, 0, None, None, 0, 0))(params, s, f, options, pred, dec)

    return lax.scan(body, states, frames)


_PROGRAMS: dict = {}
#: the most track slots ``run`` grows to
MAX_TRACKS = 4096


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


def run(params: Params, frames: Frames, options: Options, first_id: int = 1, grow: bool = True) -> RunOutput:
    """Every lane of ``params`` (scalars: one lane; leaves [B]) over ``frames`` [T, N, ...], ids
    from ``first_id``. Validates the setting first (ValueError with every problem). ``grow``: where
    a lane ran out of track slots (``overflow``) or of clipped pairs (``pairs_left``), every lane
    runs again with twice that capacity (tracks up to ``MAX_TRACKS``, pairs up to N K); the output
    says which ``options`` it ran with."""
    validate(params, options)
    p = as_arrays(params)
    b = max([np.shape(v)[0] for v in p if np.ndim(v)] or [1])
    p = Params(*(np.broadcast_to(np.atleast_1d(v), (b,)) for v in p))
    n_det, t = np.shape(frames.valid)[1], np.shape(frames.valid)[0]
    if options.buckets == 0:
        options = options._replace(buckets=3 if t >= AUTO_BUCKETS_MIN_T else 1)
    with jax.enable_x64(True):
        f = Frames(np.asarray(frames.boxes, np.float64), np.asarray(frames.valid, bool),
                   np.asarray(frames.score, np.float64), np.asarray(frames.reset, bool))
        while True:
            states = jax.tree.map(lambda v: np.repeat(np.asarray(v)[None], b, 0), init(options, first_id))
            out, counters = _program(options)(p, f, states)
            out = RunOutput(*jax.tree.map(np.asarray, tuple(out)), *(np.asarray(c) for c in counters), options)
            more = {}
            if grow and out.overflow.any() and options.tracks < MAX_TRACKS:
                more["tracks"] = min(2 * options.tracks, MAX_TRACKS)
            if grow and out.pairs_left.any() and 0 < options.pairs < n_det * options.tracks:
                more["pairs"] = min(2 * options.pairs, n_det * options.tracks)
            if not more:
                return out
            options = options._replace(**more)
