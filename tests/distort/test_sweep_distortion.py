"""Distortion sweeps: [distortion] axes expand into per-lane columns vmapped with the parameter grid."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dfrmot_jax import distort
from dfrmot_jax.trackers.dfr.config import Options, Params
from dfrmot_jax.sweep import (COMBINED, DISTORTION_AXES, OPTION_NAMES, PARAM_NAMES, RAW_COLUMN, SweepConfigError,
                              config_hash, expand, load_results, load_spec, n_settings, plan, resolve_data,
                              robustness_contrast, robustness_curves, robustness_summary, run_sweep, sweep_report)
from dfrmot_jax.synthetic import make_scene

METRICS = ["HOTA", "DetA", "AssA", "MOTA", "IDF1", "IDSW", "Frag", "CLR_FP", "CLR_FN", "IDTP"]


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    return make_scene(tmp_path_factory.mktemp("dist_scene"), n_sequences=3, n_frames=80, n_cars=5, seed=5)


def dist_spec(root, **extra) -> dict:
    spec = {"name": "dist", "chunk": 7,
            "data": {"root": str(root), "det2d": "synth2d", "det3d": "synth3d"},
            "params": {"epsilon": [1, 30]},
            "options": {"output": ["detections", "filtered"]},
            "distortion": {"kind": ["drop", "burst"], "levels": {"drop": [0.0, 0.3], "burst": [0, 8]},
                           "seeds": 2}}
    spec.update(extra)
    return spec


def quiet(**kw):
    return dict(progress=False, log=lambda m: None, **kw)


@pytest.fixture(scope="module")
def dist_table(scene) -> pd.DataFrame:
    return run_sweep(dist_spec(scene), **quiet())


@pytest.fixture(scope="module")
def clean_table(scene) -> pd.DataFrame:
    spec = dist_spec(scene)
    del spec["distortion"]
    return run_sweep(spec, **quiet())


# ---- the config table ----------------------------------------------------------------------------


def test_axes_expand_into_columns_and_hashes(scene):
    t = expand(dist_spec(scene))
    # 4 settings (epsilon x output; the baseline is one of them) x (1 undistorted + 2 kinds x 1 level x 2 seeds)
    assert len(t) == 4 * 5
    assert list(t.columns[-3:]) == list(DISTORTION_AXES)
    assert t["distortion.kind"].dtype == object and t["distortion.level"].dtype == np.float64
    assert t["distortion.seed"].dtype == np.int64
    assert t["config_hash"].is_unique and list(t["config"]) == list(range(len(t)))
    assert t.loc[0, "baseline"] and t["baseline"].sum() == 1 and t.loc[0, "distortion.kind"] == "none"
    # innermost: kind, level, seed of one config
    first = t.iloc[:5]
    assert list(zip(first["distortion.kind"], first["distortion.level"], first["distortion.seed"])) == [
        ("none", 0.0, 0), ("drop", 0.3, 0), ("drop", 0.3, 1), ("burst", 8.0, 0), ("burst", 8.0, 1)]
    assert (first[list(PARAM_NAMES) + list(OPTION_NAMES)].nunique() == 1).all()
    # level 0 is the undistorted config: the hash of the sweep without [distortion]
    spec = dist_spec(scene)
    del spec["distortion"]
    plain = expand(spec)
    assert "distortion.kind" not in plain.columns
    zero = t[t["distortion.kind"] == "none"]
    assert list(zero["config_hash"]) == list(plain["config_hash"])
    assert sorted(plain.columns) == sorted(c for c in t.columns if c not in DISTORTION_AXES)
    # every distortion axis is part of the hash; stable across expansions
    row = t.iloc[1].to_dict()
    h = config_hash(row)
    assert h == row["config_hash"] == expand(dist_spec(scene)).loc[1, "config_hash"]
    for k, v in (("distortion.kind", "drop_2d"), ("distortion.level", 0.4), ("distortion.seed", 9)):
        assert config_hash({**row, k: v}) != h
    # a sweep-wide setting that changes a lane changes its hash (and not the undistorted lanes')
    t2 = expand(dist_spec(scene, distortion={**dist_spec(scene)["distortion"], "burst_rate": 0.05}))
    same = t2["config_hash"] == t["config_hash"]
    assert same[t["distortion.kind"] != "burst"].all() and not same[t["distortion.kind"] == "burst"].any()


def test_level_forms_and_seed_lists():
    t = expand({"params": {"epsilon": [1]},
                "distortion": {"kind": "drop", "level": {"linspace": [0, 0.4, 3]}, "seeds": [3, 7]}})
    d = t[t["distortion.kind"] == "drop"]
    assert sorted(set(d["distortion.level"])) == [0.2, 0.4] and set(d["distortion.seed"]) == {3, 7}
    # the baseline is crossed too; level 0 once per setting
    assert (t["distortion.kind"] == "none").sum() == 2 and len(t) == 2 * 5
    # without level 0 only the baseline keeps its undistorted row
    t = expand({"params": {"epsilon": [1]}, "distortion": {"kind": "burst", "level": [5], "seeds": 1}})
    assert list(t["distortion.kind"]) == ["none", "burst", "burst"] and t.loc[0, "baseline"]
    assert n_settings(t) == 2


@pytest.mark.parametrize("dist, key", [
    ({"kind": "wobble", "level": [0.1]}, "distortion.kind"),
    ({"kind": ["drop", "smear"], "level": [0.1]}, "distortion.kind[1]"),
    ({"kind": "none", "level": [0.1]}, "distortion.kind"),
    ({"kind": "drop", "level": [0.1, -0.2]}, "distortion.level[1]"),
    ({"kind": "drop", "level": [0.5, 1.5]}, "distortion.level[1]"),
    ({"kind": "burst_rate", "level": 2.0}, "distortion.level"),
    ({"kind": ["drop", "burst"], "levels": {"drop": [0.1], "burst": [-1]}}, "distortion.levels.burst[0]"),
    ({"kind": "burst", "level": [40]}, "distortion.level[0]"),
    ({"kind": "drop", "level": [0.1], "seeds": 0}, "distortion.seeds"),
    ({"kind": "drop", "level": [0.1], "seeds": []}, "distortion.seeds"),
    ({"kind": "drop", "level": [0.1], "seeds": [1, -1]}, "distortion.seeds[1]"),
    ({"kind": "drop", "level": [0.1], "seeds": 2.5}, "distortion.seeds"),
    ({"kind": "drop"}, "distortion.levels"),
    ({"kind": "drop", "level": [0.1], "levels": {"burst": [2]}}, "distortion.levels.burst"),
    ({"kind": "drop", "level": [0.1], "colour": 1}, "distortion.colour"),
    ({"kind": "clutter", "level": [1.0]}, "distortion.level[0]"),
    ({"kind": "drop", "level": [0.1], "clutter_slots": -1}, "distortion.clutter_slots"),
    ({"kind": "burst", "level": [5], "burst_dist": "poisson"}, "distortion.burst_dist"),
    ({"kind": "burst", "level": [5], "burst_rate": 1.5}, "distortion.burst_rate"),
    ({"kind": "drop", "level": "high"}, "distortion.level"),
])
def test_bad_distortion_tables_name_the_key(dist, key):
    with pytest.raises(SweepConfigError) as e:
        expand({"params": {"epsilon": [1, 30]}, "distortion": dist})
    assert e.value.key == key
    assert key in str(e.value)


def test_bad_contrast_names_the_key():
    for c, key in (({"axis": "colour", "high": [1], "low": [2]}, "report.contrast.axis"),
                   ({"axis": "epsilon", "high": [30]}, "report.contrast.low"),
                   ({"axis": "epsilon", "high": [30], "low": [30]}, "report.contrast"),
                   ({"axis": "epsilon", "high": [30], "low": [1], "by": ["nope"]}, "report.contrast.by")):
        with pytest.raises(SweepConfigError) as e:
            expand({"params": {"epsilon": [1, 30]}, "report": {"contrast": c}})
        assert e.value.key == key


def test_bad_distortion_fails_before_any_work(scene, tmp_path, monkeypatch):
    import dfrmot_jax.trackers.dfr.track

    def boom(*a, **k):
        raise AssertionError("tracking started")

    monkeypatch.setattr(dfrmot_jax.trackers.dfr.track, "track", boom)
    f = tmp_path / "bad.toml"
    f.write_text(f'[data]\nroot = "{scene}"\ndet2d = "synth2d"\ndet3d = "synth3d"\n[params]\nepsilon = [1, 30]\n'
                 f'[distortion]\nkind = "drop"\nlevel = [0.0, 1.2]\nseeds = 3\n')
    from dfrmot_jax.cli import main

    assert main(["sweep", str(f), "--out", str(tmp_path / "out"), "--no-progress"]) == 2
    assert not (tmp_path / "out").exists()


def test_shipped_robustness_study():
    spec = load_spec(Path(__file__).resolve().parents[2] / "sweeps" / "robustness.toml")
    t = expand(spec)
    d = spec.distortion
    kinds = dict(d.kinds)
    assert set(kinds) == {"drop", "burst"} and len(d.seeds) == 10
    assert all(len([v for v in lv]) >= 7 for lv in kinds.values())
    assert kinds["drop"] == (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6)
    assert max(kinds["burst"]) == 30 and min(v for v in kinds["burst"] if v > 0) == 1
    settings = t[t["distortion.kind"] == "none"]
    assert len(settings) >= 8 and set(settings["filter"]) == {"fixed_gain", "kalman"}
    assert {1, 2, 3, 30, 60} <= set(settings["epsilon"])
    assert len(t) == len(settings) * d.n_lanes
    assert spec.contrast.axis == "epsilon" and set(spec.contrast.high) == {30, 60}


# ---- running -------------------------------------------------------------------------------------


@pytest.mark.slow
def test_tidy_rows_carry_the_axes(dist_table, scene):
    t = expand(dist_spec(scene))
    df = dist_table
    assert len(df) == len(t) * 4 and not df.duplicated(["config", "sequence"]).any()
    comb = df[df["sequence"] == COMBINED].reset_index(drop=True)
    pd.testing.assert_frame_equal(comb[["config", "config_hash", *DISTORTION_AXES]],
                                  t[["config", "config_hash", *DISTORTION_AXES]], check_dtype=False)
    assert (comb["overflow"] == 0).all()


@pytest.mark.slow
def test_level0_rows_equal_the_undistorted_sweep(dist_table, clean_table):
    """Level-0 lanes run inside distorted chunks (zero levels, same compiled program) and give the
    undistorted sweep's rows exactly."""
    zero = dist_table[dist_table["distortion.kind"] == "none"].drop(columns=list(DISTORTION_AXES))
    zero = zero.set_index(["config_hash", "sequence"]).sort_index()
    clean = clean_table.set_index(["config_hash", "sequence"]).sort_index()
    assert list(zero.index) == list(clean.index)
    for col in METRICS + ["overflow", "frames"]:
        np.testing.assert_array_equal(zero[col].to_numpy(), clean[col].to_numpy(), err_msg=col)
    assert all(np.array_equal(a, b) for a, b in zip(zero[RAW_COLUMN], clean[RAW_COLUMN]))


