"""The authors' point-cloud projection path: 2D detections lifted to 3D boxes from a LiDAR scan.

The rules of their C++ (``PointCloudFiltering.cpp``, ``PointCloudCalibration.cpp``, ``util.cpp``;
the calls commented out in ``main.cpp``, enabled in its order) and of the PCL they call:

1. **Voxel grid** (PCL ``VoxelGrid``, leaf 0.2 m): a point's cell is ``floor(p * inv)`` per axis in
   float32 with ``inv = 1.0f / leaf`` (5.0f), independent of the cloud's extent; each occupied cell
   gives one float32 centroid ``sum / n`` (float32 sum, divided by ``(float) n``), in ascending cell
   order with x varying fastest (then y, then z); no input point is kept. PCL sorts points into
   cells with an unstable sort, so the order of the sum inside a cell (a centroid's last bits) is
   unspecified there; here it is the scan's point order.
2. **Crop** (PCL ``CropBox``) in LiDAR coordinates: ``lo <= p <= hi`` per axis, both bounds inclusive,
   compared in float32; point order kept.
3. **Projection** with ``P2 . R_rect . Tr_velo_cam`` (4x4 with the homogeneous row 0 0 0 1), in
   float64, the pixel ``((int)(u / w), (int)(v / w))`` (truncation toward zero; no depth test, as
   the C++). Detections: the 2D loader's boxes (``stoi``: ``x = trunc(x1)``, ``w = |x - trunc(x2)|``)
   of the rows whose float32 score is not below the score cut (compared as a double, ``stof(s) <
   0.45``). A point belongs to a detection when it lies in that detection's shrunk box and in no
   other's: ``x' = (int)(x + (double)((float) s * w) / 2)``, ``w' = (int)((float) w * (1 - s))`` (the
   same for y, h), OpenCV ``Rect::contains``: ``x' <= px < x' + w'``, ``y' <= py < y' + h'``.
4. **Euclidean clusters** of each detection's points (PCL ``EuclideanClusterExtraction``): two points
   are neighbours when the float32 ``(dx*dx + dy*dy) + dz*dz`` is strictly below
   ``(float)(tolerance * tolerance)`` (FLANN's radius search); a cluster is a connected component of
   that graph, found from seeds in point order, kept with ``min_cluster`` points or more; PCL sorts
   the clusters largest first (ties: the earlier found first), and the authors keep the first. The
   3D box is the min / max corner of that cluster (``pcl::getMinMax3D``), in LiDAR coordinates. A
   detection without such a cluster gets no box.

The rules are vectorised: cells are ``numpy.unique`` of packed integer keys (several clouds at
once with a group index), the clusters are the connected components (``scipy.sparse.csgraph``) of
one radius graph over all detections of a sequence (``scipy.spatial.cKDTree`` on (x, y, z, group *
1000 m), so that no two groups touch) whose pairs are re-checked with the strict float32 rule.
Work is split in two stages so that lifting again with another shrink (or cluster) setting reuses
the first: stage 1 (voxel grid, crop, projection; only points inside some detection's unshrunk box
are kept, which every shrink in [0, 1) leaves exact; :class:`Prepared`) reads one scan at a time
(:func:`dfrmot_jax.lidar.prepare.prepare_points`), and :func:`lift_prepared` (stage 2: shrunk
boxes, assignment in blocks of points, clusters) works on what it kept.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..boxes import truncate_2d_box
from ..io.kitti import Calib
from ..lidar_settings import LiftSettings

__all__ = ["PREPARE_FIELDS", "Prepared", "Lifted", "velo_to_image", "voxel_grid", "crop_mask", "project_pixels",
           "detection_boxes", "shrunk_boxes", "contains", "assign_points", "largest_clusters", "frame_slots",
           "lift_prepared"]


#: the first stage's settings (a change of any other setting reuses a :class:`Prepared`)
PREPARE_FIELDS = ("leaf", "crop_lo", "crop_hi", "score_cut")
#: groups of points are this far apart on the radius graph's 4th axis (m)
_GROUP_GAP = 1000.0


def velo_to_image(calib: Calib) -> np.ndarray:
    """``[3, 4]`` float64 ``(P2 . R_rect) . Tr_velo_cam`` with R_rect and Tr_velo_cam as 4x4 (row 0 0 0 1),
    each product's element a left-to-right sum over k."""
    R = np.eye(4)
    R[:3, :3] = calib.R0_rect
    T = np.eye(4)
    T[:3, :] = calib.Tr_velo_to_cam

    def mul(a, b):
        out = np.zeros((a.shape[0], b.shape[1]))
        for k in range(a.shape[1]):
            out = out + a[:, k:k + 1] * b[k:k + 1, :]
        return out

    return mul(mul(np.asarray(calib.P2, np.float64), R), T)


