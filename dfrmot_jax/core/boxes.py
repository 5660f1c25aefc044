"""Box geometry inside the step: IoU of image boxes and the tracks' predicted boxes (jnp)."""

from __future__ import annotations

import jax.numpy as jnp


def iou_matrix(a, b):
    """IoU of boxes a [O, 4] against b [N, 4] (x1, y1, x2, y2) -> [O, N] float32; 0 for an empty union."""
    ax1, ay1, ax2, ay2 = (a[:, None, k] for k in range(4))
    bx1, by1, bx2, by2 = (b[None, :, k] for k in range(4))
    iw = jnp.maximum(0.0, jnp.minimum(ax2, bx2) - jnp.maximum(ax1, bx1))
    ih = jnp.maximum(0.0, jnp.minimum(ay2, by2) - jnp.maximum(ay1, by1))
    inter = iw * ih
    union = (ax2 - ax1) * (ay2 - ay1) + (bx2 - bx1) * (by2 - by1) - inter
    return jnp.where(union > 0, inter / jnp.where(union > 0, union, 1.0), 0.0)


def predicted_boxes(p2, truncate: bool):
    """Track boxes [N, 4] from the 2D filter positions (top-left x, y, bottom-right x, y) [N, 4].

    With truncation, as the code: x = trunc(tl_x), w = trunc(|x - br_x|), box (x, y, x + w, y + h).
    """
    if truncate:
        x = jnp.trunc(p2[:, 0]); y = jnp.trunc(p2[:, 1])
        w = jnp.trunc(jnp.abs(x - p2[:, 2])); h = jnp.trunc(jnp.abs(y - p2[:, 3]))
    else:
        x = p2[:, 0]; y = p2[:, 1]
        w = jnp.abs(p2[:, 2] - x); h = jnp.abs(p2[:, 3] - y)
    return jnp.stack([x, y, x + w, y + h], axis=1)
