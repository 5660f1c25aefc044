"""``dfrmot compare`` and the paired bootstrap over sequences (issue 31): a resample's figures equal
scoring the resampled set of result files directly; an output against itself has the interval [0, 0];
on generated outputs with a known difference the 95 % interval covers it about 95 % of the time."""

from __future__ import annotations

import shutil

import numpy as np
import pandas as pd
import pytest

import dfrmot_jax as dm
from dfrmot_jax.trackers.dfr.config import Options, Params, stack_params
from dfrmot_jax.metrics import evaluate_files, prepare_gt
from dfrmot_jax.metrics.kitti2d.bootstrap import (BOOTSTRAP_FIELDS, intervals, paired_bootstrap,
                                                  resample_indices, seq_fields)
from dfrmot_jax.metrics.kitti2d.table import summary_row
from dfrmot_jax.metrics.kitti2d.tracker_files import read_tracker_files
from dfrmot_jax.report.compare import COLUMNS
from dfrmot_jax.trackers.dfr.results import write_lane
from dfrmot_jax.synthetic import make_scene
from dfrmot_jax.testing.cli import error_line, run_cli

SETTINGS = (Params(score_2d=0.5, a_l=8.0), Params(score_2d=0.3, a_l=4.0, epsilon=5))


@pytest.fixture(scope="module")
def outputs(tmp_path_factory):
    """A synthetic root of 6 sequences and the result folders of two settings."""
    base = tmp_path_factory.mktemp("compare")
    root = make_scene(base / "data", n_sequences=6, n_frames=60, n_cars=5, seed=8)
    split = dm.load_split(root, "synth2d", "synth3d", "car")
    res = dm.track(split, stack_params(list(SETTINGS)), Options())
    folders = []
    for b in range(2):
        out = base / f"out{b}"
        write_lane(out, split, res.frames, res.options, res.ids[b], res.lane_boxes(b))
        folders.append(out)
    return root, folders


def test_a_resample_equals_scoring_the_resampled_files(outputs, tmp_path):
    """Sequence k of a resample is a copy of the drawn sequence (labels and results), renamed: scoring
    that folder directly gives the bootstrap's figures, to 1e-9 and exactly on counts."""
    root, folders = outputs
    gt = prepare_gt(root, "car")
    fields = [seq_fields(gt, read_tracker_files(d, gt)) for d in folders]
    idx = resample_indices(len(gt.sequences), 3, seed=5)
    idx[0] = [0, 0, 0, 1, 5, 5]                      # a sequence drawn three times
    boot_a, boot_b, _ = paired_bootstrap(fields[0], fields[1], idx=idx)
    for r, draw in enumerate(idx):
        there = tmp_path / f"r{r}"
        (there / "data" / "label_02").mkdir(parents=True)
        for k, s in enumerate(draw):
            name = gt.sequences[s]
            shutil.copy(root / "label_02" / f"{name}.txt", there / "data" / "label_02" / f"{k:04d}.txt")
            for b, d in enumerate(folders):
                (there / f"out{b}").mkdir(exist_ok=True)
                shutil.copy(d / f"{name}.txt", there / f"out{b}" / f"{k:04d}.txt")
        for b, boot in enumerate((boot_a, boot_b)):
            direct = summary_row(evaluate_files(there / f"out{b}", there / "data", "car")["COMBINED"])
            for f in BOOTSTRAP_FIELDS:
                assert boot[f][r] == pytest.approx(direct[f], abs=1e-9), (r, b, f)
                if f in ("IDSW", "CLR_FP", "CLR_FN", "Frag"):
                    assert boot[f][r] == direct[f]


