"""The 3D fields of a tracking row (``h w l x y z rot_y``): the rules every reader applies, once.

A KITTI tracking row carries a 3D box in columns 11-17 (``h w l x y z rot_y``, camera frame, see
:mod:`dfrmot_jax.metrics.common.box3d`). Three readers take them: AB3DMOT's (:mod:`~dfrmot_jax.metrics.samota.prep`),
TrackEval's with 3D / BEV similarity (:func:`dfrmot_jax.metrics.kitti2d.tracker_files.read_tracker_files`) and the
array paths (:func:`~dfrmot_jax.metrics.kitti2d.padded.tracker_dets_from_arrays`,
:mod:`~dfrmot_jax.metrics.samota.arrays`). They share these rules:

* **No 3D box.** ``h w l = -1 -1 -1`` with ``x y z = -1000 -1000 -1000`` (any ``rot_y``) is the
  placeholder of a 2D-only row (what ``--columns kitti`` writes for a row without a 3D detection,
  and what KITTI's DontCare rows carry): the row has no 3D box and is matched to nothing in 3D
  (its 3D similarity is 0). Padded arrays may also mark a row without a 3D box as all NaN.
* **A box.** Otherwise the seven fields must be finite, ``h > 0``, and ``w``, ``l`` non-zero and of
  one sign: ``-w -l`` is the same box turned by 180 degrees (the published DFR-FastMOT files write
  ``h -w -l``), as in AB3DMOT, whose volume ``w * l * h`` is then positive. Anything else (a zero
  size, ``h <= 0``, ``w`` and ``l`` of opposite signs, a NaN or infinite field) is no box: readers
  refuse it with file, line and field (arrays: config, frame and slot), never a silent zero-volume box.

Shapes: ``b3`` ``[R, 7]`` float64.
"""

from __future__ import annotations

import numpy as np

from dfrmot_jax.io.kitti import KittiFormatError, quoted, read_text_file
from dfrmot_jax.io.result_rows import parse_floats

__all__ = ["PLACEHOLDER_DIMS", "PLACEHOLDER_LOC", "FIELDS_3D", "parse_floats", "placeholder_rows", "no_box_rows", "box_rows",
           "box3d_problem", "read_box3d_columns"]

PLACEHOLDER_DIMS = (-1.0, -1.0, -1.0)
PLACEHOLDER_LOC = (-1000.0, -1000.0, -1000.0)
#: the fields of columns 11-17 of a KITTI tracking row
FIELDS_3D = ("h", "w", "l", "x", "y", "z", "rot_y")
FIRST_COLUMN = 10          # 0-based column of ``h``


def placeholder_rows(b3: np.ndarray) -> np.ndarray:
    """[R, 7] -> [R] bool: the 2D-only placeholder ``-1 -1 -1 -1000 -1000 -1000`` (any rot_y)."""
    b3 = np.asarray(b3, dtype=np.float64).reshape(-1, 7)
    return np.all(b3[:, :3] == PLACEHOLDER_DIMS, axis=1) & np.all(b3[:, 3:6] == PLACEHOLDER_LOC, axis=1)


def no_box_rows(b3: np.ndarray) -> np.ndarray:
    """[R, 7] -> [R] bool: rows without a 3D box in padded arrays (the placeholder, or all NaN)."""
    b3 = np.asarray(b3, dtype=np.float64).reshape(-1, 7)
    return placeholder_rows(b3) | np.isnan(b3).all(axis=1)


def box_rows(b3: np.ndarray) -> np.ndarray:
    """[R, 7] -> [R] bool: the rows that are a box (module docstring; the placeholder is none)."""
    b3 = np.asarray(b3, dtype=np.float64).reshape(-1, 7)
    with np.errstate(invalid="ignore"):
        return (np.isfinite(b3).all(axis=1) & (b3[:, 0] > 0) & (np.sign(b3[:, 1]) * np.sign(b3[:, 2]) > 0)) & ~placeholder_rows(b3)


def box3d_problem(b3: np.ndarray, live: np.ndarray) -> tuple[int, int, str] | None:
    """The first row of ``live`` ([R] bool) whose ``b3`` ([R, 7]) is no box (module docstring), or None.

    Returns ``(row, field index 0..6, message)``; the message has ``{0}`` for the field's value and
    ``{1}`` for ``l``'s (the caller fills in tokens or numbers). The first row wins; within a row the
    lowest field, then the message (as AB3DMOT's reader here always reported it)."""
    b3 = np.asarray(b3, dtype=np.float64).reshape(-1, 7)
    with np.errstate(invalid="ignore"):
        checks = [(j, live & ~np.isfinite(b3[:, j]), "not finite: {0}") for j in range(7)]
        checks += [(0, live & (b3[:, 0] <= 0), "height {0} is not positive (not a box; a 2D-only row writes "
                                               "h w l x y z = -1 -1 -1 -1000 -1000 -1000)"),
                   (1, live & (b3[:, 1] == 0), "width {0} is zero (not a box)"),
                   (2, live & (b3[:, 2] == 0), "length {0} is zero (not a box)"),
                   (1, live & (b3[:, 1] * b3[:, 2] < 0), "width {0} and length {1} differ in sign (a box has both "
                                                         "positive, or both negative: the box turned by 180 degrees)")]
    found = [(int(np.argmax(m)), j, msg) for j, m, msg in checks if m.any()]
    return min(found) if found else None


def read_box3d_columns(path, rows: np.ndarray, sep: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The 3D fields of data rows ``rows`` ([R] indices among the file's non-blank lines) of ``path``.

    sep: the column separator (None: whitespace). Returns ``box3d`` [R, 7] float64 and ``has3d`` [R]
    bool (False for the placeholder). Raises :class:`~dfrmot_jax.io.kitti.KittiFormatError` with
    file, line and field for a row without the seven columns, a non-number, or a field set that is
    neither a box nor the placeholder (module docstring)."""
    rows = np.asarray(rows, dtype=np.int64)
    out = np.zeros((len(rows), 7))
    if not len(rows):
        return out, np.zeros(0, dtype=bool)
    text = read_text_file(path)
    tok = np.full((len(rows), 7), "", dtype=object)
    for k, r in enumerate(rows.tolist()):
        f = text.lines[r].split(sep)[FIRST_COLUMN:FIRST_COLUMN + 7]
        if len(f) < 7:
            raise KittiFormatError(text.path, text.line_numbers[r], None,
                                   f"expected the 3D fields {' '.join(FIELDS_3D)} in columns {FIRST_COLUMN + 1}-"
                                   f"{FIRST_COLUMN + 7}, got {FIRST_COLUMN + len(f)} columns")
        tok[k] = f
    for j in range(7):
        v, ok = parse_floats(tok[:, j].astype(str))
        if not ok.all():
            k = int(np.argmin(ok))
            raise KittiFormatError(text.path, text.line_numbers[rows[k]], FIELDS_3D[j],
                                   f"not a number: {quoted(tok[k, j])}")
        out[:, j] = v
    has3d = ~placeholder_rows(out)
    bad = box3d_problem(out, has3d)
    if bad is not None:
        k, j, msg = bad
        raise KittiFormatError(text.path, text.line_numbers[rows[k]], FIELDS_3D[j],
                               msg.format(quoted(tok[k, j]), quoted(tok[k, 2])))
    return out, has3d
