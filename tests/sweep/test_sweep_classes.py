"""Sweeps over several classes: data.class lists, per-class parameter axes, class-average rows,
reports and cross-validation per class and on the class average; single-class hashes unchanged."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dfrmot_jax.trackers.dfr import config as config_mod
from dfrmot_jax.trackers.dfr.config import PRESETS, Params, preset
from dfrmot_jax.sweep import (AVERAGE, COMBINED, PARAM_NAMES, RAW_COLUMN, SweepConfigError, class_columns,
                              class_view, config_hash, cross_validate, expand, load_results, load_spec, make_folds,
                              parse_spec, plan, resolve_data_all, run_sweep, sweep_report)
from dfrmot_jax.synthetic import make_scene

SWEEPS = Path(__file__).resolve().parents[2] / "sweeps"

# config_hash of every config of the shipped single-class sweeps, computed before sweeps had classes
# (sha1 of the concatenated hashes in table order): they must never move.
GOLDEN = {
    "kitti_dfr_grid.toml": (1024, "b5af84cd4ba86a90"),
    "kitti_kalman.toml": (161, "45b1a1ed8c8fc6ad"),
    "kitti_options.toml": (128, "4550e35a5d0172b4"),
    "kitti_random.toml": (257, "aa5ed139b7ccdcbe"),
    "kitti_smoke.toml": (9, "89ba95ae7621e241"),
    "robustness.toml": (1310, "82e012a9bb1e3dc9"),
}


def _digest(table: pd.DataFrame) -> str:
    return hashlib.sha1("".join(table["config_hash"]).encode()).hexdigest()[:16]


def multiclass_scene(directory: Path, n_sequences: int = 3, n_frames: int = 40, ped_sequences=(0, 2),
                     seed: int = 3) -> Path:
    """A KITTI-layout root with cars and pedestrians: two synthetic scenes, the second relabelled
    Pedestrian (track ids + 1000, 3D type code 1) in ``ped_sequences`` only, so the pedestrian split
    is a subset of the car split."""
    cars = make_scene(directory / "cars", n_sequences=n_sequences, n_frames=n_frames, n_cars=4, seed=seed)
    peds = make_scene(directory / "peds", n_sequences=n_sequences, n_frames=n_frames, n_cars=4, seed=seed + 100)
    root = directory / "root"
    (root / "label_02").mkdir(parents=True)
    shutil.copytree(cars / "calib", root / "calib")
    for det in ("synth2d", "synth3d"):
        shutil.copytree(cars / "detections" / det / "car", root / "detections" / det / "car")
        (root / "detections" / det / "pedestrian").mkdir(parents=True)
    for s in range(n_sequences):
        name = f"{s:04d}.txt"
        lines = (cars / "label_02" / name).read_text().splitlines()
        d2 = d3 = ""
        if s in ped_sequences:
            for ln in (peds / "label_02" / name).read_text().splitlines():
                f = ln.split(" ")
                if f[2] == "Car":              # vans and don't-care regions of the second scene left out
                    f[1], f[2] = str(int(f[1]) + 1000), "Pedestrian"
                    lines.append(" ".join(f))
            d2 = (peds / "detections" / "synth2d" / "car" / name).read_text()
            d3 = "".join(ln.replace(",2,", ",1,", 1) + "\n"
                         for ln in (peds / "detections" / "synth3d" / "car" / name).read_text().splitlines())
        lines.sort(key=lambda ln: int(ln.split(" ")[0]))
        (root / "label_02" / name).write_text("".join(ln + "\n" for ln in lines))
        (root / "detections" / "synth2d" / "pedestrian" / name).write_text(d2)
        (root / "detections" / "synth3d" / "pedestrian" / name).write_text(d3)
    return root


@pytest.fixture(scope="module")
def root(tmp_path_factory) -> Path:
    return multiclass_scene(tmp_path_factory.mktemp("classes"))


def mc_spec(root, **extra) -> dict:
    """Two classes, the car settings as every class's baseline (independent of CLASS_DEFAULTS)."""
    spec = {"name": "classes", "chunk": 8,
            "data": {"root": str(root), "det2d": "synth2d", "det3d": "synth3d", "class": ["car", "pedestrian"]},
            "baseline": {"preset": "dfr2023", "class": "car"},
            "params": {"score_2d": [0.3, 0.45], "pedestrian.score_2d": [0.3, 0.45], "min_hits": [1, 2]}}
    spec.update(extra)
    return spec