@pytest.mark.slow
def test_distortion_degrades_and_seeds_differ(dist_table):
    comb = dist_table[dist_table["sequence"] == COMBINED]
    base = comb[comb["distortion.kind"] == "none"].set_index(["epsilon", "output"])["DetA"].sort_index()
    for kind in ("drop", "burst"):
        d = comb[comb["distortion.kind"] == kind]
        assert (d.groupby(["epsilon", "output"])["DetA"].max().sort_index() < base).all()
        # different seeds, different distortion
        assert d.groupby(["epsilon", "output"])["IDTP"].nunique().max() == 2


@pytest.mark.slow
def test_rows_equal_direct_track_with_per_lane_boxes(dist_table, scene):
    """A distorted row is what track(distortion=...) + evaluate_arrays on the lane's own boxes, as its
    result file prints them, give; jitter moves the boxes, so the scorer must use the per-lane boxes."""
    import dfrmot_jax as dm
    from dfrmot_jax.io.columns import as_written
    from dfrmot_jax.metrics import evaluate_arrays, metrics_table, prepare_gt

    spec = dist_spec(scene, distortion={"kind": "jitter", "level": [3.0], "seeds": [4]}, chunk=64,
                     options={"output": "filtered"})
    df = run_sweep(spec, **quiet())
    split = dm.load_split(scene, "synth2d", "synth3d", "car")
    gt = prepare_gt(scene, "car", split.names)
    comb = df[(df["sequence"] == COMBINED) & (df["distortion.kind"] == "jitter")]
    row = comb.iloc[-1]
    params = Params(**{n: row[n] for n in PARAM_NAMES})
    options = Options(**{n: type(Options._field_defaults[n])(row[n]) for n in OPTION_NAMES})
    res = dm.track(split, dm.stack_params([params]), options,
                   distortion=distort.stack_distort([distort.level_params("jitter", 3.0, seed=4)]))
    clean = dm.track(split, dm.stack_params([params]), options)
    assert not np.array_equal(res.lane_boxes(0), clean.lane_boxes(0))
    written = as_written(np.asarray(res.boxes, np.float64), 6)          # (%g, as the file prints them)
    expect = metrics_table(evaluate_arrays(gt, res.ids, written, split.offsets)[0])
    got = df[df["config"] == row["config"]].set_index("sequence")
    for col in expect.columns:
        np.testing.assert_array_equal(got.loc[list(expect.index), col].to_numpy(), expect[col].to_numpy(),
                                      err_msg=col)


