"""``dfrmot eval`` never gives a silently wrong score, and ``dfrmot track`` never leaves stale files.

* Result folders (issue 10, item 4): a missing result file, one that is a directory or a dangling
  symlink, and ``*.txt`` files that are no sequence of the ground truth are refused, listed;
  ``--allow-missing`` scores missing files as empty outputs with a warning; ``--seqs`` restricts
  both sides; a folder without a row of the evaluated class is refused (wrong ``--class``);
  ``track`` refuses a non-empty ``--out`` unless ``--overwrite`` (which removes only old result files).
* Ids and frames past what can be indexed are refused with file, line and field (item 5).
* Every file TrackEval reads is read and scored exactly as TrackEval does (item 6): rows in any
  order, ``x2 < x1``, non-integer frames and ids, 10 to 19+ columns, commas, junk in skipped rows;
  what TrackEval cannot read is refused, located.
* ``--per-seq`` marks sequences whose ground truth has nothing of the class (item 18, part).
"""

from __future__ import annotations

import csv
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from dfrmot_jax.io.kitti import KittiFormatError
from dfrmot_jax.metrics import evaluate_files, prepare_gt
from dfrmot_jax.testing.cli import error_line, run_cli

REF = Path("reference") / "dfr_fastmot_rrc_pointrcnn"
INT_FIELDS = {"CLR_TP", "CLR_FN", "CLR_FP", "IDSW", "MT", "PT", "ML", "Frag", "CLR_Frames", "IDTP", "IDFN", "IDFP",
              "Dets", "GT_Dets", "IDs", "GT_IDs", "HOTA_TP", "HOTA_FN", "HOTA_FP"}


def _copy_ref(kitti_root, dst: Path, seqs) -> Path:
    dst.mkdir(parents=True, exist_ok=True)
    for s in seqs:
        shutil.copy(kitti_root / REF / f"{s}.txt", dst / f"{s}.txt")
    return dst


def _csv_rows(path):
    return {(r["class"], r["seq"]): r for r in csv.DictReader(open(path))}


def _eval_csv(capsys, argv, tmp_path, name="m.csv"):
    out = tmp_path / name
    status, stdout, err = run_cli(capsys, argv + ["--csv", str(out)])
    assert status == 0, err
    return _csv_rows(out), stdout, err


def assert_same(te: dict, ours: dict, tag: str = "") -> None:
    """Every (seq, field) of TrackEval equals ours: counts exactly, ratios within 1e-9."""
    assert set(te) == set(ours), tag
    bad = []
    for seq in te:
        for f, v in te[seq].items():
            a, b = np.asarray(v, np.float64), np.asarray(ours[seq][f], np.float64)
            ok = np.array_equal(a, b) if f in INT_FIELDS else np.allclose(a, b, atol=1e-9, rtol=0)
            if a.shape != b.shape or not ok:
                bad.append(f"{seq}.{f}: trackeval={v!r} ours={ours[seq][f]!r}")
    assert not bad, f"{tag}: " + "\n".join(bad[:20])


def _trackeval(kitti_root, tmp: Path, files: dict, cls="car"):
    """TrackEval's Kitti2DBox on {seq: text}: the flattened results, or the exception it raised."""
    pytest.importorskip("trackeval")
    from dfrmot_jax.testing.trackeval_adapter import make_gt_folder, make_tracker_folder, run_trackeval

    gt = prepare_gt(kitti_root, cls, sorted(files))
    make_gt_folder(tmp / "gt", kitti_root, gt.lengths_dict)
    make_tracker_folder(tmp / "trk", "t", files, sorted(files))
    try:
        return run_trackeval(tmp / "gt", tmp / "trk", cls)["t"]
    except Exception as e:                                    # TrackEval refuses it, one way or another
        return e


# ---- item 4: what a results folder must hold ------------------------------------------------------

def test_missing_result_files_are_refused_and_listed(kitti_root, tmp_path, capsys):
    """``track --seqs 0001,0002`` then a plain ``eval``: 18 of the 20 car sequences have no file."""
    res = _copy_ref(kitti_root, tmp_path / "r", ["0001", "0002"])
    status, out, err = run_cli(capsys, ["eval", str(res), "--data", str(kitti_root)])
    line = error_line(err, "eval")
    assert status == 2 and not out
    assert str(res) in line and "18 of 20" in line and "0000" in line and "0020" in line and "0001," not in line
    assert "--allow-missing" in line and "--seqs" in line


