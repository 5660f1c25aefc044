"""Sweeps over the LiDAR settings ([lift], [simulate]): each setting its own split, rows equal to
separate ``dm.track`` runs on that setting's lifted boxes, bad values naming the key."""

import numpy as np
import pytest

import dfrmot_jax as dm
from dfrmot_jax.trackers.dfr.config import Options, Params
from dfrmot_jax.io.kitti import read_calib, read_tracking_labels, sequence_lengths
from dfrmot_jax.lidar import LiftSettings, SimSettings, simulate_to_folder, tie_scores
from dfrmot_jax.metrics import evaluate_arrays, metrics_table, prepare_gt
from dfrmot_jax.sweep import (COMBINED, OPTION_NAMES, PARAM_NAMES, SweepConfigError, config_hash, expand,
                              parse_spec, plan, resolve_data_all, run_sweep)
from dfrmot_jax.synthetic import make_scene

SEQS = ["0000", "0001"]


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    root = make_scene(tmp_path_factory.mktemp("lsweep"), n_sequences=2, n_frames=30, n_cars=5, seed=4)
    scans = root / "scans"
    lengths = sequence_lengths(root, SEQS)
    for s in SEQS:
        simulate_to_folder(scans, read_tracking_labels(root / "label_02" / f"{s}.txt"),
                           read_calib(root / "calib" / f"{s}.txt"), lengths[s], s, SimSettings(beams=32), seed=0)
    return root, scans


def spec_of(root, det3d, **extra):
    doc = {"name": "lsweep", "chunk": 8, "data": {"root": str(root), "det2d": "synth2d", "det3d": det3d},
           "params": {"a_l": [4.0, 8.0]}}
    doc.update(extra)
    return doc


def direct(root, det3d, lift: LiftSettings, row):
    """The metrics of one config tracked directly: load_split with the lifting settings, the scores
    tied as ``dfrmot track`` ties them, ``dm.track``, ``evaluate_arrays``."""
    split = dm.load_split(root, "synth2d", det3d, "car", SEQS, lift=lift)
    params = tie_scores(Params(**{n: row[n] for n in PARAM_NAMES}))
    options = Options(**{n: type(Options._field_defaults[n])(row[n]) for n in OPTION_NAMES})
    res = dm.track(split, dm.stack_params([params]), options)
    gt = prepare_gt(root, "car", split.names)
    boxes = res.boxes[None] if res.boxes.ndim == 3 else res.boxes
    return metrics_table(evaluate_arrays(gt, res.ids, np.broadcast_to(boxes, res.ids.shape + (4,)),
                                         split.offsets)[0])


def check_rows(table, root, det3d, lift_of, n_expected):
    comb = table[table["sequence"] == COMBINED]
    assert len(comb) == n_expected
    for _, row in comb.iterrows():
        expect = direct(root, det3d(row), lift_of(row), row)
        got = table[table["config"] == row["config"]].set_index("sequence")
        for col in expect.columns:
            np.testing.assert_array_equal(got.loc[list(expect.index), col].to_numpy(), expect[col].to_numpy(),
                                          err_msg=f"{col} (config {row['config']})")


@pytest.mark.slow
def test_a_shrink_sweep_equals_separate_track_runs(scene):
    root, scans = scene
    spec = spec_of(root, f"lidar:{scans}", lift={"shrink": [0.0, 0.3]})
    table = run_sweep(spec, progress=False, log=lambda m: None)
    comb = table[table["sequence"] == COMBINED]
    # 2 x 2 configs plus the baseline (a_l = 8 of dfr2023 is a grid value: on the first shrink)
    assert sorted(set(comb["lift.shrink"])) == [0.0, 0.3]
    assert (comb["score_3d"] == comb["score_2d"]).all()            # tied, as dfrmot track ties them
    assert comb["baseline"].sum() == 1 and comb[comb["baseline"]]["lift.shrink"].item() == 0.0
    # the two settings really differ (else the test could not fail)
    by = comb.groupby("lift.shrink")["HOTA"].apply(list)
    assert by[0.0] != by[0.3]
    check_rows(table, root, lambda r: f"lidar:{scans}", lambda r: LiftSettings(shrink=r["lift.shrink"]), len(comb))


def test_each_setting_is_its_own_split_and_chunks(scene):
    root, scans = scene
    spec = parse_spec(spec_of(root, f"lidar:{scans}", lift={"shrink": [0.0, 0.1, 0.2], "min_cluster": [5, 8]}))
    table = expand(spec)
    datas = resolve_data_all(spec)
    assert len(datas) == 6 and len({d.lidar for d in datas}) == 6
    chunks = plan(table, datas, spec.chunk, spec.axes)
    # every config in exactly one split's chunks, that split's setting
    seen = sorted(i for c in chunks for i in c.configs)
    assert seen == list(range(len(table)))
    for c in chunks:
        d = next(d for d in datas if c.of(d))
        want = dict(d.lidar[0])
        for i in c.configs:
            assert table.loc[i, "lift.shrink"] == want.get("shrink", 0.2)
            assert table.loc[i, "lift.min_cluster"] == want.get("min_cluster", 5)


