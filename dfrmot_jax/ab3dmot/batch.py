"""AB3DMOT over a split for a batch of settings: ``lax.scan`` of ``tracker.step`` over the frames,
``vmap`` over a ``Params`` batch [B], jitted once per ``Options`` (and frame shape), under
``jax.enable_x64``.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import numpy as np
from jax import lax

from .config import Options, Params, as_arrays, validate
from .tracker import Frames, State, StepOutput, init, step

__all__ = ["RunOutput", "run", "run_lane", "clear_programs"]


class RunOutput(NamedTuple):
    """A batch's output (NumPy): ``ids`` [B, T, K] (-1: not written), ``src`` [B, T, K], ``boxes``
    [B, T, K, 7] (``StepOutput``'s fields per frame), ``next_id`` [B, T] (the id counter after
    each frame), and per lane [B]: ``overflow`` (births dropped), ``peak`` (most slots needed),
    ``pairs_left``, ``degenerate``, ``fallback`` (see ``tracker.State``): a lane is AB3DMOT's exactly
    when all of ``overflow``, ``pairs_left``, ``degenerate`` and ``fallback`` are 0."""

    ids: np.ndarray
    src: np.ndarray
    boxes: np.ndarray
    next_id: np.ndarray
    overflow: np.ndarray
    peak: np.ndarray
    pairs_left: np.ndarray
    degenerate: np.ndarray
    fallback: np.ndarray


def run_lane(params: Params, frames: Frames, state: State, options: Options) -> tuple[State, StepOutput]:
    """One lane over frames [T, ...] from ``state``: (final state, outputs [T, ...]). Traceable."""
    return lax.scan(lambda s, f: step(params, s, f, options), state, frames)


_PROGRAMS: dict = {}


def _program(options: Options):
    fn = _PROGRAMS.get(options)
    if fn is None:
        def lanes(params, frames, state):
            last, out = jax.vmap(run_lane, in_axes=(0, None, None, None))(params, frames, state, options)
            return out, (last.overflow, last.peak, last.pairs_left, last.degenerate, last.fallback)
        fn = _PROGRAMS[options] = jax.jit(lanes)
    return fn


def clear_programs() -> None:
    """Forget the compiled programs."""
    _PROGRAMS.clear()


def run(params: Params, frames: Frames, options: Options, first_id: int = 1) -> RunOutput:
    """Every lane of ``params`` (scalars: one lane; leaves [B]) over ``frames`` [T, N, ...], ids
    from ``first_id``. Validates the setting first (ValueError with every problem)."""
    validate(params, options)
    p = as_arrays(params)
    b = max([np.shape(v)[0] for v in p if np.ndim(v)] or [1])
    p = Params(*(np.broadcast_to(np.atleast_1d(v), (b,)) for v in p))
    with jax.enable_x64(True):
        f = Frames(np.asarray(frames.boxes, np.float64), np.asarray(frames.valid, bool),
                   np.asarray(frames.score, np.float64), np.asarray(frames.reset, bool))
        out, counters = _program(options)(p, f, init(options, first_id))
        out = jax.tree.map(np.asarray, out)
        counters = [np.asarray(c) for c in counters]
    return RunOutput(out.ids, out.src, out.boxes, out.next_id, *counters)
