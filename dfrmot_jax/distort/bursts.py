"""Occlusion bursts: per (ground-truth object, start frame) a burst starts with probability
``burst_rate`` and lasts a drawn number of frames; stateless in ``(seed, g, s)``, so object ``g``
is occluded at ``t`` when some ``s in (t - burst_max, t]`` starts a burst whose length
``L_s`` satisfies ``s + L_s > t`` (nothing is carried between frames)."""

from __future__ import annotations

import jax.numpy as jnp

from .draws import BURST_TAG, GOLDEN, absorb, lane_hash, mix32, unit
from .spec import DistortParams, DistortSpec, cast_params


def burst_length(u: jnp.ndarray, mean: jnp.ndarray, spec: DistortSpec) -> jnp.ndarray:
    """Burst length (float32, integer-valued, in [0, burst_max]) from a uniform u in [0, 1)."""
    mean = jnp.asarray(mean, jnp.float32)
    if spec.burst_dist == "fixed":
        n = jnp.floor(mean + u)
    elif spec.burst_dist == "geometric":
        q = 1.0 / jnp.maximum(mean, 1.0)
        safe_q = jnp.where(q < 1.0, q, 0.5)
        n = jnp.where(q < 1.0, 1.0 + jnp.floor(jnp.log1p(-u) / jnp.log1p(-safe_q)), 1.0)
    else:  # uniform
        m = jnp.maximum(jnp.round(2.0 * mean - 1.0), 1.0)
        n = 1.0 + jnp.floor(u * m)
    n = jnp.minimum(n, jnp.float32(spec.burst_max))
    return jnp.where(mean > 0, n, 0.0).astype(jnp.float32)


def burst_draw(seed, g, s, dp: DistortParams, spec: DistortSpec):
    """Whether object ``g`` starts a burst at global frame ``s``, and its length.

    ``g``, ``s`` int arrays (broadcast together). Returns ``(start bool, length int32)`` of their
    shape; ``length`` is drawn whether or not the burst starts. The two uniforms of ``(g, s)``
    come from the state ``b = absorb(absorb(absorb(lane_hash(seed), BURST_TAG), g), s)``:
    ``u0 = unit(b)`` (start when ``u0 < burst_rate``), ``u1 = unit(mix(b ^ golden))`` (length).
    """
    dp = cast_params(dp)
    g, s = jnp.broadcast_arrays(jnp.asarray(g, jnp.int32), jnp.asarray(s, jnp.int32))
    b = absorb(absorb(absorb(lane_hash(seed), BURST_TAG), g), s)
    start = unit(b) < dp.burst_rate
    length = burst_length(unit(mix32(b ^ jnp.uint32(GOLDEN))), dp.burst_len, spec)
    return start, length.astype(jnp.int32)


def occluded(gid: jnp.ndarray, t, dp: DistortParams, spec: DistortSpec) -> jnp.ndarray:
    """[M] bool: the slot's ground-truth object (``gid >= 0``) is inside an occlusion burst at ``t``."""
    dp = cast_params(dp)
    gid = jnp.asarray(gid, jnp.int32)
    lag = jnp.arange(spec.burst_max, dtype=jnp.int32)                     # t - s
    s = jnp.asarray(t, jnp.int32) - lag
    start, length = burst_draw(dp.seed, jnp.maximum(gid, 0)[:, None], s[None, :], dp, spec)
    covers = start & (length > lag[None, :])
    return jnp.any(covers, axis=1) & (gid >= 0)
