"""KITTI tracking result files written: the lines (:func:`tracking_lines`, in the columns of
:mod:`dfrmot_jax.io.columns`) and the file (:func:`write_tracking_results`, atomically), with the
checks that keep every file readable by :func:`dfrmot_jax.io.kitti.read_tracking_labels`."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from .atomic import write_text_atomic
from .columns import format_lines

__all__ = ["RESULT_FILE", "result_files", "write_class_files", "write_sequence_files", "write_tracking_results", "tracking_lines"]


def _as_int(name: str, value, n: int) -> np.ndarray:
    arr = np.asarray(value)
    if arr.shape != (n,):
        raise ValueError(f"write_tracking_results: {name} has shape {arr.shape}, expected ({n},)")
    if arr.dtype.kind not in "iu":
        f = arr.astype(np.float64)
        if not np.all(np.isfinite(f) & (f == np.round(f))):
            raise ValueError(f"write_tracking_results: {name} must be integers")
    return arr.astype(np.int64)


def write_tracking_results(
    path,
    frame,
    track_id,
    box,
    type_name="Car",
    alpha=None,
    dims=None,
    loc=None,
    rot_y=None,
    score=None,
    *,
    columns: str = "kitti",
    centroid: str = "legacy",
    has3=None,
    own3=None,
    score2=None,
    box3=None,
) -> None:
    """Write KITTI tracking result lines ``frame id type -1 -1 alpha x1 y1 x2 y2 h w l x y z ry score``.

    frame, track_id: [R] integers (frames non-negative and ascending); box: [R, 4] ``x1, y1, x2, y2``;
    type_name: a str or [R] strs. The other columns come from :mod:`dfrmot_jax.io.columns`
    (``format_lines``), which holds both column sets: ``columns="kitti"`` (default) or
    ``"authors"`` (the C++'s own 18 columns), ``centroid`` the run's 3D axes.
    alpha [R], dims [R, 3] ``h, w, l``, loc [R, 3], rot_y [R], score [R]: the 3D detection written
    on each row (``format_lines``' alpha, dims, loc, rot_y, score3); has3 / own3 [R] bool say which
    rows carry it (default: every row, when any of them is given); score2 [R] the 2D detection's
    score; box3 [R, 6] filtered 3D corners (output "filtered").
    With only frame, track_id and box: alpha -10, dims -1 -1 -1, loc -1000 -1000 -1000, rot_y -10,
    score 1. Rows are written in the given order. The file is replaced atomically (written next to
    it, then renamed); parent directories are created; no rows gives an empty file. Raises
    ValueError for inputs that :func:`read_tracking_labels` would reject.
    """
    write_text_atomic(path, "".join(tracking_lines(frame, track_id, box, type_name, alpha, dims, loc, rot_y, score,
                                                   columns=columns, centroid=centroid, has3=has3, own3=own3,
                                                   score2=score2, box3=box3)))


def tracking_lines(frame, track_id, box, type_name="Car", alpha=None, dims=None, loc=None, rot_y=None, score=None,
                   *, columns: str = "kitti", centroid: str = "legacy", has3=None, own3=None, score2=None,
                   box3=None) -> list[str]:
    """The lines :func:`write_tracking_results` writes (same arguments, same checks), each ending in "\\n"."""
    box_arr = np.asarray(box, dtype=np.float64)
    if box_arr.ndim != 2 or box_arr.shape[1] != 4:
        if not (box_arr.size == 0 and box_arr.ndim <= 2):
            raise ValueError(f"write_tracking_results: box has shape {box_arr.shape}, expected (R, 4)")
        box_arr = box_arr.reshape(0, 4)
    n = box_arr.shape[0]
    frame_arr = _as_int("frame", frame, n)
    id_arr = _as_int("track_id", track_id, n)
    if not np.all(np.isfinite(box_arr)):
        raise ValueError("write_tracking_results: box has non-finite values")
    if np.any(frame_arr < 0):
        raise ValueError("write_tracking_results: negative frame")
    if np.any(frame_arr[1:] < frame_arr[:-1]):
        raise ValueError("write_tracking_results: frames must be in ascending order (sort rows by frame)")
    if np.any(box_arr[:, 2] < box_arr[:, 0]) or np.any(box_arr[:, 3] < box_arr[:, 1]):
        raise ValueError("write_tracking_results: box with x2 < x1 or y2 < y1")

    if isinstance(type_name, str):
        types = [type_name] * n
    else:
        types = [str(t) for t in np.asarray(type_name, dtype=object).reshape(-1).tolist()]
        if len(types) != n:
            raise ValueError(f"write_tracking_results: type_name has {len(types)} entries, expected {n}")
    for t in set(types):
        if not t or any(ch.isspace() for ch in t):
            raise ValueError(f"write_tracking_results: bad type name {t!r}")

    try:
        lines = format_lines(frame_arr, id_arr, box_arr, types, columns, centroid, has3=has3, own3=own3,
                             dims=dims, loc=loc, rot_y=rot_y, alpha=alpha, score3=score, score2=score2,
                             box3=box3)
    except ValueError as e:
        message = str(e).removeprefix("format_lines: ").replace("score3", "score")  # this function's name for it
        raise ValueError(f"write_tracking_results: {message}") from None
    return lines


#: the files a family's ``write_runs`` writes (``SSSS.txt``) or leaves when killed mid-write (``.SSSS.txt.PID.tmp``,
#: the temporaries of ``io.atomic.write_text_atomic``)
RESULT_FILE = re.compile(r"\d{4}\.txt|\.\d{4}\.txt\.\d+\.tmp")


def result_files(out_dir) -> list[Path]:
    """The files of ``out_dir`` that a family's ``write_runs`` writes or leaves behind, sorted: result files
    ``SSSS.txt`` and temporaries ``.SSSS.txt.PID.tmp`` of an interrupted write (nothing else)."""
    return sorted(p for p in Path(out_dir).iterdir()
                  if RESULT_FILE.fullmatch(p.name) and (p.is_file() or p.is_symlink()))


def write_sequence_files(out_dir, lines: dict[str, list[str]]) -> list[Path]:
    """``out_dir/SSSS.txt`` for each sequence name of ``lines`` (its lines, no newline each), every
    line ending with a newline, each file written atomically (:mod:`.atomic`); the one writer of a
    family's per-sequence result files. Returns the paths, sorted by sequence."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for name in sorted(lines):
        path = out_dir / f"{name}.txt"
        write_text_atomic(path, "".join(line + "\n" for line in lines[name]))
        paths.append(path)
    return paths


def write_class_files(out_dir, per_seq: dict[str, list[tuple[np.ndarray, list[str]]]]) -> list[Path]:
    """Several classes' lines in one file per sequence: ``per_seq`` name -> [(frames [n] int, n lines)]
    one part per class in writing order; each file's lines ordered by frame, the parts' order kept
    within a frame (a stable sort), written by :func:`write_sequence_files`."""
    files = {}
    for name, parts in per_seq.items():
        frames = np.concatenate([np.asarray(f, np.int64) for f, _ in parts])
        lines = [line for _, ls in parts for line in ls]
        files[name] = [lines[i] for i in np.argsort(frames, kind="stable")]
    return write_sequence_files(out_dir, files)
