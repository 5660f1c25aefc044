"""Tests of dfrmot_jax.io.kitti: property-based round trips and corruptions, error kinds, real data."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from dfrmot_jax.io import (
    Calib,
    Detections2D,
    Detections3D,
    KittiFormatError,
    TrackingLabels,
    read_calib,
    read_detections_2d,
    read_detections_3d,
    read_tracking_labels,
    sequence_lengths,
    write_tracking_results,
)

PROPS = settings(
    max_examples=60,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)

FIELDS_2D = ("frame", "x1", "y1", "x2", "y2", "score")
FIELDS_3D = ("frame", "type", "x1", "y1", "x2", "y2", "score", "h", "w", "l", "x", "y", "z", "rot_y", "alpha")
FIELDS_3D_LABEL = (
    "frame", "type", "truncated", "occluded", "alpha", "x1", "y1", "x2", "y2",
    "h", "w", "l", "x", "y", "z", "rot_y", "score",
)
FIELDS_TRACK = (
    "frame", "track_id", "type", "truncated", "occluded", "alpha", "x1", "y1", "x2", "y2",
    "h", "w", "l", "x", "y", "z", "rot_y",
)
FIELDS_TRACK_SCORE = FIELDS_TRACK + ("score",)

# name -> (reader, field names, separator options)
LAYOUTS = {
    "2d_csv": (read_detections_2d, FIELDS_2D, (",",)),
    "2d_ws": (read_detections_2d, FIELDS_2D, (" ", "\t", "   ")),
    "3d_csv": (read_detections_3d, FIELDS_3D, (",",)),
    "3d_ws": (read_detections_3d, FIELDS_3D, (" ", "\t", "  ")),
    "3d_label": (read_detections_3d, FIELDS_3D_LABEL, (" ", "\t")),
    "track17": (read_tracking_labels, FIELDS_TRACK, (" ", "\t")),
    "track18": (read_tracking_labels, FIELDS_TRACK_SCORE, (" ", "\t")),
}
STRING_FIELDS = {"type"}
INT_FIELDS = {"frame", "track_id"}

coord = st.floats(-1e4, 1e4, allow_nan=False, allow_infinity=False)
size = st.floats(0, 1e3, allow_nan=False, allow_infinity=False)
type_name = st.text("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_", min_size=1, max_size=10)


@st.composite
def rows(draw, fields: tuple[str, ...], min_rows: int = 0, max_rows: int = 12) -> list[dict]:
    """Valid rows (dicts field -> value) with ascending frames."""
    frames = sorted(draw(st.lists(st.integers(0, 5000), min_size=min_rows, max_size=max_rows)))
    is_detection = "track_id" not in fields
    out = []
    for f in frames:
        row = {"frame": f}
        for name in fields:
            if name == "frame":
                continue
            if name == "track_id":
                row[name] = draw(st.integers(-1, 10**6))
            elif name == "type":
                row[name] = draw(type_name)
            elif name in ("h", "w", "l"):
                row[name] = draw(size) if is_detection else draw(coord)
            elif name not in ("x2", "y2"):
                row[name] = draw(coord)
        row["x2"] = row["x1"] + draw(size)
        row["y2"] = row["y1"] + draw(size)
        out.append(row)
    return out


def token(name: str, value) -> str:
    if name in STRING_FIELDS or name in INT_FIELDS:
        return str(value)
    return repr(float(value))


@st.composite
def layout_text(draw, min_rows: int = 0):
    """(layout name, rows, per-row token lists, separator, line ending, blank-line flags)."""
    name = draw(st.sampled_from(sorted(LAYOUTS)))
    _, fields, seps = LAYOUTS[name]
    rs = draw(rows(fields, min_rows=min_rows))
    toks = [[token(f, r[f]) for f in fields] for r in rs]
    sep = draw(st.sampled_from(seps))
    eol = draw(st.sampled_from(["\n", "\r\n"]))
    blanks = draw(st.lists(st.booleans(), min_size=len(rs) + 1, max_size=len(rs) + 1))
    return name, rs, toks, sep, eol, blanks


def render(toks: list[list[str]], sep: str, eol: str, blanks: list[bool]) -> tuple[str, list[int]]:
    """File text and the 1-based line number of every row; blank lines go where ``blanks`` says."""
    lines: list[str] = []
    numbers = []
    for k, t in enumerate(toks):
        if blanks[k]:
            lines.append("" if k % 2 else "  ")
        lines.append(sep.join(t))
        numbers.append(len(lines))
    if blanks[-1]:
        lines.append("")
    text = eol.join(lines) + (eol if lines else "")
    return text, numbers


def write(path: Path, text: str) -> Path:
    path.write_bytes(text.encode())
    return path


def expected_columns(result, fields) -> dict[str, np.ndarray]:
    if isinstance(result, Detections2D):
        names = {"frame": result.frame, "score": result.score}
        names.update(zip(("x1", "y1", "x2", "y2"), result.box.T))
    elif isinstance(result, Detections3D):
        names = {"frame": result.frame, "type": result.type, "score": result.score,
                 "rot_y": result.rot_y, "alpha": result.alpha}
        names.update(zip(("x1", "y1", "x2", "y2"), result.box.T))
        names.update(zip(("h", "w", "l"), result.dims.T))
        names.update(zip(("x", "y", "z"), result.loc.T))
    else:
        names = {n: getattr(result, n) for n in ("frame", "track_id", "type", "truncated", "occluded",
                                                 "alpha", "rot_y", "score")}
        names.update(zip(("x1", "y1", "x2", "y2"), result.box.T))
        names.update(zip(("h", "w", "l"), result.dims.T))
        names.update(zip(("x", "y", "z"), result.loc.T))
    return {f: names[f] for f in fields if f in names}


# ---------------------------------------------------------------------------------------------
# property-based tests


@PROPS
@given(layout_text())
def test_round_trip_every_layout(tmp_path, case):
    name, rs, toks, sep, eol, blanks = case
    reader, fields, _ = LAYOUTS[name]
    text, _ = render(toks, sep, eol, blanks)
    result = reader(write(tmp_path / "f.txt", text))
    n = len(rs)
    assert result.frame.dtype == np.int64 and result.frame.shape == (n,)
    assert result.box.shape == (n, 4) and result.box.dtype == np.float64
    got = expected_columns(result, fields)
    for f in fields:
        if f not in got:
            continue
        want = [r[f] for r in rs]
        if f in STRING_FIELDS:
            assert got[f].dtype == object and list(got[f]) == want
        else:
            np.testing.assert_array_equal(got[f], np.asarray(want, dtype=got[f].dtype))
    if name == "track17":
        assert np.isnan(result.score).all() and result.score.shape == (n,)


def _corrupted_case():
    return st.tuples(
        layout_text(min_rows=1),
        st.data(),
        st.sampled_from(["abc", "nan", "inf", "-inf", "drop"]),
    )


@PROPS
@given(_corrupted_case())
def test_corrupted_field_names_line_and_field(tmp_path, case):
    (name, rs, toks, sep, eol, blanks), data, bad = case
    reader, fields, _ = LAYOUTS[name]
    row = data.draw(st.integers(0, len(rs) - 1), label="row")
    if bad == "drop":
        col = data.draw(st.integers(0, len(fields) - 1), label="col")
        # An 18-column result file missing a column on its first line is a valid 17-column layout.
        assume(not (name == "track18" and row == 0))
        toks[row] = toks[row][:col] + toks[row][col + 1:]
        expected_field = "columns"
    else:
        numeric = [k for k, f in enumerate(fields) if f not in STRING_FIELDS]
        col = data.draw(st.sampled_from(numeric), label="col")
        toks[row][col] = bad
        expected_field = fields[col]
    text, numbers = render(toks, sep, eol, blanks)
    with pytest.raises(KittiFormatError) as info:
        reader(write(tmp_path / "f.txt", text))
    e = info.value
    assert (e.line, e.field) == (numbers[row], expected_field), str(e)
    assert e.path == str(tmp_path / "f.txt")
    assert str(e).startswith(f"{e.path}:{e.line}: field '{e.field}': ")


track_rows = rows(FIELDS_TRACK_SCORE, max_rows=15)


@PROPS
@given(
    track_rows,
    st.sampled_from(["Car", "per_row"]),
    st.lists(st.booleans(), min_size=5, max_size=5),
    st.sampled_from([0, 2, 6]),
)
def test_write_tracking_results_round_trip(tmp_path, rs, types, given_mask, digits):
    n = len(rs)

    def col(*names):
        a = np.array([[r[k] for k in names] for r in rs], dtype=np.float64).reshape(n, len(names))
        return np.round(a, digits) if digits else np.round(a)

    frame = np.array([r["frame"] for r in rs], dtype=np.int64)
    track_id = np.array([r["track_id"] for r in rs], dtype=np.int64)
    box = col("x1", "y1", "x2", "y2")
    type_name = "Car" if types == "Car" else [r["type"] for r in rs]
    optional = {
        "alpha": (col("alpha")[:, 0], -10.0),
        "dims": (col("h", "w", "l"), -1.0),
        "loc": (col("x", "y", "z"), -1000.0),
        "rot_y": (col("rot_y")[:, 0], -10.0),
        "score": (col("score")[:, 0], 1.0),
    }
    kwargs = {k: (v if g else None) for (k, (v, _)), g in zip(optional.items(), given_mask)}
    path = tmp_path / "out" / "deeper" / "0000.txt"
    write_tracking_results(path, frame, track_id, box, type_name=type_name, **kwargs)
    back = read_tracking_labels(path)
    np.testing.assert_array_equal(back.frame, frame)
    np.testing.assert_array_equal(back.track_id, track_id)
    assert list(back.type) == (["Car"] * n if types == "Car" else type_name)
    np.testing.assert_array_equal(back.truncated, -1.0)
    np.testing.assert_array_equal(back.occluded, -1.0)

    def close(got, want):
        np.testing.assert_allclose(got, want, rtol=6e-6, atol=0)

    close(back.box, box)
    for (k, (v, default)), g in zip(optional.items(), given_mask):
        if g:
            close(getattr(back, k), v)
        else:
            np.testing.assert_array_equal(getattr(back, k), default)
    if digits == 0:
        np.testing.assert_array_equal(back.box, box)
        lines = path.read_text().splitlines()
        assert all("." not in line.split()[6] for line in lines)


# ---------------------------------------------------------------------------------------------
# unit tests: error kinds

ROW_2D = "0,296.0,160.0,452.0,288.0,0.5"
ROW_3D = "0,2,298.3,165.1,458.2,293.4,8.29,1.96,1.81,4.75,-4.57,1.84,13.53,-2.11,-1.78"
ROW_3D_LABEL = "0 Car 0 0 -1.78 298.3 165.1 458.2 293.4 1.96 1.81 4.75 -4.57 1.84 13.53 -2.11 8.29"
ROW_TRACK = "0 0 Car 0 0 -1.79 296.74 161.75 455.22 292.37 2.0 1.82 4.43 -4.55 1.85 13.41 -2.11"
ROW_DONTCARE = "0 -1 DontCare -1 -1 -10 219.3 188.4 245.5 218.5 -1 -1 -1 -1000 -1000 -1000 -10"


def raises(tmp_path, reader, text: str) -> KittiFormatError:
    with pytest.raises(KittiFormatError) as info:
        reader(write(tmp_path / "bad.txt", text))
    return info.value


def replace(row: str, sep: str | None, index: int, value: str) -> str:
    parts = row.split(sep)
    parts[index] = value
    return (sep or " ").join(parts)


def test_error_message_format_and_type():
    e = KittiFormatError("a/b.txt", 3, "x1", "not a number: 'abc'")
    assert str(e) == "a/b.txt:3: field 'x1': not a number: 'abc'"
    assert isinstance(e, ValueError)
    assert str(KittiFormatError("a.txt", None, None, "file not found")) == "a.txt: file not found"
    assert str(KittiFormatError("a.txt", 2, None, "oops")) == "a.txt:2: oops"
    assert str(KittiFormatError("a.txt", None, "P2", "missing")) == "a.txt: field 'P2': missing"
    e2 = pickle.loads(pickle.dumps(e))
    assert (e2.path, e2.line, e2.field, e2.message, str(e2)) == (e.path, e.line, e.field, e.message, str(e))


@pytest.mark.parametrize(
    "reader, text, line, expected, got",
    [
        (read_detections_2d, f"{ROW_2D}\n0,1,2,3,4\n", 2, "6", "5"),
        (read_detections_2d, "0,1,2,3,4\n", 1, "6", "5"),
        (read_detections_3d, f"{ROW_3D}\n{ROW_3D},1\n", 2, "15", "16"),
        (read_detections_3d, "0 2 1 2 3 4 5 6 7 8 9 10 11 12 13 14\n", 1, "15 or 17", "16"),
        (read_tracking_labels, f"{ROW_TRACK}\n{ROW_TRACK} 1 2\n", 2, "17", "19"),
        (read_tracking_labels, "0 0 Car 1 2 3\n", 1, "17 or 18", "6"),
    ],
)
def test_wrong_column_count(tmp_path, reader, text, line, expected, got):
    e = raises(tmp_path, reader, text)
    assert (e.line, e.field) == (line, "columns")
    assert f"expected {expected}" in e.message and f"got {got}" in e.message


def test_layout_must_not_change_within_a_file(tmp_path):
    ws = ROW_3D.replace(",", " ")
    e = raises(tmp_path, read_detections_3d, f"{ROW_3D}\n{ws}\n")
    assert (e.line, e.field) == (2, "columns")
    e = raises(tmp_path, read_detections_3d, f"{ws}\n{ROW_3D_LABEL}\n")
    assert (e.line, e.field) == (2, "columns")
    e = raises(tmp_path, read_tracking_labels, f"{ROW_TRACK} 0.5\n{ROW_TRACK}\n")
    assert (e.line, e.field) == (2, "columns")
    e = raises(tmp_path, read_tracking_labels, f"{ROW_TRACK.replace(' ', ',')}\n")
    assert (e.line, e.field) == (1, "columns")


NUMERIC_FIELD_CASES = [
    (read_detections_2d, ROW_2D, ",", 1, "x1"),
    (read_detections_2d, ROW_2D, ",", 5, "score"),
    (read_detections_2d, ROW_2D, ",", 0, "frame"),
    (read_detections_3d, ROW_3D, ",", 9, "l"),
    (read_detections_3d, ROW_3D, ",", 14, "alpha"),
    (read_detections_3d, ROW_3D_LABEL, None, 2, "truncated"),
    (read_detections_3d, ROW_3D_LABEL, None, 16, "score"),
    (read_tracking_labels, ROW_TRACK, None, 1, "track_id"),
    (read_tracking_labels, ROW_TRACK, None, 4, "occluded"),
    (read_tracking_labels, ROW_TRACK, None, 16, "rot_y"),
]
BAD_TOKENS = [("abc", "not a number"), ("", "not a number"), ("nan", "not finite"), ("inf", "not finite"),
              ("-Infinity", "not finite")]


@pytest.mark.parametrize(
    "reader, row, sep, index, field, bad, what",
    [case + bad for case in NUMERIC_FIELD_CASES for bad in BAD_TOKENS if bad[0] or case[2] == ","],
)
def test_non_numeric_and_non_finite(tmp_path, reader, row, sep, index, field, bad, what):
    e = raises(tmp_path, reader, f"{row}\n{replace(row, sep, index, bad)}\n")
    assert (e.line, e.field) == (2, field)
    assert e.message.startswith(what) and repr(bad) in e.message


def test_negative_frame(tmp_path):
    e = raises(tmp_path, read_detections_2d, replace(ROW_2D, ",", 0, "-1") + "\n")
    assert (e.line, e.field) == (1, "frame") and "negative" in e.message
    e = raises(tmp_path, read_tracking_labels, replace(ROW_TRACK, None, 0, "-3"))
    assert (e.line, e.field) == (1, "frame")


@pytest.mark.parametrize(
    "reader, row, sep, index, field",
    [
        (read_detections_2d, ROW_2D, ",", 0, "frame"),
        (read_detections_3d, ROW_3D, ",", 0, "frame"),
        (read_tracking_labels, ROW_TRACK, None, 0, "frame"),
        (read_tracking_labels, ROW_TRACK, None, 1, "track_id"),
    ],
)
def test_non_integer_frame_or_track_id(tmp_path, reader, row, sep, index, field):
    e = raises(tmp_path, reader, f"{row}\n{replace(row, sep, index, '1.5')}\n")
    assert (e.line, e.field) == (2, field) and e.message == "not an integer: '1.5'"


def test_integer_valued_frames_in_float_notation_are_accepted(tmp_path):
    d = read_detections_2d(write(tmp_path / "f.txt", replace(ROW_2D, ",", 0, "3.0")))
    assert d.frame.tolist() == [3] and d.frame.dtype == np.int64


@pytest.mark.parametrize(
    "reader, row, sep, lo, hi, field",
    [
        (read_detections_2d, ROW_2D, ",", 1, 3, "x2"),
        (read_detections_2d, ROW_2D, ",", 2, 4, "y2"),
        (read_detections_3d, ROW_3D, ",", 2, 4, "x2"),
        (read_detections_3d, ROW_3D_LABEL, None, 6, 8, "y2"),
        (read_tracking_labels, ROW_TRACK, None, 6, 8, "x2"),
        (read_tracking_labels, ROW_TRACK, None, 7, 9, "y2"),
    ],
)
def test_inverted_box(tmp_path, reader, row, sep, lo, hi, field):
    parts = row.split(sep)
    parts[lo], parts[hi] = parts[hi], parts[lo]
    e = raises(tmp_path, reader, f"{row}\n{row}\n{(sep or ' ').join(parts)}\n")
    assert (e.line, e.field) == (3, field)


def test_degenerate_box_is_valid(tmp_path):
    d = read_detections_2d(write(tmp_path / "f.txt", "0,5,6,5,6,0.1\n"))
    np.testing.assert_array_equal(d.box, [[5, 6, 5, 6]])


@pytest.mark.parametrize(
    "row, sep, index, field",
    [(ROW_3D, ",", 7, "h"), (ROW_3D, ",", 8, "w"), (ROW_3D, ",", 9, "l"),
     (ROW_3D.replace(",", " "), None, 9, "l"), (ROW_3D_LABEL, None, 10, "w")],
)
def test_negative_size_in_detections(tmp_path, row, sep, index, field):
    e = raises(tmp_path, read_detections_3d, f"{row}\n{replace(row, sep, index, '-0.5')}\n")
    assert (e.line, e.field) == (2, field) and "negative" in e.message


def test_negative_size_allowed_in_labels_and_results(tmp_path):
    result = replace(ROW_TRACK, None, 10, "-1.96") + " 8.2"
    labels = read_tracking_labels(write(tmp_path / "a.txt", f"{ROW_DONTCARE}\n{ROW_TRACK}\n"))
    np.testing.assert_array_equal(labels.dims[0], [-1, -1, -1])
    assert labels.track_id.tolist() == [-1, 0] and list(labels.type) == ["DontCare", "Car"]
    results = read_tracking_labels(write(tmp_path / "b.txt", result + "\n"))
    assert results.dims[0, 0] == -1.96 and results.score.tolist() == [8.2]


def test_frames_not_sorted(tmp_path):
    rows = [replace(ROW_2D, ",", 0, f) for f in ("3", "13", "13", "12", "14")]
    e = raises(tmp_path, read_detections_2d, "\n".join(rows))
    assert (e.line, e.field, e.message) == (4, "frame", "frames not sorted: 12 after 13")
    rows = [replace(ROW_TRACK, None, 0, f) for f in ("1", "0")]
    e = raises(tmp_path, read_tracking_labels, "\n".join(rows))
    assert (e.line, e.field, e.message) == (2, "frame", "frames not sorted: 0 after 1")


def test_first_offending_line_is_reported(tmp_path):
    rows = [ROW_2D, replace(ROW_2D, ",", 3, "1"), "1,2,3", replace(ROW_2D, ",", 1, "abc")]
    e = raises(tmp_path, read_detections_2d, "\n".join(rows))
    assert (e.line, e.field) == (2, "x2")
    rows = [ROW_2D, "1,2,3", replace(ROW_2D, ",", 1, "abc")]
    e = raises(tmp_path, read_detections_2d, "\n".join(rows))
    assert (e.line, e.field) == (2, "columns")
    e = raises(tmp_path, read_detections_2d, "0,inf,2,3,4,0.5\n")
    assert (e.line, e.field) == (1, "x1")


@pytest.mark.parametrize("reader", [read_detections_2d, read_detections_3d, read_tracking_labels, read_calib])
def test_file_not_found(tmp_path, reader):
    path = tmp_path / "missing" / "0000.txt"
    with pytest.raises(KittiFormatError) as info:
        reader(path)
    e = info.value
    assert (e.path, e.line, e.field, e.message) == (str(path), None, None, "file not found")
    assert str(e) == f"{path}: file not found"


def test_crlf_and_blank_lines(tmp_path):
    text = "\r\n  \r\n" + f"{ROW_2D}\r\n\r\n\t\r\n" + replace(ROW_2D, ",", 0, "4") + "\r\n\r\n"
    d = read_detections_2d(write(tmp_path / "a.txt", text))
    assert d.frame.tolist() == [0, 4] and d.score.tolist() == [0.5, 0.5]
    bad = text.replace("4,296.0", "4,abc")
    e = raises(tmp_path, read_detections_2d, bad)
    assert (e.line, e.field) == (6, "x1")
    labels = read_tracking_labels(write(tmp_path / "b.txt", f"\r\n{ROW_TRACK}\r\n{ROW_TRACK}"))
    assert labels.frame.tolist() == [0, 0] and list(labels.type) == ["Car", "Car"]


@pytest.mark.parametrize("text", ["", "\n", "\r\n\r\n", "  \n\t\n"])
def test_empty_files(tmp_path, text):
    path = write(tmp_path / "e.txt", text)
    d2 = read_detections_2d(path)
    assert d2.frame.shape == (0,) and d2.frame.dtype == np.int64
    assert d2.box.shape == (0, 4) and d2.box.dtype == np.float64 and d2.score.shape == (0,)
    d3 = read_detections_3d(path)
    assert d3.type.shape == (0,) and d3.type.dtype == object
    assert d3.box.shape == (0, 4) and d3.dims.shape == (0, 3) and d3.loc.shape == (0, 3)
    assert d3.rot_y.shape == d3.alpha.shape == d3.score.shape == (0,)
    t = read_tracking_labels(path)
    assert t.frame.dtype == t.track_id.dtype == np.int64 and t.type.dtype == object
    assert t.box.shape == (0, 4) and t.dims.shape == (0, 3) and t.loc.shape == (0, 3)
    assert t.score.shape == t.truncated.shape == t.occluded.shape == t.alpha.shape == t.rot_y.shape == (0,)


def test_three_3d_layouts_agree(tmp_path):
    a = read_detections_3d(write(tmp_path / "a.txt", ROW_3D + "\n"))
    b = read_detections_3d(write(tmp_path / "b.txt", ROW_3D.replace(",", " ") + "\n"))
    c = read_detections_3d(write(tmp_path / "c.txt", ROW_3D_LABEL.replace("Car", "2") + "\n"))
    for x, y in ((a, b), (a, c)):
        for f in Detections3D._fields:
            np.testing.assert_array_equal(getattr(x, f), getattr(y, f))
    assert a.type.tolist() == ["2"]
    np.testing.assert_array_equal(a.dims, [[1.96, 1.81, 4.75]])
    np.testing.assert_array_equal(a.loc, [[-4.57, 1.84, 13.53]])
    assert (a.score[0], a.rot_y[0], a.alpha[0]) == (8.29, -2.11, -1.78)


# ---------------------------------------------------------------------------------------------
# calibration

P = "7.215377e+02 0.0 6.095593e+02 {t} 0.0 7.215377e+02 1.728540e+02 2.163791e-01 0.0 0.0 1.0 2.745884e-03"
R = "9.999239e-01 9.837760e-03 -7.445048e-03 -9.869795e-03 9.999421e-01 -4.278459e-03 7.402527e-03 4.351614e-03 9.999631e-01"
T = "7.533745e-03 -9.999714e-01 -6.166020e-04 -4.069766e-03 1.480249e-02 7.280733e-04 -9.998902e-01 -7.631618e-02 9.998621e-01 7.523790e-03 1.480755e-02 -2.717806e-01"


def calib_text(r="R0_rect:", tr="Tr_velo_to_cam:", imu=True, trailing="  ", sep=" ") -> str:
    lines = [f"P{k}:{sep}{P.format(t=float(k))}{trailing}" for k in range(4)]
    lines.append(f"{r}{sep}{R}{trailing}")
    lines.append(f"{tr}{sep}{T}{trailing}")
    if imu:
        lines.append(f"Tr_imu_to_velo:{sep}{T}{trailing}")
    return "\n".join(lines) + "\n"


def test_calib_names_and_shapes(tmp_path):
    c = read_calib(write(tmp_path / "c.txt", calib_text()))
    assert isinstance(c, Calib)
    assert c.P2.shape == (3, 4) and c.R0_rect.shape == (3, 3) and c.Tr_velo_to_cam.shape == (3, 4)
    assert c.P.shape == (4, 3, 4) and c.Tr_imu_to_velo.shape == (3, 4)
    assert c.P2[0, 3] == 2.0 and c.P[3, 0, 3] == 3.0 and c.P[0, 0, 0] == 721.5377
    np.testing.assert_array_equal(c.P[2], c.P2)
    assert c.R0_rect[2, 2] == 9.999631e-01 and c.Tr_velo_to_cam[2, 3] == -2.717806e-01
    np.testing.assert_array_equal(c.Tr_imu_to_velo, c.Tr_velo_to_cam)


def test_calib_aliases_crlf_and_missing_imu(tmp_path):
    text = calib_text(r="R_rect", tr="Tr_velo_cam", imu=False, sep=" ").replace("\n", "\r\n")
    c = read_calib(write(tmp_path / "c.txt", text))
    assert c.R0_rect[0, 0] == 9.999239e-01 and c.Tr_velo_to_cam[0, 1] == -9.999714e-01
    np.testing.assert_array_equal(c.Tr_imu_to_velo, np.zeros((3, 4)))


@pytest.mark.parametrize("sep", [" ", "\t", "  "])
def test_calib_devkit_names_without_colon_any_blank(tmp_path, sep):
    """The tracking devkit's ``R_rect`` / ``Tr_velo_cam`` (no colon) read as ``R0_rect:`` / ``Tr_velo_to_cam:``."""
    ref = read_calib(write(tmp_path / "a.txt", calib_text()))
    c = read_calib(write(tmp_path / "b.txt", calib_text(r="R_rect", tr="Tr_velo_cam", sep=sep)))
    for name in ("P2", "R0_rect", "Tr_velo_to_cam"):
        np.testing.assert_array_equal(getattr(c, name), getattr(ref, name))
    e = raises(tmp_path, read_calib, calib_text(r="R_rect", sep=sep).replace(f"R_rect{sep}9.999239e-01", "R_rect"))
    assert (e.line, e.field) == (5, "R_rect") and "expected 9 values, got 8" in e.message


