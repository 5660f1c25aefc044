"""``dfrmot lidar simulate | lift`` and ``dfrmot track --det3d lidar:DIR --set shrink=...``."""

import os

import numpy as np
import pytest

from dfrmot_jax.io.kitti import read_detections_3d, read_tracking_labels
from dfrmot_jax.lidar import read_scan, scan_path
from dfrmot_jax.synthetic import make_scene
from dfrmot_jax.testing.cli import deadline, error_line, run_cli


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    return make_scene(tmp_path_factory.mktemp("scene"), n_sequences=2, n_frames=25, n_cars=4, seed=5)


@pytest.mark.slow
def test_simulate_lift_and_track(root, tmp_path, capsys):
    scans = tmp_path / "scans"
    status, out, err = run_cli(capsys, ["lidar", "simulate", "--data", root, "--seqs", "1", "--out", scans,
                                        "--beams", "16", "--seed", "2"])
    assert status == 0 and not err and "0001: 25 scans" in out
    assert not (scans / "velodyne" / "0000").exists()
    first = read_scan(scan_path(scans, "0001", 0))
    assert first.shape[0] > 1000
    status, _, _ = run_cli(capsys, ["lidar", "simulate", "--data", root, "--seqs", "1", "--out", tmp_path / "again",
                                    "--beams", "16", "--seed", "2"])
    assert status == 0 and scan_path(tmp_path / "again", "0001", 0).read_bytes() == first.tobytes()

    status, out, err = run_cli(capsys, ["lidar", "lift", "--data", root, "--det2d", "synth2d", "--scans", scans,
                                        "--seqs", "1", "--out", tmp_path / "lifted", "--set", "shrink=0.1"])
    assert status == 0 and not err and "shrink=0.1" in out
    det = read_detections_3d(tmp_path / "lifted" / "0001.txt")
    assert det.frame.size > 10 and set(det.type) == {"Car"}

    status, out, err = run_cli(capsys, ["track", "--data", root, "--det2d", "synth2d", "--det3d", f"lidar:{scans}",
                                        "--seqs", "1", "--set", "lift.shrink=0.1", "--set", "centroid=kitti",
                                        "--out", tmp_path / "res"])
    assert status == 0 and not err
    rows = read_tracking_labels(tmp_path / "res" / "0001.txt")
    with3 = rows.dims[:, 0] > 0
    assert with3.sum() == det.frame.size                      # every lifted box is on its own 2D detection's row
    np.testing.assert_array_equal(np.sort(rows.loc[with3, 2]), np.sort(det.loc[:, 2]))


@pytest.mark.parametrize("argv, message", [
    (["track", "--det2d", "synth2d", "--set", "shrink=0.1"], "a lifting setting, for --det3d lidar:DIR only"),
    (["track", "--det2d", "synth2d", "--det3d", "lidar:{tmp}/none"], "LiDAR scan folder not found"),
    (["lidar", "lift", "--det2d", "synth2d", "--scans", "{tmp}", "--set", "shrink=1.5"], "lift shrink 1.5"),
    (["lidar", "lift", "--det2d", "synth2d", "--scans", "{tmp}", "--set", "leafy=1"], "unknown"),
    (["lidar", "lift", "--det2d", "synth2d", "--scans", "{tmp}"], "no scan for frame 0"),
    (["lidar", "simulate", "--out", "{tmp}/s", "--dropout", "3"], "dropout"),
    # a non-finite count was an OverflowError (exit 1), in lift and in track alike
    (["lidar", "lift", "--det2d", "synth2d", "--scans", "{tmp}", "--set", "min_cluster=inf"], "lift min_cluster inf"),
    (["lidar", "lift", "--det2d", "synth2d", "--scans", "{tmp}", "--set", "min_cluster=-inf"], "lift min_cluster -inf"),
    (["lidar", "lift", "--det2d", "synth2d", "--scans", "{tmp}", "--set", "min_cluster=nan"], "lift min_cluster nan"),
    (["track", "--det2d", "synth2d", "--det3d", "lidar:{tmp}", "--set", "min_cluster=inf"], "lift min_cluster inf"),
])
def test_bad_input_is_one_line_and_exit_2(root, tmp_path, capsys, argv, message):
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv] + ["--data", str(root)]
    if argv[0] == "track":
        argv += ["--out", str(tmp_path / "out")]
    elif argv[1] == "lift":
        argv += ["--out", str(tmp_path / "lifted")]
    status, _, err = run_cli(capsys, argv)
    assert status == 2 and message in error_line(err, argv[0])


@pytest.mark.parametrize("what, message", [
    ("fifo", "000000.bin: is a FIFO (named pipe), not a regular scan file (frame 0 of sequence 0000)"),
    ("partial", "000000.bin: size 33 bytes is not a multiple of 16"),
    ("sequence loop", "000000.bin: cannot read the scan: Too many levels of symbolic links"),
    ("folder loop", "cannot read the LiDAR scan folder: Too many levels of symbolic links"),
])
def test_unreadable_scans_are_located_errors(root, tmp_path, capsys, what, message):
    """Scans that are FIFOs (the run waited forever), cut inside a point (read without it), or
    behind a folder that cannot be read (reported as "not found"): exit 2 naming the file and why."""
    scans = tmp_path / "scans"
    seq = scans / "velodyne" / "0000"
    if what == "folder loop":
        tmp_path.joinpath("loop").symlink_to("loop")
        scans = tmp_path / "loop"
    elif what == "sequence loop":
        seq.parent.mkdir(parents=True)
        seq.symlink_to("0000")
    else:
        seq.mkdir(parents=True)
        for f in range(25):
            if what == "fifo":
                os.mkfifo(scan_path(scans, "0000", f))
            else:
                scan_path(scans, "0000", f).write_bytes(bytes(33))
    argv = ["lidar", "lift", "--data", root, "--det2d", "synth2d", "--scans", scans, "--seqs", "0",
            "--out", tmp_path / "lifted"]
    with deadline(20):
        status, _, err = run_cli(capsys, argv)
    assert status == 2 and message in error_line(err, "lidar", alone=True)
    assert "not found" not in err[0]
