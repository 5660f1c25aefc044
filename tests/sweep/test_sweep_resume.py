"""Resume: a sweep killed mid-run (a real subprocess, SIGKILL) and rerun equals an uninterrupted run; a
directory written by the previous version (``tests/fixtures/sweep_v1``, hash scheme 1) resumes with
nothing recomputed."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from dfrmot_jax.sweep import (COMBINED, HASH_VERSION, HashVersionError, expand, hash_version, load_results, run_sweep,
                              sweep_report)
from dfrmot_jax.report.stored import read_ledger
from dfrmot_jax.synthetic import make_scene
from dfrmot_jax.testing.cli import kill_when

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
    return [sys.executable, "-m", "dfrmot_jax.cli", "sweep", str(toml), "--out", str(out),
            "--workers", "0", "--no-progress"]


def _recorded_chunks(out: Path) -> list[str]:
    """The chunk files the sweep directory's ledger records (what a rerun counts as done)."""
    return [n for n in read_ledger(out) if n.startswith("chunks/") and (out / n).is_file()]


@pytest.mark.slow
@pytest.mark.skipif(sys.platform == "win32", reason="SIGKILL")
def test_killed_sweep_resumes_to_the_same_table(tmp_path):
    root = make_scene(tmp_path / "scene", n_sequences=3, n_frames=150, n_cars=5, seed=11)
    toml = tmp_path / "resume.toml"
    toml.write_text(_spec_text(root))
    out = tmp_path / "killed"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}

    proc = subprocess.Popen(_cmd(toml, out), env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    chunks = out / "chunks"
    kill_when(proc, lambda: len(_recorded_chunks(out)) > 0, timeout=240, poll=0.005)
    proc.wait(timeout=60)
    log = proc.stdout.read().decode()
    assert proc.returncode == -signal.SIGKILL, f"the sweep was not killed mid-run (rc {proc.returncode}):\n{log}"
    # finished: a chunk file in place and recorded (one put in place, its record not yet written when
    # the kill came, is recomputed: the rerun names it)
    left = len(_recorded_chunks(out))
    assert 1 <= left < N_CHUNKS, f"{left} chunks finished before the kill: the run was not interrupted"
    assert not (out / "results.parquet").exists()

    rerun = subprocess.run(_cmd(toml, out), env=env, capture_output=True, text=True, timeout=300)
    assert rerun.returncode == 0, rerun.stdout + rerun.stderr
    assert f"{left} done" in rerun.stderr          # the finished chunks were skipped
    assert len(list(chunks.glob("*.parquet"))) == N_CHUNKS

    resumed = pd.read_parquet(out / "results.parquet")
    clean = run_sweep(toml, out=tmp_path / "clean", progress=False, workers=0, log=lambda m: None)
    pd.testing.assert_frame_equal(resumed, clean)
    assert not resumed.duplicated(["config", "sequence"]).any()
    assert resumed["config"].nunique() == 16
    assert (resumed.groupby("config")["sequence"].apply(list)
            .map(lambda s: s == ["0000", "0001", "0002", COMBINED]).all())


# ---- result directories written by earlier versions ---------------------------------------------

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures"
V1 = FIXTURES / "sweep_v1"


def _v1_spec() -> dict:
    """Regenerate the synthetic data of the v1 fixture (not committed) where it was written from,
    and return the fixture's sweep spec."""
    doc = json.loads((V1 / "scene.json").read_text())
    kw = dict(doc["make_scene"])
    directory = Path(kw.pop("directory"))
    assert json.loads((V1 / "manifest.json").read_text())["data"]["root"] == str(directory)
    try:
        make_scene(directory, **kw)
    except OSError as e:      # the fixture's data root is a fixed absolute path (part of its chunk ids)
        pytest.skip(f"cannot write the v1 fixture's scene at {directory}: {e}")
    return doc["spec"]


@pytest.mark.slow
def test_v1_directory_resumes_recomputing_what_an_older_version_computed(tmp_path):
    """A directory of hash scheme 1 is still this sweep's (same config hashes and chunk ids), but its
    chunks were computed by results version 1 (before ``version.RESULTS_VERSION`` was recorded): they
    are recomputed, and give the same rows (this sweep crosses no option whose scores moved)."""
    import dfrmot_jax

    spec = _v1_spec()
    out = tmp_path / "sweep_v1"
    shutil.copytree(V1, out)
    old_manifest = json.loads((out / "manifest.json").read_text())
    assert "hash_version" not in old_manifest and hash_version(old_manifest) == 1
    logs: list[str] = []
    df = run_sweep(spec, out=out, progress=False, workers=0, log=logs.append)
    assert "computed by results version 1, this one is 2" in logs[0] and "1 chunks of <= 4; 0 done" in logs[1]
    before = pd.read_parquet(V1 / "results.parquet")
    same = [c for c in before.columns if c not in ("dfrmot_jax_version", "jax_version")]   # (columns since added)
    pd.testing.assert_frame_equal(df[same], before[same])
    pd.testing.assert_frame_equal(load_results(out), df)
    logs.clear()
    run_sweep(spec, out=out, progress=False, workers=0, log=logs.append)       # now recorded: nothing to redo
    assert len(logs) == 1 and "1 chunks of <= 4; 1 done" in logs[0]
    # same config hashes and chunk ids; the manifest now says which scheme they are
    assert expand(spec)["config_hash"].tolist() == pd.read_parquet(V1 / "configs.parquet")["config_hash"].tolist()
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["chunks"] == old_manifest["chunks"]
    assert manifest["hash_version"] == HASH_VERSION == 1

    rep = sweep_report(out, folds=2)
    assert rep.summary["configs"] == 4 and rep.summary["folds"] == 2
    assert rep.text.startswith("sweep v1_fixture: 4 configs x 2 sequences")

    # the deprecated spelling still runs (and resumes) a sweep, with a DeprecationWarning
    with pytest.warns(DeprecationWarning, match="run_sweep"):
        again = dfrmot_jax.sweep.sweep(spec, out=out, progress=False, workers=0, log=logs.append)
    pd.testing.assert_frame_equal(again, df)
    assert not callable(dfrmot_jax.sweep)           # the package is a plain module


def test_directory_of_another_hash_scheme_is_refused(tmp_path):
    spec = _v1_spec()
    out = tmp_path / "sweep_v2"
    shutil.copytree(V1, out)
    manifest = json.loads((out / "manifest.json").read_text())
    (out / "manifest.json").write_text(json.dumps({**manifest, "hash_version": HASH_VERSION + 1}))
    with pytest.raises(HashVersionError, match="config_hash scheme"):
        run_sweep(spec, out=out, progress=False, workers=0, log=lambda m: None)


def test_config_hashes_are_those_of_version_1():
    """Config hashes of tables with options, random axes, distortion lanes and per-class axes, as
    the previous sweep module (hash scheme 1) computed them."""
    doc = json.loads((FIXTURES / "sweep_v1_hashes.json").read_text())
    for name, spec in doc["specs"].items():
        assert expand(spec)["config_hash"].tolist() == doc["config_hash"][name], name
