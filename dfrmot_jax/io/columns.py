"""The two column sets of a result file, and the one place where result lines are formatted.

Every line is ``frame id type trunc occ alpha x1 y1 x2 y2 c1 c2 c3 c4 c5 c6 rot_y score``
(18 whitespace-separated columns, KITTI tracking results). The column sets differ in columns
alpha and 11-18:

``"kitti"`` (default): standard KITTI results. A row whose object has its **own** 3D detection
carries that detection's alpha, ``h w l``, ``x y z`` (camera coordinates, bottom centre), rot_y and
score, exactly as read from the detection file. Any other row keeps the KITTI placeholders
(alpha -10, ``-1 -1 -1``, ``-1000 -1000 -1000``, rot_y -10) and the 2D detection's score (1 when
unknown). Output "filtered" (rows are tracks): a track with a 3D filter writes ``h w l x y z``
recovered from its filtered corners (``invert_box3d_extent`` for the run's ``centroid``) and
alpha, rot_y and score of its last 3D detection. Integers print as integers, the 2D box with
``%g``, the 3D values and scores with the fewest digits (at least 6) that read back to the same
number (so a detector file's values come back unchanged).

``"kitti-stale"``: the kitti columns, except that a row whose object has no 3D detection of its
own but matched a track with one carries that track's last 3D detection (its alpha, ``h w l``,
``x y z``, rot_y; the score stays the 2D detection's), as the authors' files do: a 3D evaluation
then sees the track's stale 3D box instead of the placeholder (unmatched in 3D).

``"authors"``: the 18 columns exactly as the authors' C++ writes them (spec section 6), so that
the ``dfr2023`` run reproduces their published files byte for byte:
``frame id type -1 -1 alpha x1 y1 x2 y2 D1 D2 D3 L1 L2 L3 rot_y score`` with, from the internal
float32 3D box (``lo``, ``hi`` = ``data.box3d_extent`` for the ``centroid``, differences in float32),
``D = (hi_z - lo_z, lo_y - hi_y, lo_x - hi_x)`` and ``L = (lo_z, lo_y, lo_x)``: with the legacy axes
``D = (h, -w, -l)``, ``L = (x, y, z)``; with the head axes ``D = (w, -h, -l)``, ``L = (-y, -x, z)``.
alpha, rot_y and score are the object's own 3D detection's. An object without 3D that matched a
track with 3D prints the track's stale last 3D box with alpha -10, rot_y -10, score 0; an object
with no 3D at all prints ``-1 -1 -1 -1000 -1000 -1000`` and alpha -10, rot_y -10, score 0. Every
number is printed like C++'s default ``ostream`` (``%g``, 6 significant digits, of the float32
value: ``-0`` stays ``-0``).
"""

from __future__ import annotations

import numpy as np

from ..geometry import box3d_extent

__all__ = ["COLUMN_SETS", "as_written", "format_lines", "invert_box3d_extent", "kitti_values", "authors_values"]

COLUMN_SETS = ("kitti", "kitti-stale", "authors")

PLACEHOLDER_ALPHA = -10.0
PLACEHOLDER_DIMS = -1.0
PLACEHOLDER_LOC = -1000.0
PLACEHOLDER_ROT_Y = -10.0
PLACEHOLDER_SCORE = 1.0      # kitti columns, a row whose 2D score is unknown
AUTHORS_NO_SCORE = 0.0       # authors' columns, an object without its own 3D detection


# ---------------------------------------------------------------------------------------------
# 3D box conventions


