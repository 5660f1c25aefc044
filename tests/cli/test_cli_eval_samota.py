"""``dfrmot eval --metrics kitti2d,ab3dmot --ab3dmot-iou 3d:0.25 [--seqmap FILE]``: AB3DMOT's figures in
the table and the CSV, and bad values refused with exit 2 and one message (no traceback)."""

import csv
import json
from pathlib import Path

import pytest

from dfrmot_jax.metrics.samota.table import AB3DMOT_COLUMNS, AB3DMOT_OTHER_COLUMNS
from dfrmot_jax.paths import default_data_root
from dfrmot_jax.testing.cli import error_line, run_cli

FIXTURES = default_data_root() / "reference" / "ab3dmot_eval"


def _rows(path):
    return {(r["tracker"], r["class"], r["seq"]): r for r in csv.DictReader(open(path))}


def _scene(tmp_path) -> tuple[Path, Path]:
    """A two-car ground truth of 4 frames and a result folder that tracks both (one as 2D-only rows)."""
    root = tmp_path / "data"
    (root / "label_02").mkdir(parents=True)
    labels, results = [], []
    for f in range(4):
        for tid, x in ((1, 0.0), (2, 4.0)):
            box = f"{100 + 40 * x} 150 {180 + 40 * x} 220"
            labels.append(f"{f} {tid} Car 0 0 -1 {box} 1.5 1.6 3.9 {x} 1.7 {10 + f} 0.2")
            three_d = "1.5 1.6 3.9 {} 1.7 {} 0.2".format(x, 10 + f) if tid == 1 else "-1 -1 -1 -1000 -1000 -1000 -10"
            results.append(f"{f} {tid + 10} Car -1 -1 -1 {box} {three_d} 0.8")
    (root / "label_02" / "0000.txt").write_text("\n".join(labels) + "\n")
    res = tmp_path / "res"
    res.mkdir()
    (res / "0000.txt").write_text("\n".join(results) + "\n")
    return root, res


def test_ab3dmot_columns_in_the_csv(tmp_path, capsys):
    root, res = _scene(tmp_path)
    out = tmp_path / "m.csv"
    status, stdout, err = run_cli(capsys, ["eval", res, "--data", root, "--metrics", "kitti2d,ab3dmot",
                                           "--per-seq", "--csv", out])
    assert status == 0, err
    assert "AB3DMOT KITTI, IoU 3d:0.25" in stdout and "sAMOTA" in stdout
    rows = _rows(out)
    comb = rows[("res", "car", "COMBINED")]
    # 3D: the 2D-only track is unmatched (4 FP, 4 FN); 8 objects give 7 recall points
    assert [comb[c] for c in ("ab3dmot_FP", "ab3dmot_FN", "ab3dmot_IDS", "ab3dmot_FRAG")] == ["4", "4", "0", "0"]
    assert float(comb["ab3dmot_MOTA"]) == pytest.approx(0.0) and float(comb["ab3dmot_MOTP"]) == pytest.approx(100.0)
    assert float(comb["MOTA"]) == pytest.approx(100.0)                     # TrackEval's 2D MOTA beside it
    assert all(rows[("res", "car", "0000")][c] == "" for c in AB3DMOT_COLUMNS)   # per sequence: none
    out2 = tmp_path / "m2.csv"
    status, stdout, err = run_cli(capsys, ["eval", res, "--data", root, "--metrics", "ab3dmot", "--ab3dmot-iou",
                                           "2d:0.5", "--csv", out2])
    assert status == 0, err
    only = _rows(out2)
    assert list(only) == [("res", "car", "COMBINED")]
    assert set(next(iter(only.values()))) == {"tracker", "class", "seq", "ab3dmot_sum", *AB3DMOT_COLUMNS,
                                              *AB3DMOT_OTHER_COLUMNS}
    r = only[("res", "car", "COMBINED")]
    assert (r["ab3dmot_FP"], r["ab3dmot_FN"], float(r["ab3dmot_MOTA"])) == ("0", "0", 100.0)
    assert float(r["sAMOTA"]) == pytest.approx(100 * 7 / 40)