@pytest.mark.parametrize("missing, field", [("P2:", "P2"), ("R0_rect:", "R0_rect"), ("Tr_velo_to_cam:", "Tr_velo_to_cam")])
def test_calib_missing_matrix(tmp_path, missing, field):
    text = "\n".join(s for s in calib_text().splitlines() if not s.startswith(missing))
    e = raises(tmp_path, read_calib, text)
    assert (e.line, e.field) == (None, field) and e.message.startswith("missing")


@pytest.mark.parametrize(
    "old, new, line, field, what",
    [
        ("R0_rect: 9.999239e-01", "R0_rect:", 5, "R0_rect", "expected 9 values, got 8"),
        ("P2: 7.215377e+02", "P2: 1 7.215377e+02", 3, "P2", "expected 12 values, got 13"),
        ("Tr_velo_to_cam: 7.533745e-03", "Tr_velo_to_cam: abc", 6, "Tr_velo_to_cam", "not a number"),
        ("P1: 7.215377e+02", "P1: nan", 2, "P1", "not finite"),
    ],
)
def test_calib_bad_values(tmp_path, old, new, line, field, what):
    text = calib_text()
    assert old in text
    e = raises(tmp_path, read_calib, text.replace(old, new))
    assert (e.line, e.field) == (line, field) and what in e.message


