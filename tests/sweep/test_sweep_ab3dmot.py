"""AB3DMOT's figures in sweeps and tunes: the same numbers as scoring the written result files."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dfrmot_jax.trackers.dfr.track import track
from dfrmot_jax.data import load_split
from dfrmot_jax.metrics.samota.evaluate import evaluate_ab3dmot_files
from dfrmot_jax.metrics.samota.table import AB3DMOT_COLUMNS, AB3DMOT_OTHER_COLUMNS, ab3dmot_columns
from dfrmot_jax.trackers.dfr.results import ClassRun, write_runs
from dfrmot_jax.report.html import html_report
from dfrmot_jax.sweep import SweepConfigError, expand, params_of, parse_spec, plan, resolve_data, run_sweep, sweep_report
from dfrmot_jax.sweep.plan import option_groups
from dfrmot_jax.synthetic import make_scene
from dfrmot_jax.tuning import run_tune


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    return make_scene(tmp_path_factory.mktemp("ab3d_scene"), n_sequences=3, n_frames=60, n_cars=4, seed=7)


def _spec(root, **extra) -> dict:
    spec = {"name": "ab3d", "chunk": 4, "data": {"root": str(root), "det2d": "synth2d", "det3d": "synth3d"},
            "params": {"a_l": [4.0, 8.0], "score_3d": [0.3, 0.7]}, "options": {"output": ["detections", "filtered"]},
            "report": {"objective": "sAMOTA"}}
    spec.update(extra)
    return spec


def _file_figures(root, table: pd.DataFrame, rows, out: Path, iou: str, columns: str = "kitti",
                  sum_mode: str = "compensated") -> list[dict]:
    """AB3DMOT's columns of config rows of ``table``, from their written result files."""
    split = load_split(root, "synth2d", "synth3d", "car")
    figures = {}
    for options, configs in option_groups(table).items():
        pos = [int(np.flatnonzero(table["config"].to_numpy() == c)[0]) for c in configs if c in rows]
        if not pos:
            continue
        res = track(split, params_of(table, pos, "car"), options, detail=True)
        for j, p in enumerate(pos):
            d = out / f"config{p}"
            write_runs(d, [ClassRun(split, res.frames, res.options, res.ids[j],
                                    None if res.boxes.ndim == 3 else res.boxes[j], res.src3[j], res.own3[j],
                                    None if res.box3 is None else res.box3[j])], columns=columns)
            figures[p] = ab3dmot_columns(evaluate_ab3dmot_files(d, root, "car", list(split.names), iou=iou,
                                                                sum_mode=sum_mode, other=True))
    return [figures[p] for p in rows]


@pytest.mark.slow
@pytest.mark.parametrize("iou, columns, sum_mode", [("3d:0.25", "kitti", "compensated"), ("2d:0.5", "kitti", "compensated"),
                                                     ("3d:0.25", "kitti-stale", "compensated"),
                                                     ("3d:0.25", "kitti", "sequential")])
def test_a_sweep_scores_ab3dmot_as_its_written_files(scene, tmp_path, iou, columns, sum_mode):
    spec = _spec(scene, metrics={"ab3dmot": iou, "ab3dmot_columns": columns, "ab3dmot_sum": sum_mode})
    df = run_sweep(spec, progress=False, log=lambda m: None)
    comb = df[df["sequence"] == "COMBINED"].reset_index(drop=True)
    per_seq = df[df["sequence"] != "COMBINED"]
    assert per_seq[list(AB3DMOT_COLUMNS)].isna().all().all()          # a whole sequence list only
    table = expand(parse_spec(spec))
    rows = list(range(len(table)))
    for p, want in zip(rows, _file_figures(scene, table, rows, tmp_path, iou, columns, sum_mode)):
        got = comb.loc[comb["config"] == p].iloc[0]
        for col in AB3DMOT_COLUMNS + AB3DMOT_OTHER_COLUMNS:       # the other sum's headline figures too
            assert got[col] == pytest.approx(want[col], abs=1e-9), (p, col)
    assert comb["sAMOTA"].nunique() > 1                               # the settings change the figure
    assert str(df["ab3dmot_IDS"].dtype) == "Int64"


@pytest.mark.slow
def test_the_report_ranks_by_samota_and_refuses_its_folds(scene, tmp_path):
    """Folds asked for sAMOTA are an error; the sweep file's folds (for the sums over sequences) are
    not taken for it: its report, and its page, go without a cross-validation."""
    out = tmp_path / "stored"
    run_sweep(_spec(scene, report={"folds": 2}, metrics={"ab3dmot": "3d:0.25"}), out, progress=False, log=lambda m: None)
    assert sweep_report(out, objective="sAMOTA").cv is None and sweep_report(out).cv is not None
    assert html_report(out, tmp_path / "page.html", objective="sAMOTA").is_file()
    df = run_sweep(_spec(scene), progress=False, log=lambda m: None)
    rep = sweep_report(df, objective="sAMOTA")
    comb = df[df["sequence"] == "COMBINED"]
    assert rep.summary["best_in_sample"] == pytest.approx(comb["sAMOTA"].max()) and rep.summary["objective"] == "sAMOTA"
    with pytest.raises(ValueError, match="not sums over sequences"):
        sweep_report(df, objective="sAMOTA", folds=2)
    with pytest.raises(SweepConfigError, match="report.folds"):
        parse_spec(_spec(scene, report={"objective": "sAMOTA", "folds": 2}))


