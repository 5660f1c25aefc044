"""Constant-acceleration filters on independent coordinates, in closed form on elementwise arrays.

Each coordinate has a state (p, v, a) in per-frame units (dt = 1 frame) and, for the Kalman filter,
the six distinct entries of its 3x3 covariance ``cov = [P00, P01, P02, P11, P12, P22]`` stacked on a
leading axis ``[6, ...]``. Nothing here uses a matrix product: XLA on CPU runs batched tiny matmuls
slowly, and every formula below is a handful of elementwise operations.

``fixed_gain`` is the authors' alpha-beta-gamma filter: p += alpha r, v += beta r, a += 2 gamma r
(the dt-free form of their gains diag(alpha, beta/dt, gamma/(dt^2/2))).
The tracker runs these in float64: XLA on CPU contracts a multiply feeding an add into one fused
multiply-add, which rounds differently from NumPy; in float64 that difference stays far below
what float32 outputs and threshold decisions can see, so the NumPy oracle agrees exactly.
``kalman`` is the paper's filter: F = [[1, 1, 1/2], [0, 1, 1], [0, 0, 1]], H = [1, 0, 0],
Q = kf_q * Q_JERK (white-noise jerk), R = kf_r.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

Q_JERK = np.array([[1 / 20, 1 / 8, 1 / 6], [1 / 8, 1 / 3, 1 / 2], [1 / 6, 1 / 2, 1.0]], dtype=np.float64)


class FilterState(NamedTuple):
    """p, v, a [..., K]; cov [6, ..., K] (Kalman) or [0, ..., K] (fixed gain: no covariance)."""

    p: jnp.ndarray
    v: jnp.ndarray
    a: jnp.ndarray
    cov: jnp.ndarray


def init(z, kind: str, kf_r=1.0, kf_p0=100.0, cov0=None) -> FilterState:
    """First observation: p = z, v = a = 0 (no prediction follows).

    Kalman covariance: diag(kf_r, kf_p0, kf_p0) ("diffuse"), or ``cov0`` when given ("steady"): [6], or
    [6, K] per coordinate. kf_r, kf_p0: scalars or broadcastable against z (e.g. [K]).
    """
    z = jnp.asarray(z)
    zero = jnp.zeros_like(z)
    cov = jnp.zeros((0,) + z.shape, z.dtype)
    if kind == "kalman":
        if cov0 is None:
            r = jnp.broadcast_to(jnp.asarray(kf_r, z.dtype), z.shape)
            p0 = jnp.broadcast_to(jnp.asarray(kf_p0, z.dtype), z.shape)
            cov = jnp.stack([r, zero, zero, p0, zero, p0])
        else:
            cov0 = jnp.asarray(cov0)
            cov0 = jnp.reshape(cov0, (6,) + (1,) * (z.ndim + 1 - cov0.ndim) + cov0.shape[1:])
            cov = jnp.broadcast_to(cov0, (6,) + z.shape).astype(z.dtype)
    return FilterState(z, zero, zero, cov)


def update(s: FilterState, z, kind: str, gains=(0.9, 0.9, 0.1), kf_r=1.0) -> FilterState:
    """Measurement update with z [..., K] (every coordinate updated)."""
    r = z - s.p
    if kind == "fixed_gain":
        ka, kb, kg = gains
        return FilterState(s.p + ka * r, s.v + kb * r, s.a + (2.0 * kg) * r, s.cov)
    p00, p01, p02, p11, p12, p22 = s.cov
    sv = p00 + kf_r
    k0, k1, k2 = p00 / sv, p01 / sv, p02 / sv
    cov = jnp.stack([p00 - k0 * p00, p01 - k0 * p01, p02 - k0 * p02, p11 - k1 * p01, p12 - k1 * p02, p22 - k2 * p02])
    return FilterState(s.p + k0 * r, s.v + k1 * r, s.a + k2 * r, cov)


def predict(s: FilterState, kind: str, kf_q=1.0) -> FilterState:
    """One frame ahead: p + v + a/2, v + a, a; for the Kalman filter P = F P F^T + kf_q Q_JERK."""
    p = s.p + s.v + 0.5 * s.a
    v = s.v + s.a
    if kind == "fixed_gain":
        return FilterState(p, v, s.a, s.cov)
    a, b, c, d, e, g = s.cov
    r00 = a + b + 0.5 * c
    r01 = b + d + 0.5 * e
    r02 = c + e + 0.5 * g
    r11 = d + e
    r12 = e + g
    q = Q_JERK
    cov = jnp.stack([
        r00 + r01 + 0.5 * r02 + kf_q * q[0, 0],
        r01 + r02 + kf_q * q[0, 1],
        r02 + kf_q * q[0, 2],
        r11 + r12 + kf_q * q[1, 1],
        r12 + kf_q * q[1, 2],
        g + kf_q * q[2, 2],
    ])
    return FilterState(p, v, s.a, cov)


def fixed_gain_radius(alpha, beta, gamma) -> np.ndarray:
    """Spectral radius [...] of the fixed-gain filter's error dynamics F (I - K H), K = (alpha,
    beta, 2 gamma) (NumPy, host). At 1 or above the filter is unstable: a track's predicted and
    filtered boxes grow without bound however good the measurements (as in the authors' code with
    the same gains); e.g. gain_beta 0.12, gain_gamma 0.16."""
    a, b, g = (np.asarray(x, np.float64) for x in np.broadcast_arrays(alpha, beta, gamma))
    F = np.array([[1.0, 1.0, 0.5], [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]])
    K = np.stack([a, b, 2.0 * g], axis=-1)[..., :, None]                      # [..., 3, 1]
    H = np.array([[1.0, 0.0, 0.0]])
    M = F @ (np.eye(3) - K @ H)
    return np.abs(np.linalg.eigvals(M)).max(axis=-1)


def select(mask, a: FilterState, b: FilterState) -> FilterState:
    """Elementwise where(mask, a, b); mask broadcasts against p."""
    cov = a.cov if a.cov.size == 0 else jnp.where(mask[None], a.cov, b.cov)
    return FilterState(jnp.where(mask, a.p, b.p), jnp.where(mask, a.v, b.v), jnp.where(mask, a.a, b.a), cov)


STEADY_ITERS = 500


def steady_cov(kf_q, kf_r, iters: int = STEADY_ITERS):
    """Steady-state *predicted* covariance [6] of one coordinate (Riccati iteration, jittable).

    A track born with this covariance updates with the steady-state gain at once, so the Kalman
    filter then runs exactly as the fixed-gain filter with ``steady_state(kf_q, kf_r)`` gains.
    """
    one = jnp.ones((1,), jnp.result_type(kf_q, kf_r))
    s0 = FilterState(one * 0, one * 0, one * 0, jnp.stack([one * 1e3, one * 0, one * 0, one * 1e3, one * 0, one * 1e3]))

    def body(_, s):
        return predict(update(s, s.p, "kalman", kf_r=kf_r), "kalman", kf_q=kf_q)

    return jax.lax.fori_loop(0, iters, body, s0).cov[:, 0]


def steady_state(kf_q: float, kf_r: float, iters: int = STEADY_ITERS) -> tuple[np.ndarray, np.ndarray]:
    """Steady-state gains (alpha, beta, gamma) and predicted covariance [3, 3] of the Kalman filter
    (``steady_cov`` in float64); ``gamma`` in the fixed-gain convention (a += 2 gamma r)."""
    with jax.enable_x64(True):
        a, b, c, d, e, g = np.asarray(steady_cov(jnp.float64(kf_q), jnp.float64(kf_r), iters))
    P = np.array([[a, b, c], [b, d, e], [c, e, g]])
    K = P[:, 0] / (P[0, 0] + kf_r)
    return np.array([K[0], K[1], K[2] / 2.0]), P
