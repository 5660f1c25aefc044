"""Robustness studies with 3D detections: an AB3DMOT sweep with a [distortion] table and its sAMOTA
(``[metrics] ab3dmot``) run end to end, each lane's figures those of the lane tracked alone on its
distorted detections and scored from its written files; DFR-FastMOT's rows of a distorted lane
carry that lane's own 3D detections (scores, shifted boxes, clutter), so its sAMOTA is the lane's."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dfrmot_jax.trackers.dfr import track as api
from dfrmot_jax import distort
from dfrmot_jax.trackers.ab3dmot import family as af
from dfrmot_jax.cli import main
from dfrmot_jax.trackers.dfr.config import Options, Params
from dfrmot_jax.data import load_split
from dfrmot_jax.metrics import evaluate_files, metrics_table, prepare_gt
from dfrmot_jax.metrics.samota.evaluate import evaluate_ab3dmot_files
from dfrmot_jax.metrics.samota.table import AB3DMOT_COLUMNS, AB3DMOT_OTHER_COLUMNS, ab3dmot_columns
from dfrmot_jax.trackers.dfr.results import kitti_rows
from dfrmot_jax.sweep import COMBINED, SweepConfigError, load_results, parse_spec, run_sweep
from dfrmot_jax.synthetic import make_scene


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    return make_scene(tmp_path_factory.mktemp("dist3d_scene"), n_sequences=2, n_frames=40, n_cars=4, seed=9)


STUDY = """name = "robust3d"
chunk = 4
[data]
root = "{root}"
det3d = "synth3d"
[options]
family = "ab3dmot"
[params]
min_hits = [1, 3]
[distortion]
kind = ["drop", "clutter"]
levels = {{ drop = [0, 0.3], clutter = [1.0] }}
seeds = 2
clutter_slots = 2
[metrics]
ab3dmot = "3d:0.25"
"""


@pytest.mark.slow           # (an AB3DMOT sweep of 10 lanes, 12 lanes tracked and scored alone)
def test_an_ab3dmot_robustness_study_runs_resumes_and_reports(scene, tmp_path, capsys):
    f = tmp_path / "study.toml"
    f.write_text(STUDY.format(root=scene))
    out = tmp_path / "out"
    assert main(["sweep", str(f), "--out", str(out), "--no-progress"]) == 0
    capsys.readouterr()
    table = load_results(out)
    comb = table[table["sequence"] == COMBINED]
    assert len(comb) == 2 * 5 and comb["sAMOTA"].notna().all()
    assert set(zip(comb["distortion.kind"], comb["distortion.level"])) == {("none", 0.0), ("drop", 0.3),
                                                                           ("clutter", 1.0)}
    # every lane: its config tracked alone on its distorted detections, written, scored from the files
    axes = parse_spec(__import__("tomllib").loads(f.read_text())).distortion
    split = load_split(scene, None, "synth3d", "car")
    gt = prepare_gt(scene, "car", split.names)
    fam = af.FAMILY
    for i, (_, row) in enumerate(comb.iterrows()):
        params = fam.config.Params(**{n: row[n] for n in fam.config.Params._fields})
        options = fam.config.Options(**{n: type(fam.config.Options._field_defaults[n])(row[n])
                                        for n in fam.config.Options._fields})
        dp = axes.lane(row["distortion.kind"], row["distortion.level"], row["distortion.seed"])
        res = af.track(split, params, options, distortion=distort.stack_distort([dp]), clutter_slots=2)
        d = tmp_path / f"alone{i}"
        af.write_runs(d, [af.class_run(split, res, 0)])
        want = ab3dmot_columns(evaluate_ab3dmot_files(d, scene, "car", list(split.names), iou="3d:0.25", other=True))
        for col in AB3DMOT_COLUMNS + AB3DMOT_OTHER_COLUMNS:
            assert row[col] == want[col], (i, col, row[col], want[col])
        assert row["HOTA"] == metrics_table(evaluate_files(d, gt)).loc[COMBINED, "HOTA"]
    lanes = comb.groupby(["distortion.kind", "distortion.seed"])["sAMOTA"].mean()
    assert lanes[("clutter", 0)] != lanes[("clutter", 1)] and lanes[("drop", 0)] < lanes[("none", 0)]
    # resumed: nothing tracked again, the same table
    assert main(["sweep", str(f), "--out", str(out), "--no-progress"]) == 0
    err = capsys.readouterr().err
    assert "tracked" not in err
    assert load_results(out).equals(table)
    # the report's per-level tables
    assert main(["report", str(out), "--objective", "sAMOTA"]) == 0
    text = capsys.readouterr().out
    assert "drop \\ level" in text and "clutter \\ level" in text
    last = json.loads(text.strip().splitlines()[-1])
    assert set(last["robustness"]) == {"drop", "clutter"}


@pytest.mark.parametrize("kind, key", [("drop_2d", "distortion.kind[1]"), ("jitter_2d", "distortion.kind[1]"),
                                       ("clutter_2d", "distortion.kind[1]"), ("score_2d", "distortion.kind[1]")])
def test_an_ab3dmot_study_refuses_kinds_of_2d_detections_only(scene, kind, key):
    doc = __import__("tomllib").loads(STUDY.format(root=scene))
    doc["distortion"]["kind"] = ["drop", kind]
    doc["distortion"]["levels"] = {"drop": [0.1], kind: [1.0]}
    with pytest.raises(SweepConfigError, match=r"2D detections only") as e:
        parse_spec(doc)
    assert e.value.key == key
    doc["options"]["family"] = "dfr"                # (DFR-FastMOT reads them: its studies take them)
    del doc["params"]
    assert parse_spec(doc).distortion.kinds[1][0] == kind


@pytest.mark.slow           # (DFR-FastMOT compiled with the distortion hook and the rows' 3D detail)
def test_dfr_rows_of_a_distorted_lane_carry_its_own_3d_detections(scene):
    """``kitti_rows`` of a distorted DFR-FastMOT lane: a row carrying its own 3D detection has the
    lane's distorted score and shifted box (read back as AB3DMOT's lanes read them), clutter rows
    the clutter's car-sized box; the level-0 lane's rows are the undistorted run's, bit for bit."""
    split = load_split(scene, "synth2d", "synth3d", "car")
    lanes = [distort.level_params("none", 0.0, seed=3),
             distort.level_params("clutter_3d", 1.5, seed=4, score_noise_3d=2.0, jitter_3d=0.5)]
    options = Options(modality="3d")
    params = Params(*(np.repeat(np.asarray(v)[None], 2) for v in Params(score_3d=-100.0)))
    res = api.track(split, params, options, detail=True, distortion=distort.stack_distort(lanes), clutter_slots=2)
    clean = api.track(split, Params(score_3d=-100.0), options, detail=True)
    got, want = kitti_rows(split, res, lanes=[0]), kitti_rows(split, clean)
    for name in ("t", "ids", "score", "box3d"):
        np.testing.assert_array_equal(getattr(got, name), getattr(want, name))
    rows = kitti_rows(split, res, lanes=[1])
    d = res.distortion
    after = distort.distort_split(d.frames, d.gid2, d.gid3, lanes[1], d.spec)
    src = np.asarray(res.src3)[1][np.asarray(res.ids)[1] >= 0]
    m3 = d.frames.valid3.shape[1]
    t, j = np.divmod(src, m3)
    own = src >= 0
    np.testing.assert_array_equal(rows.score[own].astype(np.float32), np.asarray(after.score3)[t[own], j[own]])
    fake = own & (j >= split.valid3d.shape[1])
    assert fake.sum() > 3
    np.testing.assert_array_equal(rows.box3d[fake][:, :3], np.broadcast_to(np.float32(distort.CAR_DIMS), (fake.sum(), 3)))
    np.testing.assert_array_equal(rows.box3d[fake][:, 3].astype(np.float32), np.asarray(after.lo3)[t[fake], j[fake], 2])
    real = own & ~fake
    shifted = rows.box3d[real][:, 3:6] - np.asarray(split.loc3d)[t[real], j[real]]
    assert np.abs(shifted).max() > 0.1
    lo0, lo1 = np.asarray(d.frames.lo3)[t[real], j[real]], np.asarray(after.lo3)[t[real], j[real]]
    np.testing.assert_allclose(shifted, (lo1.astype(np.float64) - lo0)[:, ::-1], rtol=0, atol=1e-12)


