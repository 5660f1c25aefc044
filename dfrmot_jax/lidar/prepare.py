"""Stage 1 of the lifting (voxel grid, crop, projection), one scan at a time, in bounded memory.

Each frame's scan is reduced as it is read: the points whose cell could hold a centroid inside the
crop, their voxel grid, the crop, the projection, and the test against the frame's own detection
boxes (its row of the padded ``[F, D_max, 4]`` box array and ``[F, D_max]`` mask: ``[n, D_max]``
comparisons for the frame's ``n`` centroids, vectorised, no loop over points). Only the centroids
inside some unshrunk box of their frame are kept (:class:`~dfrmot_jax.lidar.lift.Prepared`). So a
sequence needs one scan at a time (a KITTI scan, ~120,000 points, is ~2 MB as read) plus what the
boxes keep, never an array over all points of the sequence; with a reader (a function of the
frame, as :func:`dfrmot_jax.lidar.lift_sequence` passes) no scan outlives its frame.

The result is bit for bit the whole-sequence computation's (the tests keep that computation as a
reference): every rule of this stage is per point, or per cell of one frame's cloud, and the voxel
grid of several frames at once orders cells frame first and sums each cell in the scan's point
order, as the voxel grid of one frame does.
"""

from __future__ import annotations

from typing import Callable, Mapping

import numpy as np

from ..io.kitti import Calib
from ..lidar_settings import LiftSettings
from .lift import (Lifted, Prepared, contains, crop_mask, detection_boxes, frame_slots, lift_prepared,
                   project_pixels, velo_to_image, voxel_grid)

__all__ = ["reduce_scan", "prepare_points", "lift_frames"]


def _cells_in(scan, inv, clo, chi) -> np.ndarray:
    """[n, 3] the points of a scan whose float32 cell ``floor(p * inv)`` lies in [clo, chi) on every
    axis (z first: the ground goes at once); ``floor(a) >= k`` is ``a >= k`` for a whole k."""
    a = scan[:, 2] * inv
    idx = np.flatnonzero((a >= clo[2]) & (a < chi[2]))
    pts = scan[idx, :3]
    ax, ay = pts[:, 0] * inv, pts[:, 1] * inv
    return pts[(ax >= clo[0]) & (ax < chi[0]) & (ay >= clo[1]) & (ay < chi[1])]


def reduce_scan(scan, settings: LiftSettings) -> np.ndarray:
    """[V, 3] float32: the voxel centroids of one scan (``[N, 4]`` or ``[N, 3]`` float32 points) that
    lie in the crop, in PCL's cell order (settings validated by the caller)."""
    s = settings
    inv = np.float32(1.0) / np.float32(s.leaf)
    lo32, hi32 = np.asarray(s.crop_lo, np.float32), np.asarray(s.crop_hi, np.float32)
    # cells whose centroid could fall in the crop (one cell of margin for rounding); the rest never can
    clo = np.floor(lo32 * inv) - np.float32(1)
    chi = np.floor(hi32 * inv) + np.float32(2)
    pts = _cells_in(np.asarray(scan, np.float32), inv, clo, chi)
    cent, _ = voxel_grid(pts, np.zeros(pts.shape[0], np.int64), s.leaf)
    return cent[crop_mask(cent, s.crop_lo, s.crop_hi)]


def _frame_points(scan, grown, valid, M, settings: LiftSettings):
    """One frame: (centroids [k, 3] float32, pixels [k, 2] int64) inside some of its boxes grown [D, 4]
    (valid [D]); the scan is referenced by nothing once this returns."""
    cent = reduce_scan(scan, settings)
    pix = project_pixels(cent, M)
    keep = np.any(valid & contains(grown, pix), axis=1)                   # [k, D] -> [k]
    return cent[keep], pix[keep]


def prepare_points(scans: Mapping | Callable, det_frame, det_box, det_score, calib: Calib,
                   settings: LiftSettings) -> Prepared:
    """Stage 1 for one sequence, one scan at a time.

    scans: a mapping frame -> ``[N, 4]`` (or ``[N, 3]``) float32 points holding at least every frame
    with a kept detection (ValueError naming the missing ones), or a function of the frame giving
    them (called once per such frame, in ascending order; bounded memory); det_frame [R],
    det_box [R, 4] (x1, y1, x2, y2), det_score [R]: the sequence's 2D detections, file order.
    """
    s = settings.validate()
    det_frame = np.asarray(det_frame, np.int64).reshape(-1)
    keep, rect = detection_boxes(det_box, det_score, s.score_cut)
    rows = np.flatnonzero(keep)
    dframe, rect = det_frame[rows], rect[rows]
    frames, f_idx, slot, dmax = frame_slots(dframe)
    if not rows.size:
        return Prepared(rows, dframe, rect, np.zeros((0, 3), np.float32), np.zeros(0, np.int64),
                        np.zeros((0, 2), np.int64))
    if callable(scans):
        read = scans
    else:
        missing = [int(f) for f in frames if int(f) not in scans]
        if missing:
            raise ValueError(f"prepare_points: no scan for frame(s) {missing[:5]}")
        read = scans.__getitem__
    # unshrunk boxes grown by one pixel, [F, D_max, 4] with a mask: every shrunk box in [0, 1) lies inside
    grown = np.zeros((frames.size, dmax, 4), np.int64)
    valid = np.zeros((frames.size, dmax), bool)
    grown[f_idx, slot] = rect + np.array([-1, -1, 2, 2])
    valid[f_idx, slot] = True
    M = velo_to_image(calib)
    parts = [_frame_points(read(int(f)), grown[i], valid[i], M, s) for i, f in enumerate(frames)]
    counts = [c.shape[0] for c, _ in parts]
    return Prepared(rows, dframe, rect, np.concatenate([c for c, _ in parts]), np.repeat(frames, counts),
                    np.concatenate([p for _, p in parts]))


def lift_frames(scans, det_frame, det_box, det_score, calib: Calib, settings: LiftSettings = LiftSettings()) -> Lifted:
    """Both stages: the lifted boxes of one sequence's 2D detections (see :func:`prepare_points`)."""
    return lift_prepared(prepare_points(scans, det_frame, det_box, det_score, calib, settings), settings)