@pytest.fixture(scope="module")
def run(root, tmp_path_factory):
    out = tmp_path_factory.mktemp("classes_out") / "run"
    df = run_sweep(mc_spec(root), out=out, progress=False, workers=0, log=lambda m: None)
    return df, out


@pytest.fixture
def no_ped_defaults(monkeypatch):
    """No pedestrian defaults for one test (per-class axes alone)."""
    monkeypatch.setitem(config_mod.CLASS_DEFAULTS, "pedestrian", {})


@pytest.fixture
def ped_defaults(monkeypatch):
    """CLASS_DEFAULTS["pedestrian"] set (as after tuning) for one test."""
    monkeypatch.setitem(config_mod.CLASS_DEFAULTS, "pedestrian", {"a_l": 2.0, "score_2d": 0.6})


# ---- hashes ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", sorted(GOLDEN))
def test_single_class_hashes_unchanged(name):
    t = expand(load_spec(SWEEPS / name))
    assert (len(t), _digest(t)) == GOLDEN[name]
    assert not class_columns(t.columns)


def test_class_columns_equal_to_plain_hash_as_before():
    row = {**PRESETS["dfr2023"][0]._asdict(), **PRESETS["dfr2023"][1]._asdict()}
    h = config_hash(row)
    assert config_hash({**row, "pedestrian.a_l": row["a_l"], "car.score_2d": row["score_2d"]}) == h
    assert config_hash({**row, "pedestrian.a_l": 2.0}) != h
    assert config_hash({**row, "pedestrian.a_l": 2.0}) != config_hash({**row, "car.a_l": 2.0})
    assert config_hash({**row, "a_l": 2.0}) != config_hash({**row, "pedestrian.a_l": 2.0})


def test_multi_class_without_class_values_hashes_as_single_class(monkeypatch):
    axes = {"a_l": [4.0, 8.0], "score_2d": [0.3, 0.45]}
    single = expand({"params": axes})
    car_base = {"preset": "dfr2023", "class": "car"}
    multi = expand({"data": {"class": ["car", "pedestrian"]}, "baseline": car_base, "params": axes})
    pd.testing.assert_frame_equal(single, multi)
    monkeypatch.setitem(config_mod.CLASS_DEFAULTS, "pedestrian", {})
    pd.testing.assert_frame_equal(single, expand({"data": {"class": ["car", "pedestrian"]}, "params": axes}))


# ---- the file ----------------------------------------------------------------------------------------


def test_class_list_and_per_class_axis_forms(no_ped_defaults):
    forms = [{"pedestrian": {"a_l": [1.0, 2.0]}},          # pedestrian.a_l = [...] (TOML dotted key)
             {"pedestrian.a_l": [1.0, 2.0]},                # "pedestrian.a_l" = [...] (quoted key)
             {"pedestrian": {"a_l": {"grid": [1.0, 2.0]}}}]
    tables = []
    for form in forms:
        spec = parse_spec({"data": {"class": ["car", "pedestrian"]}, "params": {"a_l": [4.0, 8.0], **form}})
        assert spec.classes == ("car", "pedestrian") and spec.cls == "car"
        ax = [a for a in spec.variants[0].params if a.cls]
        assert [(a.name, a.param, a.cls, a.key) for a in ax] == [("pedestrian.a_l", "a_l", "pedestrian",
                                                                  ax[0].key)]
        assert ax[0].key.startswith("params.pedestrian.a_l")
        tables.append(expand(spec))
    for t in tables[1:]:
        pd.testing.assert_frame_equal(t, tables[0])
    t = tables[0]
    assert class_columns(t.columns) == ["pedestrian.a_l"]
    assert list(t.columns).index("pedestrian.a_l") == list(t.columns).index(Params._fields[-1]) + 1   # after the params
    assert t["pedestrian.a_l"].dtype == np.float64
    assert len(t) == 1 + 4 and t.loc[0, "pedestrian.a_l"] == 8.0          # the baseline: the preset for both
    grid = t[~t["baseline"]]
    assert sorted(zip(grid["a_l"], grid["pedestrian.a_l"])) == [(4.0, 1.0), (4.0, 2.0), (8.0, 1.0), (8.0, 2.0)]
    assert t["config_hash"].is_unique
    # a per-class axis of the only class is that class's parameter: a plain column, the plain hash
    one = expand({"data": {"class": "pedestrian"}, "params": {"pedestrian": {"a_l": [1.0, 2.0]}}})
    plain = expand({"data": {"class": "pedestrian"}, "params": {"a_l": [1.0, 2.0]}})
    pd.testing.assert_frame_equal(one, plain)


