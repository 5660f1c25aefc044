"""Resume: a sweep killed mid-run (a real subprocess, SIGKILL) and rerun equals an uninterrupted run."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from dfrmot_jax.sweep import COMBINED, sweep
from dfrmot_jax.synthetic import make_scene

N_CHUNKS = 8


def _spec_text(root: Path) -> str:
    return f"""
name = "resume"
chunk = 2
[data]
root = "{root}"
det2d = "synth2d"
det3d = "synth3d"
[params]
a_l = [4.0, 6.0, 8.0, 10.0]
score_2d = [0.3, 0.45, 0.6, 0.7]
"""


def _cmd(toml: Path, out: Path) -> list[str]:
    return [sys.executable, "-m", "dfrmot_jax.sweep_cli", "sweep", str(toml), "--out", str(out),
            "--workers", "0", "--no-progress"]


@pytest.mark.skipif(sys.platform == "win32", reason="SIGKILL")
def test_killed_sweep_resumes_to_the_same_table(tmp_path):
    root = make_scene(tmp_path / "scene", n_sequences=3, n_frames=150, n_cars=5, seed=11)
    toml = tmp_path / "resume.toml"
    toml.write_text(_spec_text(root))
    out = tmp_path / "killed"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}

    proc = subprocess.Popen(_cmd(toml, out), env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    chunks = out / "chunks"
    done_at_kill = 0
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and proc.poll() is None:
        done_at_kill = len(list(chunks.glob("*.parquet"))) if chunks.is_dir() else 0
        if done_at_kill >= 1:
            os.kill(proc.pid, signal.SIGKILL)
            break
        time.sleep(0.005)
    proc.wait(timeout=60)
    log = proc.stdout.read().decode()
    assert proc.returncode == -signal.SIGKILL, f"the sweep was not killed mid-run (rc {proc.returncode}):\n{log}"
    left = len(list(chunks.glob("*.parquet")))
    assert 1 <= left < N_CHUNKS, f"{left} chunks finished before the kill: the run was not interrupted"
    assert not (out / "results.parquet").exists()

    rerun = subprocess.run(_cmd(toml, out), env=env, capture_output=True, text=True, timeout=300)
    assert rerun.returncode == 0, rerun.stdout + rerun.stderr
    assert f"{left} done" in rerun.stderr          # the finished chunks were skipped
    assert len(list(chunks.glob("*.parquet"))) == N_CHUNKS

    resumed = pd.read_parquet(out / "results.parquet")
    clean = sweep(toml, out=tmp_path / "clean", progress=False, workers=0, log=lambda m: None)
    pd.testing.assert_frame_equal(resumed, clean)
    assert not resumed.duplicated(["config", "sequence"]).any()
    assert resumed["config"].nunique() == 16
    assert (resumed.groupby("config")["sequence"].apply(list)
            .map(lambda s: s == ["0000", "0001", "0002", COMBINED]).all())
