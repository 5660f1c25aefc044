"""Per-detection noise: Gaussian jitter of boxes and scores (the draws come from the caller).

Each function takes the standard normals it needs (``draws.normal`` of the frame's stream in
``hook.distort_frame``), moves only slots that hold a detection (``valid``) and only when its
level is positive, and keeps the input's dtype. Every sum of products is :func:`exact.lin`.
"""

from __future__ import annotations

import jax.numpy as jnp

from .exact import lin


def ordered(box):
    """[..., 4] boxes with x1 <= x2 and y1 <= y2 (corners swapped where needed)."""
    return jnp.stack([jnp.minimum(box[..., 0], box[..., 2]), jnp.minimum(box[..., 1], box[..., 3]),
                      jnp.maximum(box[..., 0], box[..., 2]), jnp.maximum(box[..., 1], box[..., 3])], -1)


def jitter_box(box, valid, sigma, n, truncate_fn=None):
    """Image boxes [M, 4] with ``sigma * n`` added to each corner (``n`` [M, 4] standard normals).

    With ``truncate_fn`` (the loader's rule, ``core.boxes.truncate_2d_box`` / ``truncate_3d_box``)
    the integer box is taken as the centre of its truncation cell (``box + 0.5``, exact), moved and
    truncated again; without it the moved corners are re-ordered.
    """
    if truncate_fn is None:
        out = ordered(lin(box, (sigma, n)))
    else:
        out = truncate_fn(lin(box + 0.5, (sigma, n)))        # box + 0.5 is exact
    return jnp.where((sigma > 0) & valid[:, None], out, box).astype(box.dtype)


def shift_3d(lo3, hi3, valid, sigma, n):
    """3D boxes (lo3, hi3 [M, 3]) shifted together by ``sigma * n`` (``n`` [M, 3] standard normals)."""
    move = ((sigma > 0) & valid)[:, None]
    return (jnp.where(move, lin(lo3, (sigma, n)), lo3).astype(lo3.dtype),
            jnp.where(move, lin(hi3, (sigma, n)), hi3).astype(hi3.dtype))


def score_noise(score, valid, sigma, n):
    """Scores [M] plus ``sigma * n`` (``n`` [M] standard normals); not clipped."""
    return jnp.where((sigma > 0) & valid, lin(score, (sigma, n)), score).astype(score.dtype)
