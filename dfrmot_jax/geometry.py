"""Box geometry for KITTI data (NumPy, used at data-load time).

The internal 3D box (:func:`box3d_extent`) is array-generic: NumPy in, NumPy out; jax in, jax
out. ``dfrmot_jax.distort`` traces the very same function inside the tracker's scan (clutter builds
3D boxes). The one projection that stays separate is the distortions' in-scan clutter projection
(``distort.exact.project_box``): see :func:`project_box3d_to_image` for why.

This module does not import JAX (the stored tables' readers, ``dfrmot_jax.report``, reach it through
``io``): :func:`box3d_extent` computes with ``jax.numpy`` when given a jax array (which exists only
once JAX is imported), with NumPy otherwise.

The box rules the step itself uses (the one IoU, the loaders' integer truncation) live in
``core.boxes``; this module imports nothing of the tracker, so that the test oracle
(``testing.reference``) can use the dataset's geometry and stay independent of ``core``.

Conventions (KITTI object / tracking labels, rectified camera-0 coordinates):

* ``x`` right, ``y`` down, ``z`` forward, metres.
* A 3D box is ``dims = (h, w, l)``, ``loc = (x, y, z)`` = the centre of the box's *bottom* face,
  and ``rot_y`` = rotation about the camera ``y`` axis. In the object frame the box spans
  ``x`` in ``[-l/2, l/2]`` (length), ``y`` in ``[-h, 0]`` (height, upwards is negative ``y``) and
  ``z`` in ``[-w/2, w/2]`` (width); a point is rotated by
  ``x' = cos(r) x + sin(r) z``, ``z' = -sin(r) x + cos(r) z`` and then translated by ``loc``,
  exactly as in the KITTI devkit ``computeBox3D``. Heading direction of the box's length axis
  in the ground plane is therefore ``(cos r, -sin r)`` in ``(x, z)``.
* Image boxes are ``(x1, y1, x2, y2)`` in pixels.
"""

from __future__ import annotations

import sys

import numpy as np

#: Default KITTI image size (width, height) of camera 02.
KITTI_IMAGE_SIZE = (1242, 375)

#: Corners with a projective depth at or below this many metres count as "behind the camera".
MIN_DEPTH = 0.1

#: Object-frame corner pattern of computeBox3D: rows x (times l), y (times h), z (times w); columns
#: corners 0..7 (0-3 bottom face, 4-7 top face). Every value is exact in float32.
CORNER_PATTERN = np.array([[0.5, 0.5, -0.5, -0.5, 0.5, 0.5, -0.5, -0.5],
                           [0.0, 0.0, 0.0, 0.0, -1.0, -1.0, -1.0, -1.0],
                           [0.5, -0.5, -0.5, 0.5, 0.5, -0.5, -0.5, 0.5]])
_X_PATTERN, _Y_PATTERN, _Z_PATTERN = CORNER_PATTERN


def box3d_corners(dims, loc, rot_y) -> np.ndarray:
    """The 8 corners of KITTI 3D boxes.

    Args:
        dims: ``[..., 3]`` box sizes ``(h, w, l)``.
        loc: ``[..., 3]`` bottom-face centres ``(x, y, z)``.
        rot_y: ``[...]`` rotation about the camera ``y`` axis (radians).

    Returns:
        ``[..., 8, 3]`` corner coordinates in the same (rectified camera) frame as ``loc``.
        Corners 0-3 are the bottom face, 4-7 the top face (same order), as in the devkit.
        The leading dimensions of the three inputs are broadcast together.
    """
    dims = np.asarray(dims, dtype=np.float64)
    loc = np.asarray(loc, dtype=np.float64)
    rot_y = np.asarray(rot_y, dtype=np.float64)
    h, w, l = dims[..., 0:1], dims[..., 1:2], dims[..., 2:3]           # [..., 1]
    xo = l * _X_PATTERN                                                   # [..., 8]
    yo = h * _Y_PATTERN
    zo = w * _Z_PATTERN
    c = np.cos(rot_y)[..., None]
    s = np.sin(rot_y)[..., None]
    x = c * xo + s * zo + loc[..., 0:1]
    y = yo + loc[..., 1:2]
    z = -s * xo + c * zo + loc[..., 2:3]
    x, y, z = np.broadcast_arrays(x, y, z)
    return np.stack([x, y, z], axis=-1)


def _homogeneous_project(points, P) -> np.ndarray:
    points = np.asarray(points, dtype=np.float64)
    P = np.asarray(P, dtype=np.float64).reshape(3, 4)
    return points @ P[:, :3].T + P[:, 3]                                  # [..., 3]


def project_to_image(points, P) -> np.ndarray:
    """Pinhole projection of 3D points.

    Args:
        points: ``[..., 3]`` points in the frame ``P`` expects (rectified camera-0 for KITTI
            ``P2``).
        P: ``[3, 4]`` projection matrix (12 values are reshaped row-major).

    Returns:
        ``[..., 2]`` pixel coordinates ``(u, v)``. No check of the depth sign is made: points
        behind the camera project to mirrored, meaningless pixels (see
        :func:`project_box3d_to_image` for the guarded version).
    """
    hom = _homogeneous_project(points, P)
    return hom[..., :2] / hom[..., 2:3]


