import subprocess
import sys

import pytest

from dfrmot_jax.cli import main
from dfrmot_jax.io.kitti import read_tracking_labels
from dfrmot_jax.synthetic import make_scene


@pytest.mark.slow
def test_demo_runs_with_no_data(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path), "--sequences", "2", "--frames", "60"]) == 0
    out = capsys.readouterr().out
    assert "COMBINED" in out and "HOTA" in out and "best vs baseline" in out
    assert (tmp_path / "sweep" / "results.parquet").exists() and (tmp_path / "sweep" / "report.html").exists()


@pytest.mark.slow
def test_track_writes_one_file_per_sequence_and_set_changes_output(tmp_path):
    root = make_scene(tmp_path / "scene", n_sequences=2, n_frames=80, seed=4)
    base = ["track", "--data", str(root), "--det2d", "synth2d", "--det3d", "synth3d"]
    assert main(base + ["--out", str(tmp_path / "a")]) == 0
    assert main(base + ["--set", "min_hits=3", "--set", "filter=kalman", "--out", str(tmp_path / "b")]) == 0
    a = read_tracking_labels(tmp_path / "a" / "0000.txt"); b = read_tracking_labels(tmp_path / "b" / "0000.txt")
    assert a.frame.size > b.frame.size > 0
    assert main(base + ["--seqs", "1", "--out", str(tmp_path / "c")]) == 0
    assert sorted(p.name for p in (tmp_path / "c").iterdir()) == ["0001.txt"]


def test_errors_are_reported_not_raised(tmp_path, capsys):
    root = make_scene(tmp_path / "scene", n_sequences=1, n_frames=30, seed=4)
    assert main(["track", "--data", str(root), "--det2d", "nope", "--det3d", "synth3d", "--out", str(tmp_path / "o")]) == 2
    assert "unknown detector 'nope'" in capsys.readouterr().err
    assert main(["track", "--data", str(root), "--det2d", "synth2d", "--det3d", "synth3d", "--set", "a_l=-3",
                 "--out", str(tmp_path / "o")]) == 2
    assert "a_l" in capsys.readouterr().err
    bad = root / "detections" / "synth2d" / "car" / "0000.txt"
    lines = bad.read_text().splitlines()
    lines[2] = lines[2].replace(",", ",x", 1)
    bad.write_text("\n".join(lines) + "\n")
    assert main(["track", "--data", str(root), "--det2d", "synth2d", "--det3d", "synth3d", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "0000.txt:3" in err and "x1" in err


def test_console_script_is_installed():
    out = subprocess.run([sys.executable, "-m", "dfrmot_jax.cli", "--help"], capture_output=True, text=True)
    assert out.returncode == 0 and "track" in out.stdout and "eval" in out.stdout


@pytest.mark.slow
def test_eval_zero_pads_sequence_names_as_track_does(tmp_path, capsys):
    root = make_scene(tmp_path / "scene", n_sequences=3, n_frames=40, seed=6)
    base = ["--data", str(root)]
    assert main(["track", *base, "--det2d", "synth2d", "--det3d", "synth3d", "--seqs", "1,2",
                 "--out", str(tmp_path / "r")]) == 0
    capsys.readouterr()
    assert main(["eval", str(tmp_path / "r"), *base, "--seqs", "1,2", "--per-seq"]) == 0
    short = capsys.readouterr().out
    assert main(["eval", str(tmp_path / "r"), *base, "--seqs", "0001,0002", "--per-seq"]) == 0
    padded = capsys.readouterr().out
    assert short == padded and "0001" in short and "0002" in short
