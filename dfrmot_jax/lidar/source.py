"""Lifted boxes as a 3D detection source: ``det3d="lidar:DIR"`` (``DIR/velodyne/SSSS/FFFFFF.bin``).

The mapping into the tracker's 3D detection representation (:func:`to_detections3d`). The C++
keeps the cluster's LiDAR-frame min / max corners as the object's internal 3D box, so its LiDAR
distance is the distance between the two boxes' centres ``(lo + hi) / 2``. A lifted box becomes one
row of a 3D detection file (KITTI camera coordinates, the layout every 3D detector here is read in):

* centre: ``c = R_rect . Tr_velo_cam . (lo + hi) / 2`` (rectified camera-0 coordinates);
* ``l = hi_x - lo_x`` (LiDAR forward extent), ``w = hi_y - lo_y`` (lateral), ``h = hi_z - lo_z``
  (vertical); ``rot_y`` the heading of the LiDAR x axis in the camera frame (about -pi/2 on
  KITTI: the length along the camera's z), ``loc = c + (0, h / 2, 0)`` (the bottom centre, y down),
  ``alpha = rot_y - atan2(c_x, c_z)`` wrapped to [-pi, pi];
* image box: the 2D detection's loader box ``(x, y, x + w, y + h)`` (integers), under either merge
  option (``Split.proj3d`` is that box too); score: the 2D detection's score; type: the class.

So with ``centroid="kitti"`` (the geometric centre) the tracker's LiDAR distance between two lifted
boxes is the C++'s, moved by the rigid ``R_rect . Tr_velo_cam`` (equal up to rounding); ``legacy``
and ``head`` add their own half-extent offsets, as for any 3D detector.

**Fused by construction.** A lifted box belongs to its 2D detection: its image box *is* that
detection's integer box, so the 2D/3D merge (greedy, IoU > ``merge_iou``) pairs them at IoU exactly
1, before any other pair (two detections with the same integer box share every point, so neither
has a lifted box). This holds when the tracker keeps a lifted box exactly when it keeps its 2D
detection: ``score_3d == score_2d`` (the lifted score is the 2D score; :func:`tie_scores`) and
``merge_iou < 1``. Lifting used the 2D rows at or above ``LiftSettings.score_cut``; a tracker
``score_2d`` equal to it is the authors' setting.

Lifting is cached in memory (:func:`lift_sequence`), the first stage (voxel grid, crop,
projection) separately, so that another shrink, tolerance or minimum cluster size reuses it. Both
name everything their value is made from: the scan folder, the sequence, its frame count, a SHA-256 digest of the 2D detections' arrays and of the
calibration's arrays themselves (so a caller passing changed ``det2`` or ``calib`` for the same
scans gets a new lifting, whatever files they came from), the class, and the lifting settings (the
first stage: ``PREPARE_FIELDS``; the whole lifting: all of them) in the key, and every scan's
file stamp as the memo's stamp (:class:`~dfrmot_jax.io.memo.FileMemo`: mtime, ctime, size, inode,
and no reuse of a value built within a second of a scan's change). Scans themselves are never kept.
"""

from __future__ import annotations

from pathlib import Path

import hashlib

import numpy as np

from ..io.atomic import write_text_atomic
from ..io.kitti import Calib, Detections2D, Detections3D, KittiFormatError
from ..io.memo import FileMemo
from ..lidar_settings import LiftSettings
from .lift import PREPARE_FIELDS, Lifted, Prepared, detection_boxes, lift_prepared
from .prepare import prepare_points
from .scans import check_frames, read_scan, scan_stamps

__all__ = ["LIDAR_PREFIX", "lidar_dir", "to_detections3d", "inputs_digest", "lift_sequence", "write_detections3d",
           "tie_scores", "clear_cache"]

LIDAR_PREFIX = "lidar:"
_KITTI_TYPE = {"car": "Car", "pedestrian": "Pedestrian"}
_PREPARED = FileMemo(size=256)     # stamp: the scans' (the key names the detections and calibration)
_LIFTED = FileMemo(size=256)


def lidar_dir(det3d) -> Path | None:
    """The scan folder of a ``"lidar:DIR"`` 3D detection source, None for any other source."""
    text = str(det3d)
    if not text.startswith(LIDAR_PREFIX):
        return None
    d = text[len(LIDAR_PREFIX):]
    if not d:
        raise ValueError(f"3D detection source {text!r}: expected lidar:DIR (a folder holding velodyne/SSSS/*.bin)")
    return Path(d)


def tie_scores(params):
    """``params`` with ``score_3d = score_2d``: a lifted box (score = its 2D detection's) is kept exactly
    when its 2D detection is (any ``Params``, one lane or a batch)."""
    return params._replace(score_3d=params.score_2d)


def _rigid(calib: Calib):
    R = np.eye(4)
    R[:3, :3] = calib.R0_rect
    T = np.eye(4)
    T[:3, :] = calib.Tr_velo_to_cam
    A = R @ T
    return A[:3, :3], A[:3, 3]