def test_calib_duplicate_matrix(tmp_path):
    text = calib_text() + f"R_rect {R}\n"
    e = raises(tmp_path, read_calib, text)
    assert (e.line, e.field) == (8, "R_rect") and "twice" in e.message


# ---------------------------------------------------------------------------------------------
# writer and sequence lengths


def test_write_defaults_and_number_format(tmp_path):
    path = tmp_path / "a" / "b" / "0000.txt"
    write_tracking_results(path, [0, 2], [0, 7], [[296.0, 160.0, 452.0, 288.0], [296.744956, 161.75, 455.2, 292.3728]])
    lines = path.read_text().splitlines()
    assert lines[0] == "0 0 Car -1 -1 -10 296 160 452 288 -1 -1 -1 -1000 -1000 -1000 -10 1"
    assert lines[1] == "2 7 Car -1 -1 -10 296.745 161.75 455.2 292.373 -1 -1 -1 -1000 -1000 -1000 -10 1"
    t = read_tracking_labels(path)
    assert t.frame.tolist() == [0, 2] and t.track_id.tolist() == [0, 7]
    np.testing.assert_array_equal(t.alpha, [-10, -10])
    np.testing.assert_array_equal(t.loc, np.full((2, 3), -1000.0))


def test_write_all_fields_and_type_per_row(tmp_path):
    path = tmp_path / "r.txt"
    write_tracking_results(
        path, np.array([1]), np.array([3]), np.array([[1.5, 2, 3, 4]]), type_name=["Pedestrian"],
        alpha=[-1.7867], dims=[[1.9605, -1.8137, -4.7549]], loc=[[-4.572, 1.8435, 13.5308]],
        rot_y=[-2.1125], score=[8.2981],
    )
    assert path.read_text() == (
        "1 3 Pedestrian -1 -1 -1.7867 1.5 2 3 4 1.9605 -1.8137 -4.7549 -4.572 1.8435 13.5308 -2.1125 8.2981\n"
    )