def test_an_output_against_itself_has_the_interval_zero(outputs, tmp_path, capsys):
    root, folders = outputs
    csv = tmp_path / "self.csv"
    status, out, err = run_cli(capsys, ["compare", folders[0], folders[0], "--data", root, "--resamples", "500",
                                        "--csv", csv])
    assert status == 0, err
    t = pd.read_csv(csv, dtype={"seq": str})
    assert tuple(t.columns) == COLUMNS
    assert (t["diff"] == 0).all() and (t["a"] == t["b"]).all()
    comb = t[t["seq"] == "COMBINED"]
    assert len(comb) == len(BOOTSTRAP_FIELDS) and (comb["resamples"] == 500).all()
    assert (comb["ci_low"] == 0).all() and (comb["ci_high"] == 0).all() and (comb["p_b_better"] == 0.5).all()
    assert t.loc[t["seq"] != "COMBINED", "ci_low"].isna().all()
    assert "500 resamples" in out


def test_compare_prints_and_writes_the_difference(outputs, tmp_path, capsys):
    root, folders = outputs
    csv = tmp_path / "ab.csv"
    status, out, err = run_cli(capsys, ["compare", folders[0], folders[1], "--data", root, "--resamples", "2000",
                                        "--seed", "3", "--csv", csv])
    assert status == 0, err
    t = pd.read_csv(csv, dtype={"seq": str})
    gt = prepare_gt(root, "car")
    a, b = (summary_row(evaluate_files(d, gt)["COMBINED"]) for d in folders)
    comb = t[t["seq"] == "COMBINED"].set_index("metric")
    for f in BOOTSTRAP_FIELDS:
        assert comb.loc[f, "a"] == pytest.approx(a[f], abs=1e-9) and comb.loc[f, "b"] == pytest.approx(b[f], abs=1e-9)
        assert comb.loc[f, "ci_low"] <= comb.loc[f, "ci_high"]
    assert comb.loc["HOTA", "diff"] != 0
    line = next(s for s in out.splitlines() if s.startswith("HOTA "))
    assert f"{b['HOTA'] - a['HOTA']:+.2f}" in line
    # seeded: the same resamples, the same interval
    status, _, _ = run_cli(capsys, ["compare", folders[0], folders[1], "--data", root, "--resamples", "2000",
                                    "--seed", "3", "--csv", tmp_path / "again.csv"])
    pd.testing.assert_frame_equal(t, pd.read_csv(tmp_path / "again.csv", dtype={"seq": str}))


@pytest.mark.parametrize("argv, fragment", [
    (["compare", "{missing}", "{b}"], "not a directory"),
    (["compare", "{a}", "{b}", "--resamples", "0"], "expected 1 to 10,000,000 resamples"),
    (["compare", "{a}", "{empty}"], "no result file for 6 of 6 sequences"),
])
def test_bad_input_is_one_line_and_exit_2(outputs, tmp_path, capsys, argv, fragment):
    root, folders = outputs
    (tmp_path / "empty").mkdir()
    names = {"a": folders[0], "b": folders[1], "missing": tmp_path / "nope", "empty": tmp_path / "empty"}
    status, _, err = run_cli(capsys, [a.format(**names) for a in argv] + ["--data", root])
    assert status == 2
    assert fragment in error_line(err, "compare")


@pytest.mark.parametrize("flags, fragment", [
    (["--csv", ""], "argument --csv: '': expected a file name"),
    (["--html", " "], "argument --html: ' ': expected a file name"),
    (["--csv", "{tmp}/x", "--html", "{tmp}/x"], "name one file: the page would replace the table"),
    (["--csv", "{tmp}/x", "--html", "{tmp}/sub/../x"], "name one file"),
    (["--metrics", "ab3dmot", "--ab3dmot-resamples", "10000000"],
     "argument --ab3dmot-resamples: expected 1 to 20,000 resamples, got 10,000,000"),
])
def test_output_files_are_named_and_distinct(tmp_path, capsys, flags, fragment):
    """``--csv ''`` / ``--html ''`` wrote nothing and said nothing; ``--csv X --html X`` let the page
    replace the table; ``--ab3dmot-resamples 10000000`` (0.2 s each) was accepted and ran for days. All
    refused before anything is read."""
    (tmp_path / "sub").mkdir()
    argv = ["compare", tmp_path, tmp_path] + [f.format(tmp=tmp_path) for f in flags]
    status, out, err = run_cli(capsys, argv)
    assert status == 2 and fragment in error_line(err, "compare", alone=True) and not out
    assert not (tmp_path / "x").exists()