def test_per_class_axes_in_variants_and_random(no_ped_defaults):
    t = expand({"data": {"class": ["car", "pedestrian"]}, "seed": 1, "samples": 3,
                "params": {"a_l": [4.0, 8.0]},
                "variants": [{"name": "a", "params": {"pedestrian": {"score_2d": {"uniform": [0.5, 0.7]}}}},
                             {"name": "b", "params": {"car.a_c": {"uniform": [0.1, 0.2]}}}]})
    a, b = t[t["variant"] == "a"], t[t["variant"] == "b"]
    assert len(a) == 6 and a["pedestrian.score_2d"].between(0.5, 0.7).all()
    assert (a["car.a_c"] == a["a_c"]).all()              # an axis of another variant: the plain value
    assert len(b) == 6 and b["car.a_c"].between(0.1, 0.2).all() and (b["a_c"] == 0.05).all()
    assert (b["pedestrian.score_2d"] == b["score_2d"]).all()
    assert class_columns(t.columns) == ["car.a_c", "pedestrian.score_2d"]     # classes in data.class order


def test_class_defaults_baseline_and_precedence(ped_defaults):
    assert preset("dfr2023", "pedestrian")[0].a_l == 2.0
    # one class: the baseline is the preset for that class; a plain axis overrides the class default
    one = expand({"data": {"class": "pedestrian"}, "params": {"a_l": [1.0, 4.0]}})
    assert one.loc[0, "a_l"] == 2.0 and one.loc[0, "score_2d"] == 0.6 and not class_columns(one.columns)
    assert set(one.loc[1:, "a_l"]) == {1.0, 4.0} and (one["score_2d"] == 0.6).all()
    # [baseline] class = "car": the car settings for every class, whatever the pedestrian defaults
    car = expand({"data": {"class": "pedestrian"}, "baseline": {"preset": "dfr2023", "class": "car"},
                  "params": {"a_l": [1.0, 4.0]}})
    assert car.loc[0, "a_l"] == 8.0 and car.loc[0, "score_2d"] == 0.45
    assert car.loc[0, "config_hash"] == expand({"params": {"a_l": [1.0]}}).loc[0, "config_hash"]
    # several classes: plain = the bare preset, pedestrian.* = its defaults where they differ
    multi = expand({"data": {"class": ["car", "pedestrian"]}, "params": {"a_l": [1.0, 8.0], "min_hits": [1, 2]}})
    assert class_columns(multi.columns) == ["pedestrian.score_2d", "pedestrian.a_l"]
    b = multi.loc[0]
    assert (b["a_l"], b["score_2d"], b["pedestrian.a_l"], b["pedestrian.score_2d"]) == (8.0, 0.45, 2.0, 0.6)
    grid = multi[~multi["baseline"]]
    assert (grid["pedestrian.a_l"] == grid["a_l"]).all()           # the plain a_l axis moves every class
    assert (grid["pedestrian.score_2d"] == 0.6).all()               # unswept: the class default
    assert len(multi) == 5                                          # (8, 1) is not the baseline: ped differs
    # a class default that differs from nothing is no column; [baseline] class = car: none at all
    same = expand({"data": {"class": ["car", "pedestrian"]}, "baseline": {"preset": "dfr2023", "class": "car"},
                   "params": {"a_l": [1.0, 8.0], "min_hits": [1, 2]}})
    assert not class_columns(same.columns)
    pd.testing.assert_frame_equal(same, expand({"params": {"a_l": [1.0, 8.0], "min_hits": [1, 2]}}))
    # what each class is tracked with: its columns where the table has them
    from dfrmot_jax.sweep import params_of

    for cls in ("car", "pedestrian"):
        got = params_of(multi, [0], cls)
        for k, v in preset("dfr2023", cls)[0]._asdict().items():
            assert float(getattr(got, k)[0]) == pytest.approx(v, abs=0), (cls, k)


