"""Sweeps: file parsing and validation, config table, chunked runs, tidy table, reports, CV."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dfrmot_jax.trackers.dfr.config import Options, Params
from dfrmot_jax.sweep import (COMBINED, EXTRA_AXES, OPTION_NAMES, PARAM_NAMES, RAW_COLUMN, SweepConfigError,
                              SweepDirectoryError, combine_sequences, config_hash, cross_validate, expand, load_results, load_spec,
                              make_folds, plan, resolve_data, sensitivity, summary_columns, run_sweep,
                              sweep_report)
from dfrmot_jax.synthetic import make_scene


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    return make_scene(tmp_path_factory.mktemp("sweep_scene"), n_sequences=3, n_frames=70, n_cars=4, seed=3)


def small_spec(root, **extra) -> dict:
    spec = {"name": "small", "chunk": 4,
            "data": {"root": str(root), "det2d": "synth2d", "det3d": "synth3d"},
            "params": {"a_l": [4.0, 8.0], "score_2d": [0.3, 0.45]},
            "options": {"output": ["detections", "filtered"]}}
    spec.update(extra)
    return spec


@pytest.fixture(scope="module")
def small_table(scene) -> pd.DataFrame:
    return run_sweep(small_spec(scene), progress=False, log=lambda m: None)


# ---- the sweep file -------------------------------------------------------------------------------


def test_grid_crossing_ranges_and_baseline_row():
    t = expand({"params": {"a_l": {"linspace": [4, 8, 3]}, "kf_q": {"logspace": [0.01, 100, 5]},
                           "epsilon": [10, 30]},
                "options": {"output": ["detections", "filtered"]}})
    assert t.loc[0, "baseline"] and t.loc[0, "variant"] == "baseline"
    assert (t.loc[0, list(PARAM_NAMES)].to_dict() == Params()._asdict())
    assert sorted(t["a_l"].unique()) == [4.0, 6.0, 8.0]
    assert sorted(t["kf_q"].unique()) == [0.01, 0.1, 1.0, 10.0, 100.0]
    # 3 x 5 x 2 x 2 = 60 grid configs; the baseline is one of them (a_l=8, kf_q=1, epsilon=30, detections)
    assert len(t) == 60
    assert t["config_hash"].is_unique and list(t["config"]) == list(range(60))
    assert t["epsilon"].dtype == np.int64 and t["a_l"].dtype == np.float64 and t["truncate"].dtype == bool
    # the first axis varies slowest
    grid = t[~t["baseline"]]
    assert list(grid["a_l"].iloc[:3]) == [4.0, 4.0, 4.0]


def test_random_samples_deterministic_and_in_range():
    doc = {"seed": 7, "samples": 20,
           "params": {"alpha_c": {"uniform": [0.2, 0.8]}, "kf_r": {"loguniform": [0.1, 10]},
                      "epsilon": {"randint": [5, 9]}, "a_l": {"choice": [4.0, 6.0]}, "score_2d": [0.3, 0.5]}}
    a, b = expand(doc), expand(doc)
    pd.testing.assert_frame_equal(a, b)
    g = a[~a["baseline"]]
    assert len(g) == 40
    assert g["alpha_c"].between(0.2, 0.8).all() and g["kf_r"].between(0.1, 10).all()
    assert set(g["epsilon"]) <= {5, 6, 7, 8}            # randint: high exclusive (numpy / Ray Tune)
    assert set(g["a_l"]) <= {4.0, 6.0}
    c = expand({**doc, "seed": 8})
    assert not np.array_equal(c["alpha_c"].to_numpy(), a["alpha_c"].to_numpy())


def test_variants_override_axes():
    t = expand({"params": {"a_l": [4.0, 8.0]},
                "variants": [{"name": "raw"},
                             {"name": "filtered", "options": {"output": "filtered"}, "params": {"keep_lost": [0, 2]}}]})
    assert set(t["variant"]) == {"baseline", "raw", "filtered"}
    f = t[t["variant"] == "filtered"]
    assert len(f) == 4 and set(f["output"]) == {"filtered"} and set(f["keep_lost"]) == {0, 2}


def test_config_hash_stable_and_canonical():
    row = {**Params()._asdict(), **Options()._asdict()}
    h = config_hash(row)
    assert h == config_hash(dict(row)) and len(h) == 16
    assert config_hash({**row, "a_l": 8.0 + 1e-12}) == h           # same float32 value, same config
    assert config_hash({**row, "a_l": 8.5}) != h
    assert config_hash({**row, "output": "filtered"}) != h
    # a future per-lane axis at its default keeps the hash
    EXTRA_AXES["distortion.level"] = 0.0
    try:
        assert config_hash({**row, "distortion.level": 0.0}) == h
        assert config_hash({**row, "distortion.level": 0.3}) != h
    finally:
        del EXTRA_AXES["distortion.level"]


def test_3d_kalman_noise_hashes_only_off_its_default():
    """kf_q3 / kf_r3 at 0 (= kf_q / kf_r) keep every earlier hash (the dfr2023 preset's, pinned here);
    set, they are part of the config."""
    row = {**Params()._asdict(), **Options()._asdict()}
    assert config_hash(row) == "2373fa0eace4e653"
    old = {k: v for k, v in row.items() if k not in ("kf_q3", "kf_r3")}
    assert config_hash(old) == config_hash(row)
    assert config_hash({**row, "kf_q3": 0.5}) not in (config_hash(row), config_hash({**row, "kf_r3": 0.5}))
    table = expand({"params": {"kf_q3": [0.0, 0.5], "kf_r3": [0.0, 2.0]}})
    assert table["config_hash"].is_unique and len(table) == 4
    assert table.loc[0, "config_hash"] == config_hash(row)


@pytest.mark.parametrize("doc, key", [
    ({"params": {"a_lidar": [1.0]}}, "params.a_lidar"),
    ({"params": {"a_c": [0.1, 1.5]}}, "params.a_c[1]"),
    ({"params": {"a_c": {"uniform": [0.1, 1.5]}}}, "params.a_c.uniform"),
    ({"params": {"epsilon": [3.5]}}, "params.epsilon[0]"),
    ({"params": {"a_l": []}}, "params.a_l"),
    ({"params": {"a_l": {"linspace": [1, 2, 0]}}}, "params.a_l.linspace"),
    ({"params": {"a_l": {"normal": [1, 2]}}}, "params.a_l.normal"),
    ({"params": {"filter": ["kalman"]}}, "params.filter"),
    ({"options": {"filter": ["kalman", "particle"]}}, "options.filter[1]"),
    ({"options": {"output": []}}, "options.output"),
    ({"options": {"a_l": [4.0]}}, "options.a_l"),
    ({"data": {"det2": "rrc"}}, "data.det2"),
    ({"chunk": 0, "params": {"a_l": [4.0]}}, "chunk"),
    ({"baseline": "dfr2099", "params": {"a_l": [4.0]}}, "baseline"),
    ({"params": {"keep_lost": [0, 3]}}, "params.keep_lost"),
    ({"samples": 3, "params": {"a_l": [4.0, 6.0]}}, "samples"),
    ({}, "params"),
    ({"colour": "red"}, "colour"),
])
def test_bad_files_name_the_key(doc, key):
    with pytest.raises(SweepConfigError) as e:
        expand(doc)
    assert e.value.key == key
    assert key in str(e.value)


def test_bad_data_names_the_key(scene, tmp_path):
    base = {"params": {"a_l": [4.0, 6.0]}}
    with pytest.raises(SweepConfigError, match=r"data\.det2d: unknown detector 'yolo'"):
        resolve_data({**base, "data": {"root": str(scene), "det2d": "yolo", "det3d": "synth3d"}})
    with pytest.raises(SweepConfigError, match=r"data\.det3d"):
        resolve_data({**base, "data": {"root": str(scene), "det2d": "synth2d", "det3d": "nope"}})
    with pytest.raises(SweepConfigError, match=r"data\.sequences"):
        resolve_data({**base, "data": {"root": str(scene), "det2d": "synth2d", "det3d": "synth3d",
                                       "sequences": ["0000", "0042"]}})
    with pytest.raises(SweepConfigError, match=r"data\.root"):
        resolve_data({**base, "data": {"root": str(tmp_path / "nowhere")}})


def test_bad_file_fails_before_any_work(scene, tmp_path, monkeypatch):
    import dfrmot_jax.trackers.dfr.track

    def boom(*a, **k):
        raise AssertionError("tracking started")

    monkeypatch.setattr(dfrmot_jax.trackers.dfr.track, "track", boom)
    f = tmp_path / "bad.toml"
    f.write_text(f'[data]\nroot = "{scene}"\ndet2d = "synth2d"\ndet3d = "nope"\n[params]\na_l = [4.0, 6.0]\n')
    from dfrmot_jax.cli import main

    assert main(["sweep", str(f), "--out", str(tmp_path / "out"), "--no-progress"]) == 2
    assert not (tmp_path / "out").exists()
    f.write_text(f'[data]\nroot = "{scene}"\ndet2d = "synth2d"\ndet3d = "synth3d"\n[params]\nmerge_iou = [0.2, 7]\n')
    assert main(["sweep", str(f), "--out", str(tmp_path / "out")]) == 2
    assert not (tmp_path / "out").exists()


def test_toml_file_relative_root_and_sequences(scene, tmp_path):
    import os

    (tmp_path / "sweeps").mkdir()
    f = tmp_path / "sweeps" / "s.toml"
    rel = os.path.relpath(scene, f.parent)
    f.write_text(f'name = "s"\n[data]\nroot = "{Path(rel).as_posix()}"\ndet2d = "synth2d"\ndet3d = "synth3d"\n'
                 f'sequences = "0,2"\n[params]\na_l = [4.0, 6.0]\n')
    spec = load_spec(f)                       # a relative root is relative to the sweep file
    data = resolve_data(spec)
    assert data.sequences == ("0000", "0002") and Path(data.root) == Path(scene).resolve()
    assert data.lengths == (70, 70)


def test_plan_groups_by_options_and_chunk_identity(scene):
    spec = small_spec(scene)
    t = expand(spec)
    data = resolve_data(spec)
    chunks = plan(t, data, 3)
    assert sorted(i for c in chunks for i in c.configs) == list(range(len(t)))
    for c in chunks:
        assert len({t.loc[i, "output"] for i in c.configs}) == 1 and len(c.configs) <= 3
    assert len({c.id for c in chunks}) == len(chunks)
    assert [c.id for c in plan(t, data, 3)] == [c.id for c in chunks]
    other = resolve_data({**spec, "data": {**spec["data"], "sequences": ["0000"]}})
    assert not {c.id for c in plan(t, other, 3)} & {c.id for c in chunks}


def test_shipped_sweep_files_parse():
    files = sorted((Path(__file__).resolve().parents[2] / "sweeps").glob("*.toml"))
    assert any(f.name == "kitti_dfr_grid.toml" for f in files)
    for f in files:
        if "\n[tune]" in f.read_text():            # a tune file: the sweep part plus its search space
            from dfrmot_jax.tuning import load_tune, search_space

            spec, _ = load_tune(f)
            assert search_space(spec).dims
            continue
        t = expand(load_spec(f))
        assert t.loc[0, "baseline"]
        if f.name == "kitti_dfr_grid.toml":
            assert len(t) >= 1024
            assert t["baseline"].sum() == 1
            assert t["output"].nunique() == 2
        if f.name == "kitti_ab3dmot_grid.toml":       # the second tracker family's grid, its own columns
            assert load_spec(f).family == "ab3dmot" and len(t) == 1024 and t["baseline"].sum() == 1
            assert t.groupby(["metric", "algorithm"]).size().tolist() == [128] * 8 and "a_l" not in t.columns


# ---- running ---------------------------------------------------------------------------------------


def test_tidy_table(small_table, scene):
    df = small_table
    n_cfg = len(expand(small_spec(scene)))
    assert len(df) == n_cfg * 4
    assert df.groupby("config")["sequence"].apply(list).map(lambda s: s == ["0000", "0001", "0002", COMBINED]).all()
    for col in ["config_hash", "sequence", "HOTA", "DetA", "AssA", "MOTA", "MOTP", "IDSW", "IDF1", "MT", "ML",
                "Frag", "overflow", "dfrmot_jax_version", "jax_version", *PARAM_NAMES, *OPTION_NAMES]:
        assert col in df.columns, col
    assert not df.duplicated(["config", "sequence"]).any()
    import jax

    import dfrmot_jax
    assert (df["jax_version"] == jax.__version__).all() and (df["dfrmot_jax_version"] == dfrmot_jax.__version__).all()
    comb = df[df["sequence"] == COMBINED]
    assert (comb["frames"] == 210).all() and (comb["overflow"] == 0).all()
    assert comb["baseline"].sum() == 1


@pytest.mark.slow
def test_rows_equal_direct_track_and_eval(small_table, scene, tmp_path):
    """A sweep row is what track + write_lane + evaluate_files + metrics_table give for that config
    (same names): the rows its result files carry (boxes as printed), scored from the files."""
    import dfrmot_jax as dm
    from dfrmot_jax.metrics import evaluate_files, metrics_table, prepare_gt
    from dfrmot_jax.trackers.dfr.results import write_lane

    split = dm.load_split(scene, "synth2d", "synth3d", "car")
    gt = prepare_gt(scene, "car", split.names)
    comb = small_table[small_table["sequence"] == COMBINED]
    for _, row in comb.iloc[[0, len(comb) - 1]].iterrows():
        params = Params(**{n: row[n] for n in PARAM_NAMES})
        options = Options(**{n: type(Options._field_defaults[n])(row[n]) for n in OPTION_NAMES})
        res = dm.track(split, dm.stack_params([params]), options)
        out = tmp_path / str(row["config"])
        write_lane(out, split, dm.prepare_frames(split, options), options, res.ids[0], res.lane_boxes(0))
        expect = metrics_table(evaluate_files(out, gt))
        got = small_table[small_table["config"] == row["config"]].set_index("sequence")
        for col in expect.columns:
            np.testing.assert_array_equal(got.loc[list(expect.index), col].to_numpy(),
                                          expect[col].to_numpy(), err_msg=col)


def test_recombining_all_sequences_gives_combined(small_table):
    from dfrmot_jax.sweep import per_sequence_arrays

    comb, names, lengths, arrays = per_sequence_arrays(small_table)
    out = summary_columns(combine_sequences(arrays))
    for f in ("HOTA", "DetA", "AssA", "LocA", "MOTA", "MOTP", "IDF1", "IDSW", "Frag", "MT"):
        np.testing.assert_array_equal(out[f], comb[f].to_numpy(), err_msg=f)


@pytest.mark.slow
def test_deterministic_in_memory_equals_directory(small_table, scene, tmp_path):
    a = run_sweep(small_spec(scene), out=tmp_path / "a", progress=False, log=lambda m: None)
    pd.testing.assert_frame_equal(a.drop(columns=[RAW_COLUMN]), small_table.drop(columns=[RAW_COLUMN]))
    assert all(np.array_equal(x, y) for x, y in zip(a[RAW_COLUMN], small_table[RAW_COLUMN]))
    # a rerun resumes everything: no work, the same table
    logs = []
    b = run_sweep(small_spec(scene), out=tmp_path / "a", progress=False, log=logs.append)
    assert "tracked" not in " ".join(logs)
    pd.testing.assert_frame_equal(a, b)
    pd.testing.assert_frame_equal(load_results(tmp_path / "a"), b)
    # a changed sweep is another sweep: refused (the directory belongs to the first), or with
    # force=True run afresh
    spec = small_spec(scene)
    spec["params"] = {**spec["params"], "score_2d": [0.3, 0.45, 0.6]}
    with pytest.raises(SweepDirectoryError, match="another sweep"):
        run_sweep(spec, out=tmp_path / "a", progress=False, log=lambda m: None, chunk=4)
    c = run_sweep(spec, out=tmp_path / "a", progress=False, log=lambda m: None, chunk=4, force=True)
    assert len(c) == len(expand(spec)) * 4


@pytest.mark.slow
def test_chunking_and_track_slots_do_not_change_results(small_table, scene):
    """Chunks of 2 (later chunks run with track slots sized from the group's earlier peaks) give the
    same rows as one chunk per option group."""
    df = run_sweep(small_spec(scene), chunk=2, progress=False, log=lambda m: None)
    cols = [c for c in df.columns if c not in ("chunk", RAW_COLUMN)]
    pd.testing.assert_frame_equal(df[cols], small_table[cols])


@pytest.mark.slow
def test_metric_worker_processes_give_the_same_table(small_table, scene):
    df = run_sweep(small_spec(scene), chunk=2, workers=2, progress=False, log=lambda m: None)
    cols = [c for c in df.columns if c not in ("chunk", RAW_COLUMN)]
    pd.testing.assert_frame_equal(df[cols], small_table[cols])
    assert all(np.array_equal(x, y) for x, y in zip(df[RAW_COLUMN], small_table[RAW_COLUMN]))


def test_a_split_is_read_once_until_its_files_change(small_table, scene, tmp_path, monkeypatch):
    """Sweeps on the same data (a tune's batches) read the files once; an edited file is read again."""
    import shutil

    import dfrmot_jax.data as data

    root = tmp_path / "scene"
    shutil.copytree(scene, root)
    reads = []
    real = data.load_split

    def counted(*a, **k):
        reads.append(a)
        return real(*a, **k)

    monkeypatch.setattr(data, "load_split", counted)
    for _ in range(2):
        df = run_sweep(small_spec(root), progress=False, log=lambda m: None)
    assert len(reads) == 1
    cols = [c for c in small_table.columns if c not in ("chunk", RAW_COLUMN)]
    pd.testing.assert_frame_equal(df[cols].drop(columns=["sweep"]), small_table[cols].drop(columns=["sweep"]))
    det = next((root / "detections").rglob("0001.txt"))
    lines = det.read_text().splitlines(keepends=True)
    det.write_text("".join(lines[: len(lines) // 2]))          # half of one sequence's detections
    df2 = run_sweep(small_spec(root), progress=False, log=lambda m: None)
    assert len(reads) == 2
    assert not df2["HOTA"].equals(df["HOTA"])


@pytest.mark.slow
def test_compacted_detection_slots_change_nothing(small_table, scene, monkeypatch):
    """The split compacted to the table's loosest thresholds (the default) gives every column of
    every row as the full split does; the compaction really drops slots here."""
    from dfrmot_jax.data import compact_split, load_split

    spec = small_spec(scene, params={"a_l": [4.0, 8.0], "score_2d": [0.5, 0.8], "score_3d": [0.5, 0.9]})
    compact = run_sweep(spec, progress=False, log=lambda m: None)
    full = run_sweep(spec, progress=False, log=lambda m: None, compact=False)
    pd.testing.assert_frame_equal(compact, full)
    split = load_split(scene, "synth2d", "synth3d")
    packed = compact_split(split, 0.5, 0.5)
    assert packed.valid2d.shape[1] + packed.valid3d.shape[1] < split.valid2d.shape[1] + split.valid3d.shape[1]
    assert packed.valid2d.sum() < split.valid2d.sum()


@pytest.mark.slow
def test_duplicate_outputs_scored_once_same_result(scene):
    """kf_q does not matter to the fixed-gain filter: identical outputs, identical rows."""
    spec = small_spec(scene, params={"kf_q": [0.5, 1.0, 2.0]}, options={})
    df = run_sweep(spec, progress=False, log=lambda m: None)
    comb = df[df["sequence"] == COMBINED]
    assert comb["HOTA"].nunique() == 1 and comb["IDSW"].nunique() == 1


def test_report_json_and_objectives(small_table):
    rep = sweep_report(small_table, top=3)
    last = json.loads(rep.text.strip().splitlines()[-1])
    assert {"objective", "baseline", "best_in_sample"} <= set(last)
    comb = small_table[small_table["sequence"] == COMBINED]
    assert last["best_in_sample"] == pytest.approx(comb["HOTA"].max())
    assert last["baseline"] == pytest.approx(comb[comb["baseline"]]["HOTA"].iloc[0])
    assert "best_cross_validated" not in last
    rep = sweep_report(small_table, objective="IDSW")
    assert rep.summary["best_in_sample"] == comb["IDSW"].min() and rep.summary["direction"] == "min"
    rep = sweep_report(small_table, objective="MOTA", folds=3)
    assert "best_cross_validated" in rep.summary and rep.summary["folds"] == 3
    with pytest.raises(ValueError, match="objective"):
        sweep_report(small_table, objective="a_l")
    sens = sensitivity(small_table)
    assert set(sens["axis"]) == {"a_l", "score_2d", "output"}


def test_make_folds_stratified():
    names = [f"{i:04d}" for i in range(20)]
    lengths = [154, 447, 233, 144, 314, 297, 270, 800, 390, 803, 294, 373, 78, 340, 106, 376, 209, 339, 1059, 837]
    folds = make_folds(names, lengths, 5)
    assert sorted(s for f in folds for s in f) == names
    assert [len(f) for f in folds] == [4] * 5
    frames = [sum(lengths[names.index(s)] for s in f) for f in folds]
    assert max(frames) - min(frames) < 0.25 * np.mean(frames)
    # stratified: each fold holds one of the 5 longest, one of the next 5, ...
    order = sorted(names, key=lambda s: -lengths[names.index(s)])
    for a in range(0, 20, 5):
        stratum = set(order[a:a + 5])
        assert [len(stratum & set(f)) for f in folds] == [1] * 5
    assert folds == make_folds(names, lengths, 5)
    with pytest.raises(ValueError):
        make_folds(names, lengths, 1)


def test_subset_combination_equals_direct_evaluation(small_table, scene):
    """COMBINED over a subset of sequences (what CV uses) equals evaluating that subset directly."""
    import dfrmot_jax as dm
    from dfrmot_jax.metrics import evaluate_arrays, metrics_table, prepare_gt
    from dfrmot_jax.sweep import objective_on, per_sequence_arrays

    comb, names, lengths, arrays = per_sequence_arrays(small_table)
    split = dm.load_split(scene, "synth2d", "synth3d", "car")
    i = int(np.flatnonzero(comb["output"].to_numpy() == "filtered")[-1])
    row = comb.iloc[i]
    params = Params(**{n: row[n] for n in PARAM_NAMES})
    options = Options(**{n: type(Options._field_defaults[n])(row[n]) for n in OPTION_NAMES})
    res = dm.track(split, dm.stack_params([params]), options)
    for subset in (["0000", "0002"], ["0001"]):
        gt = prepare_gt(scene, "car", subset)
        offs = [int(split.offsets[names.index(s)]) for s in subset]
        direct = metrics_table(evaluate_arrays(gt, res.ids, res.boxes, offs)[0]).loc["COMBINED"]
        cols = [names.index(s) for s in subset]
        for f in ("HOTA", "AssA", "MOTA", "IDF1"):
            got = objective_on(arrays, cols, f)[i]
            assert got == pytest.approx(direct[f], abs=1e-9), f


def test_cross_validation_picks_on_training_folds(small_table):
    from dfrmot_jax.sweep import objective_on, per_sequence_arrays

    comb, names, lengths, arrays = per_sequence_arrays(small_table)
    cv = cross_validate(small_table, folds=3, objective="HOTA")
    assert len(cv["per_fold"]) == 3
    chosen = {}
    for p in cv["per_fold"]:
        tr = [names.index(s) for s in names if s not in p["test_sequences"]]
        te = [names.index(s) for s in p["test_sequences"]]
        train = objective_on(arrays, tr, "HOTA")
        best = int(np.flatnonzero(train == train.max())[0])          # ties: first config
        assert p["config"] == comb.at[best, "config"] and p["train"] == train[best]
        assert p["held_out"] == objective_on(arrays, te, "HOTA")[best]
        for s in p["test_sequences"]:
            chosen[s] = best
    # the cross-validated figure: every sequence scored with the config chosen without it
    pooled = {f: np.stack([v[chosen[s], k] for k, s in enumerate(names)])[None] for f, v in arrays.items()}
    assert cv["cross_validated"] == summary_columns(combine_sequences(pooled))["HOTA"][0]
    assert cv["baseline"] == comb[comb["baseline"]]["HOTA"].iloc[0]


def test_cli_sweep_and_report(scene, tmp_path, capsys):
    from dfrmot_jax.cli import main

    f = tmp_path / "s.toml"
    f.write_text(f'name = "cli"\nchunk = 8\n[data]\nroot = "{scene}"\ndet2d = "synth2d"\ndet3d = "synth3d"\n'
                 f'[params]\na_l = [4.0, 8.0]\nscore_2d = [0.3, 0.45]\n')
    out = tmp_path / "out"
    assert main(["sweep", str(f), "--out", str(out), "--dry-run"]) == 0
    assert "4 configs" in capsys.readouterr().out and not out.exists()
    assert main(["sweep", str(f), "--out", str(out), "--summary", "--folds", "3", "--no-progress"]) == 0
    text = capsys.readouterr().out
    last = json.loads(text.strip().splitlines()[-1])
    assert {"objective", "baseline", "best_in_sample", "best_cross_validated"} <= set(last)
    assert (out / "results.parquet").is_file() and (out / "manifest.json").is_file()
    assert main(["report", str(out), "--objective", "IDSW", "--csv", str(tmp_path / "t.csv")]) == 0
    last = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert last["objective"] == "IDSW" and last["direction"] == "min"
    assert last["best_cross_validated"] is not None          # --folds stored by the sweep
    assert len(pd.read_csv(tmp_path / "t.csv")) == 4 * 4
    assert main(["report", str(tmp_path / "nothing")]) == 2


def test_an_option_capacity_past_the_maximum_is_refused_naming_the_key():
    from dfrmot_jax.sweep import parse_spec

    from dfrmot_jax.trackers.dfr.config import MAX_CAPACITY

    with pytest.raises(SweepConfigError, match=r"options\.capacity.*2147483648.*from 0 to 4096"):
        parse_spec({"params": {"a_l": [4.0, 8.0]}, "options": {"capacity": [2147483648]}})
    assert MAX_CAPACITY == 4096


@pytest.mark.slow
def test_the_table_records_the_capacity_asked_and_the_one_each_lane_used(scene):
    """Issue 23, bug 4: ``options.capacity = 1`` runs (overflowing lanes re-run larger); the table
    says what was asked (``capacity``: 1; 0 = from the data) and what each lane ran with."""
    df = run_sweep(small_spec(scene, options={"capacity": 1}), progress=False, log=lambda m: None)
    grid, base = df[~df["baseline"]], df[df["baseline"]]
    assert (grid["capacity"] == 1).all() and (base["capacity"] == 0).all()
    assert (df["capacity_used"] >= df["peak_tracks"]).all() and (grid["capacity_used"] > 1).all()
    assert (df["overflow"] == 0).all()
    for _, g in df.groupby("config"):
        assert g["capacity_used"].nunique() == 1