def invert_box3d_extent(lo: np.ndarray, hi: np.ndarray, centroid: str) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`dfrmot_jax.data.box3d_extent`: internal corners ``lo, hi [..., 3]`` ->
    ``dims [..., 3]`` (h, w, l) and ``loc [..., 3]`` (x, y, z; KITTI camera coordinates, bottom
    centre), float64.

    Extents are taken as ``|hi - lo|`` (filtered corners may cross, as the 2D box's do); the
    location keeps the convention's anchor: ``lo`` for legacy and head, the centre (x, z) and the
    bottom (y = hi) for kitti.
    """
    lo = np.asarray(lo, np.float64)
    hi = np.asarray(hi, np.float64)
    e = np.abs(hi - lo)
    if centroid == "legacy":      # lo = (z, y, x), hi - lo = (l, w, h)
        dims = np.stack([e[..., 2], e[..., 1], e[..., 0]], -1)
        loc = np.stack([lo[..., 2], lo[..., 1], lo[..., 0]], -1)
    elif centroid == "head":      # lo = (z, -x, -y), hi - lo = (l, h, w)
        dims = np.stack([e[..., 1], e[..., 2], e[..., 0]], -1)
        loc = np.stack([-lo[..., 1], -lo[..., 2], lo[..., 0]], -1)
    elif centroid == "kitti":     # lo = (x - l/2, y - h, z - w/2), hi = (x + l/2, y, z + w/2)
        dims = np.stack([e[..., 1], e[..., 2], e[..., 0]], -1)
        loc = np.stack([(lo[..., 0] + hi[..., 0]) / 2, hi[..., 1], (lo[..., 2] + hi[..., 2]) / 2], -1)
    else:
        raise ValueError(f"centroid {centroid!r}: expected one of ('legacy', 'head', 'kitti')")
    return dims, loc


def authors_box_columns(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The C++'s 3D output columns from the internal box: ``D [..., 3]``, ``L [..., 3]`` float32.

    ``D = (z_max - z_min, y_min - y_max, x_min - x_max)``, ``L = (z_min, y_min, x_min)``, in float32
    arithmetic as the C++ computes them from its float fields.
    """
    lo = np.asarray(lo, np.float32)
    hi = np.asarray(hi, np.float32)
    d = np.stack([hi[..., 2] - lo[..., 2], lo[..., 1] - hi[..., 1], lo[..., 0] - hi[..., 0]], -1)
    return d.astype(np.float32), np.stack([lo[..., 2], lo[..., 1], lo[..., 0]], -1).astype(np.float32)


# ---------------------------------------------------------------------------------------------
# Number formats


def _int_or(v: np.ndarray, other) -> list[str]:
    """Integral values (|v| < 1e15) as integers, the others by ``other(x)``."""
    integral = np.isfinite(v) & (v == np.round(v)) & (np.abs(v) < 1e15)
    if v.size and integral.all():
        return [str(x) for x in v.astype(np.int64).tolist()]
    return [str(int(x)) if ok else other(x) for x, ok in zip(v.tolist(), integral.tolist())]


def fmt_g(v: np.ndarray) -> list[str]:
    """The 2D box of the kitti columns: integers as integers, others ``%g``."""
    return _int_or(np.asarray(v, np.float64), lambda x: f"{x:g}")


#: values per block of :func:`as_written` (its dozen temporaries of this size stay in the CPU's caches)
AS_WRITTEN_BLOCK = 1 << 16


def as_written(v: np.ndarray, digits: int) -> np.ndarray:
    """``float(f"{x:.{digits}g}")`` of every non-integral finite x, integers as they are, vectorised:
    what a number printed with ``digits`` significant digits reads back as (:func:`fmt_g` prints the
    2D box with 6, :func:`fmt_estimate` filtered 3D values with 7).

    x is scaled to ``digits`` integer digits and rounded half to even; the quotient by a power of
    ten (exact up to 10**22) is then the double nearest to the printed decimal, as ``float`` of the
    text is. The scaled value carries a relative error of at most 2**-53, so where it lies within
    1e-9 of a rounding tie, or its digit count is off (log10 at a power of ten), the value is
    formatted by Python instead: the result equals the text's for every input. (Elementwise: a large
    array is done in blocks of ``AS_WRITTEN_BLOCK`` values, so that its temporaries stay small.)"""
    if v.size > AS_WRITTEN_BLOCK:
        flat = np.ascontiguousarray(v).reshape(-1)
        out = np.empty_like(flat)
        for a in range(0, flat.size, AS_WRITTEN_BLOCK):
            out[a:a + AS_WRITTEN_BLOCK] = as_written(flat[a:a + AS_WRITTEN_BLOCK], digits)
        return out.reshape(v.shape)
    out = v.copy()
    odd = np.isfinite(v) & (v != 0) & ((v != np.round(v)) | (np.abs(v) >= 1e15))
    x = v[odd]
    if not x.size:
        return out
    e = np.floor(np.log10(np.abs(x))).astype(np.int64)
    k = digits - 1 - e                                    # decimal places kept
    scale = 10.0 ** np.abs(k).astype(np.float64)
    r = np.where(k >= 0, x * scale, x / scale)
    m = np.round(r)                                      # half to even, as printing rounds
    got = np.where(k >= 0, m / scale, m * scale)
    frac = np.abs(np.abs(r - np.trunc(r)) - 0.5)
    unsure = (frac < 1e-9) | (np.abs(m) >= 10.0 ** digits) | (np.abs(m) < 10.0 ** (digits - 1)) | (np.abs(k) > 22)
    if unsure.any():
        got[unsure] = [float(f"{y:.{digits}g}") for y in x[unsure].tolist()]
    out[odd] = got
    return out


def as_written_fixed(v: np.ndarray, decimals: int = 6) -> np.ndarray:
    """``float(f"{x:.{decimals}f}")`` of every finite x, vectorised: what a number printed with
    ``decimals`` places (``%f``: AB3DMOT's result files) reads back as. x scaled by ``10**decimals``
    is rounded half to even and divided back (the double nearest to the printed decimal, as
    :func:`as_written`); where the scaled value lies within 1e-9 of a tie, or beyond 2**52, Python
    formats it instead: the result equals the text's for every input."""
    v = np.asarray(v, np.float64)
    out = v.copy()
    ok = np.isfinite(v)
    x = v[ok]
    scale = 10.0 ** decimals
    r = x * scale
    m = np.round(r)
    got = m / scale
    unsure = (np.abs(np.abs(r - np.trunc(r)) - 0.5) < 1e-9) | (np.abs(r) >= 2.0 ** 52)
    if unsure.any():
        got[unsure] = [float(f"{y:.{decimals}f}") for y in x[unsure].tolist()]
    out[ok] = got
    return out


def fmt_estimate(v: np.ndarray) -> list[str]:
    """Filtered 3D values (the tracker's float32 estimates): 7 significant digits, their precision."""
    return _int_or(np.asarray(v, np.float64), lambda x: f"{x:.7g}")


def fmt_exact(v: np.ndarray) -> list[str]:
    """Integers as integers, others with the fewest significant digits (at least 6, as ``%g``)
    that read back to the same value in ``v``'s precision (float32 arrays: as float32)."""
    v = np.asarray(v)
    single = v.dtype == np.float32
    v64 = v.astype(np.float64)
    dtype = np.float32 if single else np.float64

    def shortest(x: float) -> str:
        for p in range(6, 18):
            s = f"{x:.{p}g}"
            if dtype(float(s)) == dtype(x):
                return s
        return repr(x)

    return _int_or(v64, shortest)


def fmt_cxx(v: np.ndarray) -> list[str]:
    """C++ ``std::ostream << float`` with the default format: ``%g`` of the float32 value."""
    return [f"{x:g}" for x in np.asarray(v, np.float32).astype(np.float64).tolist()]


# ---------------------------------------------------------------------------------------------
# Per-row values of each column set


def _rows(name: str, value, shape: tuple[int, ...], dtype=np.float64) -> np.ndarray | None:
    """``value`` as a ``shape`` array of ``dtype`` (None stays None)."""
    if value is None:
        return None
    try:
        arr = np.asarray(value).astype(dtype)
    except (TypeError, ValueError):
        raise ValueError(f"format_lines: {name} must be numeric") from None
    if arr.shape != shape:
        raise ValueError(f"format_lines: {name} has shape {arr.shape}, expected {shape}")
    return arr


def _check_finite(name: str, arr: np.ndarray, where: np.ndarray) -> None:
    bad = where & ~np.all(np.isfinite(arr), axis=tuple(range(1, arr.ndim)))
    if bad.any():
        raise ValueError(f"format_lines: {name} has non-finite values (row {int(np.argmax(bad))})")


class _Inputs:
    """Validated per-row inputs of :func:`format_lines` (R rows)."""

    def __init__(self, n, has3, own3, dims, loc, rot_y, alpha, score3, score2, box3):
        given = any(x is not None for x in (dims, loc, rot_y, alpha, score3))
        self.has3 = _rows("has3", has3, (n,), dtype=bool)
        if self.has3 is None:
            self.has3 = np.full(n, given, bool)
        self.own3 = _rows("own3", own3, (n,), dtype=bool)
        if self.own3 is None:
            self.own3 = self.has3.copy()
        self.own3 = self.own3 & self.has3
        self.dims = _rows("dims", dims, (n, 3))
        self.loc = _rows("loc", loc, (n, 3))
        self.rot_y = _rows("rot_y", rot_y, (n,))
        self.alpha = _rows("alpha", alpha, (n,))
        self.score3 = _rows("score3", score3, (n,))
        self.score2 = _rows("score2", score2, (n,))
        self.box3 = _rows("box3", box3, (n, 6))
        # box3 rows that are NaN: the track has no 3D filter
        self.has_box3 = np.zeros(n, bool) if self.box3 is None else np.all(np.isfinite(self.box3), axis=1)
        for name in ("dims", "loc", "rot_y", "alpha", "score3"):   # only the rows that use them
            if getattr(self, name) is not None:
                _check_finite(name, getattr(self, name), self.has3)
        if self.score2 is not None:
            self.score2 = np.where(np.isfinite(self.score2), self.score2, PLACEHOLDER_SCORE)


def kitti_values(n: int, centroid: str, inp: _Inputs, stale: bool = False) -> dict[str, np.ndarray]:
    """alpha [R], dims [R, 3], loc [R, 3], rot_y [R], score [R] of the kitti columns (``stale``: of
    the kitti-stale columns)."""
    filtered = inp.box3 is not None
    carry = inp.has3 if filtered else inp.own3            # rows whose 3D detection values are written
    box_carry = inp.has3 if stale else carry              # rows whose 3D box (and angles) are written
    alpha = np.full(n, PLACEHOLDER_ALPHA)
    dims = np.full((n, 3), PLACEHOLDER_DIMS)
    loc = np.full((n, 3), PLACEHOLDER_LOC)
    rot_y = np.full(n, PLACEHOLDER_ROT_Y)
    score = inp.score2.copy() if inp.score2 is not None else np.full(n, PLACEHOLDER_SCORE)
    for out, src, rows in ((alpha, inp.alpha, box_carry), (rot_y, inp.rot_y, box_carry), (score, inp.score3, carry)):
        if src is not None:
            out[rows] = src[rows]
    if filtered:
        box3 = np.asarray(inp.box3, np.float64)
        d, l = invert_box3d_extent(box3[:, :3], box3[:, 3:], centroid)
        m = inp.has_box3
        dims[m] = d[m]; loc[m] = l[m]
    else:
        if inp.dims is not None:
            dims[box_carry] = inp.dims[box_carry]
        if inp.loc is not None:
            loc[box_carry] = inp.loc[box_carry]
    return {"alpha": alpha, "dims": dims, "loc": loc, "rot_y": rot_y, "score": score}


def authors_values(n: int, centroid: str, inp: _Inputs) -> dict[str, np.ndarray]:
    """alpha [R], D [R, 3], L [R, 3], rot_y [R], score [R] (float32) of the authors' columns."""
    d_cols = np.tile(np.float32([-1, -1, -1]), (n, 1))
    l_cols = np.tile(np.float32([-1000, -1000, -1000]), (n, 1))
    box = inp.has3 & ~inp.has_box3
    if box.any():
        if inp.dims is None or inp.loc is None:
            raise ValueError("format_lines: columns='authors' needs dims and loc for rows with has3")
        lo, hi = box3d_extent(inp.dims[box], inp.loc[box], centroid)
        d_cols[box], l_cols[box] = authors_box_columns(lo, hi)
    if inp.has_box3.any():
        m = inp.has_box3
        d_cols[m], l_cols[m] = authors_box_columns(inp.box3[m, :3], inp.box3[m, 3:])
    alpha = np.full(n, PLACEHOLDER_ALPHA, np.float32)
    rot_y = np.full(n, PLACEHOLDER_ROT_Y, np.float32)
    score = np.full(n, AUTHORS_NO_SCORE, np.float32)
    own = inp.own3
    for out, src in ((alpha, inp.alpha), (rot_y, inp.rot_y), (score, inp.score3)):
        if src is not None:
            out[own] = src[own]
    return {"alpha": alpha, "dims": d_cols, "loc": l_cols, "rot_y": rot_y, "score": score}


# ---------------------------------------------------------------------------------------------
# Lines


def format_lines(frame, track_id, box, type_name="Car", columns: str = "kitti", centroid: str = "legacy", *,
                 has3=None, own3=None, dims=None, loc=None, rot_y=None, alpha=None, score3=None,
                 score2=None, box3=None) -> list[str]:
    """Result lines (each ending in ``"\\n"``) for R rows in the given order.

    frame, track_id [R] integers; box [R, 4] ``x1 y1 x2 y2``; type_name a str or [R] strs;
    columns ``"kitti"`` | ``"kitti-stale"`` | ``"authors"`` (module docstring); centroid the run's 3D axes
    (``"legacy"`` | ``"head"`` | ``"kitti"``).
    Per-row 3D information: has3 [R] bool (the row carries a 3D detection: the object's own, or
    the stale one of the track it matched), own3 [R] bool (it is the object's own), dims [R, 3]
    (h, w, l), loc [R, 3] (x, y, z), rot_y [R], alpha [R], score3 [R] of that detection;
    score2 [R] the 2D detection's score (NaN or None: unknown); box3 [R, 6] (output "filtered")
    the track's filtered internal corners (lo, hi), NaN rows for tracks without a 3D filter.
    Defaults: has3 = all rows when any of dims, loc, rot_y, alpha, score3 is given; own3 = has3; a
    missing field writes its placeholder.
    """
    if columns not in COLUMN_SETS:
        raise ValueError(f"columns={columns!r}: expected one of {COLUMN_SETS}")
    frame = np.asarray(frame).astype(np.int64)
    track_id = np.asarray(track_id).astype(np.int64)
    box = np.asarray(box, np.float64).reshape(-1, 4)
    n = box.shape[0]
    if frame.shape != (n,) or track_id.shape != (n,):
        raise ValueError(f"format_lines: frame {frame.shape} / track_id {track_id.shape}, expected ({n},)")
    types = [type_name] * n if isinstance(type_name, str) else [str(t) for t in type_name]
    if len(types) != n:
        raise ValueError(f"format_lines: type_name has {len(types)} entries, expected {n}")
    inp = _Inputs(n, has3, own3, dims, loc, rot_y, alpha, score3, score2, box3)
    if n == 0:
        return []
    if columns in ("kitti", "kitti-stale"):
        v = kitti_values(n, centroid, inp, stale=columns == "kitti-stale")
        num, box_fmt = fmt_exact, fmt_g
    else:
        v = authors_values(n, centroid, inp)
        num = box_fmt = fmt_cxx
    # filtered 3D boxes are float32 estimates, written to their precision rather than to every digit
    # of a float64 sum of them
    box3_fmt = fmt_estimate if columns != "authors" and inp.box3 is not None else num
    cols = [
        [str(x) for x in frame.tolist()],
        [str(x) for x in track_id.tolist()],
        types,
        ["-1"] * n,
        ["-1"] * n,
        num(v["alpha"]),
        *(box_fmt(box[:, k]) for k in range(4)),
        *(box3_fmt(v["dims"][:, k]) for k in range(3)),
        *(box3_fmt(v["loc"][:, k]) for k in range(3)),
        num(v["rot_y"]),
        num(v["score"]),
    ]
    return [" ".join(row) + "\n" for row in zip(*cols)]
