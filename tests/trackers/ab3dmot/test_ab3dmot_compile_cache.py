"""AB3DMOT's programs are kept in the persistent compile cache DFR-FastMOT's runs use (issue 52): a
second ``dfrmot track --preset ab3dmot_car`` loads its program instead of compiling it again."""

from __future__ import annotations

import os
import re
import subprocess
import sys

import pytest


def _cli(args, **env):
    e = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "DFRMOT_HOST_DEVICES", "DFRMOT_COMPILE_CACHE",
                                                            "JAX_COMPILATION_CACHE_DIR")}
    e.update(env)
    return subprocess.run([sys.executable, "-m", "dfrmot_jax.cli", *args], capture_output=True, text=True, env=e,
                          timeout=600)


def _compiled_not_loaded(log: str) -> list[str]:
    """The programs JAX's log (``JAX_LOG_COMPILES``) shows compiled by XLA for 0.5 s or more (those the
    cache keeps) without a persistent cache hit."""
    hits = set(re.findall(r"Persistent compilation cache hit for '([^']+)'", log))
    slow = [(name, float(s)) for name, s in re.findall(r"Finished XLA compilation of jit\((\w+)\) in ([0-9.e-]+) sec",
                                                       log)]
    return [f"{name} ({s:.1f} s)" for name, s in slow if s >= 0.5 and f"jit_{name}" not in hits]


@pytest.mark.slow
def test_ab3dmot_programs_kept_between_runs(tmp_path):
    from dfrmot_jax.synthetic import make_scene

    root = make_scene(tmp_path / "scene", n_sequences=1, n_frames=30, n_cars=3, seed=4)
    cache = tmp_path / "cache"
    logs, files = [], []
    for k in range(2):
        out = tmp_path / f"out{k}"
        r = _cli(["track", "--data", str(root), "--det3d", "synth3d", "--preset", "ab3dmot_car", "--out", str(out)],
                 DFRMOT_COMPILE_CACHE=str(cache), JAX_LOG_COMPILES="1")
        assert r.returncode == 0, r.stderr[-3000:]
        logs.append(r.stderr)
        files.append({f.name: f.read_bytes() for f in sorted(out.glob("*.txt"))})
    kept = [p.name for p in cache.iterdir()]
    assert any(name.startswith("jit_lanes") for name in kept), f"AB3DMOT's program not kept: {kept}"
    assert "Persistent compilation cache hit for 'jit_lanes'" in logs[1], logs[1][-3000:]
    assert not _compiled_not_loaded(logs[1]), _compiled_not_loaded(logs[1])
    assert files[0] and files[0] == files[1]