def test_metrics_settings_are_checked_and_keep_other_chunk_ids(scene):
    with pytest.raises(SweepConfigError, match="metrics.ab3dmot"):
        parse_spec(_spec(scene, metrics={"ab3dmot": "4d:0.2"}))
    with pytest.raises(SweepConfigError, match="metrics.ab3dmot"):
        parse_spec(_spec(scene, metrics={"ab3dmot": False}))
    with pytest.raises(SweepConfigError, match="metrics.ab3dmot_columns"):
        parse_spec(_spec(scene, metrics={"ab3dmot_columns": "authors"}))
    with pytest.raises(SweepConfigError, match="metrics.ab3dmot_sum"):
        parse_spec(_spec(scene, metrics={"ab3dmot_sum": "fsum"}))
    comp, seq = (parse_spec(_spec(scene, metrics={"ab3dmot_sum": m})) for m in ("compensated", "sequential"))
    assert comp.ab3dmot_sum == parse_spec(_spec(scene)).ab3dmot_sum == "compensated"      # the default
    assert comp.metrics_identity() != seq.metrics_identity()        # chunks of one sum are never the other's
    plain = parse_spec(_spec(scene, report={"objective": "HOTA"}))
    assert plain.ab3dmot is None
    table = expand(plain)
    data = resolve_data(plain)
    before = [c.id for c in plan(table, data, 4)]
    assert [c.id for c in plan(table, data, 4, None, None)] == before       # no setting: the same ids
    assert not set(before) & {c.id for c in plan(table, data, 4, None, "3d:0.25")}


@pytest.mark.slow
def test_a_nested_tune_of_samota_scores_each_fold_as_its_files(scene, tmp_path):
    spec = _spec(scene)
    del spec["report"]
    spec["params"] = {"a_l": [4.0, 8.0], "score_3d": [0.3, 0.7]}
    spec["options"] = {"output": ["detections"]}
    spec["tune"] = {"sampler": "grid", "budget": 4, "batch": 4, "objectives": ["sAMOTA"], "folds": 3, "seed": 1}
    r = run_tune(spec, None, progress=False, log=lambda m: None, plots=False)
    nested = r.nested
    assert nested["objective"] == "sAMOTA" and len(nested["per_fold"]) == 3
    # each sequence's file written by the config chosen without it (or the baseline's), scored together
    from dfrmot_jax.tuning.space import search_space
    sp = search_space(parse_spec({k: v for k, v in spec.items() if k != "tune"}))
    configs = [f["config"] for f in nested["per_fold"]] + [sp.baseline_values()]
    table = sp.table([sp.row(c) for c in configs], [False] * 3 + [True])
    figures_dir = tmp_path / "files"
    _file_figures(scene, table, list(range(len(table))), figures_dir, "3d:0.25")
    split = load_split(scene, "synth2d", "synth3d", "car")
    base = ab3dmot_columns(evaluate_ab3dmot_files(figures_dir / "config3", scene, "car", list(split.names)))
    assert nested["baseline"] == pytest.approx(base["sAMOTA"], abs=1e-9)
    composite = tmp_path / "composite"
    composite.mkdir()
    for f, fold in enumerate(nested["fold_sequences"]):
        for s in fold:
            shutil.copy(figures_dir / f"config{f}" / f"{s}.txt", composite / f"{s}.txt")
    want = ab3dmot_columns(evaluate_ab3dmot_files(composite, scene, "car", list(split.names)))["sAMOTA"]
    assert nested["cross_validated"] == pytest.approx(want, abs=1e-9)
    for f, fold in enumerate(nested["fold_sequences"]):
        held = ab3dmot_columns(evaluate_ab3dmot_files(figures_dir / f"config{f}", scene, "car", list(fold)))
        assert nested["per_fold"][f]["held_out"] == pytest.approx(held["sAMOTA"], abs=1e-9)


def test_a_grid_tune_may_spend_its_budget_on_the_whole_grid(scene):
    """Optuna's grid sampler stops the study when its grid is done, which it refuses outside
    study.optimize: a budget of the whole grid ended in an internal error."""
    spec = _spec(scene)
    del spec["report"]
    spec["options"] = {"output": ["detections"]}
    spec["tune"] = {"sampler": "grid", "budget": 4, "batch": 4, "objectives": ["HOTA"], "seed": 0}
    r = run_tune(spec, None, progress=False, log=lambda m: None, plots=False)
    assert r.table["config_hash"].nunique() >= 4


