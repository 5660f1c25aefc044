"""AB3DMOT's figures on every Python: the evaluator's track-score ``sum`` as CPython <= 3.11 computes it
(``sequential``) and as CPython >= 3.12 does (``compensated``), each equal to its interpreter's figures.

* the sums themselves, bit for bit: against the running interpreter's ``sum`` and against the sums of
  CPython 3.11, 3.12 and 3.13 stored by ``scripts/python_sums_fixture.py``;
* the reference evaluator run on CPython 3.11 and 3.12 (``tests/fixtures/ab3dmot_eval/figures_py3*.jsonl``,
  its README says how): every figure to 1e-9, counts exact, pass by pass; swapped sums fail;
* the recall table on a hand-made case where a track's re-averaged score drifts below its own threshold.
"""

import json
import math
import random
import sys
from pathlib import Path

import numpy as np
import pytest

from dfrmot_jax.metrics.samota.evaluate import evaluate_ab3dmot_files
from dfrmot_jax.metrics.samota.sums import DEFAULT_SUM, group_sums, other_sum, parse_sum, python_sum, repeat_sums
from dfrmot_jax.metrics.samota.table import RECALL_TABLE_COLUMNS, other_sum_line, recall_table
from dfrmot_jax.paths import default_data_root
from dfrmot_jax.testing.cli import error_line, run_cli

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures" / "ab3dmot_eval"
REFERENCE = default_data_root() / "reference"
#: the sum each stored interpreter's evaluator used
SUM_OF = {"3.11": "sequential", "3.12": "compensated", "3.13": "compensated"}
RUNNING = "sequential" if sys.version_info < (3, 12) else "compensated"


# ---------------------------------------------------------------- the sums, bit for bit

def _stored():
    return json.loads((FIXTURES / "python_sums.json").read_text())


def test_default_and_names():
    assert DEFAULT_SUM == "compensated"
    assert parse_sum(" Sequential ") == "sequential" and other_sum("sequential") == "compensated"
    with pytest.raises(ValueError, match="expected compensated or sequential"):
        parse_sum("fsum")


@pytest.mark.parametrize("version", ["3.11", "3.12", "3.13"])
def test_sums_equal_each_interpreters_stored_sums(version):
    doc = _stored()
    got_version = next(v for v in doc["sums"] if v.startswith(version + "."))
    want = np.array(doc["sums"][got_version])
    cases = doc["cases"]
    mode = SUM_OF[version]
    values = np.concatenate([np.array(c, dtype=np.float64) for c in cases])
    group = np.repeat(np.arange(len(cases)), [len(c) for c in cases])
    assert np.array_equal(group_sums(values, group, len(cases), mode), want)        # bit for bit, all at once
    assert [python_sum(c, mode) for c in cases] == list(want)
    same = [i for i, c in enumerate(cases) if len(set(c)) == 1]                       # the evaluator's re-averages
    reps = repeat_sums(np.array([cases[i][0] for i in same]), np.array([len(cases[i]) for i in same]), mode)
    assert np.array_equal(reps, want[same])
    # the other behaviour is another one: it differs on many of these cases (a swap would be seen)
    assert sum(python_sum(c, other_sum(mode)) != s for c, s in zip(cases, want)) > 50


def test_sums_equal_the_running_interpreters_sum():
    rnd = random.Random(11)
    for _ in range(300):
        n = rnd.choice([1, 2, 5, 40, 265])
        v = [rnd.uniform(-1, 1) * 10 ** rnd.randint(-8, 8) for _ in range(n)] if rnd.random() < 0.5 \
            else [round(rnd.uniform(0, 15), 4)] * n
        assert python_sum(v, RUNNING) == sum(v)


def test_compensated_is_not_fsum():
    """CPython 3.12's sum is Neumaier's compensated sum, not the correctly rounded math.fsum (the stored
    cases end with one where they differ: CPython 3.12 and 3.13 give the compensated sum)."""
    doc = _stored()
    last = doc["cases"][-1]
    assert python_sum(last, "compensated") != math.fsum(last)
    for version, sums in doc["sums"].items():
        assert sums[-1] == python_sum(last, SUM_OF[version[:4]]), version


def test_the_issues_example_drifts_only_sequentially():
    """A 265-row track of mean 11.670440754716987: its re-average drifts on CPython 3.11, not on 3.12."""
    m = 11.670440754716987
    seq = repeat_sums(np.array([m]), np.array([265]), "sequential")[0] / 265
    comp = repeat_sums(np.array([m]), np.array([265]), "compensated")[0] / 265
    assert seq == 11.670440754716914 and seq < m
    assert comp == m


# ---------------------------------------------------------------- the reference evaluator on two interpreters

