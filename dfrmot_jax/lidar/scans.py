"""KITTI velodyne scans: ``velodyne/SSSS/FFFFFF.bin``, float32 little-endian ``x y z reflectance``.

A scan is ``[N, 4]`` float32 in the LiDAR frame (x forward, y left, z up, metres; the sensor at the
origin). The reader checks what a damaged or wrong file would show and raises
:class:`~dfrmot_jax.io.kitti.KittiFormatError` naming the file (and, for a bad value, the point as
its 1-based "line" and the field): a size that is not a multiple of 16 bytes (the file's true
size, a partial last point included), a non-finite value, a missing frame, a name that is no
regular file (a FIFO, a device or a directory: refused before anything is read from it, so nothing
waits on a pipe), a file or folder that cannot be reached (the system's reason: "Permission
denied", "Too many levels of symbolic links", ...). The writer produces the same bytes
(``numpy.tofile`` of little-endian float32), atomically.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

import numpy as np

from ..io.atomic import atomic_write
from ..io.kitti import KittiFormatError
from ..io.memo import file_stamps

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
    """One scan as ``[N, 4]`` float32 (native byte order). Raises KittiFormatError for a missing or
    unreachable file, a name that is no regular file (checked on the open descriptor before any read:
    a FIFO never blocks), a size that is not a multiple of 16 bytes (the true size in the message),
    or a NaN / infinite value (the point's 1-based number as the line, its field as the field)."""
    p = str(path)
    try:
        # O_NONBLOCK: opening a FIFO without a writer returns at once instead of waiting for one
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as e:
        raise KittiFormatError(p, None, None, _unreachable(e)) from None
    with os.fdopen(fd, "rb") as f:
        problem = _not_a_scan_file(os.fstat(fd).st_mode)
        if problem:
            raise KittiFormatError(p, None, None, problem)
        data = f.read()
    if len(data) % POINT_BYTES:
        raise KittiFormatError(p, None, None, f"size {len(data)} bytes is not a multiple of {POINT_BYTES} "
                                              f"(float32 x y z reflectance per point)")
    pts = np.frombuffer(data, dtype=_DTYPE).reshape(-1, 4).astype(np.float32)
    bad = ~np.isfinite(pts)
    if bad.any():
        row, col = (int(v) for v in np.argwhere(bad)[0])
        raise KittiFormatError(p, row + 1, FIELDS[col], f"point {row + 1} has a non-finite value {pts[row, col]}")
    return pts


def _unreachable(e: OSError) -> str:
    """The message of an error opening or stat-ing a scan: a missing file as such, else the system's
    reason."""
    if isinstance(e, FileNotFoundError):
        return "file not found (no scan for this frame)"
    if isinstance(e, IsADirectoryError):
        return "is a directory, not a scan file"
    return f"cannot read the scan: {e.strerror or e}"


def _not_a_scan_file(mode: int) -> str | None:
    """Why a file of this ``st_mode`` is no scan file (a directory, a FIFO, ...); None for a regular file."""
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISDIR(mode):
        return "is a directory, not a scan file"
    kind = ("a FIFO (named pipe)" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode)
            else "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else "not a regular file")
    return f"is {kind}, not a regular scan file"


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
    """The scan paths of frames ``0 .. n_frames - 1``; KittiFormatError naming the first that is
    missing ("file not found ... no scan for frame F"), cannot be reached (the system's reason, e.g.
    an unreadable or looping sequence folder) or is no regular file (a FIFO: nothing is opened)."""
    paths = [scan_path(directory, sequence, f) for f in range(n_frames)]
    for f, path in enumerate(paths):
        try:
            mode = os.stat(path).st_mode
        except FileNotFoundError:
            raise KittiFormatError(str(path), None, None,
                                   f"file not found: sequence {sequence} has {n_frames} frames, no scan for frame {f}"
                                   ) from None
        except OSError as e:
            raise KittiFormatError(str(path), None, None, f"{_unreachable(e)} (frame {f} of sequence {sequence})"
                                   ) from None
        problem = _not_a_scan_file(mode)
        if problem:
            raise KittiFormatError(str(path), None, None, f"{problem} (frame {f} of sequence {sequence})")
    return paths


def scan_stamps(directory, sequence: str, n_frames: int) -> tuple:
    """(mtime ns, size) of each frame's scan (None where missing): what the lifting cache keys on."""
    return file_stamps(scan_path(directory, sequence, f) for f in range(n_frames))