def test_allow_missing_scores_missing_files_as_empty_with_a_warning(kitti_root, tmp_path, capsys):
    res = _copy_ref(kitti_root, tmp_path / "r", ["0001", "0002"])
    rows, _, err = _eval_csv(capsys, ["eval", str(res), "--data", str(kitti_root), "--allow-missing"], tmp_path)
    warn = [s for s in err if s.startswith("dfrmot eval: warning: ")]
    assert len(warn) == 1 and len(err) == 1 and "18 of 20" in warn[0] and "0000" in warn[0] and "empty" in warn[0]
    api = evaluate_files(res, kitti_root, "car", missing="empty")["COMBINED"]
    assert float(rows["car", "COMBINED"]["HOTA"]) == pytest.approx(100 * np.mean(api["HOTA"]), abs=1e-9)
    two, _, err = _eval_csv(capsys, ["eval", str(res), "--data", str(kitti_root), "--seqs", "1,2"], tmp_path, "2.csv")
    assert not err
    full = evaluate_files(res, kitti_root, "car", ["0001", "0002"])["COMBINED"]
    assert float(two["car", "COMBINED"]["HOTA"]) == pytest.approx(100 * np.mean(full["HOTA"]), abs=1e-9)
    assert float(two["car", "COMBINED"]["HOTA"]) > float(rows["car", "COMBINED"]["HOTA"]) + 20


@pytest.mark.parametrize("kind", ["directory", "dangling symlink"])
@pytest.mark.parametrize("allow", [False, True])
def test_a_result_file_that_is_no_file_is_refused_by_name(kind, allow, kitti_root, tmp_path, capsys):
    res = _copy_ref(kitti_root, tmp_path / "r", ["0001"])
    bad = res / "0002.txt"
    if kind == "directory":
        bad.mkdir()
    else:
        os.symlink(tmp_path / "gone.txt", bad)
    argv = ["eval", str(res), "--data", str(kitti_root), "--seqs", "1,2"] + (["--allow-missing"] if allow else [])
    status, out, err = run_cli(capsys, argv)
    line = error_line(err, "eval")
    assert status == 2 and str(bad) in line and kind in line


def test_the_api_refuses_a_result_file_that_is_no_file(kitti_root, tmp_path):
    res = _copy_ref(kitti_root, tmp_path / "r", ["0001"])
    (res / "0002.txt").mkdir()
    with pytest.raises(KittiFormatError, match="0002.txt.*directory"):
        evaluate_files(res, kitti_root, "car", ["0001", "0002"], missing="empty")


def test_unexpected_files_are_refused_unless_seqs_restricts_them(kitti_root, tmp_path, capsys):
    res = _copy_ref(kitti_root, tmp_path / "r", sorted(p.stem for p in (kitti_root / REF).glob("*.txt")))
    clean, _, err = _eval_csv(capsys, ["eval", str(res), "--data", str(kitti_root)], tmp_path, "clean.csv")
    assert not err
    (res / "0017.txt").write_text("")          # a label_02 sequence without cars: not unexpected
    (res / "notes.md").write_text("mine")      # not a result file name
    again, _, err = _eval_csv(capsys, ["eval", str(res), "--data", str(kitti_root)], tmp_path, "again.csv")
    assert not err and again == clean
    shutil.copy(res / "0001.txt", res / "0099.txt")
    (res / "foo.txt").write_text("")
    for extra in ([], ["--allow-missing"]):
        status, out, err = run_cli(capsys, ["eval", str(res), "--data", str(kitti_root)] + extra)
        line = error_line(err, "eval")
        assert status == 2 and "0099.txt" in line and "foo.txt" in line and "0017" not in line
    some, _, err = _eval_csv(capsys, ["eval", str(res), "--data", str(kitti_root), "--seqs", "0001,0002"], tmp_path)
    assert not err and {s for _, s in some} == {"0001", "0002", "COMBINED"}