def voxel_grid(points, group, leaf: float, keep_cells=None):
    """PCL's voxel grid of several clouds at once.

    points [N, 3] float32; group [N] int (the cloud of each point, e.g. its frame); keep_cells:
    optional ``(lo [3], hi [3])`` int cell ranges, cells outside dropped first (a pre-filter for a
    crop, see :func:`prepare_points`). Returns centroids [V, 3] float32 and their group [V], sorted
    by (group, z cell, y cell, x cell): each cloud's cells in PCL's order.
    """
    pts = np.asarray(points, np.float32)
    group = np.asarray(group, np.int64)
    inv = np.float32(1.0) / np.float32(leaf)
    cell = np.floor(pts * inv).astype(np.int64)                            # [N, 3]
    if keep_cells is not None:
        lo, hi = (np.asarray(v, np.int64) for v in keep_cells)
        ok = np.all((cell >= lo) & (cell <= hi), axis=1)
        pts, group, cell = pts[ok], group[ok], cell[ok]
    if not pts.shape[0]:
        return np.zeros((0, 3), np.float32), np.zeros(0, np.int64)
    cmin = cell.min(axis=0)
    span = cell.max(axis=0) - cmin + 1
    c = cell - cmin
    key = ((group * span[2] + c[:, 2]) * span[1] + c[:, 1]) * span[0] + c[:, 0]
    uniq, inv_idx = np.unique(key, return_inverse=True)
    sums = np.zeros((uniq.size, 3), np.float32)
    np.add.at(sums, inv_idx, pts)                                          # float32, in point order
    counts = np.bincount(inv_idx, minlength=uniq.size).astype(np.float32)
    cent = sums / counts[:, None]
    return cent.astype(np.float32), uniq // (span[0] * span[1] * span[2])


def crop_mask(points, lo, hi) -> np.ndarray:
    """[N] bool: PCL CropBox, ``lo <= p <= hi`` on every axis in float32 (both bounds inclusive)."""
    pts = np.asarray(points, np.float32)
    lo32, hi32 = np.asarray(lo, np.float32), np.asarray(hi, np.float32)
    return np.all((pts >= lo32) & (pts <= hi32), axis=1)


def project_pixels(points, M) -> np.ndarray:
    """[N, 2] int64 pixels ``(int)(u / w), (int)(v / w)`` of LiDAR points [N, 3] with ``M`` [3, 4]
    (:func:`velo_to_image`), float64, each row a left-to-right sum. A non-finite or out-of-int
    quotient (a point on the camera plane) gets the pixel ``-2**40``: inside no box."""
    p = np.asarray(points, np.float32).astype(np.float64)
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    uvw = [((M[i, 0] * x + M[i, 1] * y) + M[i, 2] * z) + M[i, 3] for i in range(3)]
    with np.errstate(divide="ignore", invalid="ignore"):
        q = np.stack([uvw[0] / uvw[2], uvw[1] / uvw[2]], axis=1)
    bad = ~np.isfinite(q) | (np.abs(q) >= 2.0 ** 31)
    return np.where(bad, -(2 ** 40), np.trunc(np.where(bad, 0.0, q))).astype(np.int64)


def detection_boxes(box, score, score_cut: float):
    """The 2D loader of ``util.cpp``: ``(keep [R] bool, rect [R, 4] int64 x, y, w, h)``; a row is kept
    unless its float32 score is below ``score_cut`` (a double); ``x = trunc(x1)``, ``w = |x - trunc(x2)|``."""
    keep = np.asarray(score, np.float32).astype(np.float64) >= float(score_cut)
    b = truncate_2d_box(np.asarray(box, np.float64).reshape(-1, 4))
    rect = np.stack([b[:, 0], b[:, 1], b[:, 2] - b[:, 0], b[:, 3] - b[:, 1]], axis=1).astype(np.int64)
    return keep, rect