def test_fixture_figures_through_the_cli(tmp_path, capsys, kitti_root):
    if not FIXTURES.is_dir():
        pytest.skip(f"AB3DMOT fixtures not found at {FIXTURES}")
    figs = [json.loads(s) for s in (FIXTURES / "figures.jsonl").read_text().splitlines() if s.strip()]
    want = next(f for f in figs if f["folder"] == "dfrmot_dfr2023_kitti_columns" and f["mode"] == "3D"
                and f["thres"] == 0.5 and f["seqmap"] == "val")
    out = tmp_path / "m.csv"
    status, stdout, err = run_cli(capsys, ["eval", FIXTURES / want["folder"], "--data", kitti_root, "--metrics",
                                           "kitti2d,ab3dmot", "--ab3dmot-iou", "3d:0.5", "--ab3dmot-sum",
                                           "sequential", "--seqmap",
                                           FIXTURES / "seqmaps" / "evaluate_tracking.seqmap.val", "--csv", out])
    assert status == 0, err
    r = _rows(out)[(want["folder"], "car", "COMBINED")]
    for col, key in (("sAMOTA", "sAMOTA"), ("AMOTA", "AMOTA"), ("AMOTP", "AMOTP"), ("ab3dmot_MOTA", "MOTA"),
                     ("ab3dmot_MOTP", "MOTP")):
        assert round(float(r[col]), 4) == want[key], col
    for key in ("IDS", "FRAG", "FP", "FN"):
        assert int(r[f"ab3dmot_{key}"]) == want[key], key
    assert "car, 11 sequences" in stdout


@pytest.mark.parametrize("argv, text", [
    (["--metrics", "kitti3d"], "metric family 'kitti3d'"),
    (["--metrics", ","], "no metric family given"),
    (["--ab3dmot-iou", "3d:1.5"], "threshold must be in (0, 1]"),
    (["--ab3dmot-iou", "bev:0.5"], "kind must be 2d or 3d"),
    (["--ab3dmot-iou", "0.25"], "expected 2d:T or 3d:T"),
    (["--seqmap", "MISSING"], "file not found"),
    (["--seqmap", "SEQMAP", "--seqs", "0000"], "--seqs and --seqmap both"),
    (["--seqmap", "BADMAP"], "bad.seqmap:2: field 'sequence': no ground truth for sequence 0005"),
])
def test_bad_values_exit_2(tmp_path, capsys, argv, text):
    root, res = _scene(tmp_path)
    (tmp_path / "ok.seqmap").write_text("0000 empty 000000 000004\n")
    (tmp_path / "bad.seqmap").write_text("0000 empty 000000 000004\n0005 empty 000000 000010\n")
    subst = {"MISSING": tmp_path / "none.seqmap", "SEQMAP": tmp_path / "ok.seqmap", "BADMAP": tmp_path / "bad.seqmap"}
    argv = [subst.get(a, a) for a in argv]
    status, _, err = run_cli(capsys, ["eval", res, "--data", root, "--metrics", "ab3dmot", *argv])
    assert status == 2
    assert text in error_line(err, "eval")


def test_bad_3d_fields_exit_2_located(tmp_path, capsys):
    root, res = _scene(tmp_path)
    lines = (res / "0000.txt").read_text().splitlines()
    f = lines[2].split()
    f[11] = "-1.6"                                          # w < 0 < l: not a box
    lines[2] = " ".join(f)
    (res / "0000.txt").write_text("\n".join(lines) + "\n")
    status, _, err = run_cli(capsys, ["eval", res, "--data", root, "--metrics", "ab3dmot"])
    assert status == 2
    assert "0000.txt:3: field 'w': width '-1.6' and length '3.9' differ in sign" in error_line(err, "eval")
    status, _, err = run_cli(capsys, ["eval", res, "--data", root, "--metrics", "ab3dmot", "--ab3dmot-iou", "2d:0.5"])
    assert status == 0, err                                 # 2D matching does not read the 3D fields


def test_eval_similarity_3d_matches_in_3d(tmp_path, capsys):
    """--similarity 3d: HOTA / CLEAR in 3D (the 2D-only track unmatched), as the metrics' own call."""
    from dfrmot_jax.metrics import evaluate_files

    root, res = _scene(tmp_path)
    rows = {}
    for sim in ("2d", "3d", "bev"):
        out = tmp_path / f"{sim}.csv"
        status, stdout, err = run_cli(capsys, ["eval", res, "--data", root, "--similarity", sim, "--csv", out])
        assert status == 0, err
        assert ("3D IoU" in stdout) == (sim == "3d")
        rows[sim] = _rows(out)[("res", "car", "COMBINED")]
        want = evaluate_files(res, root, "car", ["0000"], similarity=sim)["COMBINED"]
        assert float(rows[sim]["MOTA"]) == pytest.approx(100 * float(want["MOTA"]))
    assert float(rows["2d"]["MOTA"]) == pytest.approx(100.0)
    assert float(rows["3d"]["MOTA"]) == pytest.approx(0.0) and rows["3d"]["CLR_FP"] == "4"  # 4 matched, 4 FP + 4 FN
    assert rows["bev"]["CLR_FP"] == rows["3d"]["CLR_FP"]
    status, _, err = run_cli(capsys, ["eval", res, "--data", root, "--similarity", "4d"])
    assert status == 2 and "--similarity" in error_line(err, "eval")
