"""The readers' one-pass path (dfrmot_jax.io.plain_table) against their line-by-line path.

Every reader of a KITTI table (labels, results, detections; and result files by TrackEval's rules)
first tries to read a plain file in one pass; the line reader is what remains when ``plain_text``
says no (patched here to say no always). Both must give the same arrays, bit for bit, on every data
file, and the same outcome (arrays or the located error) on malformed files.
"""

from __future__ import annotations

from decimal import Decimal

import numpy as np
import pytest

from dfrmot_jax.io import kitti as kio
from dfrmot_jax.io import result_rows
from dfrmot_jax.io.kitti import KittiFormatError
from dfrmot_jax.io.plain_table import joined_columns, plain_columns, plain_text, read_ahead

REF_DIR = "reference/dfr_fastmot_rrc_pointrcnn"

READERS = {
    "labels": kio.read_tracking_labels,
    "det2d": kio.read_detections_2d,
    "det3d": kio.read_detections_3d,
    "results": result_rows.read_result_rows,
}


def _same(a, b) -> bool:
    """Arrays (or tuples of them) equal bit for bit, with the same dtype and shape; object arrays of
    str element by element."""
    if isinstance(a, tuple):
        return type(a) is type(b) and len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if a.dtype != b.dtype or a.shape != b.shape:
        return False
    if a.dtype == object:
        return all(type(x) is type(y) is str and x == y for x, y in zip(a.tolist(), b.tolist()))
    return a.tobytes() == b.tobytes()


class Refused(str):
    """A reader's located error message."""


def _outcome(reader, path):
    try:
        return reader(path)
    except KittiFormatError as e:
        return Refused(e)


def _line_reader(monkeypatch, reader, path):
    """``reader(path)``'s outcome with the one-pass path switched off."""
    with monkeypatch.context() as m:
        m.setattr(kio, "plain_text", lambda p: None)
        m.setattr(result_rows, "plain_text", lambda p: None)
        return _outcome(reader, path)


def _one_pass_only(monkeypatch, reader, path):
    """``reader(path)`` with the line reader switched off (it fails the test if reached)."""
    def refuse(p):
        raise AssertionError(f"{p}: read line by line")
    with monkeypatch.context() as m:
        m.setattr(kio, "read_text_file", refuse)
        m.setattr(result_rows, "read_text_file", refuse)
        return reader(path)


def _agree(monkeypatch, reader, path) -> None:
    fast, slow = _outcome(reader, path), _line_reader(monkeypatch, reader, path)
    if isinstance(slow, Refused) or isinstance(fast, Refused):
        assert isinstance(fast, Refused) and isinstance(slow, Refused) and fast == slow, (fast, slow)
    else:
        assert _same(fast, slow), path.read_bytes()[:300]


@pytest.mark.slow
def test_every_data_file_reads_the_same_both_ways(kitti_root, monkeypatch):
    labels = sorted((kitti_root / "label_02").glob("*.txt"))
    results = sorted((kitti_root / "reference").rglob("*.txt"))
    dets = sorted((kitti_root / "detections").rglob("*.txt"))
    assert len(labels) == 21 and len(results) >= 20 and dets
    checked = 0
    for path in labels + results:
        for reader in (kio.read_tracking_labels, result_rows.read_result_rows):
            if plain_text(path) is None:                        # an empty result file (ByteTrack's runs have some)
                _agree(monkeypatch, reader, path)
                continue
            fast = _one_pass_only(monkeypatch, reader, path)   # every other label and result file is plain
            assert _same(fast, _line_reader(monkeypatch, reader, path)), path
            checked += 1
    for path in dets:
        first = path.read_text().split("\n", 1)[0]
        reader = kio.read_detections_2d if first.count(",") == 5 else kio.read_detections_3d
        if plain_text(path) is not None:
            fast = _one_pass_only(monkeypatch, reader, path)
            assert _same(fast, _line_reader(monkeypatch, reader, path)), path
            checked += 1
        else:                                                   # the empty file
            _agree(monkeypatch, reader, path)
    assert checked >= 2 * 41 + 80


ROW17 = "0 1 Car 0 0 -1.5 100.25 160 200 288.5 1.5 1.6 4.2 -2.1 1.8 13.5 -1.57"
ROW17B = "1 2 Van 1 2 0.3 10 20 30 40 1.4 1.5 3.9 2.5 1.7 20.25 0.5"
DC = "1 -1 DontCare -1 -1 -10 5 6 7 8 -1 -1 -1 -1000 -1000 -1000 -10"
ROW3D = "0,2,147.5421,196.9926,314.0278,281.5120,12.3170,1.5005,1.6285,4.1865,-8.2863,2.1115,16.1333,1.5404,2.0149"
ROW2D = "0,296.021,160.173,452.297,288.372,0.52923"