def test_write_empty(tmp_path):
    path = tmp_path / "x" / "0017.txt"
    write_tracking_results(path, [], [], np.zeros((0, 4)))
    assert path.read_text() == ""
    assert read_tracking_labels(path).frame.shape == (0,)


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(frame=[1, 0], track_id=[0, 0], box=[[0, 0, 1, 1]] * 2),
        dict(frame=[-1], track_id=[0], box=[[0, 0, 1, 1]]),
        dict(frame=[0.5], track_id=[0], box=[[0, 0, 1, 1]]),
        dict(frame=[0], track_id=[0], box=[[0, 0, np.nan, 1]]),
        dict(frame=[0], track_id=[0], box=[[2, 0, 1, 1]]),
        dict(frame=[0], track_id=[0], box=[[0, 0, 1]]),
        dict(frame=[0, 1], track_id=[0], box=[[0, 0, 1, 1]] * 2),
        dict(frame=[0], track_id=[0], box=[[0, 0, 1, 1]], score=[np.inf]),
        dict(frame=[0], track_id=[0], box=[[0, 0, 1, 1]], type_name="Two words"),
    ],
)
def test_write_rejects_what_cannot_be_read_back(tmp_path, kwargs):
    with pytest.raises(ValueError):
        write_tracking_results(tmp_path / "w.txt", **kwargs)