def shrunk_boxes(rect, shrink: float) -> np.ndarray:
    """[..., 4] int64 OpenCV rects shrunk as the C++: ``x + (float)(s * w) / 2.0`` and
    ``w * (1 - s)`` in float, each truncated to int."""
    rect = np.asarray(rect, np.int64)
    s = np.float32(shrink)
    x, y, w, h = (rect[..., i] for i in range(4))
    wf, hf = w.astype(np.float32), h.astype(np.float32)
    nx = np.trunc(x + (s * wf).astype(np.float64) / 2.0)
    ny = np.trunc(y + (s * hf).astype(np.float64) / 2.0)
    one_minus = np.float32(1.0) - s
    nw = np.trunc(wf * one_minus)
    nh = np.trunc(hf * one_minus)
    return np.stack([nx, ny, nw.astype(np.float64), nh.astype(np.float64)], axis=-1).astype(np.int64)


def contains(rects, pix) -> np.ndarray:
    """[n, D] bool: OpenCV ``Rect::contains`` of the pixels pix [n, 2] in rects [D, 4] (the same for
    every pixel) or [n, D, 4] (x, y, w, h): ``x <= px < x + w`` and ``y <= py < y + h``."""
    r = np.asarray(rects)
    px, py = pix[:, 0:1], pix[:, 1:2]
    return (r[..., 0] <= px) & (px < r[..., 0] + r[..., 2]) & (r[..., 1] <= py) & (py < r[..., 1] + r[..., 3])