def _variants():
    """(reader names, file bytes): plain files, files just off plain, and malformed ones."""
    good = "\n".join([ROW17, DC, ROW17B]) + "\n"
    lab = ("labels", "results")
    yield lab, good
    yield lab, good.rstrip("\n")                                   # no final newline
    yield lab, "\n".join(r + " 0.75" for r in (ROW17, DC, ROW17B)) + "\n"   # 18 columns
    yield lab, good.replace("\n", "\r\n")                          # CRLF
    yield lab, "\ufeff" + good                                    # byte-order mark
    yield lab, good + "\n"                                        # a blank line at the end
    yield lab, ROW17 + "\n\n" + ROW17B + "\n"                     # a blank line inside
    yield lab, ROW17 + "\n   \n" + ROW17B + "\n"                  # a line of spaces
    yield lab, good.replace(" ", "\t")                            # tabs
    yield lab, good.replace("Car 0", "Car  0")                    # two spaces
    yield lab, " " + good                                         # leading space
    yield lab, good.replace("\n", " \n", 1)                       # trailing space
    yield lab, good.replace("\n", "\r", 1)                        # a lone CR
    yield lab, good.replace("Car", "Car\u00a0x")                  # non-ASCII (a no-break space)
    yield lab, good.replace("Car", "C\u00e4r")                    # non-ASCII letter
    yield lab, good.replace(ROW17B, ROW17B.rsplit(" ", 1)[0])     # a short row
    yield lab, good.replace(ROW17B, ROW17B + " 7 8")              # a long row
    yield lab, good.replace("Car", '"Car"')                       # quotes stay in the type
    yield lab, good.replace("Car", "Car,x")                       # a comma in the type
    for old, new in (("100.25", "abc"), ("100.25", "nan"), ("100.25", "inf"), ("100.25", "-Infinity"),
                     ("100.25", "1_00.25"), ("100.25", "+100.25"), ("100.25", "1e39"), ("100.25", ".5e2"),
                     ("100.25", "100."), ("100.25", "0x10"), ("-1.57", "nan"), ("-1.57", "-0"), ("-1.57", "nan(1)"),
                     ("1.5 1.6", "-1.5 1.6"), ("160", "300"), ("0 1 Car", "0.5 1 Car"), ("0 1 Car", "0 1.5 Car"),
                     ("0 1 Car", "-1 1 Car"), ("0 1 Car", "2 1 Car"), ("0 1 Car", "0 99999999999999999 Car"),
                     ("0 1 Car", "3000000000 1 Car"), ("0 1 Car", "0 -0.5 Car"), ("0 1 Car", "1e3 1 Car"),
                     ("1 2 Van", "1 2 Person_sitting"), ("0 0 -1.5", "0.5 2.9 -1.5")):
        yield lab, good.replace(old, new, 1)
    yield lab, ""                                                 # empty
    yield lab, "\n\n"                                             # blank lines only
    yield lab, b"\xff\xfe" + good.encode()                        # not UTF-8
    yield ("results",), "0 -1 DontCare\n" + good                  # a short row with a negative id
    yield ("results",), "\n".join(r.replace(" ", ",") for r in (ROW17, DC, ROW17B)) + "\n"   # commas
    yield ("results",), "\n".join(r.replace(" ", ",") + "," for r in (ROW17, ROW17B)) + "\n"  # trailing comma
    good3d = "\n".join([ROW3D, ROW3D.replace("0,2,", "1,2,", 1)]) + "\n"
    yield ("det3d",), good3d
    yield ("det3d",), good3d.replace("\n", "\r\n")
    yield ("det3d",), good3d.replace(",2,", ",,", 1)               # an empty type
    yield ("det3d",), good3d.replace(",2,", ", 2,", 1)             # a space: stripped by the line reader
    yield ("det3d",), good3d.replace(",1.5005,", ",-1.5005,", 1)   # a negative size
    yield ("det3d",), good3d.replace(",", " ")                     # whitespace 15 columns
    yield ("det3d",), good3d.replace("147.5421", "147,5421", 1)    # one field too many
    yield ("det3d", "labels"), "\n".join(r.replace("0 1 Car", "0 Car").replace("1 2 Van", "1 Van")
                                         + " 0.9" for r in (ROW17, ROW17B)) + "\n"   # the 17-column 3D layout
    good2d = "\n".join([ROW2D, ROW2D.replace("0,", "1,", 1), ROW2D.replace("0,", "1,", 1)]) + "\n"
    yield ("det2d",), good2d
    yield ("det2d",), good2d.replace("0.52923", "x", 1)
    yield ("det2d",), good2d.replace(",", " ")
    yield ("det2d",), good2d.replace("1,", "0,", 1)
    yield ("det2d",), "\n".join([ROW2D.replace("0,", "1,", 1), ROW2D]) + "\n"      # frames not sorted


