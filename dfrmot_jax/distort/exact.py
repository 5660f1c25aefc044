"""Float32 arithmetic with exact products: the same bits in every XLA program.

The distortion of ``(seed, t)`` must come out bit-identical in the tracker's scanned step, in
``distort_split`` (a vmap over frames) and in one lane or a batch. :func:`lin` is the one place
that guarantees it; every sum of products of the distortions goes through it, including the
clutter's projection :func:`project_box`.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..geometry import CORNER_PATTERN, MIN_DEPTH


def wide():
    """float64 under ``jax.enable_x64`` (the tracker's step, ``hook.distort_split``), else float32."""
    return jax.dtypes.canonicalize_dtype(np.float64)


def widen(x) -> jnp.ndarray:
    """A float32 value widened (exactly) for sums of products, see :func:`lin`."""
    return jnp.asarray(x, jnp.float32).astype(wide())


def f32(x) -> jnp.ndarray:
    return jnp.asarray(x).astype(jnp.float32)


def lin(*terms) -> jnp.ndarray:
    """``sum(terms)`` rounded to float32, each term a float32 value or a ``(a, b)`` product of two.

    XLA on CPU lets LLVM contract a multiply feeding an add (even through a float32 -> float64
    conversion) into one fused multiply-add, and whether it does depends on the surrounding
    program (fusion decisions differ between a scan step, a vmap, a single jit). Here every
    product is formed in float64 from float32 operands, so it is exact and fused and unfused
    evaluation agree: the same (seed, t) gives the same bits in the tracker and in
    ``hook.distort_split`` (both run under x64). Without x64 this is plain float32 arithmetic.
    """
    acc = None
    for term in terms:
        v = widen(term[0]) * widen(term[1]) if isinstance(term, tuple) else widen(term)
        acc = v if acc is None else acc + v
    return f32(acc)


_XP, _YP, _ZP = CORNER_PATTERN.astype(np.float32)        # exact: halves, signs and zeros


def project_box(dims, loc, rot_y, p2, image_size):
    """[..., 4] float32 image boxes of KITTI 3D boxes: the rectangle of their 8 corners projected
    with ``p2``, clipped to [0, W-1] x [0, H-1].

    The rule of ``geometry.project_box3d_to_image``, traced: corners with a projective depth
    ``<= MIN_DEPTH`` (0.1 m, compared in float32) are ignored, and a box with no corner in front is
    all-NaN. The arithmetic is float32 with exact products (:func:`lin`), not that function's
    float64 NumPy, so that the clutter's boxes are the same bits in every program (see
    ``geometry.project_box3d_to_image``); the two can differ in the last float32 bits.

    The 3D clutter (``clutter.clutter_3d``) never reaches the behind-the-camera case: its boxes
    stand at depth z >= ``CLUTTER_Z[0]`` = 5 m and reach at most half their ground diagonal
    (2.1 m for ``CAR_DIMS``) towards the camera, so with a KITTI ``P2`` (third row (0, 0, 1, t),
    |t| < 0.01 m) every corner is about 2.9 m or more in front. (Until the package split this
    function clamped the depth at 0.1 m instead; on every box clutter can produce the two rules
    give the same bits.)
    """
    P = np.asarray(p2, np.float32).reshape(3, 4)
    h, w, l = dims[..., 0:1], dims[..., 1:2], dims[..., 2:3]
    xo, yo, zo = l * _XP, h * _YP, w * _ZP                                # exact (halves, signs)
    c, s = jnp.cos(rot_y)[..., None], jnp.sin(rot_y)[..., None]
    pts = (lin((c, xo), (s, zo), loc[..., 0:1]), yo + loc[..., 1:2], lin((-s, xo), (c, zo), loc[..., 2:3]))
    hom = [lin((P[i, 0], pts[0]), (P[i, 1], pts[1]), (P[i, 2], pts[2]), P[i, 3]) for i in range(3)]
    front = hom[2] > jnp.float32(MIN_DEPTH)
    depth = jnp.where(front, hom[2], jnp.float32(1.0))
    u, v = hom[0] / depth, hom[1] / depth                                  # float32, correctly rounded
    box = jnp.stack([jnp.min(jnp.where(front, u, jnp.inf), -1), jnp.min(jnp.where(front, v, jnp.inf), -1),
                     jnp.max(jnp.where(front, u, -jnp.inf), -1), jnp.max(jnp.where(front, v, -jnp.inf), -1)], -1)
    box = jnp.where(jnp.any(front, -1)[..., None], box, jnp.nan)
    W, H = image_size
    return jnp.clip(box, 0.0, jnp.asarray([W - 1.0, H - 1.0, W - 1.0, H - 1.0], jnp.float32))