@pytest.mark.slow
def test_stale_columns_give_a_row_its_tracks_last_3d_box(scene, tmp_path):
    """kitti-stale: a row without its own 3D detection carries its track's last one (box and rot_y,
    the 2D score kept); with kitti it carries the placeholders, and rows with their own are equal."""
    split = load_split(scene, "synth2d", "synth3d", "car")
    from dfrmot_jax.trackers.dfr.config import Options, Params
    res = track(split, Params(), Options(), detail=True)
    lines = {}
    for columns in ("kitti", "kitti-stale"):
        write_runs(tmp_path / columns, [ClassRun(split, res.frames, res.options, res.ids[0], None, res.src3[0],
                                                 res.own3[0])], columns=columns)
        lines[columns] = [ln.split() for f in sorted((tmp_path / columns).glob("*.txt")) for ln in f.read_text().splitlines()]
    stale = [(a, b) for a, b in zip(lines["kitti"], lines["kitti-stale"]) if a != b]
    assert stale, "the scene has no row with a stale 3D box"
    for a, b in stale:
        assert a[:5] + a[6:10] == b[:5] + b[6:10] and a[17] == b[17]     # frame .. 2D box, score
        assert a[10:16] == ["-1", "-1", "-1", "-1000", "-1000", "-1000"] and float(b[10]) > 0
    assert len(lines["kitti"]) == len(lines["kitti-stale"])


@pytest.mark.slow
def test_car_and_pedestrian_on_kitti_with_their_class_average(kitti_root, tmp_path):
    """The sweep objective on KITTI car and pedestrian: each class's figures are its files' (baseline
    config), the average row averages the ratios and sums the counts."""
    seqs = ["0012", "0013", "0017"]
    spec = {"name": "kitti_ab3d", "chunk": 8, "data": {"root": str(kitti_root), "det2d": "rrc", "det3d": "pointrcnn",
                                                        "class": ["car", "pedestrian"], "sequences": seqs},
            "baseline": {"preset": "dfr2023"}, "params": {"a_l": [8.0, 5.0]}, "report": {"objective": "sAMOTA"}}
    df = run_sweep(spec, progress=False, log=lambda m: None)
    comb = df[(df["sequence"] == "COMBINED") & (df["config"] == 0)].set_index("class")
    from dfrmot_jax.trackers.dfr.config import preset
    for cls in ("car", "pedestrian"):
        split = load_split(kitti_root, "rrc", "pointrcnn", cls, seqs)
        params, options = preset("dfr2023", cls)
        res = track(split, params, options, detail=True)
        write_runs(tmp_path / cls, [ClassRun(split, res.frames, res.options, res.ids[0], None, res.src3[0],
                                             res.own3[0])])
        want = ab3dmot_columns(evaluate_ab3dmot_files(tmp_path / cls, kitti_root, cls, list(split.names)))
        for col in AB3DMOT_COLUMNS:
            assert comb.loc[cls, col] == pytest.approx(want[col], abs=1e-9), (cls, col)
    avg = comb.loc["average"]
    assert avg["sAMOTA"] == pytest.approx((comb.loc["car", "sAMOTA"] + comb.loc["pedestrian", "sAMOTA"]) / 2)
    assert avg["ab3dmot_FP"] == comb.loc["car", "ab3dmot_FP"] + comb.loc["pedestrian", "ab3dmot_FP"]


@pytest.mark.parametrize("output, columns", [("detections", "kitti"), ("detections", "kitti-stale"),
                                             ("filtered", "kitti")])
@pytest.mark.slow
def test_rows_scored_by_their_keys_equal_rows_scored_by_their_values(scene, output, columns):
    """The sweep's AB3DMOT lanes find distinct boxes from slot / 3D-source keys (results.kitti_rows):
    the same figures as finding them from the values' bits, and as the padded arrays, some lanes only too."""
    from dfrmot_jax.trackers.dfr.config import Options, Params, stack_params
    from dfrmot_jax.metrics.samota.arrays import evaluate_ab3dmot_arrays, evaluate_ab3dmot_rows
    from dfrmot_jax.metrics.samota.prep import prepare_ab3dmot_gt
    from dfrmot_jax.trackers.dfr.results import kitti_row_arrays, kitti_rows

    split = load_split(scene, "synth2d", "synth3d", "car")
    gt = prepare_ab3dmot_gt(scene, "car", list(split.names))
    params = stack_params([Params(a_l=4.0, score_3d=0.3), Params(a_l=8.0), Params(epsilon=2, score_2d=0.6)])
    res = track(split, params, Options(output=output), detail=True)
    rows = kitti_rows(split, res, columns)
    assert (rows.box_key is None) == (output == "filtered")
    by_keys = evaluate_ab3dmot_rows(gt, **rows._asdict(), seq_offsets=split.offsets)
    by_values = evaluate_ab3dmot_rows(gt, **rows._replace(box_key=None, box3d_key=None)._asdict(), seq_offsets=split.offsets)
    padded = evaluate_ab3dmot_arrays(gt, res.ids, *kitti_row_arrays(split, res, columns), seq_offsets=split.offsets)
    assert by_keys == by_values == padded
    assert len({r["sAMOTA"] for r in by_keys}) > 1
    some = kitti_rows(split, res, columns, lanes=[2, 0])
    assert evaluate_ab3dmot_rows(gt, **some._asdict(), seq_offsets=split.offsets) == [by_keys[2], by_keys[0]]