@pytest.mark.slow
def test_the_interval_covers_a_known_difference_about_95_percent_of_the_time(tmp_path):
    """A pool of 120 generated sequences tracked with two settings is the population; its combined
    HOTA difference is the truth. 200 times, 20 sequences are drawn from the pool and the paired
    bootstrap's 95 % interval (1,000 resamples) is checked against the truth. The percentile bootstrap
    of a ratio over 20 units covers a little less than its level; the count must lie in [170, 198]."""
    root = make_scene(tmp_path / "pool", n_sequences=120, n_frames=40, n_cars=5, seed=21)
    split = dm.load_split(root, "synth2d", "synth3d", "car")
    res = dm.track(split, stack_params(list(SETTINGS)), Options())
    gt = prepare_gt(root, "car")
    fields = []
    for b in range(2):
        out = tmp_path / f"out{b}"
        write_lane(out, split, res.frames, res.options, res.ids[b], res.lane_boxes(b))
        fields.append(seq_fields(gt, read_tracker_files(out, gt)))
    everything = np.arange(len(gt.sequences))[None]
    whole_a, whole_b, _ = paired_bootstrap(fields[0], fields[1], idx=everything)
    truth = float(whole_b["HOTA"][0] - whole_a["HOTA"][0])
    assert abs(truth) > 0.1, "the two settings must differ for the test to mean anything"
    rng = np.random.default_rng(0)
    covered = 0
    for trial in range(200):
        pick = rng.choice(len(gt.sequences), size=20, replace=False)
        fa = {f: v[pick] for f, v in fields[0].items()}
        fb = {f: v[pick] for f, v in fields[1].items()}
        ba, bb, _ = paired_bootstrap(fa, fb, 1000, seed=trial)
        ci = intervals(ba, bb)["HOTA"]
        covered += ci["ci_low"] <= truth <= ci["ci_high"]
    print(f"covered {covered} of 200 (truth {truth:+.3f} HOTA)")
    assert 170 <= covered <= 198, covered


def test_resamples_as_counts_equal_the_exact_recombination(outputs):
    """The reports' path (sums as matrix products with each resample's counts, all configs at once)
    equals combining the drawn sequences one by one, for every field."""
    from dfrmot_jax.metrics.kitti2d.bootstrap import counts_of, resampled_figure

    root, folders = outputs
    gt = prepare_gt(root, "car")
    fa, fb = (seq_fields(gt, read_tracker_files(d, gt)) for d in folders)
    boot_a, boot_b, idx = paired_bootstrap(fa, fb, 64, seed=2)
    arrays = {f: np.stack([fa[f], fb[f]]) for f in fa}
    counts = counts_of(idx, len(gt.sequences))
    assert (counts.sum(axis=1) == len(gt.sequences)).all()
    for f in BOOTSTRAP_FIELDS:
        got = resampled_figure(arrays, counts, f, per_step=10)
        np.testing.assert_allclose(got[0], boot_a[f], rtol=0, atol=1e-9, err_msg=f)
        np.testing.assert_allclose(got[1], boot_b[f], rtol=0, atol=1e-9, err_msg=f)


