"""Readers for the KITTI tracking text formats used by DFR-FastMOT (the writer of tracking results
is :mod:`dfrmot_jax.io.result_writer`).

Every reader returns numpy arrays with rows in file order and raises :class:`KittiFormatError`
(naming file, 1-based line and field) for any malformed input. Blank lines are skipped, CRLF line
endings and a leading UTF-8 byte-order mark are accepted and an empty file gives zero-length arrays.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Iterator, NamedTuple, Sequence

import numpy as np

from .plain_table import first_line, joined_columns, plain_text, read_ahead

__all__ = ["KittiFormatError", "Detections2D", "Detections3D", "TrackingLabels", "Calib", "read_detections_2d",
           "read_detections_3d", "read_tracking_labels", "iter_tracking_labels", "joined_tracking_labels",
           "read_calib", "sequence_lengths"]


class KittiFormatError(ValueError):
    """The one error type for bad KITTI input.

    Attributes: ``path`` (str), ``line`` (1-based int, or None when the error concerns the whole
    file), ``field`` (column or matrix name, or None) and ``message``.
    ``str(e)`` is ``"{path}:{line}: field '{field}': {message}"`` with the None parts left out.
    """
    def __init__(self, path, line: int | None = None, field: str | None = None, message: str = ""):
        self.path = str(path)
        self.line = None if line is None else int(line)
        self.field = field
        self.message = message
        super().__init__(self.path, self.line, self.field, self.message)

    def __str__(self) -> str:
        where = self.path if self.line is None else f"{self.path}:{self.line}"
        what = self.message if self.field is None else f"field '{self.field}': {self.message}"
        return f"{where}: {what}"

    def __reduce__(self):
        return (type(self), (self.path, self.line, self.field, self.message))


class Detections2D(NamedTuple):
    """2D detections, rows in file order (R rows).

    frame: [R] int64; box: [R, 4] float64 ``x1, y1, x2, y2`` in pixels; score: [R] float64.
    """
    frame: np.ndarray
    box: np.ndarray
    score: np.ndarray


class Detections3D(NamedTuple):
    """3D detections, rows in file order (R rows).

    frame: [R] int64; type: [R] object (str as written, e.g. ``"2"`` or ``"Car"``);
    box: [R, 4] float64 the detector's image box ``x1, y1, x2, y2``; score: [R] float64;
    dims: [R, 3] float64 ``h, w, l`` (metres); loc: [R, 3] float64 ``x, y, z`` (camera
    coordinates, bottom centre); rot_y: [R] float64; alpha: [R] float64.
    """
    frame: np.ndarray
    type: np.ndarray
    box: np.ndarray
    score: np.ndarray
    dims: np.ndarray
    loc: np.ndarray
    rot_y: np.ndarray
    alpha: np.ndarray


class TrackingLabels(NamedTuple):
    """KITTI tracking label or result rows, file order (R rows).

    frame, track_id: [R] int64; type: [R] object str as written (``"Car"``, ``"DontCare"``, ...);
    truncated, occluded, alpha: [R] float64; box: [R, 4] float64 ``x1, y1, x2, y2``;
    dims: [R, 3] float64 ``h, w, l``; loc: [R, 3] float64 ``x, y, z``; rot_y: [R] float64;
    score: [R] float64, NaN when the file has no score column (17 columns).
    """
    frame: np.ndarray
    track_id: np.ndarray
    type: np.ndarray
    truncated: np.ndarray
    occluded: np.ndarray
    alpha: np.ndarray
    box: np.ndarray
    dims: np.ndarray
    loc: np.ndarray
    rot_y: np.ndarray
    score: np.ndarray


class Calib(NamedTuple):
    """KITTI tracking calibration.

    P2: [3, 4]; R0_rect: [3, 3]; Tr_velo_to_cam: [3, 4]; P: [4, 3, 4] ``P0..P3`` (a missing
    ``P0``, ``P1`` or ``P3`` is zeros); Tr_imu_to_velo: [3, 4] (zeros if absent).
    """
    P2: np.ndarray
    R0_rect: np.ndarray
    Tr_velo_to_cam: np.ndarray
    P: np.ndarray
    Tr_imu_to_velo: np.ndarray


_FIELDS_2D = ("frame", "x1", "y1", "x2", "y2", "score")
_FIELDS_3D = ("frame", "type", "x1", "y1", "x2", "y2", "score", "h", "w", "l", "x", "y", "z", "rot_y", "alpha")
_FIELDS_3D_LABEL = (
    "frame", "type", "truncated", "occluded", "alpha", "x1", "y1", "x2", "y2",
    "h", "w", "l", "x", "y", "z", "rot_y", "score",
)
_FIELDS_TRACK = (
    "frame", "track_id", "type", "truncated", "occluded", "alpha", "x1", "y1", "x2", "y2",
    "h", "w", "l", "x", "y", "z", "rot_y",
)
_FIELDS_TRACK_SCORE = _FIELDS_TRACK + ("score",)

_TRACK_LAYOUTS = {(None, 17): _FIELDS_TRACK, (None, 18): _FIELDS_TRACK_SCORE}
_STRING_FIELDS = frozenset({"type"})
_INT_FIELDS = ("frame", "track_id")
#: frames index int32 arrays; ids only need to stay exact integers through float64 parsing
_INT_MAX = {"frame": int(np.iinfo(np.int32).max), "track_id": 2**53 - 1}
_DIM_FIELDS = ("h", "w", "l")


class _Text(NamedTuple):
    path: str
    lines: list[str]
    line_numbers: list[int]


def read_text_file(path) -> _Text:
    p = str(path)
    try:
        with open(path, encoding="utf-8-sig") as f:
            raw = f.read().split("\n")
    except FileNotFoundError:
        raise KittiFormatError(p, None, None, "file not found") from None
    except IsADirectoryError:
        raise KittiFormatError(p, None, None, "is a directory, not a file") from None
    except UnicodeDecodeError as e:
        raise KittiFormatError(p, None, None, f"not UTF-8 text ({e.reason} at byte {e.start})") from None
    numbers = [i for i, s in enumerate(raw, 1) if s and not s.isspace()]
    lines = raw if len(numbers) == len(raw) else [raw[i - 1] for i in numbers]
    return _Text(p, lines, numbers)


def line_of_row(path, row: int) -> int | None:
    """1-based line number of data row ``row`` of a text file (blank lines are not rows); None
    when there is no path or no such row."""
    if path is None:
        return None
    with open(path, encoding="utf-8-sig", errors="replace") as f:
        k = -1
        for n, line in enumerate(f.read().split("\n"), 1):
            if line and not line.isspace():
                k += 1
                if k == row:
                    return n
    return None


def quoted(token: str) -> str:
    return repr(token.strip())


def _fmt_value(v: float) -> str:
    if math.isfinite(v) and v == int(v) and abs(v) < 1e15:
        return str(int(v))
    return f"{v:g}"


def _columns_message(layouts: dict, sep: str | None, got: int) -> str:
    counts = sorted(n for (s, n) in layouts if s == sep)
    if not counts:
        counts = sorted({n for (_, n) in layouts})
    kind = "comma-separated" if sep == "," else "whitespace-separated"
    want = " or ".join(str(n) for n in counts)
    return f"expected {want} {kind} columns, got {got}"


def _parse_table(path, layouts: dict, check_dims: bool) -> tuple[tuple[str, ...], dict[str, np.ndarray]]:
    """Parse a one-record-a-line table.

    ``layouts`` maps ``(separator, column count)`` (separator ``","`` or ``None`` for whitespace)
    to the field names of that layout. Returns the field names of the layout found and a dict
    field -> array ([R] float64, [R] int64 for frame/track_id, [R] object for string fields).
    A plain file (:mod:`dfrmot_jax.io.plain_table`) is read in one pass and checked by the same
    :func:`_checked_columns`; any problem, or any other file, is read line by line (located errors).
    """
    plain = _parse_tables([path], layouts, check_dims)
    if plain is not None:          # any problem: the line reader below names the first (its messages need tokens)
        return plain[0], plain[1]

    text = read_text_file(path)
    lines = text.lines
    if not lines:
        fields = next(iter(layouts.values()))
        return fields, _empty_columns(fields)

    sep, ncols, fields = _layout(lines[0], layouts)
    if fields is None:
        raise KittiFormatError(text.path, text.line_numbers[0], "columns", _columns_message(layouts, sep, ncols))

    if sep == ",":
        counts = [s.count(",") + 1 for s in lines]
        bad = _first_mismatch(counts, ncols)
        n_ok = len(lines) if bad is None else bad
        tokens = ",".join(lines[:n_ok]).split(",") if n_ok else []
    else:
        tokens = []
        counts = []
        for s in lines:
            parts = s.split()
            counts.append(len(parts))
            tokens += parts
        bad = _first_mismatch(counts, ncols)
        n_ok = len(lines) if bad is None else bad
        if bad is not None:
            del tokens[n_ok * ncols:]

    columns = _convert(text, fields, tokens, n_ok, check_dims)
    if bad is not None:
        raise KittiFormatError(
            text.path, text.line_numbers[bad], "columns", _columns_message({(sep, ncols): fields}, sep, counts[bad])
        )
    return fields, columns


def _parse_tables(paths: Sequence, layouts: dict, check_dims: bool) -> tuple | None:
    """The one-pass path of :func:`_parse_table`, for one or several plain files of one layout at once
    (:func:`~dfrmot_jax.io.plain_table.joined_columns`): (field names, the columns of all their rows,
    [n + 1] each file's first row), or None where a file is not plain, the layouts differ or any check
    fails (each file is then read line by line, which names the problem)."""
    texts = [plain_text(p) for p in paths]
    if not texts or any(t is None for t in texts):
        return None
    found = {_layout(first_line(t), layouts) for t in texts}
    sep, ncols, fields = found.pop() if len(found) == 1 else (None, 0, None)
    joined = fields and joined_columns(texts, sep, ncols, [i for i, n in enumerate(fields) if n in _STRING_FIELDS])
    if not joined:
        return None
    cols, starts = joined
    numeric = {n: c for c, n in zip(cols, fields) if n not in _STRING_FIELDS}
    strings = {n: c for c, n in zip(cols, fields) if n in _STRING_FIELDS}
    columns, problems = _checked_columns(fields, numeric, None, strings, lambda r, name: "", check_dims, starts,
                                         plain=True)
    return None if problems else (fields, columns, starts)


def _layout(first: str, layouts: dict) -> tuple[str | None, int, tuple | None]:
    """(separator, column count, field names or None) of a table whose first non-blank line is ``first``."""
    sep = "," if ("," in first and any(s == "," for (s, _) in layouts)) else None
    ncols = first.count(",") + 1 if sep == "," else len(first.split())
    return sep, ncols, layouts.get((sep, ncols))


def _first_mismatch(counts: list[int], n: int) -> int | None:
    c = np.asarray(counts)
    bad = np.flatnonzero(c != n)
    return int(bad[0]) if bad.size else None


def _empty_columns(fields: Sequence[str]) -> dict[str, np.ndarray]:
    out = {}
    for name in fields:
        if name in _STRING_FIELDS:
            out[name] = np.empty(0, dtype=object)
        elif name in _INT_FIELDS:
            out[name] = np.empty(0, dtype=np.int64)
        else:
            out[name] = np.empty(0, dtype=np.float64)
    return out


def _convert(text: _Text, fields: Sequence[str], tokens: list[str], nrows: int, check_dims: bool) -> dict[str, np.ndarray]:
    ncols = len(fields)
    if nrows == 0:
        return _empty_columns(fields)
    numeric = [i for i, name in enumerate(fields) if name not in _STRING_FIELDS]
    values = np.empty((nrows, len(numeric)), dtype=np.float64)
    unparsable = None
    for j, i in enumerate(numeric):
        col = tokens[i::ncols]
        try:
            values[:, j] = np.array(col, dtype=np.float64)
        except ValueError:
            for r, tok in enumerate(col):
                try:
                    values[r, j] = float(tok)
                except ValueError:
                    values[r, j] = np.nan
                    if unparsable is None:
                        unparsable = np.zeros(values.shape, dtype=bool)
                    unparsable[r, j] = True

    strings = {}
    for i, name in enumerate(fields):
        if name in _STRING_FIELDS:
            strings[name] = np.empty(nrows, dtype=object)
            strings[name][:] = [s.strip() for s in tokens[i::ncols]]
    names = [fields[i] for i in numeric]
    out, problems = _checked_columns(fields, {n: values[:, j] for j, n in enumerate(names)},
                                     None if unparsable is None else {n: unparsable[:, j] for j, n in enumerate(names)},
                                     strings,
                                     lambda r, name: tokens[r * ncols + fields.index(name)], check_dims)
    if problems:
        r, _, name, message = min(problems, key=lambda p: (p[0], p[1]))
        raise KittiFormatError(text.path, text.line_numbers[r], name, message)
    return out


def _checked_columns(fields: Sequence[str], col: dict, unparsable: dict | None, strings: dict,
                     token, check_dims: bool, starts: np.ndarray | None = None,
                     plain: bool = False) -> tuple[dict[str, np.ndarray], list]:
    """(columns, problems ``(row, priority, field, message)``) of a table. col: numeric field -> [R] float64
    (NaN where ``unparsable[field]`` [R] bool, when given); strings: field -> [R] object str; token(r, name):
    its text. starts: the tables' first rows where the columns hold several one after the other (their
    frames are each sorted on their own); default one table. plain: read by
    :func:`~dfrmot_jax.io.plain_table.plain_columns`, which refused non-finite numbers and empty strings
    already. Of cells in one row, the leftmost is named."""
    numeric = [name for name in fields if name not in _STRING_FIELDS]
    problems: list[tuple[int, int, str, str]] = []
    at = None if plain else _first_cell([(name, ~np.isfinite(col[name])) for name in numeric])
    if at is not None:
        r, name = at
        what = "not a number" if unparsable is not None and unparsable[name][r] else "not finite"
        problems.append((r, 0, name, f"{what}: {quoted(token(r, name))}"))

    # Values are float32 (boxes, scores, 3D values) or int32 (frames, ids) downstream: a value they
    # cannot hold is refused here, located, not later at write time.
    big = float(np.finfo(np.float32).max)
    with np.errstate(invalid="ignore"):
        at = _first_cell([(name, (np.abs(col[name]) > big) & (plain or np.isfinite(col[name]))) for name in numeric])
    if at is not None:
        r, name = at
        problems.append((r, 0, name, f"outside the float32 range: {quoted(token(r, name))}"))
    for name, most in _INT_MAX.items():
        if name in col and np.any(np.abs(col[name]) > most):
            r = int(np.argmax(np.abs(col[name]) > most))
            problems.append((r, 1, name, f"too large (at most {most}): {quoted(token(r, name))}"))

    def first(mask: np.ndarray) -> int | None:
        return int(np.argmax(mask)) if mask.any() else None
    for name in _INT_FIELDS:
        if name in col:
            v = col[name]
            r = first(np.isfinite(v) & (v != np.floor(v)))
            if r is not None:
                problems.append((r, 1, name, f"not an integer: {quoted(token(r, name))}"))

    frame = col["frame"]
    r = first(frame < 0)
    if r is not None:
        problems.append((r, 2, "frame", f"negative frame {quoted(token(r, 'frame'))}"))
    unsorted = frame[1:] < frame[:-1]
    if starts is not None:
        unsorted[starts[1:-1][(starts[1:-1] > 0) & (starts[1:-1] < len(frame))] - 1] = False
    r = first(unsorted)
    if r is not None:
        r += 1
        problems.append(
            (r, 3, "frame", f"frames not sorted: {_fmt_value(frame[r])} after {_fmt_value(frame[r - 1])}")
        )

    for prio, (lo, hi) in enumerate((("x1", "x2"), ("y1", "y2")), start=4):
        r = first(col[hi] < col[lo])
        if r is not None:
            problems.append(
                (r, prio, hi, f"{hi} < {lo} ({_fmt_value(col[hi][r])} < {_fmt_value(col[lo][r])})")
            )

    if check_dims:
        dims = np.stack([col[d] for d in _DIM_FIELDS], axis=1)
        neg = dims < 0
        if neg.any():
            r, j = divmod(int(np.argmax(neg)), 3)
            name = _DIM_FIELDS[j]
            problems.append((r, 6, name, f"negative 3D size {name} = {quoted(token(r, name))}"))

    for name, vals in strings.items():
        r = None if plain else first(vals == "")
        if r is not None:
            problems.append((r, 7, name, "empty"))
    return ({}, problems) if problems else (_typed(fields, col, strings), problems)


def _typed(fields: Sequence[str], col: dict, strings: dict) -> dict[str, np.ndarray]:
    """The checked columns by field: strings as they are, frames and ids int64, the rest float64."""
    return {name: strings[name] if name in strings else col[name].astype(np.int64) if name in _INT_FIELDS
            else col[name] for name in fields}


def _first_cell(masks: list) -> tuple[int, str] | None:
    """(row, field) of the first True cell of a table, rows first then fields in order: ``masks`` is
    [(field, [R] bool)] in column order. None when there is none."""
    best = None
    for name, m in masks:
        if m.any():
            r = int(np.argmax(m))
            if best is None or r < best[0]:
                best = (r, name)
    return best


def _stack(c: dict[str, np.ndarray], names: Sequence[str]) -> np.ndarray:
    return np.stack([c[n] for n in names], axis=1)


def read_detections_2d(path) -> Detections2D:
    """Read 2D detections ``frame,x1,y1,x2,y2,score`` (comma- or whitespace-separated).

    Returns frame [R] int64, box [R, 4] float64, score [R] float64.
    """
    layouts = {(",", 6): _FIELDS_2D, (None, 6): _FIELDS_2D}
    _, c = _parse_table(path, layouts, check_dims=False)
    return Detections2D(frame=c["frame"], box=_stack(c, ("x1", "y1", "x2", "y2")), score=c["score"])


def read_detections_3d(path) -> Detections3D:
    """Read 3D detections in one of three layouts, detected from the first non-empty line.

    (a) 15 comma-separated columns ``frame,type,x1,y1,x2,y2,score,h,w,l,x,y,z,rot_y,alpha``;
    (b) the same 15 columns whitespace-separated; (c) KITTI label layout, 17 whitespace-separated
    columns ``frame type truncated occluded alpha x1 y1 x2 y2 h w l x y z rot_y score``.
    Returns frame [R], type [R], box [R, 4], score [R], dims [R, 3], loc [R, 3], rot_y [R], alpha [R].
    """
    layouts = {(",", 15): _FIELDS_3D, (None, 15): _FIELDS_3D, (None, 17): _FIELDS_3D_LABEL}
    _, c = _parse_table(path, layouts, check_dims=True)
    return Detections3D(
        frame=c["frame"],
        type=c["type"],
        box=_stack(c, ("x1", "y1", "x2", "y2")),
        score=c["score"],
        dims=_stack(c, ("h", "w", "l")),
        loc=_stack(c, ("x", "y", "z")),
        rot_y=c["rot_y"],
        alpha=c["alpha"],
    )


def read_tracking_labels(path) -> TrackingLabels:
    """Read KITTI tracking labels (17 columns) or results (18 columns, with score).

    Columns ``frame track_id type truncated occluded alpha x1 y1 x2 y2 h w l x y z rot_y [score]``,
    whitespace-separated. Negative 3D sizes are allowed (``DontCare`` rows have ``-1``).
    Returns [R] / [R, 4] / [R, 3] arrays as described in :class:`TrackingLabels`.
    """
    return _labels(*_parse_table(path, _TRACK_LAYOUTS, check_dims=False))


def iter_tracking_labels(paths: Sequence) -> Iterator[TrackingLabels]:
    """:func:`read_tracking_labels` of each of ``paths``, in order: from one parse where
    :func:`joined_tracking_labels` can, else one file after the other, read ahead in two threads
    (:func:`~dfrmot_jax.io.plain_table.read_ahead`), a file's error raised when its turn comes."""
    paths = list(paths)
    joined = joined_tracking_labels(paths)
    if joined is None:
        return read_ahead(read_tracking_labels, paths)
    lab, starts = joined
    return (TrackingLabels(*(f[a:b] for f in lab)) for a, b in zip(starts[:-1], starts[1:]))