def assign_points(pix, frame_of_point, rects, valid, block: int = 1 << 20) -> np.ndarray:
    """[N] int64: the detection slot each point belongs to, -1 for none.

    pix [N, 2] int pixels; frame_of_point [N] index into the padded per-frame detections
    rects [F, D, 4] (x, y, w, h) and valid [F, D]. A point belongs to the one valid detection whose
    rect contains it (``x <= px < x + w``, ``y <= py < y + h``); in two or more: to none. Computed
    over blocks of points, at most ``block`` (point, slot) pairs at a time ([block / D, D, 4]
    gathered rects), so memory does not grow with N.
    """
    pix = np.asarray(pix)
    fop = np.asarray(frame_of_point, np.int64)
    rects, valid = np.asarray(rects), np.asarray(valid)
    step = max(1, int(block) // max(rects.shape[1], 1))
    owner = np.full(pix.shape[0], -1, np.int64)
    for a in range(0, pix.shape[0], step):
        f = fop[a:a + step]
        inside = valid[f] & contains(rects[f], pix[a:a + step])              # [b, D]
        owner[a:a + step] = np.where(inside.sum(axis=1) == 1, np.argmax(inside, axis=1), -1)
    return owner


def largest_clusters(points, group, n_groups: int, tolerance: float, min_cluster: int):
    """Per group, PCL's first cluster (the largest, ties to the earliest found) and its min / max corner.

    points [N, 3] float32 with group [N] int in [0, n_groups), each group's points in their cloud
    order (groups need not be contiguous). Returns found [G] bool, lo [G, 3], hi [G, 3] float32.
    """
    pts = np.asarray(points, np.float32)
    group = np.asarray(group, np.int64)
    found = np.zeros(n_groups, bool)
    lo = np.zeros((n_groups, 3), np.float32)
    hi = np.zeros((n_groups, 3), np.float32)
    n = pts.shape[0]
    if n == 0:
        return found, lo, hi
    r2 = np.float32(float(tolerance) * float(tolerance))
    coords = np.concatenate([pts.astype(np.float64), (group * _GROUP_GAP)[:, None].astype(np.float64)], axis=1)
    pairs = cKDTree(coords).query_pairs(float(tolerance) * (1 + 1e-5) + 1e-6, output_type="ndarray")
    if pairs.size:
        d = pts[pairs[:, 0]] - pts[pairs[:, 1]]                              # float32
        d2 = (d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]) + d[:, 2] * d[:, 2]
        pairs = pairs[(d2 < r2) & (group[pairs[:, 0]] == group[pairs[:, 1]])]
    graph = coo_matrix((np.ones(len(pairs), np.int8), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    size = np.bincount(label)
    first = np.full(size.size, n, np.int64)
    np.minimum.at(first, label, np.arange(n))                               # the component's seed
    comp_group = group[first]
    ok = size >= int(min_cluster)
    comps = np.flatnonzero(ok)
    if not comps.size:
        return found, lo, hi
    # PCL's order within a group: largest first, ties to the earlier seed; the authors take the first.
    order = np.lexsort((first[comps], -size[comps], comp_group[comps]))
    comps = comps[order]
    g = comp_group[comps]
    head = np.ones(comps.size, bool)
    head[1:] = g[1:] != g[:-1]
    best = comps[head]
    chosen = np.full(size.size, -1, np.int64)
    chosen[best] = comp_group[best]
    sel = chosen[label] >= 0
    gsel = chosen[label[sel]]
    lo[:] = np.inf
    hi[:] = -np.inf
    np.minimum.at(lo, gsel, pts[sel])
    np.maximum.at(hi, gsel, pts[sel])
    found[comp_group[best]] = True
    lo[~found] = 0
    hi[~found] = 0
    return found, lo, hi


class Prepared(NamedTuple):
    """The first stage of a sequence's lifting (voxel grid, crop, projection; shrink-independent).

    rows [D] int64: the 2D detection rows kept by the score cut, file order; det_frame [D] their
    frames; rect [D, 4] int64 their loader boxes (x, y, w, h). points [N, 3] float32 the voxelised,
    cropped points inside at least one kept (unshrunk) box of their frame, in cloud order per frame;
    point_frame [N] int64 (frame); pix [N, 2] int64 their pixels.
    """

    rows: np.ndarray
    det_frame: np.ndarray
    rect: np.ndarray
    points: np.ndarray
    point_frame: np.ndarray
    pix: np.ndarray


class Lifted(NamedTuple):
    """Lifted boxes: rows [K] int64 (2D detection file rows, ascending), lo [K, 3] and hi [K, 3]
    float32: the cluster's min / max corner in LiDAR coordinates (the C++'s ``Box3D(minPoint, maxPoint)``)."""

    rows: np.ndarray
    lo: np.ndarray
    hi: np.ndarray


def frame_slots(det_frame: np.ndarray):
    """Padded per-frame layout of detections in row order: (frames [F] unique, f_idx [D], slot [D], D_max)."""
    frames, f_idx = np.unique(det_frame, return_inverse=True)
    order = np.argsort(f_idx, kind="stable")
    counts = np.bincount(f_idx, minlength=frames.size)
    starts = np.cumsum(counts) - counts
    slot = np.empty(det_frame.size, np.int64)
    slot[order] = np.arange(det_frame.size) - np.repeat(starts, counts)
    return frames, f_idx.reshape(-1), slot, int(counts.max(initial=0))


def lift_prepared(prep: Prepared, settings: LiftSettings) -> Lifted:
    """Stage 2: shrunk boxes, exclusive assignment, the largest Euclidean cluster of each detection."""
    s = settings.validate()
    if not prep.rows.size or not prep.points.shape[0]:
        z = np.zeros((0, 3), np.float32)
        return Lifted(np.zeros(0, np.int64), z, z.copy())
    frames, f_idx, slot, dmax = frame_slots(prep.det_frame)
    rects = np.zeros((frames.size, dmax, 4), np.int64)
    valid = np.zeros((frames.size, dmax), bool)
    rects[f_idx, slot] = shrunk_boxes(prep.rect, s.shrink)
    valid[f_idx, slot] = True
    pf = np.searchsorted(frames, prep.point_frame)
    owner = assign_points(prep.pix, pf, rects, valid)                      # slot within the frame
    det_of_slot = np.full((frames.size, dmax), -1, np.int64)
    det_of_slot[f_idx, slot] = np.arange(prep.rows.size)
    mine = owner >= 0
    det = det_of_slot[pf[mine], owner[mine]]
    found, lo, hi = largest_clusters(prep.points[mine], det, prep.rows.size, s.tolerance, s.min_cluster)
    return Lifted(prep.rows[found], lo[found], hi[found])