@pytest.mark.slow
def test_report_intervals_of_a_sweep(tmp_path):
    """In a sweep's report: a copy of the best config is not distinguishable from it, the best against
    itself as baseline has the interval [0, 0], and the report prints and stores the figures."""
    from dfrmot_jax.report.intervals import report_intervals
    from dfrmot_jax.sweep import run_sweep, sweep_report

    root = make_scene(tmp_path / "scene", n_sequences=5, n_frames=50, n_cars=4, seed=12)
    df = run_sweep({"name": "iv", "chunk": 8, "data": {"root": str(root), "det2d": "synth2d", "det3d": "synth3d"},
                    "params": {"a_l": [1.0, 4.0, 8.0], "score_2d": [0.2, 0.6]}}, tmp_path / "sweep", progress=False,
                   workers=0, log=lambda m: None)
    comb = df[df["sequence"] == "COMBINED"]
    best = int(comb.loc[comb["HOTA"].idxmax(), "config"])
    twin = df[df["config"] == best].copy()
    twin["config"] = int(df["config"].max()) + 1
    doubled = pd.concat([df, twin], ignore_index=True)
    iv = report_intervals(doubled, "HOTA", baseline_config=best, resamples=300)
    assert iv["best_config"] in (best, int(twin["config"].iloc[0]))
    assert {best, int(twin["config"].iloc[0])} <= set(iv["not_distinguishable"])
    assert iv["best_minus_baseline"] == [0.0, 0.0] and iv["p_best_better"] == 0.5
    worst = int(comb.loc[comb["HOTA"].idxmin(), "config"])
    assert worst not in iv["not_distinguishable"]          # 2 HOTA below the best on every resample
    rep = sweep_report(tmp_path / "sweep")
    assert "not distinguishable from the best" in rep.text
    assert rep.summary["bootstrap"]["not_distinguishable_from_best"] == len(rep.intervals["not_distinguishable"])


@pytest.mark.slow
def test_compare_page_opens_in_chromium_with_the_switches_the_metrics_count(outputs, tmp_path, capsys):
    """``--html``: one self-contained page; in headless Chromium its whole-sequence timelines hold one
    switch mark per identity switch the metrics count for that sequence, for A and B."""
    webdriver = pytest.importorskip("selenium.webdriver", reason="selenium is a dev dependency: pip install -e .[dev]")
    from selenium.webdriver.chrome.service import Service

    from test_report_html import _chromium

    root, folders = outputs
    page, csv = tmp_path / "cmp.html", tmp_path / "cmp.csv"
    status, _, err = run_cli(capsys, ["compare", folders[0], folders[1], "--data", root, "--resamples", "200",
                                      "--csv", csv, "--html", page])
    assert status == 0, err
    text = page.read_text()
    assert "<script" not in text and "src=" not in text and "href=" not in text      # nothing beside the file
    t = pd.read_csv(csv, dtype={"seq": str})
    browser, driver_path = _chromium()
    opts = webdriver.ChromeOptions()
    opts.binary_location = browser
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", f"--user-data-dir={tmp_path / 'profile'}"):
        opts.add_argument(a)
    drv = webdriver.Chrome(service=Service(executable_path=driver_path), options=opts)
    try:
        drv.get(page.resolve().as_uri())
        seq = drv.execute_script("return document.querySelector('figure.whole').dataset.seq")
        marks = drv.execute_script("""
            const out = {};
            for (const s of document.querySelectorAll('figure.whole svg.timeline')) {
                const drawn = Array.from(s.querySelectorAll('line.switch')).filter(l => l.getBBox().height > 0);
                out[s.dataset.output] = drawn.length; }
            return out;""")
        views = drv.execute_script("return document.querySelectorAll('svg.bev').length")
    finally:
        drv.quit()
    idsw = t[(t["seq"] == seq) & (t["metric"] == "IDSW")].iloc[0]
    assert marks == {"A": int(idsw["a"]), "B": int(idsw["b"])}
    assert marks["A"] + marks["B"] > 0, "no switch in the sequence: the count proves nothing"
    assert views >= 2