def to_detections3d(lifted: Lifted, det2: Detections2D, calib: Calib, cls: str = "car") -> Detections3D:
    """Lifted boxes -> 3D detection rows (the module docstring's mapping), in 2D row order."""
    rows = np.asarray(lifted.rows, np.int64)
    lo, hi = (np.asarray(v, np.float32).astype(np.float64).reshape(-1, 3) for v in (lifted.lo, lifted.hi))
    A, b = _rigid(calib)
    centre = ((lo + hi) / 2.0) @ A.T + b
    ext = hi - lo
    l, w, h = ext[:, 0], ext[:, 1], ext[:, 2]
    heading = A[:, 0]
    rot = float(np.arctan2(-heading[2], heading[0]))
    rot_y = np.full(rows.size, rot)
    alpha = rot_y - np.arctan2(centre[:, 0], centre[:, 2])
    alpha = (alpha + np.pi) % (2 * np.pi) - np.pi
    loc = centre + np.stack([np.zeros_like(h), h / 2.0, np.zeros_like(h)], axis=1)
    _, rect = detection_boxes(det2.box[rows], det2.score[rows], -np.inf)
    box = np.stack([rect[:, 0], rect[:, 1], rect[:, 0] + rect[:, 2], rect[:, 1] + rect[:, 3]], axis=1)
    return Detections3D(frame=np.asarray(det2.frame, np.int64)[rows],
                        type=np.array([_KITTI_TYPE.get(cls, cls)] * rows.size, dtype=object),
                        box=box.astype(np.float64), score=np.asarray(det2.score, np.float64)[rows],
                        dims=np.stack([h, w, l], axis=1), loc=loc, rot_y=rot_y, alpha=alpha)


def clear_cache() -> None:
    """Forget every cached lifting (both stages)."""
    _PREPARED.clear()
    _LIFTED.clear()


def inputs_digest(*values) -> str:
    """SHA-256 (hex) of NamedTuples of arrays (``Detections2D``, ``Calib``): every field's name, dtype,
    shape and bytes, in field order; what the lifting caches key on instead of the files' stamps."""
    h = hashlib.sha256()
    for value in values:
        for name, arr in zip(value._fields, value):
            a = np.ascontiguousarray(arr)
            if a.dtype == object:
                raise TypeError(f"inputs_digest: field {name} is an object array")
            h.update(f"{type(value).__name__}.{name}:{a.dtype.str}:{a.shape};".encode())
            h.update(a.tobytes())
    return h.hexdigest()


def lift_sequence(scan_dir, sequence: str, n_frames: int, det2: Detections2D, calib: Calib,
                  settings: LiftSettings = LiftSettings(), cls: str = "car") -> Detections3D:
    """The lifted 3D detections of one sequence from ``scan_dir/velodyne/SSSS/*.bin`` (cached).

    det2: the sequence's 2D detections (file order); calib: its calibration. The cache keys (the
    module docstring) hold a digest of ``det2`` and ``calib`` themselves (:func:`inputs_digest`) and
    the size and mtime of every scan. Every frame ``0 .. n_frames - 1`` must have a scan
    (KittiFormatError naming the first missing or unreachable one, with the system's reason
    for the latter); only the frames with a kept detection are
    read, one at a time (:func:`~dfrmot_jax.lidar.prepare.prepare_points` with a reader: memory
    bounded by one scan plus what the boxes keep).
    """
    s = settings.validate()
    scan_dir = Path(scan_dir)
    if not scan_dir.is_dir():
        try:
            scan_dir.stat()
            why = "is not a folder"
        except FileNotFoundError:
            why = "LiDAR scan folder not found"
        except OSError as e:                    # a loop of symlinks, no permission: the system's reason
            why = f"cannot read the LiDAR scan folder: {e.strerror or e}"
        raise KittiFormatError(str(scan_dir), None, None, f"{why} (lidar:DIR expects DIR/velodyne/SSSS/FFFFFF.bin)")
    paths = check_frames(scan_dir, sequence, n_frames)
    base = (str(scan_dir.resolve()), str(sequence), int(n_frames), cls, inputs_digest(det2, calib))
    stamp = scan_stamps(scan_dir, sequence, n_frames)       # (the memo's stamp: its racy rule applies)

    def prepare() -> Prepared:
        return prepare_points(lambda f: read_scan(paths[f]), det2.frame, det2.box, det2.score, calib, s)

    def lift() -> Detections3D:
        prep = _PREPARED.get(base + tuple(getattr(s, f) for f in PREPARE_FIELDS), stamp, prepare)
        return to_detections3d(lift_prepared(prep, s), det2, calib, cls)

    return _LIFTED.get(base + (tuple(s),), stamp, lift)


def _num(v: float) -> str:
    return repr(float(v)) if np.isfinite(v) else "nan"


def write_detections3d(path, det: Detections3D) -> None:
    """One sequence's 3D detections as the 15-column CSV of the PointRCNN files
    (``frame,type,x1,y1,x2,y2,score,h,w,l,x,y,z,rot_y,alpha``), every value as the shortest text that
    reads back to the same double; written atomically."""
    lines = []
    for i in range(det.frame.size):
        vals = [str(int(det.frame[i])), str(det.type[i])]
        vals += [_num(v) for v in det.box[i]] + [_num(det.score[i])]
        vals += [_num(v) for v in det.dims[i]] + [_num(v) for v in det.loc[i]]
        vals += [_num(det.rot_y[i]), _num(det.alpha[i])]
        lines.append(",".join(vals) + "\n")
    write_text_atomic(path, "".join(lines))