@pytest.mark.slow           # (a DFR-FastMOT sweep with sAMOTA per lane, tracked twice)
def test_a_dfr_robustness_study_scores_samota_per_lane(scene):
    spec = {"name": "dfr3d", "chunk": 4, "data": {"root": str(scene), "det2d": "synth2d", "det3d": "synth3d"},
            "params": {"epsilon": [1, 30]}, "metrics": {"ab3dmot": "3d:0.25"},
            "distortion": {"kind": ["score_3d", "clutter_3d"], "levels": {"score_3d": [0, 2.0], "clutter_3d": [1.0]},
                           "seeds": 1, "clutter_slots": 2}}
    table = run_sweep(spec, progress=False, log=lambda m: None, workers=0)
    comb = table[table["sequence"] == COMBINED]
    assert comb["sAMOTA"].notna().all()
    clean = run_sweep({k: v for k, v in spec.items() if k != "distortion"}, progress=False, log=lambda m: None,
                      workers=0)
    zero = comb[comb["distortion.kind"] == "none"].set_index("epsilon")["sAMOTA"]
    base = clean[clean["sequence"] == COMBINED].set_index("epsilon")["sAMOTA"]
    assert zero.to_dict() == base.loc[zero.index].to_dict()
    for kind in ("score_3d", "clutter_3d"):       # each lane scored on its own detections, not the split's
        lane = comb[comb["distortion.kind"] == kind].set_index("epsilon")["sAMOTA"]
        assert (lane != zero.loc[lane.index]).any(), kind