@pytest.mark.slow
def test_sweep_configs_are_compared_as_their_rows_say(tmp_path, capsys):
    """``DIR:best`` and ``DIR:baseline`` (and ``DIR:config=N``) are tracked alone on the directory's data
    and written: their figures are the table's COMBINED rows."""
    from dfrmot_jax.sweep import run_sweep

    root = make_scene(tmp_path / "scene", n_sequences=3, n_frames=50, n_cars=4, seed=4)
    df = run_sweep({"name": "refs", "chunk": 8, "data": {"root": str(root), "det2d": "synth2d", "det3d": "synth3d"},
                    "baseline": {"preset": "dfr2023"}, "params": {"a_l": [1.0, 8.0], "epsilon": [3, 30]},
                    "options": {"output": ["detections", "filtered"]}},
                   tmp_path / "sweep", progress=False, workers=0, log=lambda m: None)
    comb = df[df["sequence"] == "COMBINED"].set_index("config")
    best = int(comb["HOTA"].idxmax())
    base = int(comb.index[comb["baseline"]][0])
    other = int(comb["HOTA"].idxmin())
    csv = tmp_path / "refs.csv"
    d = tmp_path / "sweep"
    status, out, err = run_cli(capsys, ["compare", f"{d}:baseline", f"{d}:best", "--data", root, "--resamples", "100",
                                        "--csv", csv])
    assert status == 0, err
    assert f"config {best} " in out and f"config {base} " in out
    t = pd.read_csv(csv, dtype={"seq": str})
    row = t[(t["seq"] == "COMBINED") & (t["metric"] == "HOTA")].iloc[0]
    assert row["a"] == pytest.approx(comb.at[base, "HOTA"], abs=1e-9)
    assert row["b"] == pytest.approx(comb.at[best, "HOTA"], abs=1e-9)
    status, _, err = run_cli(capsys, ["compare", f"{d}:config={other}", f"{d}:best", "--data", root, "--resamples",
                                      "100", "--csv", csv])
    assert status == 0, err
    row = pd.read_csv(csv, dtype={"seq": str}).query("seq == 'COMBINED' and metric == 'MOTA'").iloc[0]
    assert row["a"] == pytest.approx(comb.at[other, "MOTA"], abs=1e-9)
    status, _, err = run_cli(capsys, ["compare", f"{d}:config=999", f"{d}:best", "--data", root])
    assert status == 2 and "no config 999" in error_line(err, "compare")
    status, _, err = run_cli(capsys, ["compare", f"{tmp_path}:best", f"{d}:best", "--data", root])
    assert status == 2 and "no manifest.json" in error_line(err, "compare")


@pytest.mark.slow
def test_an_ab3dmot_resample_is_the_resampled_files_scored(outputs, tmp_path, capsys):
    """AB3DMOT's figures of a resample (a sequence drawn twice is two sequences) equal scoring a folder
    of the resampled files renamed, and ``--metrics ab3dmot`` adds its rows with their intervals."""
    from dfrmot_jax.metrics.samota.evaluate import evaluate_ab3dmot_files
    from dfrmot_jax.metrics.samota.table import ab3dmot_columns
    from dfrmot_jax.report.compare_samota import split_figures

    root, folders = outputs
    names = ["0002", "0002", "0000", "0005", "0005", "0005"]
    got = split_figures(root, "car", names, folders, "3d:0.25")
    there = tmp_path / "r"
    (there / "data" / "label_02").mkdir(parents=True)
    for k, name in enumerate(names):
        shutil.copy(root / "label_02" / f"{name}.txt", there / "data" / "label_02" / f"{k:04d}.txt")
        for b, d in enumerate(folders):
            (there / f"out{b}").mkdir(exist_ok=True)
            shutil.copy(d / f"{name}.txt", there / f"out{b}" / f"{k:04d}.txt")
    for b in range(2):
        direct = ab3dmot_columns(evaluate_ab3dmot_files(there / f"out{b}", there / "data", "car", iou="3d:0.25"))
        assert got[b] == pytest.approx(direct, abs=1e-9, nan_ok=True)     # other_*: NaN in both (not computed)
    csv = tmp_path / "c.csv"
    status, out, err = run_cli(capsys, ["compare", folders[0], folders[1], "--data", root, "--resamples", "100",
                                        "--metrics", "kitti2d,ab3dmot", "--ab3dmot-resamples", "12", "--csv", csv])
    assert status == 0, err
    t = pd.read_csv(csv, dtype={"seq": str})
    ab = t[t["metric"].str.startswith("sAMOTA@")]
    assert len(ab) == 1 and ab["resamples"].iloc[0] == 12 and ab["ci_low"].iloc[0] <= ab["ci_high"].iloc[0]
    assert "12 paired resamples, each rescored" in out