def joined_tracking_labels(paths: Sequence) -> tuple[TrackingLabels, np.ndarray] | None:
    """The rows of every file of ``paths`` read in one parse (:func:`~dfrmot_jax.io.plain_table.joined_columns`:
    all KITTI ``label_02`` in ~20 ms instead of ~45 ms in two threads), one file after the other, and
    [n + 1] each file's first row; None unless there are two or more files, all plain, of one layout
    and passing every check of :func:`read_tracking_labels` (which then names the problem)."""
    tables = _parse_tables(paths, _TRACK_LAYOUTS, check_dims=False) if len(paths) > 1 else None
    return None if tables is None else (_labels(tables[0], tables[1]), tables[2])


def _labels(fields: Sequence[str], c: dict) -> TrackingLabels:
    score = c["score"] if "score" in fields else np.full(len(c["frame"]), np.nan)
    return TrackingLabels(
        frame=c["frame"],
        track_id=c["track_id"],
        type=c["type"],
        truncated=c["truncated"],
        occluded=c["occluded"],
        alpha=c["alpha"],
        box=_stack(c, ("x1", "y1", "x2", "y2")),
        dims=_stack(c, ("h", "w", "l")),
        loc=_stack(c, ("x", "y", "z")),
        rot_y=c["rot_y"],
        score=score,
    )