@pytest.mark.slow
def test_clutter_lanes_add_false_positives(scene):
    spec = dist_spec(scene, options={}, distortion={"kind": "clutter", "level": [0, 1.5], "seeds": 2,
                                                     "clutter_slots": 3})
    df = run_sweep(spec, **quiet())
    comb = df[df["sequence"] == COMBINED]
    fp = comb.groupby(["epsilon", "distortion.kind"])["CLR_FP"].mean().unstack()
    assert (fp["clutter"] > fp["none"]).all() and (comb["overflow"] == 0).all()
    # the reserved slots are part of the lane's identity
    other = expand(dist_spec(scene, options={}, distortion={**spec["distortion"], "clutter_slots": 4}))
    t = expand(spec)
    assert (other["config_hash"] != t["config_hash"]).sum() == (t["distortion.kind"] == "clutter").sum()


@pytest.mark.slow
def test_deterministic_and_chunking_independent(dist_table, scene):
    again = run_sweep(dist_spec(scene, chunk=3), **quiet())
    cols = [c for c in dist_table.columns if c not in ("chunk", RAW_COLUMN)]
    pd.testing.assert_frame_equal(again[cols], dist_table[cols])
    assert all(np.array_equal(a, b) for a, b in zip(again[RAW_COLUMN], dist_table[RAW_COLUMN]))