@pytest.mark.slow
def test_a_sweep_of_an_older_results_version_is_compared_as_the_report_reads_it(tmp_path, capsys):
    """``compare DIR:best`` of a directory whose table lacks the parameters and options added since
    (kf_q3, kf_r3, the weak margins, assign: ``tests/fixtures/sweep_v1``) was ``internal error:
    KeyError: 'kf_q3'`` where ``report`` read it: they are their defaults, the rows' figures scored."""
    import json
    from pathlib import Path

    from dfrmot_jax.table_columns import LATE_OPTIONS, LATE_PARAMS
    from dfrmot_jax.report.stored import load_results

    v1 = Path(__file__).resolve().parents[1] / "fixtures" / "sweep_v1"
    scene = json.loads((v1 / "scene.json").read_text())["make_scene"]
    root = make_scene(tmp_path / "scene", **{k: v for k, v in scene.items() if k != "directory"})
    d = tmp_path / "sweep"
    shutil.copytree(v1, d)
    manifest = json.loads((d / "manifest.json").read_text())
    manifest["data"]["root"] = str(root)
    (d / "manifest.json").write_text(json.dumps(manifest))
    df = load_results(d)
    assert not set(LATE_PARAMS) & set(df.columns) and not set(LATE_OPTIONS) & set(df.columns)
    comb = df[df["sequence"] == "COMBINED"].set_index("config")
    csv = tmp_path / "t.csv"
    status, out, err = run_cli(capsys, ["compare", f"{d}:baseline", f"{d}:best", "--data", root, "--resamples", "50",
                                        "--csv", csv])
    assert status == 0, err
    row = pd.read_csv(csv, dtype={"seq": str}).query("seq == 'COMBINED' and metric == 'HOTA'").iloc[0]
    assert row["a"] == pytest.approx(comb.loc[comb["baseline"], "HOTA"].iloc[0], abs=1e-9)
    assert row["b"] == pytest.approx(comb["HOTA"].max(), abs=1e-9)


@pytest.fixture(scope="module")
def two_classes(tmp_path_factory):
    """A sweep over car and pedestrian whose best config by its objective (AssA) on the class average
    (config 2) is not its best on car (config 0): (scene root, sweep directory, its table)."""
    from test_sweep_classes import multiclass_scene

    from dfrmot_jax.sweep import run_sweep

    base = tmp_path_factory.mktemp("two_classes")
    root = multiclass_scene(base / "scene")
    spec = {"name": "two", "chunk": 8, "report": {"objective": "AssA"},
            "data": {"root": str(root), "det2d": "synth2d", "det3d": "synth3d", "class": ["car", "pedestrian"]},
            "baseline": {"preset": "dfr2023", "class": "car"},
            "params": {"car.min_hits": [1, 3], "pedestrian.score_2d": [0.95, 0.3]}}
    df = run_sweep(spec, base / "sweep", progress=False, workers=0, log=lambda m: None)
    return root, base / "sweep", df


