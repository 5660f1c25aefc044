"""float64 products rounded on their own inside XLA programs.

XLA on CPU lets LLVM contract a product feeding a sum into one fused multiply-add (rounded once);
ByteTrack's NumPy / Cython code rounds every product. :func:`mul` passes a product's bits through an
integer XOR with a zero the compiler cannot see (:func:`runtime_zero`), which no contraction can
cross. Divisions, square roots and sums are never contracted.
"""

from __future__ import annotations

import jax.numpy as jnp
from jax import lax

__all__ = ["runtime_zero", "guard", "mul"]


def runtime_zero(counter) -> jnp.ndarray:
    """An int64 zero the compiler cannot fold: ``min(counter, 0)`` of a non-negative runtime int."""
    return jnp.minimum(jnp.asarray(counter), 0).astype(jnp.int64)


def guard(x, zero) -> jnp.ndarray:
    """``x`` (float64) unchanged, through an integer XOR with ``zero``."""
    bits = lax.bitcast_convert_type(jnp.asarray(x, jnp.float64), jnp.int64)
    return lax.bitcast_convert_type(bits ^ zero, jnp.float64)


def mul(a, b, zero) -> jnp.ndarray:
    """``a * b`` rounded once, never fused into a later sum."""
    return guard(jnp.asarray(a, jnp.float64) * b, zero)