@pytest.mark.slow
def test_resume_skips_finished_chunks(dist_table, scene, tmp_path):
    out = tmp_path / "run"
    spec = dist_spec(scene)
    first = run_sweep(spec, out=out, **quiet())
    chunks = sorted((out / "chunks").glob("*.parquet"))
    manifest = json.loads((out / "manifest.json").read_text())
    assert len(chunks) == len(manifest["chunks"]) >= 3
    assert manifest["distortion"]["kinds"] == {"drop": [0.0, 0.3], "burst": [0.0, 8.0]}
    # a crash after some chunks: remove two finished chunks and the final table, rerun
    for p in chunks[:2]:
        p.unlink()
    (out / "results.parquet").unlink()
    logs = []
    resumed = run_sweep(spec, out=out, progress=False, log=logs.append)
    assert f"{len(chunks) - 2} done" in logs[0] and "tracked" in " ".join(logs)
    pd.testing.assert_frame_equal(resumed, first)
    cols = [c for c in first.columns if c != RAW_COLUMN]
    pd.testing.assert_frame_equal(first[cols], dist_table[cols])
    # everything finished: no work at all
    logs = []
    again = run_sweep(spec, out=out, progress=False, log=logs.append)
    assert f"{len(chunks)} done" in logs[0] and "tracked" not in " ".join(logs)
    pd.testing.assert_frame_equal(again, first)
    pd.testing.assert_frame_equal(load_results(out), first)
    # other distortion settings are other chunks: nothing reused by mistake
    t = expand(spec)
    data = resolve_data(spec)
    other = with_distortion(spec, burst_dist="geometric")
    ids = {c.id for c in plan(expand(other), data, spec["chunk"], _axes(other))}
    assert not ids & {c.id for c in plan(t, data, spec["chunk"], _axes(spec))}


def with_distortion(spec, **dist):
    return {**spec, "distortion": {**spec["distortion"], **dist}}


def _axes(spec):
    from dfrmot_jax.sweep import parse_spec

    return parse_spec(spec).distortion


# ---- curves, contrasts, report -------------------------------------------------------------------


