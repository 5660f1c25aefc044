"""One writer per output folder (issue 23, bug 5), with real processes: while another process holds a
folder, ``dfrmot sweep`` / ``tune`` / ``track --overwrite`` on it fail at once (exit 2) naming the
folder and that process; the lock goes with its process however it ends (normal exit, an error,
kill -9), and the record a killed process leaves is taken over with a warning naming it. The store's
and the tune's claim of a folder are one mechanism (bug 7). Every wait is bounded."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
import warnings
from pathlib import Path

import pytest

from dfrmot_jax.io.lock import LOCK_NAME, FolderInUseError, folder_lock, lock_holder
from dfrmot_jax.sweep import SweepDirectoryError, run_sweep
from dfrmot_jax.synthetic import make_scene
from dfrmot_jax.testing.cli import deadline, error_line, kill_when, run_cli

REPO = Path(__file__).resolve().parents[2]
HOLD = textwrap.dedent("""
    import sys, time
    from dfrmot_jax.io.lock import folder_lock
    with folder_lock(sys.argv[1]):
        print("locked", flush=True)
        if sys.argv[2] == "hold":
            time.sleep(120)
""")


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    return make_scene(tmp_path_factory.mktemp("lock") / "scene", n_sequences=2, n_frames=40, n_cars=3, seed=2)


def _env():
    return {**os.environ, "PYTHONPATH": str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", "")}


def _holder(folder: Path, how: str = "hold") -> subprocess.Popen:
    """A process holding ``folder``'s lock (until killed, with ``how="hold"``); returns once it holds it."""
    proc = subprocess.Popen([sys.executable, "-c", HOLD, str(folder), how], env=_env(), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    line = proc.stdout.readline()          # bounded: the process exits (EOF) if it cannot lock
    assert line.strip() == "locked", proc.stderr.read()
    return proc


def _sweep_file(tmp_path: Path, root: Path, name="s") -> Path:
    f = tmp_path / f"{name}.toml"
    f.write_text(f'name = "{name}"\nchunk = 2\n[data]\nroot = "{root}"\ndet2d = "synth2d"\ndet3d = "synth3d"\n'
                 f'[params]\na_l = [4.0, 6.0, 8.0]\nscore_2d = [0.3, 0.5]\n')
    return f


def _tune_file(tmp_path: Path, root: Path) -> Path:
    f = tmp_path / "t.toml"
    f.write_text(f'name = "t"\n[data]\nroot = "{root}"\ndet2d = "synth2d"\ndet3d = "synth3d"\n'
                 f'[params]\na_l = {{uniform = [2.0, 10.0]}}\n[tune]\nbudget = 4\nbatch = 2\n')
    return f


@pytest.mark.slow
def test_a_folder_in_use_is_refused_at_once_naming_it_and_the_other_process(scene, tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "0000.txt").write_text("")                   # a track folder to --overwrite
    holder = _holder(out)
    try:
        want = f"{out} is in use by process {holder.pid}"
        # a real second process: the sweep command, refused before any work
        t0 = time.monotonic()
        other = subprocess.run([sys.executable, "-m", "dfrmot_jax.cli", "sweep", str(_sweep_file(tmp_path, scene)),
                                "--out", str(out), "--no-progress"], env=_env(), capture_output=True, text=True,
                               timeout=300)
        assert other.returncode == 2, other.stderr
        assert want in other.stderr and "Traceback" not in other.stderr, other.stderr
        assert not (out / "manifest.json").exists() and not (out / "chunks").exists()
        # the same in this process: tune and track --overwrite
        for argv in (["tune", _tune_file(tmp_path, scene), "--out", out],
                     ["track", "--data", scene, "--det2d", "synth2d", "--det3d", "synth3d", "--out", out,
                      "--overwrite"]):
            status, _, err = run_cli(capsys, argv)
            assert status == 2 and want in error_line(err, argv[0]), err
        assert (out / "0000.txt").exists() and sorted(p.name for p in out.iterdir()) == [LOCK_NAME, "0000.txt"]
        assert time.monotonic() - t0 < 240                 # (bounded: nothing waited for the lock)
        rec = lock_holder(out)
        assert rec["pid"] == holder.pid and "-c" in rec["command"]
    finally:
        holder.kill()
        holder.wait(timeout=30)


@pytest.mark.slow
def test_the_lock_goes_with_its_process_and_a_killed_ones_record_is_taken_over(scene, tmp_path):
    out = tmp_path / "out"
    done = _holder(out, "exit")                       # a normal exit releases and clears the record
    assert done.wait(timeout=60) == 0
    assert lock_holder(out) is None
    with warnings.catch_warnings():
        warnings.simplefilter("error")                 # nothing to take over
        with folder_lock(out):
            pass

    with pytest.raises(ZeroDivisionError):             # an error inside releases too
        with folder_lock(out):
            1 / 0
    assert _holder(out, "exit").wait(timeout=60) == 0

    killed = _holder(out)                              # kill -9: the kernel releases the lock
    os.kill(killed.pid, signal.SIGKILL)
    killed.wait(timeout=30)
    assert lock_holder(out)["pid"] == killed.pid       # its record stays behind
    with pytest.warns(RuntimeWarning, match=f"took over the lock of process {killed.pid}.*ended without releasing"):
        df = run_sweep(_sweep_file(tmp_path, scene), out, progress=False, workers=0, log=lambda m: None)
    assert df["config"].nunique() == 7 and lock_holder(out) is None


@pytest.mark.slow
def test_a_sweep_killed_mid_run_leaves_no_lock_in_the_way(scene, tmp_path):
    """A real ``dfrmot sweep`` killed (-9) after its first chunk: the rerun takes the folder over,
    says so, and finishes."""
    toml, out = _sweep_file(tmp_path, scene), tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "dfrmot_jax.cli", "sweep", str(toml), "--out", str(out),
                             "--no-progress", "--workers", "0"], env=_env(), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    chunks = out / "chunks"
    killed = kill_when(proc, lambda: chunks.is_dir() and any(chunks.glob("*.parquet")), timeout=240, poll=0.005)
    proc.wait(timeout=60)
    assert killed and lock_holder(out)["pid"] == proc.pid
    rerun = subprocess.run([sys.executable, "-m", "dfrmot_jax.cli", "sweep", str(toml), "--out", str(out),
                            "--no-progress", "--workers", "0"], env=_env(), capture_output=True, text=True, timeout=300)
    assert rerun.returncode == 0, rerun.stderr
    assert f"took over the lock of process {proc.pid}" in rerun.stderr
    assert (out / "results.parquet").is_file() and lock_holder(out) is None


