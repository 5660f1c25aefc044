"""The distortions' random draws: a counter-based, stateless 32-bit hash (not ``jax.random``).

Every draw is a function of ``(seed, t, stream, i)`` only: a hash chain ``absorb(h, w) =
mix(h ^ mix(w + golden))`` (``mix`` the bijective lowbias32 integer hash) of ``(seed, t, stream)``
gives a per-frame stream state ``h`` (``t`` the global frame index of the split, so different
sequences differ), and element ``i`` of the stream is ``unit(mix(h ^ mix(2 i + 1)))``; bursts
chain ``(seed, BURST_TAG, g, s)`` for the burst of object ``g`` starting at frame ``s``
(``bursts.burst_draw``). Nothing is carried between frames, and element ``i`` never depends on
the shape drawn.

Why not ``jax.random`` (``fold_in`` per seed, frame and stream)? Measured, not assumed:
``benchmarks/bench_distort_rng.py`` runs the same per-frame distortion (``hook.distort_frame``
without clutter) with either source of draws inside ``lax.scan`` over 400 frames, vmapped over 16
lanes, under x64 as the tracker's step; KITTI-car slot counts (M2 = 14, M3 = 19), burst_max = 30;
2-core VM shared with other jobs, best of 3; two runs, at load ~1.5 and (in brackets) ~2.5:

    groups                    draws      compile s        us / lane-frame
    drop + burst              hash       0.40 (0.75)       1.4 (4.6)
    (the published study)     threefry   2.18 (4.33)      48.9 (61.9)
                              rbg        1.78 (2.88)      31.0 (55.1)
    drop+burst+jitter+score   hash       0.76 (0.96)      12.0 (13.0)
                              threefry   3.35 (5.82)      59.8 (71.3)
                              rbg        2.14 (3.54)      42.0 (65.7)

The tracker's step itself costs ~30 us per lane-frame, so keys would make the robustness study's
tracking ~2-3x slower and add seconds to each compilation (one per option group and lanes per
compiled call).
The cost is the bursts: a frame needs ``(M2 + M3) x burst_max`` (~1000) draws, one stream per
(object, start frame), so that an object's burst depends neither on the slot it lands in nor on
the frame it is tested from; with keys that is ~1000 ``fold_in`` per lane-frame (one key per start
frame and a table of ids instead would need a static bound on ground-truth ids, and draws for all
of them). And the published robustness study (``sweeps/README.md``, notebook 02) is a function of
these exact draws: any other generator changes every distorted number there. So the hash stays.
"""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np

#: Stream tags of the per-frame states (``stream_hash(seed, t, TAG)``); bursts have their own root.
DROP2, DROP3, JIT2, JITB3, JIT3, SCORE2, SCORE3, CLUT2, CLUT3 = range(1, 10)
BURST_TAG = 0x7FFFFFFF

GOLDEN = 0x9E3779B9
_SALT = 0x2545F491


def mix32(x: jnp.ndarray) -> jnp.ndarray:
    """A bijective 32-bit integer hash (``lowbias32``: xor-shift-multiply, full avalanche)."""
    x = x ^ (x >> jnp.uint32(16))
    x = x * jnp.uint32(0x7FEB352D)
    x = x ^ (x >> jnp.uint32(15))
    x = x * jnp.uint32(0x846CA68B)
    return x ^ (x >> jnp.uint32(16))


def _u32(x) -> jnp.ndarray:
    """int32 (two's complement) -> uint32 bits."""
    return jax.lax.bitcast_convert_type(jnp.asarray(x).astype(jnp.int32), jnp.uint32)


def absorb(h: jnp.ndarray, w) -> jnp.ndarray:
    """Chain one int32 word into a 32-bit hash state: ``mix(h ^ mix(w + golden))``."""
    return mix32(h ^ mix32(_u32(w) + jnp.uint32(GOLDEN)))


def lane_hash(seed) -> jnp.ndarray:
    """uint32 root of a lane: ``absorb(SALT, seed)``."""
    return absorb(jnp.uint32(_SALT), seed)


def stream_hash(seed, t, stream: int) -> jnp.ndarray:
    """uint32 state of one per-frame stream: ``absorb(absorb(lane_hash(seed), t), stream)``."""
    return absorb(absorb(lane_hash(seed), t), stream)


def unit(x: jnp.ndarray) -> jnp.ndarray:
    """uint32 -> float32 uniform in [0, 1) (top 24 bits, exact)."""
    return (x >> jnp.uint32(8)).astype(jnp.float32) * jnp.float32(2.0 ** -24)


def _np_mix32(x: np.ndarray) -> np.ndarray:
    x = x.astype(np.uint32)
    x ^= x >> np.uint32(16)
    x *= np.uint32(0x7FEB352D)
    x ^= x >> np.uint32(15)
    x *= np.uint32(0x846CA68B)
    x ^= x >> np.uint32(16)
    return x


@functools.cache
def _counters(n: int) -> np.ndarray:
    """``mix(2 i + 1)`` for i < n, precomputed (a constant of the program)."""
    with np.errstate(over="ignore"):
        return _np_mix32(np.arange(n, dtype=np.uint32) * np.uint32(2) + np.uint32(1))


def uniform(h: jnp.ndarray, shape) -> jnp.ndarray:
    """float32 uniforms in [0, 1) of ``shape`` from a stream state: element i (row-major) is
    ``unit(mix(h ^ mix(2 i + 1)))`` (counter-based: element i never depends on the shape)."""
    n = int(np.prod(shape))
    return unit(mix32(h ^ jnp.asarray(_counters(n).reshape(shape))))


def normal(h: jnp.ndarray, shape) -> jnp.ndarray:
    """float32 standard normals of ``shape``: Box-Muller on uniform pairs (u_2k, u_2k+1) of the
    stream, element 2k = r cos(theta), element 2k+1 = r sin(theta) (row-major)."""
    n = int(np.prod(shape))
    u = uniform(h, ((n + 1) // 2, 2))
    r = jnp.sqrt(jnp.float32(-2.0) * jnp.log(jnp.float32(1.0) - u[:, 0]))      # 1 - u in (0, 1]
    theta = jnp.float32(2.0 * math.pi) * u[:, 1]
    z = jnp.stack([r * jnp.cos(theta), r * jnp.sin(theta)], axis=-1).reshape(-1)
    return z[:n].reshape(shape)
