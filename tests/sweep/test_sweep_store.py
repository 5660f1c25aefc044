"""The sweep directory trusts nothing blindly: sizes are checked before anything is allocated,
damaged chunk files are reported and recomputed (never trusted, never fatal), a directory belongs
to one sweep, and filesystem errors are one-line messages with exit status 2 and no temp file left."""

from __future__ import annotations

import errno
import json
import os
import shutil
from pathlib import Path

import pandas as pd
import pytest

from dfrmot_jax.sweep import SweepConfigError, load_results, run_sweep
from dfrmot_jax.synthetic import make_scene
from dfrmot_jax.testing.cli import error_line, run_cli

QUIET = ["--no-progress", "--workers", "0"]


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    return make_scene(tmp_path_factory.mktemp("store") / "scene", n_sequences=2, n_frames=30, n_cars=3, seed=5)


def _toml(path: Path, root: Path, name: str = "store", params: str = "a_l = [4.0, 8.0]\nscore_2d = [0.3, 0.45]",
          top: str = "", tail: str = "") -> Path:
    path.write_text(f'name = "{name}"\nchunk = 2\n{top}\n[data]\nroot = "{root}"\ndet2d = "synth2d"\n'
                    f'det3d = "synth3d"\n[params]\n{params}\n{tail}\n')
    return path


@pytest.fixture(scope="module")
def clean(root, tmp_path_factory):
    """(sweep file, the directory of an uninterrupted run, its table)."""
    base = tmp_path_factory.mktemp("clean")
    toml = _toml(base / "store.toml", root)
    out = base / "out"
    df = run_sweep(toml, out=out, progress=False, workers=0, log=lambda m: None)
    return toml, out, df


def _copy(clean, tmp_path) -> tuple[Path, Path, pd.DataFrame, list[Path]]:
    toml, src, df = clean
    out = tmp_path / "out"
    shutil.copytree(src, out)
    return toml, out, df, sorted((out / "chunks").glob("*.parquet"))