@pytest.mark.slow
def test_best_of_a_two_class_sweep_is_the_reports_best_for_every_class(two_classes, tmp_path, capsys):
    """``compare A SW:best`` of a two-class sweep tracked the car ranking's best, car only, where
    ``dfrmot report SW`` names the class average's: now the report's best, tracked for every class."""
    from dfrmot_jax.report import sweep_report

    root, d, df = two_classes
    comb = df[df["sequence"] == "COMBINED"]
    pick = {c: int(comb[comb["class"] == c].sort_values(["AssA", "config"], ascending=[False, True]).iloc[0]["config"])
            for c in ("car", "average")}
    assert pick == {"car": 0, "average": 2}                  # (the case: the two rankings differ)
    assert sweep_report(d, objective="AssA").summary["best_config"]["config"] == 2      # dfrmot report SW
    csv = tmp_path / "t.csv"
    status, out, err = run_cli(capsys, ["compare", f"{d}:baseline", f"{d}:best", "--class", "car,pedestrian",
                                        "--data", root, "--resamples", "50", "--csv", csv])
    assert status == 0, err
    assert f"{d} config 2 (hash " in out and "best by AssA on the class average" in out
    t = pd.read_csv(csv, dtype={"seq": str}).query("seq == 'COMBINED' and metric == 'HOTA'").set_index("class")
    for c in ("car", "pedestrian"):
        want = comb[(comb["class"] == c)].set_index("config")["HOTA"]
        assert t.at[c, "a"] == pytest.approx(want[0], abs=1e-9) and t.at[c, "b"] == pytest.approx(want[2], abs=1e-9)


@pytest.mark.slow
def test_a_class_or_sequence_a_sweep_did_not_track_names_the_sweep(tmp_path, capsys):
    """``compare BOTH SW:best --class car,pedestrian`` where SW tracked car only named a temporary folder
    (``.../dfrmot-compare-.../B: no pedestrian row``) and blamed result files; ``--seqs`` outside the
    sweep likewise. Now the sweep folder and what it lacks, before anything is tracked."""
    from dfrmot_jax.sweep import run_sweep

    root = make_scene(tmp_path / "scene", n_sequences=3, n_frames=30, n_cars=3, seed=6)
    d = tmp_path / "sweep"
    run_sweep({"name": "cars", "chunk": 4, "data": {"root": str(root), "det2d": "synth2d", "det3d": "synth3d",
                                                    "sequences": ["0000", "0001"]},
               "params": {"a_l": [4.0, 8.0]}}, d, progress=False, workers=0, log=lambda m: None)
    (tmp_path / "res").mkdir()
    status, _, err = run_cli(capsys, ["compare", tmp_path / "res", f"{d}:best", "--class", "car,pedestrian",
                                      "--data", root])
    line = error_line(err, "compare", alone=True)
    assert status == 2 and f"{d}: the directory tracked car only, not pedestrian (--class car,pedestrian)" in line
    assert "dfrmot-compare-" not in line
    status, _, err = run_cli(capsys, ["compare", f"{d}:baseline", f"{d}:best", "--seqs", "0001,0002", "--data", root])
    line = error_line(err, "compare", alone=True)
    assert status == 2 and f"{d}: sequences 0002 are outside the directory's data (it tracked 0000, 0001)" in line


@pytest.mark.slow
def test_a_sweep_side_is_scored_against_its_own_ground_truth(tmp_path, capsys, monkeypatch):
    """After ``dfrmot demo``, ``compare SW:baseline SW:best`` scored the configs (tracked on the demo's
    scene) against --data's default labels (KITTI): HOTA 2.81 vs 2.81, exit 0. A ``DIR:`` side is now
    scored against its own data; two sides on different data, or --data naming another root, refused."""
    from dfrmot_jax.sweep import run_sweep

    sweeps = []
    for k in range(2):
        root = make_scene(tmp_path / f"scene{k}", n_sequences=2, n_frames=30, n_cars=3, seed=10 + k)
        d = tmp_path / f"sweep{k}"
        df = run_sweep({"name": f"s{k}", "chunk": 4, "data": {"root": str(root), "det2d": "synth2d", "det3d": "synth3d"},
                        "params": {"a_l": [2.0, 8.0]}}, d, progress=False, workers=0, log=lambda m: None)
        sweeps.append((root, d, df[df["sequence"] == "COMBINED"].set_index("config")))
    (root0, d0, comb0), (root1, d1, _) = sweeps
    monkeypatch.setenv("DFRMOT_DATA", str(root1))          # the default data: another scene
    csv = tmp_path / "t.csv"
    status, _, err = run_cli(capsys, ["compare", f"{d0}:baseline", f"{d0}:best", "--resamples", "50", "--csv", csv])
    assert status == 0, err
    row = pd.read_csv(csv, dtype={"seq": str}).query("seq == 'COMBINED' and metric == 'HOTA'").iloc[0]
    assert row["a"] == pytest.approx(comb0.loc[comb0["baseline"], "HOTA"].iloc[0], abs=1e-9)
    assert row["b"] == pytest.approx(comb0["HOTA"].max(), abs=1e-9)
    status, _, err = run_cli(capsys, ["compare", f"{d0}:best", f"{d1}:best"])
    line = error_line(err, "compare", alone=True)
    assert status == 2 and f"{d0} was tracked on {root0}, {d1} on {root1}: two sides on different data" in line
    status, _, err = run_cli(capsys, ["compare", f"{d0}:baseline", f"{d0}:best", "--data", root1])
    line = error_line(err, "compare", alone=True)
    assert status == 2 and f"--data {root1}, but {d0} was tracked on {root0}" in line


