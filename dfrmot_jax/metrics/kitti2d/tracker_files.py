"""A tracker's KITTI result files, read as TrackEval reads them, for scoring: what a results folder
holds (:func:`inspect_results`) and its rows of one class as one lane (:func:`read_tracker_files`)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Iterator, NamedTuple, Sequence

import numpy as np

from dfrmot_jax.io import kitti as kio
from dfrmot_jax.io.result_rows import ResultRows, iter_result_rows
from dfrmot_jax.metrics.common.fields3d import read_box3d_columns
from dfrmot_jax.metrics.common.sequences import seq_name
from dfrmot_jax.metrics.kitti2d.kitti import PreparedGT, TrackerDets, class_ids

__all__ = ["ResultFolder", "inspect_results", "read_tracker_files", "result_file_problem", "result_paths"]


def result_file_problem(path) -> str | None:
    """Why ``path`` cannot be read as a result file although something has that name: ``'is a
    directory'``, ``'is a dangling symlink (to TARGET)'``, ``'is not a regular file'``; None for a
    readable file (after symlinks) and for no entry at all (a missing file)."""
    path = Path(path)
    if path.is_file() or not (path.exists() or path.is_symlink()):
        return None
    if path.is_dir():
        return "is a directory"
    if not path.exists():
        return f"is a dangling symlink (to {os.readlink(path)})"
    return "is not a regular file"


class ResultFolder(NamedTuple):
    """What a results folder holds for the sequences to evaluate (:func:`inspect_results`).

    missing: names of sequences without a result file; unreadable: ``(path, why)`` of names that
    are no readable file (:func:`result_file_problem`); unexpected: ``*.txt`` file names that are
    no sequence of the ground truth (stale or foreign files), sorted.
    """
    missing: tuple
    unreadable: tuple
    unexpected: tuple


def inspect_results(results_dir, sequences: Sequence, known: Sequence | None = None) -> ResultFolder:
    """The :class:`ResultFolder` of ``results_dir`` for ``sequences`` (names or ints); ``known``:
    every sequence of the ground truth (``*.txt`` files named otherwise are unexpected), None to
    not look for unexpected files."""
    results_dir = Path(results_dir)
    missing, unreadable = [], []
    for name in (seq_name(s) for s in sequences):
        path = results_dir / f"{name}.txt"
        why = result_file_problem(path)
        if why is not None:
            unreadable.append((str(path), why))
        elif not path.is_file():
            missing.append(name)
    unexpected = ()
    if known is not None:
        names = {seq_name(s) for s in known}
        unexpected = tuple(sorted(p.name for p in results_dir.glob("*.txt") if p.stem not in names))
    return ResultFolder(tuple(missing), tuple(unreadable), unexpected)


def result_paths(results_dir, sequences: Sequence) -> list[Path]:
    """The result files of ``sequences`` (names or ints) that :func:`read_tracker_files` reads, in its
    order: ``results_dir/SSSS.txt`` where that is a file."""
    return [p for s in sequences if (p := Path(results_dir) / f"{seq_name(s)}.txt").is_file()]


def read_tracker_files(results_dir, gt: PreparedGT, missing: str = "empty", need_3d: bool = False,
                       rows: Iterator[ResultRows] | None = None) -> TrackerDets:
    """Read ``results_dir/SSSS.txt`` for every sequence of ``gt`` (KITTI tracking result format).

    Files are read as TrackEval reads them (:mod:`dfrmot_jax.io.result_rows`: rows in any order,
    ``x2 < x1`` allowed, frames and ids truncated toward zero, 10 or more columns); rows with a
    negative id are skipped unread. Rows of the evaluated class (``Car``/``car_2`` for car,
    ``Pedestrian`` for pedestrian; any case) are kept, in frame order (file order within a frame);
    rows of other known classes are dropped. Unknown class names raise :class:`KittiFormatError`
    (field ``type``), as do frames outside the sequence (field ``frame``) and whatever
    :func:`~dfrmot_jax.io.result_rows.read_result_rows` refuses. A name that is no readable file
    (a directory, a dangling symlink) always raises. A missing file is an empty output with
    ``missing='empty'`` (TrackEval itself refuses to run without every file; an empty file there
    gives the same numbers) or raises with ``missing='error'``. need_3d: also read the 3D fields
    ``h w l x y z rot_y`` (columns 11-17) of the kept rows, by the rules of
    :mod:`dfrmot_jax.metrics.common.fields3d` (the placeholder: no 3D box; anything else that is no box, a
    missing column or a non-number: ``KittiFormatError`` with file, line and field). The files are
    parsed together (:func:`~dfrmot_jax.io.result_rows.iter_result_rows`); ``rows``: that parse of
    ``result_paths(results_dir, gt.sequences)``, started earlier. Returns one lane.
    """
    results_dir = Path(results_dir)
    if not results_dir.is_dir():
        raise FileNotFoundError(f"results folder not found: {results_dir}")
    fr, ids, bx, src, paths, b3, h3 = [], [], [], [], [], [], []
    files = rows if rows is not None else iter_result_rows(result_paths(results_dir, gt.sequences))
    for s, name in enumerate(gt.sequences):
        path = results_dir / f"{name}.txt"
        why = result_file_problem(path)
        if why is not None:
            raise kio.KittiFormatError(path, None, None, f"{why}, not a result file")
        if not path.is_file():
            if missing == "error":
                raise kio.KittiFormatError(path, None, None, "result file not found")
            paths.append(None)
            continue
        paths.append(str(path))
        rows = next(files)
        cid = class_ids(rows.type, path, kio, rows.row)
        bad = np.flatnonzero(rows.frame >= gt.lengths[s])
        if bad.size:
            r = int(rows.row[bad[0]])
            raise kio.KittiFormatError(path, kio.line_of_row(path, r) or r + 1, "frame",
                                       f"frame {int(rows.frame[bad[0]])} is beyond sequence {name} "
                                       f"({int(gt.lengths[s])} frames: 0..{int(gt.lengths[s]) - 1})")
        keep = np.flatnonzero(cid == gt.cls_id)
        keep = keep[np.argsort(rows.frame[keep], kind="stable")]
        fr.append(rows.frame[keep] + gt.offsets[s])
        ids.append(rows.track_id[keep])
        bx.append(rows.box[keep])
        src.append(rows.row[keep])
        if need_3d:
            with open(path, encoding="utf-8-sig") as f:
                first = f.readline()
            # io.result_rows' separator rule: commas when the first line has one, else whitespace
            box3d, has3d = read_box3d_columns(path, rows.row[keep], "," if "," in first else None)
            b3.append(box3d)
            h3.append(has3d)
    e = np.zeros(0, np.int64)
    box3d = has3d = None
    if need_3d:
        box3d = np.concatenate(b3) if b3 else np.zeros((0, 7))
        has3d = np.concatenate(h3) if h3 else np.zeros(0, dtype=bool)
    if fr:
        frame = np.concatenate(fr)
        return TrackerDets(1, np.zeros(len(frame), np.int64), frame, np.concatenate(ids),
                           np.ascontiguousarray(np.concatenate(bx), dtype=np.float64), np.concatenate(src),
                           (tuple(paths),), box3d, has3d)
    return TrackerDets(1, e, e, e, np.zeros((0, 4)), e, (tuple(paths),), box3d, has3d)