def project_box3d_to_image(dims, loc, rot_y, P2, image_size=KITTI_IMAGE_SIZE, clip: bool = True) -> np.ndarray:
    """Image boxes of KITTI 3D boxes: the bounding rectangle of their 8 projected corners.

    Args:
        dims: ``[..., 3]`` ``(h, w, l)``.
        loc: ``[..., 3]`` bottom centres ``(x, y, z)`` in rectified camera-0 coordinates.
        rot_y: ``[...]`` rotations about ``y``.
        P2: ``[3, 4]`` projection matrix of the image (KITTI ``P2`` for image 02).
        image_size: ``(W, H)`` in pixels.
        clip: clip the box to the image (default ``True``).

    Returns:
        ``[..., 4]`` boxes ``(x1, y1, x2, y2)``.

        * Clipping: each coordinate is clipped to ``[0, W-1]`` (x) and ``[0, H-1]`` (y), the
          convention of the KITTI labels and of the PointRCNN detection files (e.g. ``x2 = 1241``
          for a 1242 px wide image). A box entirely outside the image therefore becomes a
          degenerate box of zero width or height lying on the border; callers that care should
          test ``x2 > x1`` and ``y2 > y1``.
        * Corners behind the camera: the depth of a corner is the third homogeneous coordinate of
          ``P2 @ [X, 1]``. Corners with depth ``<= 0.1 m`` are ignored and the box is that of the
          remaining corners (an approximation: it does not intersect the box edges with the near
          plane, so the box of a car straddling the camera plane is too small towards the image
          border). When no corner is in front, the box is all-NaN (NaN also survives clipping).
          ``distort.exact.project_box`` (the 3D clutter's image boxes) applies the same rule.

    Arithmetic: float64 NumPy (corners, then ``points @ P[:, :3].T + P[:, 3]``). These values are
    ``Split.proj3d``, the image boxes of ``merge="calib_projection"`` / ``modality="3d"`` runs, so
    they are kept as they are. The distortions' projection cannot call this function (it runs
    traced inside the scan, per lane and frame) and uses float32 with exact products instead, so
    that ``distort_frame`` and ``distort_split`` agree bit for bit (``distort.exact.lin``); the two
    can differ in the last float32 bits, never in the behind-the-camera rule.
    """
    corners = box3d_corners(dims, loc, rot_y)                              # [..., 8, 3]
    hom = _homogeneous_project(corners, P2)                                # [..., 8, 3]
    depth = hom[..., 2]
    front = depth > MIN_DEPTH                                              # [..., 8]
    safe_depth = np.where(front, depth, 1.0)
    u = hom[..., 0] / safe_depth
    v = hom[..., 1] / safe_depth
    x1 = np.min(np.where(front, u, np.inf), axis=-1)
    x2 = np.max(np.where(front, u, -np.inf), axis=-1)
    y1 = np.min(np.where(front, v, np.inf), axis=-1)
    y2 = np.max(np.where(front, v, -np.inf), axis=-1)
    boxes = np.stack([x1, y1, x2, y2], axis=-1)
    none_in_front = ~np.any(front, axis=-1)
    boxes = np.where(none_in_front[..., None], np.nan, boxes)
    if clip:
        W, H = image_size
        lo = np.array([0.0, 0.0, 0.0, 0.0])
        hi = np.array([W - 1.0, H - 1.0, W - 1.0, H - 1.0])
        boxes = np.clip(boxes, lo, hi)                                     # NaN stays NaN
    return boxes


def box3d_extent(dims, loc, centroid: str):
    """Internal 3D box (min corner, max corner) [..., 3] in float32, as the authors' loader builds it.

    legacy: min = (z, y, x), max = min + (l, w, h)      (published runs)
    head:   min = (z, -x, -y), max = min + (l, h, w)    (code at HEAD)
    kitti:  min = (x - l/2, y - h, z - w/2), max = (x + l/2, y, z + w/2)   (geometric centre (x, y - h/2, z))

    Array-generic (NumPy or jax; ``dfrmot_jax.data`` re-exports it). Every value is
    one float32 operation on float32 inputs (``0.5 * l`` is exact), so no multiply-add can be
    contracted differently in different XLA programs.
    """
    jax = sys.modules.get("jax")            # a jax array exists only once JAX is imported
    xp = jax.numpy if jax is not None and (isinstance(dims, jax.Array) or isinstance(loc, jax.Array)) else np
    h, w, l = (xp.asarray(dims[..., i]).astype(xp.float32) for i in range(3))
    x, y, z = (xp.asarray(loc[..., i]).astype(xp.float32) for i in range(3))
    if centroid == "legacy":
        lo = xp.stack([z, y, x], -1); ext = xp.stack([l, w, h], -1)
        return lo, lo + ext
    if centroid == "head":
        lo = xp.stack([z, -x, -y], -1); ext = xp.stack([l, h, w], -1)
        return lo, lo + ext
    if centroid == "kitti":
        half = xp.float32(0.5)
        lo = xp.stack([x - half * l, y - h, z - half * w], -1)
        hi = xp.stack([x + half * l, y, z + half * w], -1)
        return lo, hi
    raise ValueError(f"centroid {centroid!r}")
