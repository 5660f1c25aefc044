"""AB3DMOT's constant-velocity Kalman filter (61f3bd7 ``kalman_filter.KF`` on filterpy 1.4.5) in
closed form, elementwise over tracks, and its heading rules.

State ``x = [x, y, z, theta, l, w, h, dx, dy, dz]`` [..., 10]; ``F`` adds ``dx, dy, dz`` to
``x, y, z``; ``H`` measures the first 7 states; ``P0 = 10 diag(1 (7), 1000 (3))``,
``Q = diag(1 (7), 0.01 (3))``, ``R = I``. With these, P only ever couples each position with its
own velocity: it is held as one 2x2 block ``[[a, b], [c, d]]`` per position axis (``a, b, c, d``
[..., 3]: ``P[i, i], P[i, i+7], P[i+7, i], P[i+7, i+7]``) and the variances ``q`` [..., 4] of
theta, l, w, h; the innovation covariance ``S = H P H' + R`` is diagonal, and filterpy's products
reduce to the elementwise formulas below, rounded as its BLAS products round (each product on its
own, one nonzero term per sum but for the ones written):

- predict: ``x[:3] += x[7:]``; ``a = ((a + c) + (b + d)) + 1``, ``b = b + d``, ``c = c + d``,
  ``d = d + 0.01``, ``q = q + 1``;
- update with z [..., 7]: ``y = z - x[:7]``; gains ``k1 = a (1 / (a + 1))``, ``k2 = c (1 / (a + 1))``,
  ``kq = q (1 / (q + 1))``; ``x[:3] += k1 y``, ``x[7:] += k2 y``, ``x[3:7] += kq y``; Joseph form
  with ``al = 1 - k1``, ``be = -k2``: ``a = (al a) al + k1 k1``, ``b = ((al a) be + al b) + k1 k2``,
  ``c = (be a + c) al + k2 k1``, ``d = ((be a + c) be + (be b + d)) + k2 k2``;
  ``q = ((1 - kq) q)(1 - kq) + kq kq``.

Headings: :func:`wrap` after every predict and update; :func:`orientation_correction` before an
update. Every product goes through ``exact.mul`` (no fused multiply-add), and no two constants
meet in a sum XLA could fold (``exact.guard``).
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from .exact import guard, mul

__all__ = ["Gauss", "birth", "predict", "innovation", "update", "wrap", "orientation_correction"]

PI = np.pi
TWO_PI = np.pi * 2


class Gauss(NamedTuple):
    """A track's state x [..., 10] and covariance blocks a, b, c, d [..., 3], q [..., 4]."""

    x: jnp.ndarray
    a: jnp.ndarray
    b: jnp.ndarray
    c: jnp.ndarray
    d: jnp.ndarray
    q: jnp.ndarray


def birth(box) -> Gauss:
    """The filter of a new track at box [..., 7] (the detection's state, heading not wrapped)."""
    lead = box.shape[:-1]
    x = jnp.concatenate([box, jnp.zeros(lead + (3,), box.dtype)], -1)
    return Gauss(x, jnp.full(lead + (3,), 10.0), jnp.zeros(lead + (3,)), jnp.zeros(lead + (3,)),
                 jnp.full(lead + (3,), 10000.0), jnp.full(lead + (4,), 10.0))


def wrap(theta):
    """AB3DMOT's ``within_range``: -2 pi once if ``theta >= pi``, then +2 pi once if ``< -pi``."""
    theta = jnp.where(theta >= PI, theta - TWO_PI, theta)
    return jnp.where(theta < -PI, theta + TWO_PI, theta)


def orientation_correction(pre, obs, zero):
    """(pre, obs) both wrapped; pre turned by pi (and wrapped) when the two are more than 90 and
    less than 270 degrees apart; then moved by 2 pi towards obs (+ if obs > 0) when still at
    least 270 degrees apart. (``pre + pi`` is guarded: XLA would fold ``(pre + pi) - 2 pi`` into
    ``pre - pi``, another rounding.)"""
    pre, obs = wrap(pre), wrap(obs)
    gap = jnp.abs(obs - pre)
    pre = jnp.where((gap > PI / 2.0) & (gap < PI * 3 / 2.0), wrap(guard(pre + PI, zero)), pre)
    far = jnp.abs(obs - pre) >= PI * 3 / 2.0
    return jnp.where(far, jnp.where(obs > 0, pre + TWO_PI, pre - TWO_PI), pre), obs


def predict(g: Gauss) -> Gauss:
    """One constant-velocity step (heading wrapped)."""
    x = g.x
    pos = x[..., :3] + x[..., 7:]
    x = jnp.concatenate([pos, wrap(x[..., 3:4]), x[..., 4:]], -1)
    a, b, c, d = g.a, g.b, g.c, g.d
    return Gauss(x, ((a + c) + (b + d)) + 1.0, b + d, c + d, d + 0.01, g.q + 1.0)


def innovation(g: Gauss):
    """The diagonal of S = H P H' + R, [..., 7]."""
    return jnp.concatenate([g.a + 1.0, g.q + 1.0], -1)


def update(g: Gauss, z, zero) -> Gauss:
    """filterpy's update with measurement z [..., 7] (heading already corrected), then the heading
    wrapped."""
    x = g.x
    y = z - x[..., :7]
    a, b, c, d, q = g.a, g.b, g.c, g.d, g.q
    inv = 1.0 / (a + 1.0)
    k1, k2 = mul(a, inv, zero), mul(c, inv, zero)
    kq = mul(q, 1.0 / (q + 1.0), zero)
    pos = x[..., :3] + mul(k1, y[..., :3], zero)
    rest = x[..., 3:7] + mul(kq, y[..., 3:], zero)
    vel = x[..., 7:] + mul(k2, y[..., :3], zero)
    al, be = 1.0 - k1, 0.0 - k2
    ap00, ap01 = mul(al, a, zero), mul(al, b, zero)
    ap10, ap11 = mul(be, a, zero) + c, mul(be, b, zero) + d
    na = mul(ap00, al, zero) + mul(k1, k1, zero)
    nb = (mul(ap00, be, zero) + ap01) + mul(k1, k2, zero)
    nc = mul(ap10, al, zero) + mul(k2, k1, zero)
    nd = (mul(ap10, be, zero) + ap11) + mul(k2, k2, zero)
    aq = 1.0 - kq
    nq = mul(mul(aq, q, zero), aq, zero) + mul(kq, kq, zero)
    x = jnp.concatenate([pos, wrap(rest[..., :1]), rest[..., 1:], vel], -1)
    return Gauss(x, na, nb, nc, nd, nq)