def test_results_without_a_row_of_the_class_are_refused(kitti_root, tmp_path, capsys):
    """Car results scored with ``--class pedestrian`` (the ground truth of 0001, 0002 has pedestrians)."""
    res = _copy_ref(kitti_root, tmp_path / "r", ["0001", "0002"])
    argv = ["eval", str(res), "--data", str(kitti_root), "--seqs", "1,2", "--class", "pedestrian"]
    status, out, err = run_cli(capsys, argv)
    line = error_line(err, "eval")
    assert status == 2 and "pedestrian" in line and "--class car" in line and str(res) in line
    status, out, err = run_cli(capsys, argv[:-1] + ["car,pedestrian"])
    assert status == 2 and "pedestrian" in error_line(err, "eval")
    rows, _, err = _eval_csv(capsys, argv + ["--allow-missing"], tmp_path)
    assert len(err) == 1 and err[0].startswith("dfrmot eval: warning: ") and "pedestrian" in err[0]
    assert int(rows["pedestrian", "COMBINED"]["Dets"]) == 0
    # no ground truth of the class either (0017 has no cars): an empty output is the right answer
    (res / "0017.txt").write_text("")
    rows, _, err = _eval_csv(capsys, ["eval", str(res), "--data", str(kitti_root), "--seqs", "17"], tmp_path)
    assert not err and int(rows["car", "COMBINED"]["GT_Dets"]) == 0


def test_per_seq_marks_sequences_without_ground_truth_of_the_class(kitti_root, tmp_path, capsys):
    res = _copy_ref(kitti_root, tmp_path / "r", ["0016"])
    (res / "0017.txt").write_text("0 1 Car -1 -1 -10 100 100 200 200 -1 -1 -1 -1000 -1000 -1000 -10 1\n")
    status, out, err = run_cli(capsys, ["eval", str(res), "--data", str(kitti_root), "--seqs", "16,17", "--per-seq"])
    assert status == 0 and not err
    lines = out.splitlines()
    row16 = [s for s in lines if s.startswith("0016")]
    row17 = [s for s in lines if s.startswith("0017")]
    assert len(row16) == 1 and len(row17) == 1 and not row16[0].startswith("0016*") and row17[0].startswith("0017*")
    note = [s for s in lines if s.startswith("*")]
    assert len(note) == 1 and "0017" in note[0] and "car" in note[0] and "false positive" in note[0]


# ---- item 4: track refuses a used --out unless --overwrite ----------------------------------------

@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    from dfrmot_jax.synthetic import make_scene

    return make_scene(tmp_path_factory.mktemp("eval_inputs") / "scene", n_sequences=2, n_frames=30, seed=4)


def _track(scene, out, *extra):
    return ["track", "--data", str(scene), "--det2d", "synth2d", "--det3d", "synth3d", "--out", str(out), *extra]


def test_track_refuses_a_non_empty_out(scene, tmp_path, capsys):
    out = tmp_path / "o"
    out.mkdir()
    (out / "0005.txt").write_text("stale\n")
    status, stdout, err = run_cli(capsys, _track(scene, out))
    line = error_line(err, "track")
    assert status == 2 and str(out) in line and "--overwrite" in line and "tracked" not in stdout
    assert sorted(p.name for p in out.iterdir()) == ["0005.txt"]


@pytest.mark.slow
def test_track_overwrite_removes_old_result_files_only(scene, tmp_path, capsys):
    out = tmp_path / "o"
    out.mkdir()                                               # empty: fine without --overwrite
    status, _, err = run_cli(capsys, _track(scene, out))
    assert status == 0 and sorted(p.name for p in out.iterdir()) == ["0000.txt", "0001.txt"]
    first = {p.name: p.read_text() for p in out.iterdir()}
    (out / "0000.txt").write_text("stale\n")
    for name in ("0005.txt", ".0001.txt.4242.tmp"):             # stale results, a temporary left by a kill
        (out / name).write_text("stale\n")
    for name in ("notes.txt", "0000.csv", "run.log"):           # the user's own files
        (out / name).write_text("mine\n")
    status, _, err = run_cli(capsys, _track(scene, out, "--overwrite"))
    assert status == 0 and not err
    assert sorted(p.name for p in out.iterdir()) == ["0000.csv", "0000.txt", "0001.txt", "notes.txt", "run.log"]
    assert {n: (out / n).read_text() for n in first} == first and (out / "notes.txt").read_text() == "mine\n"