def test_default_lifting_keeps_the_hash():
    row = expand({"data": {"det3d": "lidar:x"}, "params": {"a_l": [4.0, 8.0]},
                  "lift": {"shrink": [0.2, 0.3]}}).iloc[0].to_dict()
    assert row["lift.shrink"] == 0.2 and row["baseline"]
    plain = {k: v for k, v in row.items() if not k.startswith("lift.")}
    assert config_hash(row) == config_hash(plain)
    assert config_hash({**row, "lift.shrink": 0.3}) != config_hash(plain)


@pytest.mark.parametrize("extra, key", [
    ({"lift": {"shrink": [0.0, 1.5]}}, "lift.shrink[1]"),
    ({"lift": {"shrink": "a"}}, "lift.shrink"),
    ({"lift": {"bogus": [1]}}, "lift.bogus"),
    ({"lift": {"min_cluster": [5, 2.5]}}, "lift.min_cluster[1]"),
    ({"lift": {"min_cluster": float("inf")}}, "lift.min_cluster"),          # was an OverflowError
    ({"lift": {"min_cluster": [5, float("nan")]}}, "lift.min_cluster[1]"),
    ({"lift": {"crop_lo": [[0.5, -20, 1.0]]}}, "lift.crop_lo[0]"),        # above crop_hi's z
    ({"lift": {"crop_lo": "0.5,-20,0.4", "crop_hi": [[180, 20, 0.3]]}}, "lift"),   # each fine, not together
    ({"lift": {"shrink": []}}, "lift.shrink"),
    ({"simulate": {"beams": [64, 0]}}, "simulate.beams[1]"),
    ({"simulate": {"dropout": 1.5}}, "simulate.dropout"),
    ({"simulate": {"seed": -1}}, "simulate.seed"),
    ({"simulate": {"rain": 1}}, "simulate.rain"),
])
def test_bad_lidar_values_name_the_key(extra, key):
    with pytest.raises(SweepConfigError) as e:
        parse_spec(spec_of("/nowhere", "lidar:/nowhere", **extra))
    assert e.value.key == key


def test_lidar_tables_need_lidar_data():
    with pytest.raises(SweepConfigError) as e:
        parse_spec(spec_of("/nowhere", "pointrcnn", lift={"shrink": [0.1]}))
    assert e.value.key == "lift"


def test_lidar_without_a_folder_names_the_file_and_data_det3d(tmp_path, capsys):
    """``det3d = "lidar:"``: the error named neither the sweep file nor the key."""
    from dfrmot_jax.sweep import load_spec
    from dfrmot_jax.testing.cli import error_line, run_cli

    f = tmp_path / "s.toml"
    f.write_text('[data]\nroot = "/nowhere"\ndet2d = "synth2d"\ndet3d = "lidar:"\n[params]\na_l = [4.0, 8.0]\n')
    with pytest.raises(SweepConfigError, match="expected lidar:DIR") as e:
        load_spec(f)
    assert (e.value.key, e.value.source) == ("data.det3d", str(f))
    status, _, err = run_cli(capsys, ["sweep", f, "--out", tmp_path / "out", "--dry-run"])
    assert status == 2 and f"{f}: data.det3d: " in error_line(err, "sweep", alone=True)
    f.write_text(f.read_text() + "[lift]\nmin_cluster = inf\n")
    f.write_text(f.read_text().replace('"lidar:"', '"lidar:/nowhere"'))
    status, _, err = run_cli(capsys, ["sweep", f, "--out", tmp_path / "out", "--dry-run"])
    assert status == 2 and f"{f}: lift.min_cluster: " in error_line(err, "sweep", alone=True)


def test_a_missing_scan_folder_names_data_det3d(scene, tmp_path):
    root, _ = scene
    with pytest.raises(SweepConfigError) as e:
        resolve_data_all(spec_of(root, f"lidar:{tmp_path / 'none'}", lift={"shrink": [0.1]}))
    assert e.value.key == "data.det3d"


@pytest.mark.slow
def test_a_beams_sweep_simulates_each_setting_once(scene, tmp_path):
    root, _ = scene
    cache = tmp_path / "cache"
    spec = spec_of(root, f"lidar:{cache}", params={"a_l": [8.0]}, simulate={"beams": [32, 16]},
                   lift={"shrink": [0.1]})
    table = run_sweep(spec, progress=False, log=lambda m: None)
    comb = table[table["sequence"] == COMBINED]
    assert sorted(comb["simulate.beams"]) == [16, 32]
    assert len(list((cache / "simulated").iterdir())) == 2
    lengths = sequence_lengths(root, SEQS)

    def det3d(row):        # the same setting's scans, simulated directly
        out = tmp_path / f"direct{int(row['simulate.beams'])}"
        if not out.is_dir():
            for s in SEQS:
                simulate_to_folder(out, read_tracking_labels(root / "label_02" / f"{s}.txt"),
                                   read_calib(root / "calib" / f"{s}.txt"), lengths[s], s,
                                   SimSettings(beams=int(row["simulate.beams"])), seed=0)
        return f"lidar:{out}"

    check_rows(table, root, det3d, lambda r: LiftSettings(shrink=0.1), 2)
    assert comb.set_index("simulate.beams").loc[16, "HOTA"] != comb.set_index("simulate.beams").loc[32, "HOTA"]
    # a second run reads the cached scans (no new simulation)
    stamp = {p: p.stat().st_mtime_ns for p in (cache / "simulated").rglob("*.bin")}
    run_sweep(spec, progress=False, log=lambda m: None)
    assert stamp == {p: p.stat().st_mtime_ns for p in (cache / "simulated").rglob("*.bin")}
