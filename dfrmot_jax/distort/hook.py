"""The per-frame distortion: :func:`distort_frame` (pure, jittable, vmappable), the tracker's
hook :class:`FrameDistortion` (``trackers.dfr.run.FrameHook.fn``), and the host drivers
:func:`distort_split` / :func:`distort_lanes` that materialise distorted frames for evaluation
and tests."""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp

from ..boxes import truncate_2d_box, truncate_3d_box
from ..data import DEFAULT_IMAGE_SIZE
from ..frames import Frames
from . import draws
from .bursts import occluded
from .clutter import clutter_2d, clutter_3d
from .draws import normal, stream_hash, uniform
from .noise import jitter_box, score_noise, shift_3d
from .spec import DistortParams, DistortSpec, cast_params


class FrameDistortion(NamedTuple):
    """The tracker's per-frame hook (``trackers.dfr.run.FrameHook.fn``) of a distortion study: hashable by
    its static spec; the hook's lane values are ``DistortParams``, its xs the (gid2, gid3) arrays."""

    spec: DistortSpec

    def __call__(self, frame: Frames, dp: DistortParams, gids, t) -> Frames:
        return distort_frame(frame, gids[0], gids[1], t, dp, self.spec)


def distort_frame(frame: Frames, gid2, gid3, t, dp: DistortParams, spec: DistortSpec,
                  image_size=DEFAULT_IMAGE_SIZE) -> Frames:
    """One frame's inputs distorted for one lane (pure, jittable, vmappable over ``dp``).

    frame:  one frame of ``Frames`` (reset [], box2 [M2, 4], score2 [M2], valid2 [M2], box3 [M3, 4],
            score3 [M3], valid3 [M3], lo3 / hi3 [M3, 3]); with clutter, slots from
            ``clutter.pad_for_clutter`` (the last ``spec.clutter_slots`` of each modality).
    gid2:   [M2] int32 ground-truth id of each 2D slot (``identity.gt_identity``, -1 = none).
    gid3:   [M3] int32 the same for 3D slots.
    t:      int32 scalar, the frame's global index in the split (seeds the per-frame streams).
    dp:     ``DistortParams`` of this lane (scalars); ``spec`` static; ``image_size`` (W, H) static.

    Returns a ``Frames`` slice of the same shapes and dtypes (float32 boxes and scores, bool
    masks); with every level 0 it is bit-identical to ``frame``. Groups not in ``spec.enabled``
    are not computed. Call it under ``jax.enable_x64`` (as the tracker's step runs) for values
    bit-identical to :func:`distort_split`. See the package docstring (``dfrmot_jax.distort``) for the meaning of each
    level and the order of the steps.
    """
    return apply_draws(frame, gid2, gid3, t, dp, spec, HashDraws(), image_size)


class HashDraws(NamedTuple):
    """Where :func:`apply_draws` takes its randomness: the counter-based hash streams of
    ``draws`` (the package's choice, see its docstring). ``benchmarks/bench_distort_rng.py`` hands
    the same steps ``jax.random`` keys instead, to measure the difference."""

    def streams(self, seed, t):
        return functools.partial(stream_hash, seed, t)

    def uniform(self, key, shape):
        return uniform(key, shape)

    def normal(self, key, shape):
        return normal(key, shape)

    def occluded(self, gid, t, dp, spec):
        return occluded(gid, t, dp, spec)