def test_a_failed_run_leaves_no_new_folder(tmp_path):
    out = tmp_path / "new" / "out"
    with pytest.raises(RuntimeError):
        with folder_lock(out):
            raise RuntimeError("bad input found after the lock")
    assert not out.exists()
    afile = tmp_path / "f"
    afile.write_text("x")
    with pytest.raises(ValueError, match="is a file, not a directory"):
        with folder_lock(afile):
            pass


@pytest.mark.slow     # (the not-slow tier's 3-minute budget; the full suite runs it)
def test_one_claim_for_sweeps_and_tunes(scene, tmp_path):
    """Bug 7: a tune folder refuses a sweep and a sweep folder a tune, with the same words; --force
    deletes the other run's files (the tune's journal and batches too), and nothing else."""
    from dfrmot_jax.tuning import run_tune

    out = tmp_path / "out"
    run_tune(_tune_file(tmp_path, scene), out, progress=False, workers=0, log=lambda m: None, plots=False)
    (out / "notes.txt").write_text("mine")
    sweep = _sweep_file(tmp_path, scene)
    with pytest.raises(SweepDirectoryError, match=f"{out} holds a tune \\('t'\\): its results would be replaced"):
        run_sweep(sweep, out, progress=False, workers=0, log=lambda m: None)
    run_sweep(sweep, out, progress=False, workers=0, log=lambda m: None, force=True)
    left = sorted(p.name for p in out.iterdir())
    assert "journal.log" not in left and "batches" not in left and "notes.txt" in left, left
    assert json.loads((out / "manifest.json").read_text()).get("kind", "sweep") == "sweep"
    with pytest.raises(SweepDirectoryError, match=f"{out} holds a sweep \\('s'\\): its results would be replaced"):
        run_tune(_tune_file(tmp_path, scene), out, progress=False, workers=0, log=lambda m: None, plots=False)
    with pytest.raises(FolderInUseError):               # (the lock is the same for both, in one process too)
        with folder_lock(out):
            run_sweep(sweep, out, progress=False, workers=0, log=lambda m: None)


def test_a_fifo_named_like_the_lock_is_refused_without_blocking(scene, tmp_path, capsys):
    """A FIFO named ``.dfrmot.lock`` in the output folder: the run read it and waited forever."""
    out = tmp_path / "out"
    out.mkdir()
    os.mkfifo(out / LOCK_NAME)
    with deadline(10):
        assert lock_holder(out) is None
        with pytest.raises(ValueError, match=f"{out / LOCK_NAME} is a FIFO \\(named pipe\\), not the lock file"):
            with folder_lock(out):
                pass
        status, _, err = run_cli(capsys, ["track", "--data", scene, "--det2d", "synth2d", "--det3d", "synth3d",
                                          "--out", out])
    assert status == 2 and "is a FIFO (named pipe)" in error_line(err, "track", alone=True)
    assert (out / LOCK_NAME).is_fifo()                  # (left alone: not ours to remove)


def test_the_takeover_warning_is_one_clean_line(scene, tmp_path, capsys):
    """A record left by a killed run is taken over with a warning: it was Python's warnings line
    (``/path/runner.py:NN: RuntimeWarning: ...`` and the source line), now ``dfrmot CMD: warning: ...``."""
    out = tmp_path / "out"
    out.mkdir()
    (out / LOCK_NAME).write_text(json.dumps({"pid": 2 ** 22 + 12345, "host": "elsewhere", "command": "dfrmot track",
                                             "started": "2024-01-01 00:00:00"}) + "\n")
    # a real run that takes the lock over, then stops at a bad detector (no tracking needed)
    status, _, err = run_cli(capsys, ["track", "--data", scene, "--det2d", "nosuch", "--det3d", "synth3d",
                                      "--out", out])
    assert status == 2 and len(err) == 2, err
    assert err[0] == (f"dfrmot track: warning: {out}: took over the lock of process {2 ** 22 + 12345} on elsewhere "
                      f"(dfrmot track, since 2024-01-01 00:00:00), which ended without releasing it (killed or "
                      f"crashed): its partial output is checked as usual"), err
    assert err[1].startswith("dfrmot track: error: ")