@pytest.mark.slow           # (DFR-FastMOT compiled with the distortion hook and the rows' 3D detail)
def test_distorted_dfr_lanes_scored_together_equal_each_lane_scored_alone(scene):
    """AB3DMOT's figures of distorted DFR-FastMOT lanes scored in one pass (as a sweep's scorer
    scores a chunk) equal each lane's rows scored alone: an undistorted lane, jittered lanes of two
    seeds and a cluttered lane share object slots and 3D indices but not their values, so no lane's
    values stand for another's (the noise study's lanes once scored a neighbour's boxes)."""
    from dfrmot_jax.metrics.samota.arrays import evaluate_ab3dmot_rows
    from dfrmot_jax.metrics.samota.prep import prepare_ab3dmot_gt

    split = load_split(scene, "synth2d", "synth3d", "car")
    lanes = [distort.level_params("none", 0.0, seed=0),
             distort.level_params("jitter", 8.0, seed=1),
             distort.level_params("jitter", 8.0, seed=2),
             distort.level_params("jitter", 2.0, seed=1),
             distort.level_params("clutter", 2.0, seed=3)]
    params = Params(*(np.repeat(np.asarray(v)[None], len(lanes)) for v in Params()))
    res = api.track(split, params, Options(), detail=True, distortion=distort.stack_distort(lanes), clutter_slots=2)
    gt = prepare_ab3dmot_gt(scene, "car", split.names)

    def score(which):
        rows = kitti_rows(split, res, lanes=which)
        return evaluate_ab3dmot_rows(gt, **rows._asdict(), seq_offsets=split.offsets, check_ids=False)

    together = score(list(range(len(lanes))))
    alone = [score([b])[0] for b in range(len(lanes))]
    assert together == alone
    samota = [r["sAMOTA"] for r in alone]
    assert samota[1] < samota[3] and samota[1] < samota[0] and samota[1] != samota[2]