def test_the_page_shows_counts_as_whole_numbers(outputs, tmp_path, capsys):
    """The compare page printed counts with decimals (IDSW 177.000); now as the printed comparison:
    whole numbers, differences and interval bounds signed."""
    import re

    root, folders = outputs
    page = tmp_path / "p.html"
    status, _, err = run_cli(capsys, ["compare", folders[0], folders[1], "--data", root, "--resamples", "200",
                                      "--html", page])
    assert status == 0, err
    html = page.read_text()
    for metric in ("IDSW", "CLR_FP", "CLR_FN", "Frag"):
        [row] = re.findall(rf"<tr><td>{metric}</td>(.*?)</tr>", html)
        cells = re.findall(r"<td>(.*?)</td>", row)
        assert all(re.fullmatch(r"[+-]?\d+", v) for v in cells[:5]) and "." in cells[5], (metric, cells)
    [hota] = re.findall(r"<tr><td>HOTA</td>(.*?)</tr>", html)
    assert all("." in v for v in re.findall(r"<td>(.*?)</td>", hota)[:6])      # (then its resamples, whole)


@pytest.mark.slow
def test_the_two_birds_eye_views_of_a_pair_share_one_extent(outputs, tmp_path, capsys):
    """A's and B's bird's-eye views were drawn on extents of their own, so they could not be read side by
    side: one extent per pair now, the ground truth drawn at the same place in both."""
    import re

    root, _ = outputs
    split = dm.load_split(root, "synth2d", "synth3d", "car")
    res = dm.track(split, stack_params(list(SETTINGS)), Options(), detail=True)
    a, b = tmp_path / "a", tmp_path / "b"
    for k, d in enumerate((a, b)):            # with each row's own 3D box, which the views draw
        write_lane(d, split, res.frames, res.options, res.ids[k], res.lane_boxes(k), src3=res.src3[k],
                   own3=res.own3[k])
    for f in b.glob("*.txt"):                 # B's rows moved 30 m right: its own extent would be another
        rows = [ln.split(" ") for ln in f.read_text().splitlines()]
        f.write_text("".join(" ".join(r[:13] + [f"{float(r[13]) + 30:.6f}" if float(r[13]) > -999 else r[13]]
                                      + r[14:]) + "\n" for r in rows))
    page = tmp_path / "p.html"
    status, _, err = run_cli(capsys, ["compare", a, b, "--data", root, "--resamples", "50", "--html", page])
    assert status == 0, err
    figures = re.findall(r"<figure>(<svg [^>]*class=\"bev\".*?)</figure>", page.read_text(), flags=re.S)
    assert figures
    for fig in figures:
        views = re.findall(r"<svg [^>]*class=\"bev\".*?</svg>", fig, flags=re.S)
        gt = [re.findall(r'<polyline class="gt" points="([^"]*)"', v) for v in views]
        assert len(views) == 2 and gt[0] and gt[0] == gt[1]
        assert all('class="row"' in v for v in views)