# ---- item 6: every file TrackEval reads is scored as TrackEval scores it --------------------------

def _rows(kitti_root, seq):
    return [s.split() for s in (kitti_root / REF / f"{seq}.txt").read_text().splitlines() if s.strip()]


def _written_and_trackeval(kitti_root, tmp_path, capsys, files: dict):
    """Write ``files`` ({sequence: text}) as a result folder; (the folder, TrackEval's scores of them)."""
    res = tmp_path / "r"
    res.mkdir()
    for seq, text in files.items():
        (res / f"{seq}.txt").write_text(text)
    te = _trackeval(kitti_root, tmp_path / "te", files)
    capsys.readouterr()
    assert isinstance(te, dict), te
    return res, te


def test_rows_sorted_by_id_and_swapped_corners_score_like_trackeval(kitti_root, tmp_path, capsys):
    files = {}
    for seq in ("0001", "0002"):
        rows = sorted(_rows(kitti_root, seq), key=lambda r: (int(r[1]), int(r[0])))   # by id, not by frame
        for k, r in enumerate(rows):
            if k % 3 == 0:
                r[6], r[8] = r[8], r[6]                          # x2 < x1
            if k % 5 == 0:
                r[7], r[9] = r[9], r[7]                          # y2 < y1
        files[seq] = "".join(" ".join(r) + "\n" for r in rows)
    res, te = _written_and_trackeval(kitti_root, tmp_path, capsys, files)
    ours = evaluate_files(res, kitti_root, "car", ["0001", "0002"])
    assert_same(te, ours, "sorted by id, swapped corners")
    assert te["COMBINED"]["CLR_FP"] > 300 and te["COMBINED"]["CLR_TP"] > 1000     # the edits matter
    rows, _, err = _eval_csv(capsys, ["eval", str(res), "--data", str(kitti_root), "--seqs", "1,2"], tmp_path)
    assert not err
    assert float(rows["car", "COMBINED"]["HOTA"]) == pytest.approx(100 * np.mean(te["COMBINED"]["HOTA"]), abs=1e-9)
    assert int(rows["car", "COMBINED"]["IDSW"]) == te["COMBINED"]["IDSW"]


def test_other_files_trackeval_reads_score_like_trackeval(kitti_root, tmp_path, capsys):
    """Non-integer frames and ids (truncated toward zero), 19 columns in some frames and 18 in others,
    NaN in columns TrackEval does not use, junk in rows with a negative id (skipped unread),
    comma-separated rows of 10 columns."""
    rows = _rows(kitti_root, "0001")
    out = []
    for k, r in enumerate(rows):
        r = list(r)
        if k % 4 == 0:
            r[0] = f"{r[0]}.75"
        if k % 7 == 0:
            r[1] = f"{r[1]}.5"
        if k % 5 == 0:
            r[10], r[5] = "nan", "-inf"
        if int(float(r[0])) >= 200:
            r.append("7")
        out.append(" ".join(r))
        if k % 50 == 0:
            out.append(f"-{k} -{k % 3 + 1}.5 Bogus x y z" + " ?" * 12)     # skipped unread: any frame, any junk
    files = {"0001": "\n".join(out) + "\n",
             "0002": "".join(",".join(r[:10]) + "\n" for r in _rows(kitti_root, "0002"))}
    res, te = _written_and_trackeval(kitti_root, tmp_path, capsys, files)
    assert_same(te, evaluate_files(res, kitti_root, "car", ["0001", "0002"]), "lenient rows")
    status, _, err = run_cli(capsys, ["eval", str(res), "--data", str(kitti_root), "--seqs", "1,2"])
    assert status == 0 and not err


ROW = "{f} {i} {t} -1 -1 -10 {x1} 160 {x2} 288 -1 -1 -1 -1000 -1000 -1000 -10 1"
GOOD = ROW.format(f=0, i=1, t="Car", x1=296, x2=452)


def _line(f=3, i=2, t="Car", x1=600, x2=700, cols=None, **at):
    """A result row of sequence 0000 (154 frames); ``at`` {column index: token} replaces columns."""
    r = ROW.format(f=f, i=i, t=t, x1=x1, x2=x2).split()
    for k, v in at.items():
        r[int(k[1:])] = v
    return " ".join(r if cols is None else (r + ["7"] * cols)[:cols])