def test_sequence_lengths_synthetic(tmp_path):
    (tmp_path / "label_02").mkdir()
    write(tmp_path / "label_02" / "0000.txt", f"{ROW_TRACK}\n{replace(ROW_TRACK, None, 0, '9')}\n")
    write(tmp_path / "label_02" / "0001.txt", "")
    write(tmp_path / "label_02" / "0002.txt", f"{replace(ROW_DONTCARE, None, 0, '4')}\n")
    assert sequence_lengths(tmp_path) == {"0000": 10, "0001": 0, "0002": 5}
    assert sequence_lengths(tmp_path, [2, "0000"]) == {"0002": 5, "0000": 10}
    with pytest.raises(KittiFormatError):
        sequence_lengths(tmp_path, ["0003"])


# ---------------------------------------------------------------------------------------------
# real data

SEQS = [f"{k:04d}" for k in range(21)]
REF = "reference/dfr_fastmot_rrc_pointrcnn"


def nonblank_lines(path: Path) -> int:
    with open(path, encoding="utf-8") as f:
        return sum(1 for line in f if line.strip())


def test_real_sequence_lengths(kitti_root):
    lengths = sequence_lengths(kitti_root)
    assert list(lengths) == SEQS
    assert sum(lengths.values()) == 8008
    assert lengths["0000"] == 154 and lengths["0019"] == 1059
    assert sum(v for k, v in lengths.items() if k != "0017") == 7863