def apply_draws(frame: Frames, gid2, gid3, t, dp: DistortParams, spec: DistortSpec, source,
                image_size=DEFAULT_IMAGE_SIZE, pose: bool = False):
    """The steps of :func:`distort_frame` with the random draws of ``source`` (``HashDraws``).
    With ``pose``: (frame, [S, 4] float32 x, y, z, heading of the 3D clutter slots' boxes, zeros
    without clutter; ``clutter.Placement3D.pose``), what a family tracking rotated 3D boxes reads."""
    dp = cast_params(dp)
    t = jnp.asarray(t, jnp.int32)
    gid2 = jnp.asarray(gid2, jnp.int32)
    gid3 = jnp.asarray(gid3, jnp.int32)
    m2 = frame.valid2.shape[0]
    key = source.streams(dp.seed, t)

    valid2, valid3 = frame.valid2, frame.valid3
    box2, box3, lo3, hi3 = frame.box2, frame.box3, frame.lo3, frame.hi3
    score2, score3 = frame.score2, frame.score3
    on = set(spec.enabled)
    # 1. occlusion bursts (one test for the 2D and 3D slots together: same object, same answer)
    if "burst" in on:
        occ = source.occluded(jnp.concatenate([gid2, gid3]), t, dp, spec)
        valid2 = valid2 & ~occ[:m2]
        valid3 = valid3 & ~occ[m2:]
    # 2. independent drops
    if "drop" in on:
        valid2 = valid2 & ~(source.uniform(key(draws.DROP2), valid2.shape) < dp.drop_2d)
        valid3 = valid3 & ~(source.uniform(key(draws.DROP3), valid3.shape) < dp.drop_3d)
    # 3. jitter (only slots holding a detection move: empty slots stay as they are)
    if "jitter" in on:
        box2 = jitter_box(box2, frame.valid2, dp.jitter_2d, source.normal(key(draws.JIT2), box2.shape),
                          truncate_2d_box if spec.truncate else None)
        box3 = jitter_box(box3, frame.valid3, dp.jitter_box3, source.normal(key(draws.JITB3), box3.shape),
                          truncate_3d_box if spec.truncate else None)
        lo3, hi3 = shift_3d(lo3, hi3, frame.valid3, dp.jitter_3d, source.normal(key(draws.JIT3), lo3.shape))
    # 4. score noise
    if "score" in on:
        n2 = source.normal(key(draws.SCORE2), score2.shape)
        n3 = source.normal(key(draws.SCORE3), score3.shape)
        score2 = score_noise(score2, frame.valid2, dp.score_noise_2d, n2)
        score3 = score_noise(score3, frame.valid3, dp.score_noise_3d, n3)
    # 5. clutter in the reserved slots (free space judged against the frame's real detections)
    where = jnp.zeros((int(spec.clutter_slots), 4), jnp.float32)
    if spec.clutter_slots > 0 and "clutter" in on:
        box2, score2, valid2 = clutter_2d(key(draws.CLUT2), box2, score2, valid2, frame.valid2, dp.clutter_2d,
                                           spec, image_size)
        box3, score3, valid3, lo3, hi3, *placed = clutter_3d(key(draws.CLUT3), box3, score3, valid3, lo3, hi3,
                                                              frame.valid3, dp.clutter_3d, spec, image_size, pose)
        where = placed[0] if pose else where
    out = Frames(reset=frame.reset, box2=box2, score2=score2, valid2=valid2, box3=box3, score3=score3,
                 valid3=valid3, lo3=lo3, hi3=hi3)
    return (out, where) if pose else out


@functools.partial(jax.jit, static_argnames=("spec", "image_size", "pose"))
def _distort_all(frames, gid2, gid3, t, dp, spec, image_size, pose=False):
    return jax.vmap(lambda fr, g2, g3, tt: apply_draws(fr, g2, g3, tt, dp, spec, HashDraws(), image_size, pose))(
        frames, gid2, gid3, t)


@functools.partial(jax.jit, static_argnames=("spec", "image_size", "pose"))
def _distort_lanes(frames, gid2, gid3, t, dp, spec, image_size, pose=False):
    return jax.vmap(lambda d: _distort_all(frames, gid2, gid3, t, d, spec, image_size, pose))(dp)


def _on_host(fn, frames: Frames, gid2, gid3, dp: DistortParams, spec: DistortSpec, image_size, t0: int, pose: bool):
    """``fn`` (:func:`_distort_all` or :func:`_distort_lanes`) of the frames under x64."""
    with jax.enable_x64(True):
        frames = Frames(*(jnp.asarray(x) for x in frames))
        t = jnp.arange(frames.reset.shape[0], dtype=jnp.int32) + jnp.int32(t0)
        return fn(frames, jnp.asarray(gid2, jnp.int32), jnp.asarray(gid3, jnp.int32), t, cast_params(dp), spec,
                  tuple(image_size), pose)


def distort_lanes(frames: Frames, gid2, gid3, dp: DistortParams, spec: DistortSpec,
                  image_size=DEFAULT_IMAGE_SIZE, t0: int = 0, pose: bool = False):
    """:func:`distort_split` for a batch ``dp [B]`` (e.g. from ``spec.stack_distort``): Frames
    ``[B, T, ...]``, one jit(vmap) call (with ``pose``, and the clutter's poses [B, T, S, 4]).
    Materialises B copies: for evaluation and tests."""
    return _on_host(_distort_lanes, frames, gid2, gid3, dp, spec, image_size, t0, pose)


def distort_split(frames: Frames, gid2, gid3, dp: DistortParams, spec: DistortSpec,
                  image_size=DEFAULT_IMAGE_SIZE, t0: int = 0, pose: bool = False):
    """All frames ``[T, ...]`` of one lane distorted (global frame index ``t0 + arange(T)``).

    The same bits the scanned step sees frame by frame when the step runs under ``jax.enable_x64``
    as the tracker's does (see ``exact.lin``); runs under x64 itself. For evaluation, plots and
    tests: materialises one lane's ``[T, ...]`` copy. ``dp`` scalars (:func:`distort_lanes` for a
    batch). With ``pose``: (frames, [T, S, 4] the 3D clutter slots' x, y, z, heading;
    :func:`apply_draws`).
    """
    return _on_host(_distort_all, frames, gid2, gid3, dp, spec, image_size, t0, pose)