_CALIB_NAMES = {
    "P0": "P0",
    "P1": "P1",
    "P2": "P2",
    "P3": "P3",
    "R0_rect": "R0_rect",
    "R_rect": "R0_rect",
    "Tr_velo_to_cam": "Tr_velo_to_cam",
    "Tr_velo_cam": "Tr_velo_to_cam",
    "Tr_imu_to_velo": "Tr_imu_to_velo",
    "Tr_imu_velo": "Tr_imu_to_velo",
}
_CALIB_SHAPES = {
    "P0": (3, 4),
    "P1": (3, 4),
    "P2": (3, 4),
    "P3": (3, 4),
    "R0_rect": (3, 3),
    "Tr_velo_to_cam": (3, 4),
    "Tr_imu_to_velo": (3, 4),
}
_CALIB_ALIASES = {"R0_rect": "R_rect", "Tr_velo_to_cam": "Tr_velo_cam", "Tr_imu_to_velo": "Tr_imu_velo"}


def read_calib(path) -> Calib:
    """Read a KITTI calibration file: one matrix a line, ``NAME: v v ...`` (the colon is optional:
    the tracking devkit writes ``R_rect v v ...`` and ``Tr_velo_cam v v ...``, the object files and
    the shared data ``R0_rect: v v ...`` and ``Tr_velo_to_cam: v v ...``; spaces or tabs).

    ``P2``, ``R0_rect`` (or ``R_rect``) and ``Tr_velo_to_cam`` (or ``Tr_velo_cam``) are required;
    ``P0``, ``P1``, ``P3`` and ``Tr_imu_to_velo`` (or ``Tr_imu_velo``) are zeros when absent.
    Unknown names are ignored. Returns P2 [3, 4], R0_rect [3, 3], Tr_velo_to_cam [3, 4],
    P [4, 3, 4], Tr_imu_to_velo [3, 4].
    """
    text = read_text_file(path)
    found: dict[str, tuple[int, np.ndarray]] = {}
    for line_no, s in zip(text.line_numbers, text.lines):
        if ":" in s:
            name, rest = s.split(":", 1)
        else:                                          # the tracking devkit's "R_rect v v ..." (any blank)
            name, rest = (s.split(None, 1) + [""])[:2]
        name = name.strip()
        key = _CALIB_NAMES.get(name)
        if key is None:
            continue
        if key in found:
            raise KittiFormatError(text.path, line_no, name, f"defined twice (first on line {found[key][0]})")
        tokens = rest.split()
        shape = _CALIB_SHAPES[key]
        size = shape[0] * shape[1]
        if len(tokens) != size:
            raise KittiFormatError(text.path, line_no, name, f"expected {size} values, got {len(tokens)}")
        vals = np.empty(size, dtype=np.float64)
        for k, tok in enumerate(tokens):
            try:
                vals[k] = float(tok)
            except ValueError:
                raise KittiFormatError(text.path, line_no, name, f"value {k + 1} is not a number: {tok!r}") from None
            if not math.isfinite(vals[k]):
                raise KittiFormatError(text.path, line_no, name, f"value {k + 1} is not finite: {tok!r}")
        found[key] = (line_no, vals.reshape(shape))

    for key in ("P2", "R0_rect", "Tr_velo_to_cam"):
        if key not in found:
            alias = _CALIB_ALIASES.get(key)
            message = "missing" if alias is None else f"missing (also looked for '{alias}')"
            raise KittiFormatError(text.path, None, key, message)

    def get(key: str) -> np.ndarray:
        return found[key][1] if key in found else np.zeros(_CALIB_SHAPES[key])

    P = np.stack([get(f"P{k}") for k in range(4)])
    return Calib(
        P2=get("P2"),
        R0_rect=get("R0_rect"),
        Tr_velo_to_cam=get("Tr_velo_to_cam"),
        P=P,
        Tr_imu_to_velo=get("Tr_imu_to_velo"),
    )


def sequence_lengths(root, sequences=None) -> dict[str, int]:
    """Frames per sequence of a KITTI tracking root: ``max frame in label_02/SSSS.txt + 1``.

    ``sequences`` are names (``"0000"``) or ints; default every ``label_02/*.txt``, sorted.
    A label file with no rows gives 0. Returns {name: length}.
    """
    label_dir = Path(root) / "label_02"
    if sequences is None:
        names = sorted(p.stem for p in label_dir.glob("*.txt"))
    else:
        names = [f"{s:04d}" if isinstance(s, (int, np.integer)) else str(s) for s in sequences]
    out = {}
    for name in names:
        frame = read_tracking_labels(label_dir / f"{name}.txt").frame
        out[name] = int(frame.max()) + 1 if frame.size else 0
    return out