@pytest.mark.parametrize("cls", ["car", "pedestrian"])
def test_real_detections(kitti_root, cls):
    lengths = sequence_lengths(kitti_root)
    for seq in SEQS:
        p2 = kitti_root / "detections" / "rrc" / cls / f"{seq}.txt"
        d2 = read_detections_2d(p2)
        assert len(d2.frame) == nonblank_lines(p2)
        assert d2.box.shape == (len(d2.frame), 4)
        if len(d2.frame):
            assert 0 <= d2.frame.min() and d2.frame.max() < lengths[seq]
            assert ((0 <= d2.score) & (d2.score <= 1)).all()
        p3 = kitti_root / "detections" / "pointrcnn" / cls / f"{seq}.txt"
        d3 = read_detections_3d(p3)
        assert len(d3.frame) == nonblank_lines(p3)
        assert set(d3.type) <= {"1", "2"}
        if len(d3.frame):
            assert d3.frame.max() < lengths[seq] and (d3.dims >= 0).all()
    first = read_detections_2d(kitti_root / "detections" / "rrc" / "car" / "0000.txt")
    assert first.frame[0] == 0 and first.box[0].tolist() == [296.021, 160.173, 452.297, 288.372]
    assert first.score[0] == 0.52923


def test_real_detections_3d_values(kitti_root):
    d = read_detections_3d(kitti_root / "detections" / "pointrcnn" / "car" / "0000.txt")
    assert d.type[0] == "2" and d.frame[0] == 0
    np.testing.assert_array_equal(d.box[0], [298.3125, 165.1800, 458.2292, 293.4391])
    np.testing.assert_array_equal(d.dims[0], [1.9605, 1.8137, 4.7549])
    np.testing.assert_array_equal(d.loc[0], [-4.5720, 1.8435, 13.5308])
    assert (d.score[0], d.rot_y[0], d.alpha[0]) == (8.2981, -2.1125, -1.7867)