@pytest.mark.slow
def test_curves_and_contrast(dist_table):
    curves = robustness_curves(dist_table, ["HOTA", "IDSW"])
    assert set(curves["kind"]) == {"drop", "burst"}
    assert curves.groupby(["setting", "kind"]).size().eq(2).all()          # level 0 + one level per kind
    zero = curves[curves["level"] == 0]
    assert (zero["n"] == 1).all() and (zero["HOTA_se"] == 0).all()
    dist = curves[curves["level"] > 0]
    assert (dist["n"] == 2).all()
    assert (dist["HOTA_min"] <= dist["HOTA"]).all() and (dist["HOTA"] <= dist["HOTA_max"]).all()
    comb = dist_table[dist_table["sequence"] == COMBINED]
    sel = comb[(comb["epsilon"] == 1) & (comb["output"] == "filtered") & (comb["distortion.kind"] == "drop")]
    row = curves[(curves["setting"] == "epsilon=1 output=filtered") & (curves["kind"] == "drop")
                 & (curves["level"] > 0)]
    assert row["HOTA"].iloc[0] == pytest.approx(sel["HOTA"].mean())
    assert row["HOTA_se"].iloc[0] == pytest.approx(sel["HOTA"].std(ddof=1) / np.sqrt(2))

    con = robustness_contrast(dist_table, "epsilon", high=[30], low=[1], metrics=["HOTA", "IDSW"], by=["output"])
    assert len(con) == 2 * 2 * 2 * 2            # output x kind x level x metric
    r = con[(con["output"] == "detections") & (con["kind"] == "burst") & (con["level"] == 8) &
            (con["metric"] == "HOTA")].iloc[0]
    d = comb[(comb["output"] == "detections") & (comb["distortion.kind"] == "burst")]
    diff = (d[d["epsilon"] == 30].set_index("distortion.seed")["HOTA"]
            - d[d["epsilon"] == 1].set_index("distortion.seed")["HOTA"])
    assert r["gap"] == pytest.approx(diff.mean()) and r["se"] == pytest.approx(diff.std(ddof=1) / np.sqrt(2))
    assert r["n"] == 2
    summ = robustness_summary(con)
    assert len(summ) == 2 * 2 * 2 and {"helps_up_to", "stops_at", "crossing", "gap_before", "max_gap"} <= set(summ)


@pytest.mark.slow
def test_report_prints_levels_and_contrast(dist_table, scene, tmp_path, capsys):
    rep = sweep_report(dist_table, top=3, contrast={"axis": "epsilon", "high": [30], "low": [1]})
    assert "robustness: HOTA" in rep.text and "drop \\ level" in rep.text and "burst \\ level" in rep.text
    assert "contrast epsilon in [30] minus epsilon in [1]" in rep.text
    assert max(len(x) for x in rep.text.splitlines()[:-1]) <= 120      # the JSON line is one object
    last = json.loads(rep.text.strip().splitlines()[-1])
    assert set(last["robustness"]) == {"drop", "burst"}
    assert last["robustness"]["drop"]["levels"] == [0.0, 0.3]
    assert {a["kind"] for a in last["contrast"]["answer"]} == {"drop", "burst"}
    # a contrast the table cannot answer is reported, not raised
    rep = sweep_report(dist_table, top=3, contrast={"axis": "epsilon", "high": [99], "low": [1]})
    assert "contrast epsilon [99] vs [1]: contrast: no rows with epsilon in [99]" in rep.text
    from dfrmot_jax.cli import main

    f = tmp_path / "s.toml"
    f.write_text(f'name = "cli"\nchunk = 8\n[data]\nroot = "{scene}"\ndet2d = "synth2d"\ndet3d = "synth3d"\n'
                 f'[params]\nepsilon = [1, 30]\n[distortion]\nkind = "drop"\nlevel = [0, 0.4]\nseeds = 2\n'
                 f'[report]\ncontrast = {{axis = "epsilon", high = [30], low = [1]}}\n')
    out = tmp_path / "out"
    assert main(["sweep", str(f), "--out", str(out), "--dry-run"]) == 0
    text = capsys.readouterr().out
    assert "6 configs" in text and "2 settings x 3 lanes" in text
    assert main(["sweep", str(f), "--out", str(out), "--no-progress", "--summary"]) == 0
    text = capsys.readouterr().out
    assert "contrast epsilon in [30] minus epsilon in [1]" in text
    assert main(["report", str(out), "--contrast", "epsilon:30/1"]) == 0
    last = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert last["contrast"]["high"] == [30] and last["contrast"]["low"] == [1]


@pytest.mark.slow          # the fast tier's budget: one of its costliest tests
def test_a_robustness_report_leads_with_its_robustness_tables(dist_table):
    """Issue 41, item 18: a robustness sweep's report led with the generic sections (the best of every
    lane vs the baseline, a distortion lane's seed as a sensitivity axis) before its robustness tables:
    the robustness tables come first, and a seed (a replicate, no setting) is no sensitivity axis."""
    rep = sweep_report(dist_table, top=3, contrast={"axis": "epsilon", "high": [30], "low": [1]})
    lines = rep.text.splitlines()
    first = lambda prefix: next(i for i, x in enumerate(lines) if x.startswith(prefix))  # noqa: E731
    assert first("robustness: HOTA") < first("contrast epsilon in [30] minus epsilon in [1]") < first("top 3 configs")
    assert "distortion.seed" not in set(rep.sensitivity["axis"])
    assert "epsilon" in set(rep.sensitivity["axis"])
