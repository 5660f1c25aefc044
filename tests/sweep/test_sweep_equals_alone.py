"""A sweep row is its config tracked, written and scored alone: random sweep tables crossing every
static option, run as users run them (chunks, the scores' memo, scoring overlapped with tracking),
each row checked field by field (exact) against ``track`` + ``write_lane`` + ``evaluate_files`` of
that config by itself. The memo once keyed a sequence's output on its ids and only the per-lane
boxes: option groups sharing ids but not boxes (``truncate``, ``merge``, ``modality``) got each
other's scores. The same for a tune's trials and for ``evaluate_arrays`` on mixed option groups, and
for sweeps of the second tracker family, AB3DMOT (``[options] family = "ab3dmot"``): a row is its config
tracked alone by the family's ``track``, written by its ``write_runs`` and scored from the files (and
its AB3DMOT figures, ``[metrics] ab3dmot``, those of ``dfrmot eval --metrics ab3dmot`` of the files), and of
the third, ByteTrack (camera only; with and without a ``[distortion]`` table)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

import dfrmot_jax as dm
from dfrmot_jax.trackers.dfr.config import OPTION_CHOICES, Options, Params
from dfrmot_jax.trackers.registry import family_of
from dfrmot_jax.metrics import evaluate_arrays, evaluate_files, metrics_table, prepare_gt
from dfrmot_jax.metrics.samota.evaluate import evaluate_ab3dmot_files
from dfrmot_jax.metrics.samota.table import AB3DMOT_COLUMNS, AB3DMOT_OTHER_COLUMNS, ab3dmot_columns
from dfrmot_jax.trackers.dfr.results import write_lane
from dfrmot_jax.distort import stack_distort
from dfrmot_jax.sweep import COMBINED, OPTION_NAMES, PARAM_NAMES, parse_spec, run_sweep
from dfrmot_jax.synthetic import make_scene

#: every static option a sweep may cross, with its values (capacity: the data's default)
OPTION_VALUES = {**OPTION_CHOICES, "truncate": (True, False)}
#: the options whose image boxes every lane of an option group shares (output "detections")
SHARED_BOX_OPTIONS = ("merge", "truncate", "modality")


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    return make_scene(tmp_path_factory.mktemp("alone_scene"), n_sequences=3, n_frames=36, n_cars=4, seed=5)


@pytest.fixture(scope="module")
def ground(scene):
    split = dm.load_split(scene, "synth2d", "synth3d", "car")
    return split, prepare_gt(scene, "car", split.names)


def options_of(row) -> Options:
    return Options(**{n: type(Options._field_defaults[n])(row[n]) for n in OPTION_NAMES})


def params_of(row) -> Params:
    return Params(**{n: row[n] for n in PARAM_NAMES})


def alone(split, gt, params: Params, options: Options, out: Path) -> pd.DataFrame:
    """``metrics_table`` of one config tracked, written (kitti columns) and scored from its files."""
    res = dm.track(split, dm.stack_params([params]), options)
    write_lane(out, split, dm.prepare_frames(split, options), options, res.ids[0], res.lane_boxes(0))
    return metrics_table(evaluate_files(out, gt))


def assert_rows_equal_alone(table: pd.DataFrame, split, gt, tmp: Path, key: str = "config") -> None:
    """Every (config, sequence) row of ``table`` equals that config run alone, every metric field."""
    done: dict = {}
    for cfg, rows in table.groupby(key, sort=False):
        first = rows.iloc[0]
        p, o = params_of(first), options_of(first)
        if (p, o) not in done:
            done[(p, o)] = alone(split, gt, p, o, tmp / f"{key}{cfg}")
        expect = done[(p, o)]
        got = rows.set_index("sequence")
        assert list(got.index) == list(expect.index)
        for col in expect.columns:
            np.testing.assert_array_equal(got[col].to_numpy(), expect[col].to_numpy(),
                                          err_msg=f"{key} {cfg} ({o}), {col}")


@st.composite
def variants(draw) -> list[dict]:
    """2-4 variants, each with every static option drawn and a few parameters; at least one a twin
    of another that differs only in options whose boxes the lanes share (the same ids, other boxes)."""
    def one(base=None):
        opts = {n: draw(st.sampled_from(v)) for n, v in OPTION_VALUES.items()} if base is None else dict(base)
        params = {"a_l": [draw(st.sampled_from([3.0, 6.0, 9.0]))],
                  "epsilon": [draw(st.integers(0, 6))],
                  "score_2d": [draw(st.sampled_from([0.0, 0.3, 0.5]))]}
        if draw(st.booleans()):
            params["a_c"] = [draw(st.sampled_from([0.0, 0.1, 0.4]))]
            params["alpha_c"] = [draw(st.sampled_from([0.3, 0.5, 0.9]))]
        if opts["output"] == "filtered" and draw(st.booleans()):
            params["keep_lost"] = [draw(st.integers(0, 2))]
        return opts, params

    n = draw(st.integers(2, 4))
    out = [one() for _ in range(n - 1)]
    opts, params = out[draw(st.integers(0, len(out) - 1))]
    twin = dict(opts)
    flip = draw(st.sampled_from(SHARED_BOX_OPTIONS))
    twin[flip] = draw(st.sampled_from([v for v in OPTION_VALUES[flip] if v != opts[flip]]))
    out.append((twin, params))
    return [{"name": f"v{i}", "options": o, "params": p} for i, (o, p) in enumerate(out)]


@pytest.mark.slow
@settings(max_examples=4, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(vs=variants(), chunk=st.sampled_from([1, 2, 3]))
def test_every_sweep_row_equals_its_config_run_alone(scene, ground, tmp_path_factory, vs, chunk):
    """4 drawn sweeps (each crossing every static option drawn, with a twin sharing its ids but not
    its boxes, so the memo's bug is in every draw): every row == its config alone, every field."""
    split, gt = ground
    spec = {"name": "alone", "chunk": chunk, "data": {"root": str(scene), "det2d": "synth2d", "det3d": "synth3d"},
            "params": {"a_f": [0.1, 0.3]}, "variants": vs}
    table = run_sweep(spec, progress=False, workers=0, log=lambda m: None)
    assert_rows_equal_alone(table, split, gt, tmp_path_factory.mktemp("alone"))


#: each AB3DMOT metric's thresholds, on its own scale (an overlap at least; a distance at most)
AB3DMOT_THRESHOLDS = {"iou_2d": (0.01, 0.2), "iou_3d": (0.01, 0.2), "giou_2d": (-0.4, 0.0), "giou_3d": (-0.4, -0.2, 0.1),
                      "dist_2d": (2.0, 4.0), "dist_3d": (2.0, 4.0), "m_dis": (6.0, 11.0)}


@pytest.fixture(scope="module")
def ground3d(scene):
    """The split as a family reading 3D detections only reads it (no 2D detections), its ground truth."""
    split = dm.load_split(scene, None, "synth3d", "car")
    return split, prepare_gt(scene, "car", split.names)


def ab3dmot_alone(scene, split, gt, row, out: Path, iou: str | None, dist=None) -> tuple[pd.DataFrame, dict | None]:
    """One AB3DMOT config (a table row) tracked alone by its family's ``track`` (one lane; with
    ``dist``, the sweep's ``DistortionAxes``, on the row's distortion lane), written by its
    ``write_runs`` and scored from the files: ``metrics_table``, and with ``iou`` AB3DMOT's figures
    of the files (what ``dfrmot eval --metrics ab3dmot`` prints)."""
    fam = family_of("ab3dmot")
    fc = fam.config
    params = fc.Params(**{n: row[n] for n in fc.Params._fields})
    options = fc.Options(**{n: type(fc.Options._field_defaults[n])(row[n]) for n in fc.Options._fields})
    kw = {}
    if dist is not None:
        dp = dist.lane(row["distortion.kind"], row["distortion.level"], row["distortion.seed"])
        kw = dict(distortion=stack_distort([dp]), clutter_slots=dist.clutter_slots)
    res = fam.track(split, params, options, **kw)
    fam.write_runs(out, [fam.class_run(split, res, 0)])
    figures = None if iou is None else ab3dmot_columns(
        evaluate_ab3dmot_files(out, scene, "car", list(split.names), iou=iou, other=True))
    return metrics_table(evaluate_files(out, gt)), figures


@st.composite
def ab3dmot_variants(draw) -> list[dict]:
    """1-2 variants of distinct AB3DMOT metrics, each with its algorithm, a threshold on its scale,
    min_hits and max_age drawn."""
    metrics = draw(st.lists(st.sampled_from(sorted(AB3DMOT_THRESHOLDS)), min_size=1, max_size=2, unique=True))
    return [{"name": f"v{i}", "options": {"metric": m, "algorithm": draw(st.sampled_from(["hungarian", "greedy"]))},
             "params": {"threshold": [draw(st.sampled_from(AB3DMOT_THRESHOLDS[m]))],
                        "min_hits": [draw(st.integers(0, 3))], "max_age": [draw(st.integers(1, 3))]}}
            for i, m in enumerate(metrics)]


#: the distortions an AB3DMOT sweep may draw: none, drops and bursts, or every 3D distortion with clutter
AB3DMOT_DISTORTIONS = (None, {"kind": ["drop_3d", "burst"], "levels": {"drop_3d": [0.3], "burst": [4]}, "seeds": 1},
                       {"kind": ["clutter", "jitter"], "levels": {"clutter": [1.0], "jitter": [3.0]}, "seeds": [7],
                        "clutter_slots": 2})


#: the AB3DMOT sweeps always run (with one drawn): each distortion, with and without sAMOTA, two
#: metrics in one sweep, chunks of 1 and 2; metrics whose programs compile quickest (no footprint
#: geometry), the drawn sweep taking any
AB3DMOT_EXAMPLES = (
    dict(vs=[{"name": "v0", "options": {"metric": "dist_3d", "algorithm": "hungarian"},
              "params": {"threshold": [4.0], "min_hits": [1], "max_age": [2]}},
             {"name": "v1", "options": {"metric": "m_dis", "algorithm": "hungarian"},
              "params": {"threshold": [11.0], "min_hits": [0], "max_age": [3]}}],
         chunk=2, figures=True, dist=AB3DMOT_DISTORTIONS[2]),
    dict(vs=[{"name": "v0", "options": {"metric": "dist_3d", "algorithm": "hungarian"},
              "params": {"threshold": [2.0], "min_hits": [3], "max_age": [1]}}],
         chunk=1, figures=False, dist=AB3DMOT_DISTORTIONS[1]),
)


@pytest.mark.slow
@settings(max_examples=1, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(vs=ab3dmot_variants(), chunk=st.sampled_from([1, 2, 3]), figures=st.booleans(),
       dist=st.sampled_from(AB3DMOT_DISTORTIONS))
@example(**AB3DMOT_EXAMPLES[0])
@example(**AB3DMOT_EXAMPLES[1])
def test_every_ab3dmot_sweep_row_equals_its_config_run_alone(scene, ground3d, tmp_path_factory, vs, chunk, figures,
                                                            dist):
    """An AB3DMOT sweep (its own columns, chunks, the scores' memo, its rows as its files print them):
    every (config, sequence) row == the config alone, every metric field exactly; with ``[metrics]
    ab3dmot`` every AB3DMOT figure of its COMBINED row == the files' (its other sum's too); with a
    ``[distortion]`` table each row's lane tracked alone on its distorted detections. Three sweeps:
    two fixed examples (``AB3DMOT_EXAMPLES``: clutter + jitter with sAMOTA and two metrics, drops +
    bursts without), so a distortion and sAMOTA are always covered, and one drawn."""
    split, gt = ground3d
    spec = {"name": "alone_ab3dmot", "chunk": chunk, "data": {"root": str(scene), "det3d": "synth3d"},
            "options": {"family": "ab3dmot"}, "params": {"score_threshold": [-10000.0, 8.0]}, "variants": vs}
    iou = "3d:0.25" if figures else None
    if figures:
        spec["metrics"] = {"ab3dmot": iou}
    if dist is not None:
        spec["distortion"] = dist
    axes = parse_spec(spec).distortion
    table = run_sweep(spec, progress=False, workers=0, log=lambda m: None)
    fc = family_of("ab3dmot").config
    assert set(fc.Params._fields + fc.Options._fields) <= set(table.columns) and "a_l" not in table.columns
    tmp = tmp_path_factory.mktemp("alone_ab3dmot")
    for cfg, rows in table.groupby("config", sort=False):
        expect, want = ab3dmot_alone(scene, split, gt, rows.iloc[0], tmp / f"config{cfg}", iou, axes)
        got = rows.set_index("sequence")
        assert list(got.index) == list(expect.index)
        for col in expect.columns:
            np.testing.assert_array_equal(got[col].to_numpy(), expect[col].to_numpy(), err_msg=f"config {cfg}, {col}")
        if figures:
            comb = got.loc[COMBINED]
            for col in AB3DMOT_COLUMNS + AB3DMOT_OTHER_COLUMNS:
                assert comb[col] == want[col], (cfg, col, comb[col], want[col])
    if figures:
        assert "sAMOTA" in table.columns
    else:
        assert "sAMOTA" not in table.columns


@pytest.mark.slow          # the fast tier's budget: one of its costliest tests
def test_option_groups_with_the_same_ids_keep_their_own_scores(scene, ground, tmp_path):
    """The memo's bug, pinned: truncation changes the boxes (here not the ids); each group scores its own."""
    split, gt = ground
    spec = {"name": "twins", "data": {"root": str(scene), "det2d": "synth2d", "det3d": "synth3d"},
            "params": {"a_l": [6.0]},
            "variants": [{"name": "raw", "options": {"truncate": False}},
                         {"name": "cut", "options": {"truncate": True}}]}
    table = run_sweep(spec, progress=False, workers=0, log=lambda m: None)
    comb = table[table["sequence"] == COMBINED].set_index("variant")
    assert comb.loc["raw", "LocA"] != comb.loc["cut", "LocA"]
    assert_rows_equal_alone(table, split, gt, tmp_path)


@pytest.mark.slow
def test_evaluate_arrays_of_mixed_option_groups_equals_each_alone(ground):
    """One batch of lanes from several option groups (per-lane boxes, repeated ids) scores each lane
    as it scores alone."""
    split, gt = ground
    ids, boxes = [], []
    for opts in (Options(), Options(truncate=False), Options(merge="calib_projection"), Options(truncate=False)):
        res = dm.track(split, dm.stack_params([Params()]), opts)
        ids.append(res.ids[0])
        boxes.append(np.broadcast_to(res.lane_boxes(0), res.ids.shape[1:] + (4,)))
    ids, boxes = np.stack(ids), np.stack(boxes).astype(np.float64)
    batch = evaluate_arrays(gt, ids, boxes, split.offsets, lanes_per_batch=2)
    for b in range(len(ids)):
        one = evaluate_arrays(gt, ids[b:b + 1], boxes[b:b + 1], split.offsets)[0]
        assert metrics_table(batch[b]).equals(metrics_table(one)), b


@pytest.mark.slow
def test_every_tune_row_equals_its_config_run_alone(scene, ground, tmp_path):
    """A tune's batches are sweeps on tables of trials (one memo across a batch's option groups)."""
    from dfrmot_jax.tuning import run_tune

    split, gt = ground
    path = tmp_path / "tune.toml"
    path.write_text(f"""
name = "tune_alone"
[data]
root = "{scene}"
det2d = "synth2d"
det3d = "synth3d"
[params]
a_l = [4.0, 8.0]
[options]
truncate = [true, false]
merge = ["detector_box", "calib_projection"]
modality = ["fused", "2d", "3d"]
output = ["detections", "filtered"]
[tune]
sampler = "random"
budget = 12
batch = 6
seed = 1
objectives = ["HOTA"]
""")
    res = run_tune(path, tmp_path / "out", progress=False, workers=0, log=lambda m: None)
    assert res.table["config_hash"].nunique() == 12
    assert_rows_equal_alone(res.table, split, gt, tmp_path, key="config_hash")


def test_the_scores_key_names_the_boxes_the_lanes_share(ground):
    """LaneScorer.seq_digests / digests: equal ids with other shared boxes are another output."""
    from dfrmot_jax.metrics.kitti2d.lane_scorer import LaneScorer

    split, gt = ground
    sc = LaneScorer(gt, split.offsets)
    ids = np.full((2, split.n_frames, 3), -1, np.int32)
    ids[:, :, 0] = 1
    boxes = np.tile(np.array([10.0, 20.0, 60.0, 90.0], np.float32), (split.n_frames, 3, 1))
    other = boxes.copy()
    other[0, 0, 0] += 0.5                              # one box of sequence 0, frame 0
    a, b = sc.seq_digests(ids, boxes), sc.seq_digests(ids, other)
    assert a[0] == a[1] and a[0][0] != b[0][0] and a[0][1:] == b[0][1:]
    assert LaneScorer.digests(ids, boxes) != LaneScorer.digests(ids, other)
    written = LaneScorer(gt, split.offsets, as_written=True)
    assert written.seq_digests(ids, boxes)[0] != a[0]          # scored another way: another key


@pytest.fixture(scope="module")
def ground2d(scene):
    """The split as a family reading 2D detections only reads it (no 3D detections), its ground truth."""
    split = dm.load_split(scene, "synth2d", None, "car")
    return split, prepare_gt(scene, "car", split.names)


#: ByteTrack's sweeps: two settings, without and with a [distortion] table (level 0, drops and bursts,
#: every 2D fault in a kind of its own: clutter, jitter, score noise)
BYTETRACK_DISTORTIONS = (None, {"kind": ["drop", "burst", "clutter", "jitter", "score"],
                                "levels": {"drop": [0, 0.3], "burst": [4], "clutter": [1.0], "jitter": [3.0],
                                           "score": [0.1]},
                                "seeds": [3], "clutter_slots": 2})


@pytest.mark.slow
@pytest.mark.parametrize("dist", BYTETRACK_DISTORTIONS, ids=["plain", "distorted"])
def test_every_bytetrack_sweep_row_equals_its_config_run_alone(scene, ground2d, tmp_path, dist):
    """A ByteTrack sweep (``[options] family = "bytetrack"``: its columns, chunks, the scores' memo, its
    rows as its files print them): every (config, sequence) row == the config tracked alone by the
    family's ``track`` (with a ``[distortion]`` table, on the row's distortion lane), written by its
    ``write_runs`` and scored from the files, every metric field exactly."""
    split, gt = ground2d
    spec = {"name": "alone_bytetrack", "chunk": 3, "data": {"root": str(scene), "det2d": "synth2d"},
            "options": {"family": "bytetrack"}, "params": {"track_thresh": [0.4, 0.6], "track_buffer": [5]}}
    if dist is not None:
        spec["distortion"] = dist
    axes = parse_spec(spec).distortion
    table = run_sweep(spec, progress=False, workers=0, log=lambda m: None)
    fam = family_of("bytetrack")
    fc = fam.config
    assert set(fc.Params._fields) <= set(table.columns) and "a_l" not in table.columns
    n = 2 * (1 if dist is None else axes.n_lanes)
    assert table["config"].nunique() >= n          # (and the baseline's config)
    for cfg, rows in table.groupby("config", sort=False):
        row = rows.iloc[0]
        params = fc.Params(**{k: row[k] for k in fc.Params._fields})
        options = fc.Options(**{k: type(fc.Options._field_defaults[k])(row[k]) for k in fc.Options._fields})
        kw = {}
        if dist is not None:
            dp = axes.lane(row["distortion.kind"], row["distortion.level"], row["distortion.seed"])
            kw = dict(distortion=stack_distort([dp]), clutter_slots=axes.clutter_slots)
        res = fam.track(split, params, options, **kw)
        out = tmp_path / f"config{cfg}"
        fam.write_runs(out, [fam.class_run(split, res, 0)])
        expect = metrics_table(evaluate_files(out, gt))
        got = rows.set_index("sequence")
        assert list(got.index) == list(expect.index)
        for col in expect.columns:
            np.testing.assert_array_equal(got[col].to_numpy(), expect[col].to_numpy(), err_msg=f"config {cfg}, {col}")
    if dist is not None:
        comb = table[table["sequence"] == COMBINED]
        assert comb.groupby("distortion.kind")["HOTA"].mean().nunique() == len(dist["kind"]) + 1