def test_real_labels_and_calib(kitti_root):
    total = 0
    for seq in SEQS:
        path = kitti_root / "label_02" / f"{seq}.txt"
        t = read_tracking_labels(path)
        total += len(t.frame)
        assert len(t.frame) == nonblank_lines(path)
        assert np.isnan(t.score).all()
        dontcare = t.type == "DontCare"
        assert (t.track_id[dontcare] == -1).all() and (t.track_id[~dontcare] >= 0).all()
        c = read_calib(kitti_root / "calib" / f"{seq}.txt")
        assert c.P2[2, 2] == 1.0 and abs(np.linalg.det(c.R0_rect) - 1) < 1e-4
        assert np.abs(c.Tr_imu_to_velo).sum() > 0
    assert total == 65301
    t = read_tracking_labels(kitti_root / "label_02" / "0000.txt")
    assert (t.frame[2], t.track_id[2], t.type[2]) == (0, 0, "Van")
    np.testing.assert_array_equal(t.box[2], [296.744956, 161.752147, 455.226042, 292.372804])
    c = read_calib(kitti_root / "calib" / "0000.txt")
    assert c.P2[0, 0] == 721.5377 and c.P2[0, 3] == 44.85728


def test_real_reference_results(kitti_root, tmp_path):
    total = 0
    for seq in SEQS:
        path = kitti_root / REF / f"{seq}.txt"
        if seq == "0017":
            assert not path.exists()
            continue
        r = read_tracking_labels(path)
        total += len(r.frame)
        assert set(r.type) == {"Car"} and np.isfinite(r.score).all()
    assert total == 28812
    r = read_tracking_labels(kitti_root / REF / "0000.txt")
    assert (r.frame[0], r.track_id[0]) == (0, 0)
    assert r.box[0].tolist() == [296, 160, 452, 288]
    out = tmp_path / "0000.txt"
    write_tracking_results(out, r.frame, r.track_id, r.box, alpha=r.alpha, dims=r.dims, loc=r.loc,
                           rot_y=r.rot_y, score=r.score)
    back = read_tracking_labels(out)
    for f in TrackingLabels._fields:
        if f != "type":
            np.testing.assert_allclose(getattr(back, f), getattr(r, f), rtol=1e-6, atol=0)
    assert out.read_text().splitlines()[0] == (kitti_root / REF / "0000.txt").read_text().splitlines()[0]