def test_shipped_pedestrian_sweep_baseline_is_the_car_settings(ped_defaults):
    spec = load_spec(SWEEPS / "kitti_pedestrian.toml")
    assert spec.classes == ("pedestrian",) and spec.baseline_class == "car"
    t = expand(spec)
    base = t.loc[0]
    for k, v in PRESETS["dfr2023"][0]._asdict().items():
        assert base[k] == v, k
    assert base["config_hash"] == expand({"params": {"a_l": [1.0]}}).loc[0, "config_hash"]
    config_mod.CLASS_DEFAULTS["pedestrian"] = {}
    pd.testing.assert_frame_equal(t, expand(spec))        # the table does not depend on the pedestrian defaults


@pytest.mark.parametrize("doc, key", [
    ({"data": {"class": ["car", "cyclist"]}}, "data.class[1]"),
    ({"data": {"class": ["car", "car"]}}, "data.class"),
    ({"data": {"class": []}}, "data.class"),
    ({"data": {"class": 3}}, "data.class"),
    ({"params": {"pedestrian": {"a_l": [1.0]}}}, "params.pedestrian.a_l"),                 # class not swept
    ({"data": {"class": ["car", "pedestrian"]}, "params": {"pedestrian": {"a_l": [0.0]}}}, "params.pedestrian.a_l[0]"),
    ({"data": {"class": ["car", "pedestrian"]}, "params": {"pedestrian.a_l": [-1.0]}}, "params.pedestrian.a_l[0]"),
    ({"data": {"class": ["car", "pedestrian"]}, "params": {"pedestrian": {"a_lidar": [1.0]}}},
     "params.pedestrian.a_lidar"),
    ({"data": {"class": ["car", "pedestrian"]}, "params": {"pedestrian": {"output": ["filtered"]}}},
     "params.pedestrian.output"),
    ({"data": {"class": ["car", "pedestrian"]}, "params": {"cyclist": {"a_l": [1.0]}}}, "params.cyclist"),
    ({"data": {"class": ["car", "pedestrian"]}, "params": {"cyclist.a_l": [1.0]}}, "params.cyclist"),
    ({"data": {"class": ["car", "pedestrian"]}, "params": {"a_l": [4.0]},
      "options": {"pedestrian": {"output": "filtered"}}}, "options.pedestrian"),
    ({"data": {"class": ["car", "pedestrian"]}, "params": {"a_l": [4.0]},
      "variants": [{"params": {"pedestrian.epsilon": [2.5]}}]}, "variants[0].params.pedestrian.epsilon[0]"),
    ({"data": {"class": ["car", "pedestrian"]}, "params": {"pedestrian.keep_lost": [0, 2]}},
     "params.pedestrian.keep_lost"),
    ({"params": {"a_l": [4.0]}, "report": {"class": "pedestrian"}}, "report.class"),
    ({"params": {"a_l": [4.0]}, "baseline": {"preset": "dfr2023", "class": "truck"}}, "baseline.class"),
])
def test_bad_class_settings_name_the_key(doc, key):
    with pytest.raises(SweepConfigError) as e:
        expand(doc)
    assert e.value.key == key, str(e.value)
    assert key in str(e.value)


def test_each_class_its_own_split(root):
    datas = resolve_data_all(mc_spec(root))
    assert [(d.cls, d.sequences) for d in datas] == [("car", ("0000", "0001", "0002")),
                                                     ("pedestrian", ("0000", "0002"))]
    given = resolve_data_all(mc_spec(root, data={**mc_spec(root)["data"], "sequences": ["0001", "0002"]}))
    assert [d.sequences for d in given] == [("0001", "0002")] * 2
    t = expand(mc_spec(root))
    chunks = plan(t, datas, 8)
    assert [c.cls for c in chunks] == ["car", "pedestrian"]
    assert all(c.configs == tuple(range(len(t))) for c in chunks) and chunks[0].id != chunks[1].id
    # one class's chunks are what a single-class plan gives for it
    assert [c.id for c in plan(t, datas[1], 8)] == [chunks[1].id]


# ---- running -----------------------------------------------------------------------------------------