@pytest.mark.parametrize("k", range(len(list(_variants()))))
def test_malformed_and_odd_files_give_the_line_readers_outcome(tmp_path, monkeypatch, k):
    names, content = list(_variants())[k]
    path = tmp_path / "0000.txt"
    path.write_bytes(content if isinstance(content, bytes) else content.encode())
    for name in names:
        _agree(monkeypatch, READERS[name], path)


def test_plain_text_says_no_to_what_the_one_pass_path_cannot_read(tmp_path):
    path = tmp_path / "a.txt"
    for content, want in ((b"1 2\n", b"1 2\n"), (b"\xef\xbb\xbf1 2\r\n3 4\r\n", b"1 2\n3 4\n"), (b"", None),
                          (b"1\t2\n", None), (b"1 2\r3 4\n", None), (b"1 \xc3\xa4\n", None), (b"1 2\x00\n", None)):
        path.write_bytes(content)
        assert plain_text(path) == want, content
    assert plain_text(tmp_path / "missing.txt") is None
    assert plain_text(tmp_path) is None


def test_plain_columns_reads_fields_or_says_no():
    cols = plain_columns(b"1 a 2.5\n-0 b 1e3\n", None, 3, (1,))
    assert cols[1].dtype == object and cols[1].tolist() == ["a", "b"]
    assert cols[0].dtype == np.float64 and np.signbit(cols[0][1]) and cols[2].tolist() == [2.5, 1000.0]
    for data, sep in ((b"1 a 2\n3 b\n", None), (b"1 a 2\n3 b 4 5\n", None), (b"1 a nan\n", None),
                      (b"1 a inf\n", None), (b"1 a x\n", None), (b"1  2\n", None), (b"1 a 2\n\n3 b 4\n", None),
                      (b"1,,2\n", ","), (b"1, a,2\n", ","), (b"1,a,2,\n", ","), (b"1 a 2 \n", None)):
        assert plain_columns(data, sep, 3, (1,)) is None, data


def test_numbers_are_read_as_pythons_float_reads_them():
    """pyarrow's numbers are the line reader's (Python's ``float``, numpy's conversion) bit for bit:
    random decimal strings of up to 25 digits with and without exponents and signs, and the
    halfway points between neighbouring doubles (where a parser that is not correctly rounded errs)."""
    rng = np.random.default_rng(7)
    toks = []
    for _ in range(20000):
        digits = "".join(map(str, rng.integers(0, 10, rng.integers(1, 26))))
        k = int(rng.integers(0, len(digits) + 1))
        s = digits[:k] + "." + digits[k:] if rng.random() < 0.8 and len(digits) > 1 else digits
        if rng.random() < 0.3:
            s += f"{'eE'[int(rng.integers(2))]}{['', '+', '-'][int(rng.integers(3))]}{int(rng.integers(0, 280))}"
        toks.append(["", "+", "-"][int(rng.integers(3))] + s)
    for _ in range(2000):
        x = float(rng.random() * 10.0 ** int(rng.integers(-300, 300)))
        toks.append(str((Decimal(x) + Decimal(np.nextafter(x, np.inf))) / 2))
    toks += ["2.2250738585072011e-308", "4.9e-324", "1e-400", "-0", "0.30000000000000004", "9007199254740993"]
    (col,) = plain_columns("\n".join(toks).encode(), None, 1)
    want = np.array([float(t) for t in toks])
    assert col.view(np.int64).tolist() == want.view(np.int64).tolist()
    assert want.view(np.int64).tolist() == np.array(toks, dtype=np.float64).view(np.int64).tolist()


