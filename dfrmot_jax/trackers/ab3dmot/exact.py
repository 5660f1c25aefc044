"""float64 arithmetic with NumPy's (and Python's) roundings inside XLA programs.

XLA on CPU lets LLVM contract a multiplication feeding an addition into one fused multiply-add
(``a * b + c`` rounded once), and whether it does depends on the surrounding program. AB3DMOT's
decisions (a float32 affinity, the turn of a heading, the threshold) come from float64 values
computed with one rounding per operation, except in its BLAS products, which fuse. So:

- :func:`mul` rounds a product on its own: the product's bits pass through an integer XOR with a
  zero the compiler cannot see (``zero``: an int64 zero made from a runtime value, see
  :func:`runtime_zero`), which no contraction can cross;
- :func:`fma` is a correctly rounded fused multiply-add built from exact operations (a product split
  into exact halves, error-free sums and a sum rounded to odd: Boldo & Melquiond, "Emulation of
  FMA and correctly rounded sums: proved algorithms using rounding to odd", IEEE TC 57(4), 2008),
  the same bits whether the compiler contracts or not.

Divisions, square roots and sums are never contracted. Every function takes arrays of any shape
(broadcast); ``zero`` is an int64 scalar (or broadcastable) equal to 0.
"""

from __future__ import annotations

import jax.numpy as jnp
from jax import lax

__all__ = ["runtime_zero", "guard", "mul", "two_sum", "two_prod", "fma"]

_LOW27 = (1 << 27) - 1


def runtime_zero(counter) -> jnp.ndarray:
    """An int64 zero the compiler cannot fold: ``min(counter, 0)`` of a non-negative runtime int
    (the step's frame counter). Constant-folded zeros would let XLA remove :func:`guard`."""
    return jnp.minimum(jnp.asarray(counter), 0).astype(jnp.int64)


def guard(x, zero) -> jnp.ndarray:
    """``x`` (float64) unchanged, through an integer XOR with ``zero``: no contraction crosses it."""
    bits = lax.bitcast_convert_type(jnp.asarray(x, jnp.float64), jnp.int64)
    return lax.bitcast_convert_type(bits ^ zero, jnp.float64)


def mul(a, b, zero) -> jnp.ndarray:
    """``a * b`` rounded once, never fused into a later sum."""
    return guard(jnp.asarray(a, jnp.float64) * b, zero)


def two_sum(a, b):
    """(s, e): ``s = a + b`` rounded and its exact error ``e = a + b - s`` (Knuth's TwoSum)."""
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


def _split(a):
    """a = hi + lo exactly, hi with at most 26 significant bits (a's mantissa rounded at bit 27, by
    integer arithmetic: no product involved), lo with at most 26."""
    bits = lax.bitcast_convert_type(a, jnp.int64)
    hi = lax.bitcast_convert_type((bits + (1 << 26)) & ~_LOW27, jnp.float64)
    return hi, a - hi


def two_prod(a, b, zero):
    """(p, e): ``p = a * b`` rounded and its exact error (Dekker's product on exact halves, whose
    partial products are exact: fused or not, the same bits)."""
    p = mul(a, b, zero)
    ah, al = _split(a)
    bh, bl = _split(b)
    return p, (((ah * bh - p) + ah * bl) + al * bh) + al * bl


def _add_odd(a, b):
    """``a + b`` rounded to odd: the exact sum if representable, else the neighbour of the
    round-to-nearest sum, on the side of the exact sum, whose last mantissa bit is 1."""
    s, e = two_sum(a, b)
    bits = lax.bitcast_convert_type(s, jnp.int64)
    even = (bits & 1) == 0
    away = (e > 0) == (s > 0)                                  # the exact sum lies farther from 0
    moved = lax.bitcast_convert_type(bits + jnp.where(away, 1, -1), jnp.float64)
    return jnp.where((e != 0) & even, moved, s)


def fma(a, b, c, zero) -> jnp.ndarray:
    """``a * b + c`` rounded once (binary64; no underflow or overflow in the partial results)."""
    a, b, c = (jnp.asarray(v, jnp.float64) for v in (a, b, c))
    uh, ul = two_prod(a, b, zero)
    th, tl = two_sum(c, uh)
    return th + _add_odd(tl, ul)