@pytest.mark.slow
def test_tidy_table_rows_per_class_and_average(run):
    df, _ = run
    n = df["config"].nunique()
    assert n == 8                                   # 2 x 2 x 2 (the baseline is one of them)
    for cfg, g in df.groupby("config"):
        assert list(zip(g["class"], g["sequence"])) == [
            ("car", "0000"), ("car", "0001"), ("car", "0002"), ("car", COMBINED),
            ("pedestrian", "0000"), ("pedestrian", "0002"), ("pedestrian", COMBINED), (AVERAGE, COMBINED)]
    assert "pedestrian.score_2d" in df.columns and not df.duplicated(["config", "class", "sequence"]).any()
    comb = df[df["sequence"] == COMBINED]
    assert comb.groupby("class")["frames"].first().to_dict() == {"car": 120, "pedestrian": 80, AVERAGE: 200}
    # the classes were tracked with their own values: pedestrian rows depend on pedestrian.score_2d only
    ped = comb[comb["class"] == "pedestrian"]
    assert ped.groupby(["pedestrian.score_2d", "min_hits"])["HOTA"].nunique().eq(1).all()
    assert ped["HOTA"].nunique() > 1
    car = comb[comb["class"] == "car"]
    assert car.groupby(["score_2d", "min_hits"])["HOTA"].nunique().eq(1).all()


@pytest.mark.slow
def test_average_rows_are_trackeval_class_average(run):
    from dfrmot_jax.metrics.kitti2d.evaluate import CLASS_SUMMED_FIELDS, class_average
    from dfrmot_jax.metrics.kitti2d.table import TABLE_FIELDS

    df, _ = run
    comb = df[df["sequence"] == COMBINED]
    fields = [f for f in TABLE_FIELDS if f in df.columns]
    for cfg in comb["config"].unique():
        rows = comb[comb["config"] == cfg].set_index("class")
        expect = class_average({k: rows.loc[k, fields].to_dict() for k in ("car", "pedestrian")})
        for f in fields:
            assert rows.loc[AVERAGE, f] == pytest.approx(expect[f], abs=1e-9), f
        assert rows.loc[AVERAGE, "HOTA"] == pytest.approx((rows.loc["car", "HOTA"] + rows.loc["pedestrian", "HOTA"]) / 2)
        assert rows.loc[AVERAGE, "IDSW"] == rows.loc["car", "IDSW"] + rows.loc["pedestrian", "IDSW"]
        assert "IDSW" in CLASS_SUMMED_FIELDS and "HOTA" not in CLASS_SUMMED_FIELDS
    assert df.loc[df["class"] == AVERAGE, "IDSW"].dtype == np.int64


@pytest.mark.slow
def test_pedestrian_rows_equal_a_single_class_sweep(run, root):
    """The pedestrian rows of the two-class sweep are what a pedestrian-only sweep of the same
    effective settings gives (the chunk split, compilation and metrics are per class)."""
    df, _ = run
    one = run_sweep({"name": "ped", "chunk": 8,
                 "data": {"root": str(root), "det2d": "synth2d", "det3d": "synth3d", "class": "pedestrian"},
                 "baseline": {"preset": "dfr2023", "class": "car"},
                 "params": {"score_2d": [0.3, 0.45], "min_hits": [1, 2]}},
                progress=False, workers=0, log=lambda m: None)
    view = class_view(df, "pedestrian")
    assert not class_columns(view.columns) and view["config"].nunique() == 4     # 8 configs, 4 distinct for it
    key = ["score_2d", "min_hits", "sequence"]
    metrics = ["HOTA", "DetA", "AssA", "MOTA", "IDF1", "IDSW", "Frag", "CLR_FP"]
    a = view.set_index(key)[metrics].sort_index()
    b = one.set_index(key)[metrics].sort_index()
    pd.testing.assert_frame_equal(a, b)


@pytest.mark.slow
def test_resume_and_directory(run, root):
    df, out = run
    pd.testing.assert_frame_equal(load_results(out), df)
    logs = []
    again = run_sweep(mc_spec(root), out=out, progress=False, workers=0, log=logs.append)
    assert "tracked" not in " ".join(logs) and "[pedestrian]" in " ".join(logs)
    pd.testing.assert_frame_equal(again, df)
    # from the chunks alone (no results.parquet) the average rows are rebuilt identically
    (out / "results.parquet").rename(out / "r.parquet")
    try:
        pd.testing.assert_frame_equal(load_results(out), df)
    finally:
        (out / "r.parquet").rename(out / "results.parquet")
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["classes"] == ["car", "pedestrian"]
    assert manifest["class_data"]["pedestrian"]["sequences"] == ["0000", "0002"]