def test_read_ahead_keeps_the_callers_order_and_error(tmp_path):
    """Files read ahead in threads come back in order; a bad file's error comes at its turn (after
    the files before it), as a plain loop raises it."""
    good = "0 1 Car 0 0 -1 10 20 30 40 1.5 1.6 3.9 1 2 10 0.1\n"
    paths = []
    for i, text in enumerate([good, good * 2, "zero" + good[1:], good * 3]):
        paths.append(tmp_path / f"{i}.txt")
        paths[-1].write_text(text)
    it = read_ahead(kio.read_tracking_labels, paths)
    assert [len(next(it).frame) for _ in range(2)] == [1, 2]
    with pytest.raises(KittiFormatError, match=r"2\.txt"):
        next(it)
    assert [len(x.frame) for x in read_ahead(kio.read_tracking_labels, [paths[3], paths[0]])] == [3, 1]


# ---- several files in one parse (io.kitti.iter_tracking_labels, io.result_rows.iter_result_rows) ------------


def _outcomes(it, n):
    """The first ``n`` items of ``it``, or up to its located error (a Refused) and nothing after it."""
    out = []
    try:
        for _ in range(n):
            out.append(next(it))
    except KittiFormatError as e:
        out.append(Refused(e))
    return out


def test_files_read_in_one_parse_equal_each_file_read_alone(kitti_root, monkeypatch):
    """All 21 label files and the reference results, each joined read equal to the file read alone, bit
    for bit; the joined path is the one taken (frames restart at each file: no 'frames not sorted')."""
    labels = sorted((kitti_root / "label_02").glob("*.txt"))
    results = sorted((kitti_root / REF_DIR).glob("*.txt"))
    assert kio.joined_tracking_labels(labels) is not None
    assert result_rows._joined_rows(results) is not None
    for read_many, read_one, paths in ((kio.iter_tracking_labels, kio.read_tracking_labels, labels),
                                       (result_rows.iter_result_rows, result_rows.read_result_rows, results),
                                       (lambda p: result_rows.iter_result_rows(p, ahead=True),
                                        result_rows.read_result_rows, results)):
        many = list(read_many(paths))
        assert len(many) == len(paths)
        for path, got in zip(paths, many):
            assert _same(got, read_one(path)), path


def _group_variants():
    """(reader name, [file bytes]): a good file, then a variant of :func:`_variants`, then good files
    of the same and of another column count."""
    good = ("\n".join([ROW17, DC, ROW17B]) + "\n").encode()
    good18 = ("\n".join(r + " 0.75" for r in (ROW17, DC, ROW17B)) + "\n").encode()
    for names, content in _variants():
        content = content if isinstance(content, bytes) else content.encode()
        for name in ("labels", "results"):
            if name in names:
                yield name, [good, content, good]
                yield name, [content, good18]
    yield "labels", [good, good.replace(b"\n", b"\r\n"), b"\xef\xbb\xbf" + good]
    yield "results", [good, good.replace(b" ", b",")]                 # commas and spaces


MANY = {"labels": kio.iter_tracking_labels, "results": result_rows.iter_result_rows}


@pytest.mark.parametrize("k", range(len(list(_group_variants()))))
def test_a_group_of_files_reads_as_each_file_alone_with_its_error_at_its_turn(tmp_path, k):
    """Whatever a group holds (odd, malformed or plain files of other layouts), the joined readers give
    each file's own outcome in order: its arrays, or its located error after the files before it."""
    name, contents = list(_group_variants())[k]
    paths = []
    for i, content in enumerate(contents):
        paths.append(tmp_path / f"{i:04d}.txt")
        paths[-1].write_bytes(content)
    alone = []
    for p in paths:
        alone.append(_outcome(READERS[name], p))
        if isinstance(alone[-1], Refused):
            break
    for many in (MANY[name], lambda p: result_rows.iter_result_rows(p, ahead=True)) if name == "results" else (
            MANY[name],):
        got = _outcomes(many(paths), len(paths))
        assert len(got) == len(alone)
        for a, b in zip(got, alone):
            assert (a == b) if isinstance(b, Refused) else _same(a, b), (a, b)


def test_joined_columns_numbers_each_texts_lines():
    cols, starts = joined_columns([b"1 a\n2 b", b"3 c\n", b"4 a\n5 a\n6 b\n"], None, 2, (1,))
    assert starts.tolist() == [0, 2, 3, 6]
    assert cols[0].tolist() == [1, 2, 3, 4, 5, 6] and cols[1].tolist() == list("abcaab")
    assert cols[1][0] is cols[1][3]                 # one str per distinct name
    assert joined_columns([b"1 a\n", b"2\n"], None, 2, (1,)) is None