#: second line(s) after GOOD in 0000.txt -> "same" (read and scored as TrackEval does) or the field
#: refused, with the line; "!" marks what TrackEval reads too but cannot score (ours refuses, item 5)
VARIANTS = [
    (_line(f="3.75"), "same"), (_line(f="-0.5"), "same"), (_line(i="2.5"), "same"), (_line(i="-0.5"), "same"),
    (_line(x1=700, x2=600), "same"), (_line(c7="288", c9="160"), "same"), (_line(cols=10), "same"),
    (_line(cols=19), "same"), (_line(c5="nan", c10="inf", c17="-inf"), "same"),
    ("-5 -1 Bogus x y", "same"), ("-5 -3.5 Bogus", "same"), (_line(f=200, i=-1), "same"),
    (_line(f=5) + "\n" + _line(f=2, i=3), "same"), (_line(x2="1e39"), "same"),
    (_line(f="nan", i=-1), "frame"), (_line(f=-1), "frame"), (_line(f=154), "frame"), (_line(f="1e19"), "frame"),
    (_line(i="abc"), "track_id"), (_line(i="inf"), "track_id"), (_line(c10="abc"), "h"),
    (_line(cols=9), "columns"), ("1 -1", "columns"), (_line(f=0, cols=17), "columns"),
    (_line(t="Truck_2"), "type"), (_line(f=0, x1="nan"), "x1"), (_line(x1="0x1"), "x1"),
    (_line(i="9223372036854775808"), "!track_id"), (_line(i="18446744073709551616"), "!track_id"),
]


def test_we_read_exactly_what_trackeval_reads(kitti_root, tmp_path, capsys):
    """Each variant: TrackEval accepts it iff we do; accepted, the same scores; refused, ``dfrmot
    eval`` names file, line and field in one line, no traceback."""
    gt = prepare_gt(kitti_root, "car", ["0000"])
    problems = []
    for k, (rows, want) in enumerate(VARIANTS):
        text = GOOD + "\n" + rows + "\n"
        res = tmp_path / f"r{k}"
        res.mkdir()
        (res / "0000.txt").write_text(text)
        te = None if want.startswith("!") else _trackeval(kitti_root, tmp_path / f"te{k}", {"0000": text})
        capsys.readouterr()                                   # TrackEval prints its tracebacks
        if want == "same":
            if not isinstance(te, dict):
                problems.append(f"{rows!r}: TrackEval refuses it ({te!r})")
                continue
            try:
                assert_same(te, evaluate_files(res, gt), rows)
            except (AssertionError, ValueError) as e:
                problems.append(f"{rows!r}: {e}")
            continue
        if te is not None and not isinstance(te, Exception):
            problems.append(f"{rows!r}: TrackEval reads it")
        status, _, err = run_cli(capsys, ["eval", str(res), "--data", str(kitti_root), "--seqs", "0"])
        line = error_line(err, "eval") if status == 2 else f"exit {status}"
        if f"0000.txt:2: field '{want.lstrip('!')}'" not in line:
            problems.append(f"{rows!r}: {line}")
    assert not problems, "\n".join(problems)


def test_a_ragged_row_is_the_one_that_differs_from_the_files_own_column_count(tmp_path):
    """Issue 23, bug 1: in a file of 18-column rows, a frame whose first row has 17 columns is
    reported at that row (not at the next, correct one), with the file's count."""
    row = "{f} {i} Car -1 -1 -10 100 160 200 288 -1 -1 -1 -1000 -1000 -1000 -10"
    lines = [row.format(f=f, i=i) + " 1" for f in range(48) for i in (1, 2)]       # lines 1..96: 18 columns
    lines[94] = row.format(f=47, i=1)                                                  # line 95: 17 columns
    lines += [row.format(f=48, i=1) + " 1"]
    path = tmp_path / "0012.txt"
    path.write_text("\n".join(lines) + "\n")
    from dfrmot_jax.io.result_rows import read_result_rows

    with pytest.raises(KittiFormatError) as e:
        read_result_rows(path)
    msg = str(e.value)
    assert "0012.txt:95: field 'columns'" in msg, msg
    assert "17 columns" in msg and "the file's rows have 18" in msg and "line 96" in msg, msg
