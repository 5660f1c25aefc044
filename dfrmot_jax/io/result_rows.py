"""KITTI tracking result files read by TrackEval's rules: the reader behind ``dfrmot eval``.

The ground truth and detection readers (:mod:`dfrmot_jax.io.kitti`) are strict. A tracker's result
file is read as TrackEval's Kitti2DBox reads it (``_BaseDataset._load_simple_text_file`` and
``Kitti2DBox._load_raw_file``, v1.3.0), so that every file TrackEval scores is scored, identically:

* Rows come in any order (TrackEval groups them by frame, keeping file order within a frame), and
  boxes may have ``x2 < x1`` or ``y2 < y1`` (the metrics then apply TrackEval's IoU formula to the
  negative widths as it does).
* Columns are separated by whitespace, or by commas when the first line has one. A row is
  ``frame id type truncated occluded alpha x1 y1 x2 y2`` and any number of further columns (17 or
  18 in KITTI files); rows of different frames may differ in length.
* On every row ``frame`` and ``id`` are numbers (Python's ``float``) truncated toward zero, as
  ``int(float(s))``: ``3.75`` is 3, ``-0.5`` is 0. A row whose id is then negative is skipped:
  nothing else of it is looked at (it needs only a third column).
* Of a kept row every column but the type is a number (``nan`` and ``inf`` included, except in
  the box); the type is looked up, and the frame checked against the sequence, by
  :func:`dfrmot_jax.metrics.kitti2d.tracker_files.read_tracker_files`.

Refused with file, line and field (:class:`~dfrmot_jax.io.kitti.KittiFormatError`): what TrackEval
cannot read (a frame or id that is no finite number, a row of fewer than 3 columns, a kept row of
fewer than 10 or with a non-number, kept rows of one frame that differ in length, a negative
frame) and what it reads but cannot score: a box coordinate that is not finite (TrackEval's
assignment fails, or its scores become NaN) and an id past 2^53 - 1 (TrackEval allocates max id + 1
entries; past 2^63 the id wraps negative). Blank lines are skipped (TrackEval refuses them).
TrackEval's ``csv.Sniffer`` could also pick ``;`` or ``:`` as the separator: such files are refused.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Iterator, NamedTuple, Sequence

import numpy as np

from .kitti import KittiFormatError, quoted, read_text_file
from .plain_table import first_line, joined_columns, plain_text, read_ahead

__all__ = ["ResultRows", "read_result_rows", "iter_result_rows", "parse_floats", "MIN_COLUMNS"]

#: ``frame id type truncated occluded alpha x1 y1 x2 y2``: TrackEval's boxes are columns 6..9
MIN_COLUMNS = 10
_NAMES = ("frame", "track_id", "type", "truncated", "occluded", "alpha", "x1", "y1", "x2", "y2",
          "h", "w", "l", "x", "y", "z", "rot_y", "score")
_BOX = slice(6, 10)
_ID_MAX = 2**53 - 1                      # ids stay exact integers through float64
_FRAME_MAX = int(np.iinfo(np.int32).max)


class ResultRows(NamedTuple):
    """The rows of a result file that TrackEval keeps (id >= 0 once truncated), file order (R rows).

    frame, track_id: [R] int64 (truncated toward zero); type: [R] object str as written;
    box: [R, 4] float64 ``x1, y1, x2, y2`` as written (``x2 < x1`` allowed); row: [R] int64 the
    row's index among the file's non-blank lines (``io.kitti.line_of_row`` gives its line).
    """

    frame: np.ndarray
    track_id: np.ndarray
    type: np.ndarray
    box: np.ndarray
    row: np.ndarray


def _field(j: int) -> str:
    return _NAMES[j] if j < len(_NAMES) else f"column {j + 1}"


def parse_floats(tokens: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """[N] str tokens (object or str arrays) -> ([N] float64 as Python's ``float`` reads them, NaN where it
    cannot; [N] bool read)."""
    try:
        return tokens.astype(np.float64), np.ones(len(tokens), dtype=bool)
    except (ValueError, TypeError):
        out = np.full(len(tokens), np.nan)
        ok = np.zeros(len(tokens), dtype=bool)
        for k, tok in enumerate(tokens):
            try:
                out[k] = float(tok)
                ok[k] = True
            except (ValueError, TypeError):
                pass
        return out, ok


def read_result_rows(path) -> ResultRows:
    """Read a KITTI tracking result file by TrackEval's rules (module docstring).

    Returns the kept rows (:class:`ResultRows`); raises :class:`KittiFormatError` naming file,
    line and field for what TrackEval cannot read or score. A plain file
    (:mod:`dfrmot_jax.io.plain_table`) is read in one pass and checked by the same :func:`_kept_rows`;
    any problem, or any other file, is read line by line.
    """
    plain = _joined_rows([path])
    if plain is not None:      # any problem: the line reader below names the first (its messages need tokens)
        return plain[0]

    text = read_text_file(path)
    lines = text.lines
    sep = "," if lines and "," in lines[0] else None
    split = [s.split(sep) for s in lines]
    if sep:   # TrackEval drops one empty field at the end of a row (a trailing separator)
        split = [r[:-1] if len(r) > 1 and not r[-1].strip() else r for r in split]
    count = np.fromiter(map(len, split), dtype=np.int64, count=len(split))
    width = max(int(count.max(initial=0)), MIN_COLUMNS)
    if count.size and np.all(count == width):
        tok = np.array(split, dtype=object).reshape(len(split), width)
    else:
        tok = np.empty((len(split), width), dtype=object)
        for k, r in enumerate(split):
            tok[k] = r + [""] * (width - len(r))
    kept, problems = _kept_rows(count, lambda j, rows: parse_floats(tok[rows, j]), lambda r, j: tok[r, j],
                                text.line_numbers)
    if problems:
        r, _, name, message = min(problems, key=lambda p: (p[0], p[1]))
        raise KittiFormatError(text.path, text.line_numbers[r], name, message)
    kf, kt, box, keep = kept
    types = np.empty(len(keep), dtype=object)
    types[:] = [str(s).strip() for s in tok[keep, 2]]
    return ResultRows(kf, kt, types, box, keep)


def iter_result_rows(paths: Sequence, ahead: bool = False) -> Iterator[ResultRows]:
    """:func:`read_result_rows` of each of ``paths``, in order. Plain files of one separator and one
    column count are read in one parse (:func:`~dfrmot_jax.io.plain_table.joined_columns`) and
    checked together by :func:`_kept_rows` (all rows of equal length: every rule is a row's own);
    otherwise, or when any check fails, the files are read one by one, ahead in two threads
    (:func:`~dfrmot_jax.io.plain_table.read_ahead`), so that a file's error is raised when its turn
    comes, as a plain loop over :func:`read_result_rows` raises it. ahead: the parse starts in a
    thread now (pyarrow releases Python's lock), and the first row waits for it: a cold
    ``evaluate_files`` prepares the ground truth meanwhile (~10 ms of ~100 saved)."""
    paths = list(paths)
    if len(paths) < 2:
        return read_ahead(read_result_rows, paths)
    if not ahead:
        joined = _joined_rows(paths)
        return read_ahead(read_result_rows, paths) if joined is None else iter(joined)
    ex = ThreadPoolExecutor(1)
    future = ex.submit(_joined_rows, paths)
    ex.shutdown(wait=False)

    def rows():
        joined = future.result()
        yield from (read_ahead(read_result_rows, paths) if joined is None else joined)

    return rows()


def _joined_rows(paths: list) -> list[ResultRows] | None:
    """The kept rows of every file of ``paths`` (one or several) from one parse, or None where a file is
    not plain, the files' separators or column counts differ or any check fails (as
    :func:`iter_result_rows` says; each file is then read line by line, which names the problem)."""
    texts = [plain_text(p) for p in paths]
    if any(t is None for t in texts):
        return None
    firsts = [first_line(t) for t in texts]
    seps = {"," if "," in f else None for f in firsts}
    if len(seps) != 1:
        return None
    sep = seps.pop()
    widths = {len(f.split(sep)) for f in firsts}
    if len(widths) != 1 or (width := widths.pop()) < MIN_COLUMNS:
        return None
    joined = joined_columns(texts, sep, width, (2,))
    if joined is None:
        return None
    cols, starts = joined
    n = int(starts[-1])
    kept, problems = _kept_rows(np.full(n, width), lambda j, rows: (cols[j][rows], np.ones(len(rows), bool)),
                                lambda r, j: "", range(1, n + 1))
    if problems:
        return None
    frame, track_id, box, keep = kept
    cut = np.searchsorted(keep, starts)
    return [ResultRows(frame[i:j], track_id[i:j], cols[2][keep[i:j]], box[i:j], keep[i:j] - a)
            for a, i, j in zip(starts[:-1], cut[:-1], cut[1:])]


def _kept_rows(count: np.ndarray, floats, token, line_numbers) -> tuple[tuple, list]:
    """((frame, track_id, box, kept row indices), problems ``(row, column, field, message)``) of a table.

    count: [n] fields per row; floats(j, rows): ([len(rows)] float64 of field j at row indices
    ``rows``, NaN where not read; [len(rows)] bool read); token(r, j): the text of a field and
    line_numbers[r] a row's line, for the messages.
    """
    problems: list[tuple[int, int, str, str]] = []           # (row, column, field, message)
    width = int(count.max(initial=0))

    def flag(mask: np.ndarray, rows: np.ndarray, j: int, message) -> None:
        if mask.any():
            r = int(rows[np.argmax(mask)])
            problems.append((r, j, _field(j) if j >= 0 else "columns", message(r)))

    every = np.arange(len(count))
    flag(count < 3, every, -1, lambda r: f"expected at least 3 columns ({MIN_COLUMNS} on a row with an id >= 0), "
                                         f"got {count[r]}")
    frame, frame_ok = floats(0, every)
    tid, id_ok = floats(1, every)
    for j, v, ok in ((0, frame, frame_ok), (1, tid, id_ok)):
        flag(~ok, every, j, lambda r, j=j: f"not a number: {quoted(token(r, j))}")
        flag(ok & ~np.isfinite(v), every, j, lambda r, j=j: f"not finite: {quoted(token(r, j))}")
    with np.errstate(invalid="ignore"):
        frame, tid = np.trunc(frame), np.trunc(tid)
        keep = np.flatnonzero(id_ok & np.isfinite(tid) & (tid >= 0) & (count >= 3))
    kc = count[keep]
    flag(kc < MIN_COLUMNS, keep, -1, lambda r: f"expected at least {MIN_COLUMNS} columns (frame id type truncated "
                                               f"occluded alpha x1 y1 x2 y2 ...), got {count[r]}")
    kf, kt = frame[keep], tid[keep]
    flag(kt > _ID_MAX, keep, 1, lambda r: f"too large (at most {_ID_MAX}): {quoted(token(r, 1))}")
    flag(np.isfinite(kf) & (kf < 0), keep, 0, lambda r: f"negative frame {quoted(token(r, 0))}")
    flag(np.isfinite(kf) & (kf > _FRAME_MAX), keep, 0, lambda r: f"too large (at most {_FRAME_MAX}): "
                                                                 f"{quoted(token(r, 0))}")
    box = np.zeros((len(keep), 4))
    for j in range(3, width):
        has = kc > j
        v, ok = floats(j, keep[has])
        flag(~ok, keep[has], j, lambda r, j=j: f"not a number: {quoted(token(r, j))}")
        if _BOX.start <= j < _BOX.stop:
            flag(ok & ~np.isfinite(v), keep[has], j, lambda r, j=j: f"not finite: {quoted(token(r, j))}")
            box[has, j - _BOX.start] = v
    # TrackEval stacks the kept rows of a frame into one array: they must have the same length. Of a
    # frame whose rows differ, the rows off the file's own count (its most common one among kept
    # rows; a tie: the first kept row's) are the ones named
    if kc.size and kc.min() != kc.max():
        _flag_ragged(kc, kf, keep, count, line_numbers, flag)
    if problems:
        return (), problems
    return (kf.astype(np.int64), kt.astype(np.int64), box, keep.astype(np.int64)), problems


def _flag_ragged(kc: np.ndarray, kf: np.ndarray, keep: np.ndarray, count: np.ndarray, line_numbers, flag) -> None:
    """Flag the kept rows (``keep``, of ``kc`` fields, frames ``kf``) whose frame's rows differ in length."""
    order = np.lexsort((keep, kf))
    same = np.zeros(len(keep), dtype=bool)
    same[1:] = kf[order][1:] == kf[order][:-1]
    group = np.empty(len(keep), dtype=np.int64)
    group[order] = np.cumsum(~same) - 1
    lo = np.full(group.max(initial=-1) + 1, np.iinfo(np.int64).max)
    hi = np.full_like(lo, -1)
    np.minimum.at(lo, group, kc)
    np.maximum.at(hi, group, kc)
    ragged_frame = lo[group] != hi[group]
    if ragged_frame.any():
        values, counts = np.unique(kc, return_counts=True)
        top = values[counts == counts.max()]
        usual = int(kc[0]) if kc[0] in top else int(top[0])
        odd = ragged_frame & (kc != usual)
        # another row of the same frame, for the message: one with the file's count if there is one
        other = {}
        for j in np.flatnonzero(ragged_frame)[::-1]:
            if kc[j] == usual or group[j] not in other:
                other[group[j]] = int(keep[j])

        def ragged(r):
            j = int(np.flatnonzero(keep == r)[0])
            o = other[group[j]]
            return (f"{count[r]} columns, but the file's rows have {usual} (line {line_numbers[o]} of the same "
                    f"frame has {count[o]})")
        flag(odd, keep, -1, ragged)