@pytest.mark.slow
def test_cv_on_the_average_folds_each_class(run):
    from dfrmot_jax.sweep import objective_on, per_sequence_arrays, combine_sequences, summary_columns

    df, _ = run
    cv = cross_validate(df, folds=2, objective="HOTA")            # several classes: the average by default
    assert cv["class"] == AVERAGE and len(cv["per_fold"]) == 2
    per = {}
    for k in ("car", "pedestrian"):
        comb, names, lengths, arrays = per_sequence_arrays(df[df["class"] == k])
        per[k] = (names, arrays, make_folds(names, lengths, 2))
    avg = df[df["class"] == AVERAGE].reset_index(drop=True)
    chosen = {k: {} for k in per}
    for f, p in enumerate(cv["per_fold"]):
        assert p["test_sequences"] == {k: per[k][2][f] for k in per}
        train = np.mean([objective_on(a, [names.index(s) for s in names if s not in fs[f]], "HOTA")
                         for names, a, fs in per.values()], axis=0)
        test = np.mean([objective_on(a, [names.index(s) for s in fs[f]], "HOTA") for names, a, fs in per.values()],
                       axis=0)
        best = int(np.flatnonzero(train == train.max())[0])
        assert p["config"] == avg.at[best, "config"] and p["train"] == pytest.approx(train[best])
        assert p["held_out"] == pytest.approx(test[best])
        for k in per:
            chosen[k].update({s: best for s in per[k][2][f]})
    pooled = []
    for k, (names, arrays, _) in per.items():
        sub = {f: np.stack([v[chosen[k][s], i] for i, s in enumerate(names)])[None] for f, v in arrays.items()}
        pooled.append(summary_columns(combine_sequences(sub))["HOTA"][0])
    assert cv["cross_validated"] == pytest.approx(np.mean(pooled))
    assert cv["baseline"] == avg[avg["baseline"]]["HOTA"].iloc[0]
    # IDSW (a count) is summed over the classes, and minimised
    cv = cross_validate(df, folds=2, objective="IDSW")
    assert cv["baseline"] == avg[avg["baseline"]]["IDSW"].iloc[0]


@pytest.mark.slow
def test_cv_and_report_on_one_class_equal_its_view(run):
    df, _ = run
    view = class_view(df, "pedestrian")
    a, b = cross_validate(df, 2, "HOTA", cls="pedestrian"), cross_validate(view, 2, "HOTA")
    assert a == b
    rep = sweep_report(df, folds=2, cls="pedestrian")
    assert rep.summary["class"] == "pedestrian" and rep.summary["configs"] == 4
    ped = df[(df["class"] == "pedestrian") & (df["sequence"] == COMBINED)]
    assert rep.summary["best_in_sample"] == ped["HOTA"].max()
    assert rep.summary["baseline"] == ped[ped["baseline"]]["HOTA"].iloc[0]
    assert set(rep.summary["best_config"]) - {"config", "config_hash"} <= set(PARAM_NAMES)   # its own values
    assert "class pedestrian" in rep.text.splitlines()[0]
    with pytest.raises(ValueError, match="cyclist"):
        sweep_report(df, cls="cyclist")


@pytest.mark.slow
def test_report_defaults_to_the_average(run):
    df, _ = run
    rep = sweep_report(df, folds=2, top=3)
    avg = df[df["class"] == AVERAGE]
    assert rep.summary["class"] == AVERAGE and rep.summary["classes"] == ["car", "pedestrian"]
    assert rep.summary["best_in_sample"] == avg["HOTA"].max() and rep.summary["configs"] == 8
    assert "pedestrian.score_2d" in rep.summary["best_config"]
    assert "class average" in rep.text.splitlines()[0] and "car:" in rep.text
    assert rep.summary["best_cross_validated"] == cross_validate(df, 2, "HOTA")["cross_validated"]
    assert set(rep.sensitivity["axis"]) == {"score_2d", "pedestrian.score_2d", "min_hits"}