def test_real_data_loads(kitti_root):
    """Every file of the split reads without an error (its speed: benchmarks/, never a timed test)."""
    rows = 0
    for seq in SEQS:
        for cls in ("car", "pedestrian"):
            rows += len(read_detections_2d(kitti_root / "detections" / "rrc" / cls / f"{seq}.txt").frame)
            rows += len(read_detections_3d(kitti_root / "detections" / "pointrcnn" / cls / f"{seq}.txt").frame)
        assert len(read_tracking_labels(kitti_root / "label_02" / f"{seq}.txt").frame) > 0, seq
        assert read_calib(kitti_root / "calib" / f"{seq}.txt").P2.shape == (3, 4), seq
    assert rows > 0


def test_values_downstream_types_cannot_hold_are_refused_located(tmp_path):
    from dfrmot_jax.io.kitti import KittiFormatError, read_detections_2d, read_tracking_labels

    p = tmp_path / "d.txt"
    p.write_text("0,1,2,3,4,0.5\n1,1,2,4e38,4,0.5\n")
    with pytest.raises(KittiFormatError, match=r"d\.txt:2: field 'x2': outside the float32 range"):
        read_detections_2d(p)
    row = "1 Car 0 0 -1 1 2 3 4 1 1 1 1 1 1 0"
    p.write_text(f"0 {row}\n1e19 {row}\n")
    with pytest.raises(KittiFormatError, match=r"d\.txt:2: field 'frame': too large"):
        read_tracking_labels(p)
    p.write_text(f"0 {row}\n1 9223372036854775808 Car 0 0 -1 1 2 3 4 1 1 1 1 1 1 0\n")
    with pytest.raises(KittiFormatError, match=r"d\.txt:2: field 'track_id': too large"):
        read_tracking_labels(p)


def test_frame_beyond_the_sequence_names_the_file_line_after_blank_lines(tmp_path):
    from dfrmot_jax.data import load_sequences
    from dfrmot_jax.io.kitti import KittiFormatError
    from dfrmot_jax.synthetic import make_scene

    root = make_scene(tmp_path / "scene", n_sequences=1, n_frames=20, seed=2)
    det = root / "detections" / "synth2d" / "car" / "0000.txt"
    lines = det.read_text().splitlines()
    det.write_text("\n\n" + "\n".join(lines[:3] + ["25,1,2,3,4,0.9"]) + "\n")
    with pytest.raises(KittiFormatError, match=r"0000\.txt:6: field 'frame': 2D detection at frame 25 beyond"):
        load_sequences(root, "synth2d", "synth3d", "car")