def _runs():
    params = []
    for py in ("311", "312"):
        path = FIXTURES / f"figures_py{py}.jsonl"
        for line in path.read_text().splitlines() if path.is_file() else ():
            f = json.loads(line)
            params.append(pytest.param(py, f, id=f"py{py}-{Path(f['folder']).name}-{f['mode']}{f['thres']}-{f['seqmap']}",
                                       marks=[pytest.mark.slow] if f["seqmap"] == "all" else []))   # 21 sequences
    return params


def _evaluate(f, kitti_root, sum_mode):
    folder = REFERENCE / f["folder"]
    if not folder.is_dir():
        pytest.skip(f"reference folder not found: {folder}")
    seqmap = REFERENCE / "ab3dmot_eval" / "seqmaps" / f"evaluate_tracking.seqmap.{f['seqmap']}"
    return evaluate_ab3dmot_files(folder, kitti_root, "car", iou=f"{f['mode'].lower()}:{f['thres']}", seqmap=seqmap,
                                  sum_mode=sum_mode)


COUNTS = ("IDS", "FRAG", "FP", "FN", "TP", "n_recall_points")
RATIOS = ("sAMOTA", "AMOTA", "AMOTP", "MOTA", "MOTP", "recall", "precision", "best_threshold")
PASS_RATIOS = ("threshold", "MOTA", "MOTP", "sMOTA", "recall", "precision")
PASS_COUNTS = ("TP", "FP", "FN", "IDS", "FRAG")


@pytest.mark.parametrize("py, fig", _runs())
def test_each_sum_equals_its_interpreters_evaluator(py, fig, kitti_root):
    mode = SUM_OF[f"{py[0]}.{py[1:]}"]
    r = _evaluate(fig, kitti_root, mode)
    assert {k: r[k] for k in COUNTS} == {k: fig[k] for k in COUNTS}
    for k in RATIOS:
        assert r[k] == pytest.approx(fig[k], abs=1e-9, rel=0), k
    at = r["all_tracks"]
    for k, v in fig["all_tracks"].items():
        assert at[k] == (v if isinstance(v, int) else pytest.approx(v, abs=1e-9, rel=0)), k
    passes = fig["passes"]
    assert len(r["passes"]["threshold"]) == len(passes)
    for j, p in enumerate(passes):
        assert r["passes"]["recall_point"][j] == pytest.approx(p["r"], abs=1e-12)
        assert {k: r["passes"][k][j] for k in PASS_COUNTS} == {k: p[k] for k in PASS_COUNTS}, j
        for k in PASS_RATIOS:
            assert r["passes"][k][j] == pytest.approx(p[k], abs=1e-9, rel=0), (j, k)


def _differing_runs():
    """The runs whose figures differ between the two interpreters (a swap must be caught there)."""
    runs = {py: {(f["folder"], f["mode"], f["thres"], f["seqmap"]): f for f in (p.values[1] for p in _runs()
                                                                                 if p.values[0] == py)}
            for py in ("311", "312")}
    return [pytest.param(runs["311"][k], runs["312"][k], id=f"{Path(k[0]).name}-{k[1]}{k[2]}-{k[3]}",
                         marks=[pytest.mark.slow] if k[3] == "all" else [])
            for k in runs["311"] if k in runs["312"] and runs["311"][k]["sAMOTA"] != runs["312"][k]["sAMOTA"]]


@pytest.mark.parametrize("f311, f312", _differing_runs())
def test_swapped_sums_fail(f311, f312, kitti_root):
    """Each sum against the other interpreter's figures: they differ (the test above would fail on a swap)."""
    assert _evaluate(f311, kitti_root, "compensated")["sAMOTA"] != pytest.approx(f311["sAMOTA"], abs=1e-9)
    assert _evaluate(f312, kitti_root, "sequential")["sAMOTA"] != pytest.approx(f312["sAMOTA"], abs=1e-9)


def test_the_3d_fixtures_differ_between_interpreters():
    assert len(_differing_runs()) >= 2 or not (FIXTURES / "figures_py312.jsonl").is_file()


# ---------------------------------------------------------------- the recall table on a hand-made drift

SCORE = "1.0111"            # 40 copies: mean 1.0110999999999994 on 3.11, whose re-average drifts below it
N_CAR = 40