@pytest.mark.slow
def test_cli_report_class(run, root, tmp_path, capsys):
    from dfrmot_jax.cli import main

    _, out = run
    assert main(["report", str(out), "--class", "pedestrian", "--folds", "2"]) == 0
    last = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert last["class"] == "pedestrian" and "best_cross_validated" in last
    assert main(["report", str(out)]) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["class"] == AVERAGE
    assert main(["report", str(out), "--class", "cyclist"]) == 2
    # report.class in the file is the default of the sweep's summary and of later reports
    f = tmp_path / "c.toml"
    f.write_text(f'name = "c"\nchunk = 8\n[data]\nroot = "{root}"\ndet2d = "synth2d"\ndet3d = "synth3d"\n'
                 f'class = ["car", "pedestrian"]\n[baseline]\npreset = "dfr2023"\nclass = "car"\n[params]\nscore_2d = [0.3, 0.45]\npedestrian.score_2d = [0.3, 0.45]\n'
                 f'min_hits = [1, 2]\n[report]\nclass = "pedestrian"\n')
    assert main(["sweep", str(f), "--out", str(tmp_path / "o"), "--dry-run"]) == 0
    text = capsys.readouterr().out
    assert "pedestrian (2 sequences" in text and "pedestrian.score_2d" in text
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)                   # the same configs and data: every chunk is reused
    assert main(["sweep", str(f), "--out", str(copy), "--summary", "--no-progress", "--workers", "0"]) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["class"] == "pedestrian"


@pytest.mark.slow
def test_raw_column_of_average_rows(run):
    df, _ = run
    avg = df[df["class"] == AVERAGE]
    raw = np.stack(avg[RAW_COLUMN].to_numpy()).reshape(len(avg), 7, 19)
    car = np.stack(df[(df["class"] == "car") & (df["sequence"] == COMBINED)][RAW_COLUMN].to_numpy()).reshape(-1, 7, 19)
    ped = np.stack(df[(df["class"] == "pedestrian") & (df["sequence"] == COMBINED)][RAW_COLUMN].to_numpy()
                   ).reshape(-1, 7, 19)
    np.testing.assert_array_equal(raw[:, :3], car[:, :3] + ped[:, :3])          # HOTA_TP, FN, FP summed
    np.testing.assert_allclose(raw[:, 3:], (car[:, 3:] + ped[:, 3:]) / 2)       # AssA, AssRe, AssPr, LocA averaged


def test_shipped_ablation_tuned_variant_is_the_pedestrian_default():
    t = expand(load_spec(SWEEPS / "kitti_pedestrian_ablation.toml"))
    tuned = t[t["variant"] == "tuned"].iloc[0]
    assert config_mod.CLASS_DEFAULTS["pedestrian"], "the pedestrian defaults are set"
    for k, v in preset("dfr2023", "pedestrian")[0]._asdict().items():
        assert tuned[k] == v, k
    for k, v in PRESETS["dfr2023"][0]._asdict().items():
        assert t.loc[0, k] == v, k                      # the baseline row: the car settings


@pytest.mark.slow
def test_kitti_pedestrian_baseline_and_defaults(kitti_root):
    """On KITTI (skipped without the data): pedestrians with the car settings score HOTA 50.43, with
    the pedestrian defaults (CLASS_DEFAULTS, from sweeps/kitti_pedestrian.toml) 55.82."""
    df = run_sweep({"name": "ped", "data": {"root": str(kitti_root), "class": "pedestrian"},
                "baseline": {"preset": "dfr2023", "class": "car"},
                "variants": [{"name": "tuned", "params": dict(config_mod.CLASS_DEFAULTS["pedestrian"])}]},
               progress=False, log=lambda m: None)
    comb = df[df["sequence"] == COMBINED].set_index("variant")
    assert df["sequence"].nunique() == 16                               # 15 sequences with pedestrians
    assert round(float(comb.loc["baseline", "HOTA"]), 2) == 50.43
    assert round(float(comb.loc["tuned", "HOTA"]), 2) == 55.82
    rows = expand({"data": {"class": "pedestrian"}, "params": {"a_c": [0.1]}})
    assert rows.loc[0, "config_hash"] == comb.loc["tuned", "config_hash"]   # [baseline] preset = tuned
