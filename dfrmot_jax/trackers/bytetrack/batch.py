"""Many lanes (``Params`` [B]) of ByteTrack over one run of padded frames: a ``lax.scan`` over
frames of ``tracker.step_batch`` (the lanes vmapped inside each frame's step, so that lapjv's full
emulation runs only for the lanes whose association needs it, one lane at a time), one compilation
per ``Options`` and shape; B = 1 runs ``tracker.step`` (its branches then taken for real)."""

from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .config import Options, Params
from .tracker import Frames, init, step, step_batch

__all__ = ["RunOutput", "pack_frames", "run", "data_capacity"]


class RunOutput(NamedTuple):
    """Per lane, per frame, per slot: tid, tlwh, score, written [B, T, K]; overflow / solver [B]; key
    [B, T, K] each track's order in its list (a frame's written tracks in ByteTrack's output order:
    ascending key)."""
    tid: np.ndarray
    tlwh: np.ndarray
    score: np.ndarray
    written: np.ndarray
    overflow: np.ndarray
    solver: np.ndarray
    key: np.ndarray | None = None


def pack_frames(sequences: list[list[np.ndarray]], d: int | None = None) -> Frames:
    """Frames of one or more sequences one after the other (``reset`` at each one's first frame),
    padded to ``d`` detections (default the most of a frame, at least 1)."""
    flat = [f for seq in sequences for f in seq]
    d = d or max(1, max((len(f) for f in flat), default=1))
    t = len(flat)
    dets = np.zeros((t, d, 5))
    dets[:, :, 2:4] = 1.0
    valid = np.zeros((t, d), bool)
    reset = np.zeros(t, bool)
    i = 0
    for seq in sequences:
        if seq:
            reset[i] = True
        for f in seq:
            n = min(len(f), d)
            dets[i, :n] = f[:n]
            valid[i, :n] = True
            i += 1
    return Frames(dets, valid, reset)


def data_capacity(frames: Frames) -> int:
    """A track capacity from the data: twice the most detections of a frame, at least 8."""
    return int(max(8, 2 * np.asarray(frames.valid).sum(axis=1).max(initial=0)))


@lru_cache(maxsize=32)
def _program(options: Options, k: int, batched: bool, lanes_in_step: bool = False):
    """One lane (``Params`` scalars): outputs [T, ...]. Batched (``Params`` [B]): outputs [B, T, ...],
    the lanes one after the other (``lax.map`` of the one-lane scan: its branches taken for real,
    the fastest on CPU), or with ``lanes_in_step`` vmapped inside each frame's step
    (``tracker.step_batch``: lapjv's full emulation one lane at a time, the rest vectorised)."""
    def scan(p, frames, st0, fn):
        def body(st, fr):
            return fn(p, options, st, fr[0], fr[1], fr[2])
        st, outs = jax.lax.scan(body, st0, (frames.dets, frames.valid, frames.reset))
        return outs, st.overflow, st.solver

    def one(p, frames):
        return scan(p, frames, init(k), step)

    def lanes(p, frames):
        if lanes_in_step:
            b = p.track_thresh.shape[0]
            st0 = jax.tree.map(lambda a: jnp.broadcast_to(a, (b,) + a.shape), init(k))
            outs, ov, sv = scan(p, frames, st0, step_batch)
            return jax.tree.map(lambda a: jnp.swapaxes(a, 0, 1), outs), ov, sv
        return jax.lax.map(lambda q: one(q, frames), p)
    return jax.jit(lanes if batched else one)


def run(params: Params, options: Options, frames: Frames, capacity: int | None = None) -> RunOutput:
    """All lanes of ``params`` (leaves [B]) over ``frames``; ``capacity`` track slots (default
    :func:`data_capacity`)."""
    k = capacity or data_capacity(frames)
    options = options._replace(demo_filter=False)         # a writer's filter: not in the program
    with jax.enable_x64(True):
        p = Params(np.asarray(params.track_thresh, np.float64).reshape(-1),
                   np.asarray(params.match_thresh, np.float64).reshape(-1),
                   np.asarray(params.track_buffer, np.int32).reshape(-1),
                   np.asarray(params.det_thresh_margin, np.float64).reshape(-1))
        b = p.track_thresh.shape[0]
        f = Frames(jnp.asarray(frames.dets, jnp.float64), jnp.asarray(frames.valid), jnp.asarray(frames.reset))
        if b == 1:
            outs, ov, sv = _program(options, k, False)(Params(*(v[0] for v in p)), f)
            outs, ov, sv = jax.tree.map(lambda a: np.asarray(a)[None], (outs, ov, sv))
        else:
            outs, ov, sv = jax.tree.map(np.asarray, _program(options, k, True, jax.default_backend() != "cpu")(p, f))
    return RunOutput(outs.tid, outs.tlwh, outs.score, outs.written, ov, sv, outs.key)