def _drift_scene(tmp_path) -> tuple[Path, Path]:
    """One car over 40 frames tracked by one track of constant score 1.0111, and a van (ignored ground
    truth: the neighbouring class) over 10 frames covered by a track of score 0.5."""
    root = tmp_path / "data"
    (root / "label_02").mkdir(parents=True)
    labels, rows = [], []
    for f in range(N_CAR):
        labels.append(f"{f} 1 Car 0 0 -1 100 150 180 220 1.5 1.6 3.9 0.0 1.7 {10 + f} 0.2")
        rows.append(f"{f} 7 Car -1 -1 -1 100 150 180 220 1.5 1.6 3.9 0.0 1.7 {10 + f} 0.2 {SCORE}")
        if f < 10:
            labels.append(f"{f} 2 Van 0 0 -1 400 150 480 220 1.9 1.8 4.5 6.0 1.8 20 0.2")
            rows.append(f"{f} 8 Car -1 -1 -1 400 150 480 220 1.9 1.8 4.5 6.0 1.8 20 0.2 0.5")
    (root / "label_02" / "0000.txt").write_text("\n".join(labels) + "\n")
    res = tmp_path / "res"
    res.mkdir()
    (res / "0000.txt").write_text("\n".join(rows) + "\n")
    return root, res


def test_the_recall_table_shows_the_drift_and_the_ignored_matches(tmp_path):
    root, res = _drift_scene(tmp_path)
    r = evaluate_ab3dmot_files(res, root, "car", ["0000"], iou="2d:0.5", other=True)
    assert r["sum"] == "compensated" and r["other"]["sum"] == "sequential"
    t = recall_table(r, tracker="res")
    assert list(t.columns) == ["tracker", "sum", *RECALL_TABLE_COLUMNS]
    seq, comp = t[t["sum"] == "sequential"], t[t["sum"] == "compensated"]
    mean_seq = 1.0110999999999994                     # the car track's first mean on 3.11
    at_own = seq[seq["threshold"] == mean_seq]
    assert len(at_own) and (at_own["drifted"] == 1).all() and (at_own["TP"] == 0).all()   # dropped at its own mean
    assert (comp["drifted"] == 0).all()
    car = comp[comp["threshold"] == 1.0111]
    assert len(car) and (car["TP"] == N_CAR).all() and (car["TP_ignored"] == 0).all()
    low = t[t["threshold"] == 0.5]                    # the van's track kept: its 10 matches are to ignored GT
    assert set(low["sum"]) == {"compensated", "sequential"}
    assert (low["TP_ignored"] == 10).all() and (low["drifted"] == 0).all()
    # the van's matches count in TP, and so in the recall that places the points, not in sMOTA's denominator
    assert r["all_tracks"]["TP"] == N_CAR + 10 and r["n_objects"] == N_CAR
    assert r["sAMOTA"] > r["other"]["sAMOTA"]
    line = other_sum_line(r, "res")
    assert line.startswith("res: with the sequential sum") and "CPython <= 3.11" in line


def test_recall_table_and_other_sum_through_the_cli(tmp_path, capsys):
    root, res = _drift_scene(tmp_path)
    out = tmp_path / "points.csv"
    status, stdout, err = run_cli(capsys, ["eval", res, "--data", root, "--ab3dmot-iou", "2d:0.5", "--recall-table",
                                           out])
    assert status == 0, err
    assert "compensated sum" in stdout and "res car: with the sequential sum" in stdout
    import pandas as pd
    t = pd.read_csv(out)
    assert set(t["sum"]) == {"compensated", "sequential"} and t["drifted"].max() == 1
    status, stdout, err = run_cli(capsys, ["eval", res, "--data", root, "--ab3dmot-iou", "2d:0.5", "--metrics",
                                           "ab3dmot", "--ab3dmot-sum", "sequential"])
    assert status == 0, err
    assert "sequential sum" in stdout and "res car: with the compensated sum" in stdout
    status, _, err = run_cli(capsys, ["eval", res, "--data", root, "--recall-table", ""])
    assert status == 2 and "expected a file name" in error_line(err, "eval")
    status, _, err = run_cli(capsys, ["eval", res, "--data", root, "--ab3dmot-sum", "fsum"])
    assert status == 2 and "invalid choice" in error_line(err, "eval")


def test_recall_points_on_the_compare_page(tmp_path, capsys):
    root, res = _drift_scene(tmp_path)
    page, points = tmp_path / "c.html", tmp_path / "c.csv"
    status, stdout, err = run_cli(capsys, ["compare", res, res, "--data", root, "--metrics", "kitti2d,ab3dmot",
                                           "--ab3dmot-iou", "2d:0.5", "--ab3dmot-resamples", "3", "--resamples", "50",
                                           "--html", page, "--recall-table", points])
    assert status == 0, err
    assert "A: with the sequential sum" in stdout and "B: with the sequential sum" in stdout
    html = page.read_text()
    assert "AB3DMOT's recall points" in html and "TP_ignored" in html and "drifted" in html
    import pandas as pd
    t = pd.read_csv(points)
    assert set(t["tracker"]) == {"A", "B"} and set(t["sum"]) == {"compensated", "sequential"}
