"""Box rules used inside the step and on the host: IoU, the loaders' integer truncation, the
tracks' predicted boxes.

:func:`iou` is the package's one IoU: NumPy in, NumPy out; jax in, jax out (``geometry.iou_2d``
and the distortions' clutter placement call it too).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np


def _iou(a, b, clip_areas: bool, xp):
    """IoU from unpacked corners a = (x1, y1, x2, y2), b = (...) (broadcast together).

    The intersection is clipped at 0; with ``clip_areas`` so is each box's width and height (an
    inverted box has area 0), without it the areas are the raw products (the tracker's rule). The
    IoU is 0 when the union is not positive, which covers empty unions and NaN (and with infinite
    coordinates every case that is not a finite ratio: the union is then inf or NaN).
    """
    ax1, ay1, ax2, ay2 = a
    bx1, by1, bx2, by2 = b
    iw = xp.maximum(0.0, xp.minimum(ax2, bx2) - xp.maximum(ax1, bx1))
    ih = xp.maximum(0.0, xp.minimum(ay2, by2) - xp.maximum(ay1, by1))
    inter = iw * ih
    if clip_areas:
        area_a = xp.maximum(0.0, ax2 - ax1) * xp.maximum(0.0, ay2 - ay1)
        area_b = xp.maximum(0.0, bx2 - bx1) * xp.maximum(0.0, by2 - by1)
    else:
        area_a = (ax2 - ax1) * (ay2 - ay1)
        area_b = (bx2 - bx1) * (by2 - by1)
    union = area_a + area_b - inter
    return xp.where(union > 0, inter / xp.where(union > 0, union, 1.0), 0.0)


def iou(a, b, clip_areas: bool = True):
    """IoU of boxes a [..., 4] and b [..., 4] (x1, y1, x2, y2; broadcast together) -> [...].

    Array-generic: jnp when either input is a jax array (also under tracing), else NumPy; the
    arithmetic is in the inputs' dtype (callers widen first when they want float64). Continuous
    boxes (no ``+1``); see :func:`_iou` for ``clip_areas`` and the zero cases.
    """
    xp = jnp if isinstance(a, jax.Array) or isinstance(b, jax.Array) else np
    return _iou(tuple(a[..., k] for k in range(4)), tuple(b[..., k] for k in range(4)), clip_areas, xp)


def iou_matrix(a, b):
    """IoU of boxes a [O, 4] against b [N, 4] (x1, y1, x2, y2) -> [O, N] float32; 0 for an empty union
    (:func:`iou` without clipping the areas, as the tracker always computed it)."""
    return _iou(tuple(a[:, None, k] for k in range(4)), tuple(b[None, :, k] for k in range(4)), False, jnp)


def xp_of(*arrays):
    """jnp when any input is a jax array (also a tracer), else NumPy."""
    return jnp if any(isinstance(a, jax.Array) for a in arrays) else np


def truncate_2d_box(box):
    """The 2D loader's integer box: x = trunc(x1), w = |x - trunc(x2)| (C++ stoi), as x1, y1, x1+w, y1+h.

    Array-generic (NumPy or jax, ``[..., 4]``).
    """
    xp = xp_of(box)
    x = xp.trunc(box[..., 0]); y = xp.trunc(box[..., 1])
    w = xp.abs(x - xp.trunc(box[..., 2])); h = xp.abs(y - xp.trunc(box[..., 3]))
    return xp.stack([x, y, x + w, y + h], axis=-1)


def truncate_3d_box(box):
    """The 3D loader's integer image box: x = trunc(x1), w = trunc(|x - x2|).

    Array-generic (NumPy or jax, ``[..., 4]``); also the rule of a track's predicted box
    (:func:`predicted_boxes`).
    """
    xp = xp_of(box)
    x = xp.trunc(box[..., 0]); y = xp.trunc(box[..., 1])
    w = xp.trunc(xp.abs(x - box[..., 2])); h = xp.trunc(xp.abs(y - box[..., 3]))
    return xp.stack([x, y, x + w, y + h], axis=-1)


def predicted_boxes(p2, truncate: bool):
    """Track boxes [N, 4] from the 2D filter positions (top-left x, y, bottom-right x, y) [N, 4].

    With truncation, as the code: the 3D loader's rule (:func:`truncate_3d_box`); without, the
    corners may cross: (x1, y1, x1 + |x2 - x1|, y1 + |y2 - y1|).
    """
    if truncate:
        return truncate_3d_box(p2)
    x = p2[:, 0]; y = p2[:, 1]
    w = jnp.abs(p2[:, 2] - x); h = jnp.abs(p2[:, 3] - y)
    return jnp.stack([x, y, x + w, y + h], axis=1)