def _truncate(path: Path) -> None:
    path.write_bytes(path.read_bytes()[:path.stat().st_size // 2])


def _flip(path: Path) -> None:
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0x10
    path.write_bytes(bytes(data))


def _unrecord(path: Path) -> None:
    ledger = path.parent.parent / "ledger.jsonl"
    lines = ledger.read_text().splitlines(keepends=True)
    kept = [line for line in lines if path.name not in line]
    assert len(kept) == len(lines) - 1
    ledger.write_text("".join(kept))


# ---- item 14: damaged chunk files ---------------------------------------------------------------

@pytest.mark.parametrize("damage", [_truncate, _flip, _unrecord], ids=["truncated", "byte-flip", "no-record"])
def test_damaged_chunk_is_reported_and_recomputed(clean, tmp_path, damage):
    toml, out, expect, chunks = _copy(clean, tmp_path)
    n = len(chunks)
    assert n >= 2
    victim = chunks[1]
    damage(victim)
    (out / "results.parquet").unlink()
    stamps = {p.name: p.stat().st_mtime_ns for p in chunks if p != victim}
    logs: list[str] = []
    df = run_sweep(toml, out=out, progress=False, workers=0, log=logs.append)
    assert "recomputed" in logs[0] and f"chunks/{victim.name}" in logs[0], logs
    assert f"{n - 1} done" in logs[1]
    pd.testing.assert_frame_equal(df, expect)
    pd.testing.assert_frame_equal(load_results(out), expect)
    assert {p.name: p.stat().st_mtime_ns for p in chunks if p != victim} == stamps     # the others were trusted
    logs.clear()                                   # recomputed and recorded: a rerun trusts it
    pd.testing.assert_frame_equal(run_sweep(toml, out=out, progress=False, workers=0, log=logs.append), expect)
    assert len(logs) == 1 and f"{n} done" in logs[0]


def test_load_results_leaves_out_damaged_chunks(clean, tmp_path):
    _, out, expect, chunks = _copy(clean, tmp_path)
    _flip(out / "results.parquet")                 # a damaged final table is rebuilt from the chunks
    pd.testing.assert_frame_equal(load_results(out), expect)
    (out / "results.parquet").unlink()
    _truncate(chunks[0])
    with pytest.warns(RuntimeWarning, match=f"chunks/{chunks[0].name}"):
        part = load_results(out, allow_partial=True)
    keep = expect[expect["chunk"] != chunks[0].stem].reset_index(drop=True)
    assert 0 < len(keep) < len(expect)
    pd.testing.assert_frame_equal(part, keep)
    with pytest.warns(RuntimeWarning), pytest.raises(FileNotFoundError, match="1 damaged"):
        load_results(out)


# ---- item 15: one sweep per directory ------------------------------------------------------------

@pytest.mark.slow      # (the not-slow tier's 3-minute budget)
def test_another_sweep_is_refused_unless_forced(root, tmp_path, capsys):
    a = _toml(tmp_path / "a.toml", root, name="a")
    b = _toml(tmp_path / "b.toml", root, name="b", params="a_l = [5.0, 7.0]")
    out = tmp_path / "out"
    assert run_cli(capsys, ["sweep", a, "--out", out] + QUIET)[0] == 0
    first = (out / "results.parquet").read_bytes()

    status, _, err = run_cli(capsys, ["sweep", b, "--out", out] + QUIET)
    line = error_line(err, "sweep")
    assert status == 2 and "another sweep ('a'" in line and "--force" in line, line
    assert (out / "results.parquet").read_bytes() == first

    status, _, err = run_cli(capsys, ["sweep", a, "--out", out] + QUIET)       # the same sweep: resumed
    n = len(json.loads((out / "manifest.json").read_text())["chunks"])
    assert status == 0 and f"{n} done" in "\n".join(err)

    status, _, err = run_cli(capsys, ["sweep", b, "--out", out, "--force"] + QUIET)
    assert status == 0, err
    df = pd.read_parquet(out / "results.parquet")
    assert set(df["sweep"]) == {"b"} and {5.0, 7.0} <= set(df["a_l"])
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["name"] == "b"
    assert {p.stem for p in (out / "chunks").glob("*.parquet")} == set(manifest["chunks"])   # a's are gone


# ---- item 16: filesystem errors ------------------------------------------------------------------

def test_out_or_chunks_being_a_file_is_a_clear_error(root, tmp_path, capsys):
    toml = _toml(tmp_path / "s.toml", root)
    afile = tmp_path / "afile"
    afile.write_text("not a directory")
    status, _, err = run_cli(capsys, ["sweep", toml, "--out", afile] + QUIET)
    assert status == 2 and f"{afile} is a file, not a directory" in error_line(err, "sweep")
    d = tmp_path / "d"
    d.mkdir()
    (d / "chunks").write_text("not a directory")
    status, _, err = run_cli(capsys, ["sweep", toml, "--out", d] + QUIET)
    assert status == 2 and f"{d / 'chunks'} is a file" in error_line(err, "sweep")


def test_full_disk_is_a_clear_error_and_leaves_no_temp_file(root, tmp_path, capsys, monkeypatch):
    toml = _toml(tmp_path / "s.toml", root)
    out = tmp_path / "out"
    real = pd.DataFrame.to_parquet

    def full(self, path, *args, **kwargs):          # the OS: some bytes written, then no space left
        if Path(path).parent.name == "chunks":
            Path(path).write_bytes(b"PAR1 partial")
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(self, path, *args, **kwargs)

    monkeypatch.setattr(pd.DataFrame, "to_parquet", full)
    status, _, err = run_cli(capsys, ["sweep", toml, "--out", out] + QUIET)
    line = error_line(err, "sweep")
    assert status == 2 and "No space left on device" in line and str(out / "chunks") in line, line
    assert not list(out.rglob("*.tmp"))
    monkeypatch.undo()
    assert run_cli(capsys, ["sweep", toml, "--out", out] + QUIET)[0] == 0


def test_temp_files_of_killed_runs_are_removed(clean, tmp_path):
    toml, out, expect, _ = _copy(clean, tmp_path)
    dead = 2 ** 31 - 2                       # above any pid_max: no such process
    orphans = [out / "chunks" / f".x.parquet.{dead}.tmp", out / f".results.parquet.{dead}.tmp"]
    live = out / "chunks" / f".y.parquet.{os.getppid()}.tmp"       # a running process's write
    for p in orphans + [live]:
        p.write_bytes(b"PAR1 partial")
    df = run_sweep(toml, out=out, progress=False, workers=0, log=lambda m: None)
    pd.testing.assert_frame_equal(df, expect)
    assert not any(p.exists() for p in orphans) and live.exists()


# ---- item 13: sizes checked before anything is allocated -----------------------------------------

@pytest.mark.parametrize("params, top, tail, key, number", [
    ("a_l = {linspace = [1, 10, 1000000000000]}", "", "", "params.a_l.linspace", "1,000,000,000,000"),
    ("a_l = {uniform = [1.0, 10.0]}", "samples = 1000000000000", "", "samples", "1,000,000,000,001 configs"),
    ("a_l = {linspace = [1, 10, 10000]}\nscore_2d = {linspace = [0.1, 0.9, 1000]}", "", "", "params.a_l",
     "10,000,001 configs"),
    ("epsilon = [1, 2]", "", '[distortion]\nkind = "drop"\nlevel = [0.0, 0.1]\nseeds = 100000000', "distortion.seeds",
     "100,000,000"),
], ids=["linspace", "samples", "grid", "seeds"])
def test_oversized_sweeps_are_refused_before_allocating(root, tmp_path, capsys, params, top, tail, key, number):
    toml = _toml(tmp_path / "big.toml", root, params=params, top=top, tail=tail)
    status, _, err = run_cli(capsys, ["sweep", toml, "--dry-run"])
    line = error_line(err, "sweep")
    assert status == 2 and f": {key}: " in line and number in line and "limit" in line, line


def test_size_limits_can_be_raised_or_lowered(root, tmp_path, capsys):
    toml = _toml(tmp_path / "s.toml", root)
    assert run_cli(capsys, ["sweep", toml, "--dry-run"])[0] == 0
    status, _, err = run_cli(capsys, ["sweep", toml, "--dry-run", "--max-configs", "3"])
    line = error_line(err, "sweep")
    assert status == 2 and "above the limit of 3" in line and "--max-configs" in line, line
    status, _, err = run_cli(capsys, ["sweep", toml, "--dry-run", "--max-memory", "0.000001"])
    line = error_line(err, "sweep")
    assert status == 2 and ": chunk: " in line and "GB of tracker output" in line and "--max-memory" in line, line
    with pytest.raises(SweepConfigError, match="above the limit of 3"):
        run_sweep(toml, max_configs=3, progress=False, log=lambda m: None)


def test_chunk_memory_is_estimated_before_tracking(root, tmp_path, capsys, monkeypatch):
    """512 configs in one chunk x 60 frames x 4096 track slots x 20 bytes (ids, filtered boxes) = 2.5 GB."""
    import dfrmot_jax.trackers.dfr.track

    toml = _toml(tmp_path / "mem.toml", root, params="a_l = {linspace = [1, 64, 64]}\nscore_2d = "
                 "{linspace = [0.1, 0.8, 8]}", tail='[options]\ncapacity = 4096\noutput = "filtered"')
    toml.write_text(toml.read_text().replace("chunk = 2", "chunk = 1000"))
    status, _, err = run_cli(capsys, ["sweep", toml, "--dry-run"])
    line = error_line(err, "sweep")
    assert status == 2 and "512 configs x 60 frames (car) x 4096 track slots (options.capacity) x 20 bytes = 2.52 GB" \
        in line and "above the limit of 2 GB" in line, line

    def boom(*args, **kwargs):
        raise AssertionError("tracked before the memory check")

    monkeypatch.setattr(dfrmot_jax.trackers.dfr.track, "track", boom)
    with pytest.raises(SweepConfigError, match="GB of tracker output"):
        run_sweep(toml, out=tmp_path / "out", progress=False, log=lambda m: None)
    assert not (tmp_path / "out").exists()
