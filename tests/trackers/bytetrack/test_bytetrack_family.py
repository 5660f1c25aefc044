"""ByteTrack as a tracker family (``trackers/bytetrack/family.py``): registered beside the others, read
without JAX, and through its batch entry point and result writer the reference runs' files byte for
byte (``dfrmot track --preset bytetrack_car`` gives ByteTrack's own files: the same lines, the same
order inside a frame, ids counted from 1 in each sequence)."""

from __future__ import annotations

import numpy as np
import pytest

from dfrmot_jax.data import load_split
from dfrmot_jax.testing.cli import run_cli
from dfrmot_jax.trackers.bytetrack import family as bt
from dfrmot_jax.trackers.bytetrack.config import FAMILY_CONFIG, Options, Params, parse_assignment
from dfrmot_jax.trackers.protocol import family_problems
from dfrmot_jax.trackers.registry import family_config, family_of, preset_family

REF = "reference/bytetrack_tracker"
#: run name -> (class, --set overrides)
RUNS = {"car_default": ("car", []), "car_mot20": ("car", ["fuse_score=false"]),
        "car_low": ("car", ["track_thresh=0.3", "track_buffer=60", "match_thresh=0.9"]),
        "car_fps30": ("car", ["frame_rate=30"]), "car_default_demofilter": ("car", ["demo_filter=true"]),
        "pedestrian_default": ("pedestrian", []),
        "pedestrian_low": ("pedestrian", ["track_thresh=0.3", "track_buffer=60", "match_thresh=0.9"])}


def test_the_family_is_registered_and_follows_the_protocol():
    fam = family_of("bytetrack")
    assert fam is bt.FAMILY and family_problems(fam) == [] and family_config("bytetrack") is FAMILY_CONFIG
    assert preset_family("bytetrack_car") is FAMILY_CONFIG and FAMILY_CONFIG.detections == ("2d",)
    p, o = parse_assignment("fuse_score=false", *FAMILY_CONFIG.preset("bytetrack_car", "car"))
    assert o.fuse_score is False and p == Params()
    with pytest.raises(ValueError, match="--set track_buffer=1.5: expected an integer"):
        parse_assignment("track_buffer=1.5", p, o)


def _files(out):
    return {f.name: f.read_bytes() for f in sorted(out.iterdir())}


@pytest.mark.parametrize("run", ["car_default", "car_default_demofilter", "car_mot20"])
def test_dfrmot_track_writes_the_reference_runs_files(kitti_root, tmp_path, capsys, run):
    cls, sets = RUNS[run]
    seqs = "0001,0012,0017"
    argv = ["track", "--data", str(kitti_root), "--preset", f"bytetrack_{cls}", "--class", cls, "--seqs", seqs,
            "--out", str(tmp_path / run)] + [a for s in sets for a in ("--set", s)]
    status, _, err = run_cli(capsys, argv)
    assert status == 0, err
    got = _files(tmp_path / run)
    want = {f"{s}.txt": (kitti_root / REF / run / f"{s}.txt").read_bytes() for s in seqs.split(",")}
    assert got == want


def test_lanes_of_one_batch_equal_each_setting_alone(kitti_root):
    split = load_split(kitti_root, "rrc", None, "car", ["0012", "0017"])
    params = Params(np.array([0.5, 0.3, 0.6]), np.array([0.8, 0.9, 0.7]), np.array([30, 60, 5]),
                    np.array([0.1, 0.1, 0.2]))
    both = bt.track(split, params, Options(), lanes_per_call=2)
    for b in range(3):
        alone = bt.track(split, Params(*(v[b] for v in params)))
        k = alone.ids.shape[2]
        assert np.array_equal(both.ids[b, :, :k], alone.ids[0]) and (both.ids[b, :, k:] < 0).all()
        rows = both.ids[b] >= 0
        assert np.array_equal(both.boxes[b][rows], alone.boxes[0][alone.ids[0] >= 0])


@pytest.mark.slow
@pytest.mark.parametrize("run", list(RUNS))
def test_every_reference_run_byte_for_byte(kitti_root, tmp_path, capsys, run):
    cls, sets = RUNS[run]
    argv = ["track", "--data", str(kitti_root), "--preset", f"bytetrack_{cls}", "--class", cls,
            "--seqs", ",".join(f"{i:04d}" for i in range(21)), "--out", str(tmp_path / run)]
    status, _, err = run_cli(capsys, argv + [a for s in sets for a in ("--set", s)])
    assert status == 0, err
    got = _files(tmp_path / run)
    want = {f.name: f.read_bytes() for f in sorted((kitti_root / REF / run).iterdir()) if f.suffix == ".txt"}
    assert set(got) == set(want)
    assert [n for n in want if got[n] != want[n]] == []


def test_the_demos_sweep_file_of_bytetrack_reads_2d_detections_only(tmp_path):
    from dfrmot_jax.cli.demo import sweep_file
    from dfrmot_jax.cli.demo_parser import BASELINES, GRIDS, default_out
    text = sweep_file(tmp_path, ["0000", "0001"], "bytetrack")
    assert 'det2d = "synth2d"' in text and "det3d" not in text and 'family = "bytetrack"' in text
    assert BASELINES["bytetrack"] == "bytetrack_car" and set(GRIDS["bytetrack"]) <= set(Params._fields)
    assert default_out("bytetrack").name == "demo_bytetrack"


@pytest.mark.slow
def test_dfrmot_demo_family_bytetrack_sweeps_its_grid(tmp_path, capsys):
    status, out, err = run_cli(capsys, ["demo", "--family", "bytetrack", "--out", str(tmp_path / "demo")])
    assert status == 0, err
    assert "track_thresh" in out and (tmp_path / "demo" / "sweep" / "report.html").is_file()
