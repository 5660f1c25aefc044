"""KITTI velodyne scans: ``velodyne/SSSS/FFFFFF.bin``, float32 little-endian ``x y z reflectance``.

A scan is ``[N, 4]`` float32 in the LiDAR frame (x forward, y left, z up, metres; the sensor at the
origin). The reader checks what a damaged or wrong file would show and raises
:class:`~dfrmot_jax.io.kitti.KittiFormatError` naming the file (and, for a bad value, the point as
its 1-based "line" and the field): a size that is not a multiple of 16 bytes, a non-finite value,
a missing frame. The writer produces the same bytes (``numpy.tofile`` of little-endian float32),
atomically.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io.atomic import atomic_write
from ..io.kitti import KittiFormatError, file_stamps

__all__ = ["POINT_BYTES", "FIELDS", "scan_path", "read_scan", "write_scan", "check_frames", "scan_stamps"]

#: bytes per point: four little-endian float32
POINT_BYTES = 16
FIELDS = ("x", "y", "z", "reflectance")
_DTYPE = np.dtype("<f4")


def scan_path(directory, sequence: str, frame: int) -> Path:
    """``DIR/velodyne/SSSS/FFFFFF.bin``; ``directory`` may also be the ``velodyne`` folder itself."""
    d = Path(directory)
    base = d if d.name == "velodyne" else d / "velodyne"
    return base / str(sequence) / f"{int(frame):06d}.bin"


def read_scan(path) -> np.ndarray:
    """One scan as ``[N, 4]`` float32 (native byte order). Raises KittiFormatError for a missing
    file, a size that is not a multiple of 16 bytes, or a NaN / infinite value (the point's 1-based
    number as the line, its field as the field)."""
    p = str(path)
    try:
        raw = np.fromfile(path, dtype=_DTYPE)
    except FileNotFoundError:
        raise KittiFormatError(p, None, None, "file not found (no scan for this frame)") from None
    except IsADirectoryError:
        raise KittiFormatError(p, None, None, "is a directory, not a scan file") from None
    if raw.size % 4:
        size = raw.size * 4
        raise KittiFormatError(p, None, None, f"size {size} bytes is not a multiple of {POINT_BYTES} "
                                              f"(float32 x y z reflectance per point)")
    pts = raw.reshape(-1, 4).astype(np.float32)
    bad = ~np.isfinite(pts)
    if bad.any():
        row, col = (int(v) for v in np.argwhere(bad)[0])
        raise KittiFormatError(p, row + 1, FIELDS[col], f"point {row + 1} has a non-finite value {pts[row, col]}")
    return pts


def write_scan(path, points) -> None:
    """Write ``[N, 3]`` or ``[N, 4]`` points (reflectance 0 when absent) as a KITTI ``.bin``, atomically,
    creating parent folders."""
    pts = np.asarray(points, dtype=np.float32)
    if pts.ndim != 2 or pts.shape[1] not in (3, 4):
        raise ValueError(f"write_scan: points of shape {pts.shape}, expected (N, 3) or (N, 4)")
    if pts.shape[1] == 3:
        pts = np.concatenate([pts, np.zeros((pts.shape[0], 1), np.float32)], axis=1)
    data = np.ascontiguousarray(pts, dtype=_DTYPE)
    atomic_write(path, lambda tmp: data.tofile(tmp), parents=True)


def check_frames(directory, sequence: str, n_frames: int) -> list[Path]:
    """The scan paths of frames ``0 .. n_frames - 1``; KittiFormatError naming the first missing one."""
    paths = [scan_path(directory, sequence, f) for f in range(n_frames)]
    stamps = file_stamps(paths)
    for f, (path, st) in enumerate(zip(paths, stamps)):
        if st is None:
            raise KittiFormatError(str(path), None, None,
                                   f"file not found: sequence {sequence} has {n_frames} frames, no scan for frame {f}")
    return paths


def scan_stamps(directory, sequence: str, n_frames: int) -> tuple:
    """(mtime ns, size) of each frame's scan (None where missing): what the lifting cache keys on."""
    return file_stamps(scan_path(directory, sequence, f) for f in range(n_frames))
