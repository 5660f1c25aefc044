"""ARCHITECTURE.md's recipe, "Adding a tracker family", followed: a toy family
(``tests/fixtures/toy_family/``) joins a copy of the package by its folder (``trackers/toy/``), its
line in the registry and its oracle in ``testing/``, nothing else; then, in processes of their own on
that copy, its sweep tracks and scores, ``compare DIR:best`` writes its best config's files, a tune
searches it, the report ranks it, ``dfrmot track --preset`` runs it, and its JAX tracker equals its
oracle."""

from __future__ import annotations

import filecmp
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from dfrmot_jax.synthetic import make_scene

ROOT = Path(__file__).resolve().parents[2]
FIXTURE = ROOT / "tests" / "fixtures" / "toy_family"
REGISTRY_LINE = "from .dfr import config as dfr\n"
#: the tuple of the registry's configs (its last entry closes it)
REGISTRY_ENTRY = re.compile(r"\(dfr\.FAMILY_CONFIG(, \w+\.FAMILY_CONFIG)*\)")


def _add_toy_family(pkg: Path) -> None:
    """The recipe's steps on a copy of the package: the folder, the registry line, the oracle."""
    shutil.copytree(FIXTURE, pkg / "trackers" / "toy", ignore=shutil.ignore_patterns("oracle.py", "__pycache__"))
    shutil.copy(FIXTURE / "oracle.py", pkg / "testing" / "toy_oracle.py")
    reg = pkg / "trackers" / "registry.py"
    text = reg.read_text()
    entry = REGISTRY_ENTRY.search(text)
    assert REGISTRY_LINE in text and entry, "the registry's family lines moved: update the recipe"
    text = text.replace(REGISTRY_LINE, REGISTRY_LINE + "from .toy import config as toy\n")
    reg.write_text(text.replace(entry.group(0), entry.group(0)[:-1] + ", toy.FAMILY_CONFIG)"))


def _changed(a: Path, b: Path, rel=Path()) -> list[str]:
    """Files that differ or exist on one side only between two package trees (no caches)."""
    cmp = filecmp.dircmp(a, b, ignore=["__pycache__"])
    out = [str(rel / n) for n in cmp.left_only + cmp.right_only + cmp.diff_files]
    for d in cmp.common_dirs:
        out += _changed(a / d, b / d, rel / d)
    return out


@pytest.fixture(scope="module")
def toy(tmp_path_factory):
    base = tmp_path_factory.mktemp("recipe")
    pkg = base / "pkg" / "dfrmot_jax"
    shutil.copytree(ROOT / "dfrmot_jax", pkg, ignore=shutil.ignore_patterns("__pycache__"))
    _add_toy_family(pkg)
    scene = make_scene(base / "scene", n_sequences=2, n_frames=40, n_cars=4, seed=3)
    return base, pkg, scene


def _run(base: Path, *args: str, timeout=600) -> str:
    env = {**os.environ, "PYTHONPATH": str(base / "pkg"), "DFRMOT_COMPILE_CACHE": str(base / "cache")}
    proc = subprocess.run([sys.executable, *args], cwd=base, env=env, capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, f"{args}: exit {proc.returncode}\n{proc.stdout[-2000:]}\n{proc.stderr[-3000:]}"
    return proc.stdout + proc.stderr


def test_a_family_is_its_folder_the_registry_line_and_its_oracle(toy):
    _, pkg, _ = toy
    assert sorted(_changed(ROOT / "dfrmot_jax", pkg)) == ["testing/toy_oracle.py", "trackers/registry.py", "trackers/toy"]


@pytest.mark.slow
def test_the_toy_family_sweeps_compares_tunes_reports_and_tracks(toy):
    base, _, scene = toy
    (base / "toy.toml").write_text(
        f'name = "toy"\nchunk = 2\nseed = 0\n[data]\nroot = "{scene}"\ndet3d = "synth3d"\nclass = "car"\n'
        f'[params]\niou_min = [0.1, 0.5]\nscore_min = [0.0, 0.5]\n[options]\nfamily = "toy"\n')
    _run(base, "-m", "dfrmot_jax.cli", "sweep", "toy.toml", "--out", "sweep", "--no-progress", "--workers", "0")
    import pandas as pd
    table = pd.read_parquet(base / "sweep" / "results.parquet")
    table = table[table["sequence"] == "COMBINED"]
    assert len(table) == 5 and set(table["iou_min"]) == {0.3, 0.1, 0.5} and (table["HOTA"] > 0).all()
    assert table["HOTA"].nunique() > 1                       # the settings track differently
    out = _run(base, "-m", "dfrmot_jax.cli", "report", "sweep")
    assert "iou_min" in out
    out = _run(base, "-m", "dfrmot_jax.cli", "compare", "sweep:best", "sweep:baseline", "--data", str(scene),
               "--resamples", "200")
    assert "HOTA" in out
    (base / "tune.toml").write_text(
        f'name = "toytune"\nchunk = 2\nseed = 0\n[data]\nroot = "{scene}"\ndet3d = "synth3d"\nclass = "car"\n'
        f'[params]\niou_min = {{uniform = [0.05, 0.9]}}\nscore_min = [0.0, 0.5]\n[options]\nfamily = "toy"\n'
        f'[tune]\nsampler = "tpe"\nbudget = 4\nbatch = 2\nobjectives = ["HOTA"]\nseed = 0\n')
    _run(base, "-m", "dfrmot_jax.cli", "tune", "tune.toml", "--out", "tune", "--no-progress", "--workers", "0")
    tuned = pd.read_parquet(base / "tune" / "results.parquet")
    assert tuned["config_hash"].nunique() >= 4 and (tuned["HOTA"] > 0).all()
    _run(base, "-m", "dfrmot_jax.cli", "track", "--preset", "toy_strict", "--data", str(scene), "--det3d", "synth3d",
         "--out", "tracked")
    assert sorted(p.name for p in (base / "tracked").iterdir()) == ["0000.txt", "0001.txt"]
    # its JAX tracker equals its oracle, id for id
    _run(base, "-c", f"""
import numpy as np
from dfrmot_jax.data import load_split
from dfrmot_jax.testing.toy_oracle import track as oracle
from dfrmot_jax.trackers.registry import family_of
fam = family_of("toy")
split = load_split({str(scene)!r}, det2d=None, det3d="synth3d")
P = fam.config.Params
params = P(iou_min=np.array([0.1, 0.3, 0.6]), score_min=np.array([0.0, 0.5, 0.2]))
res = fam.track(split, params)
f = fam.prepare_frames(split)
for b in range(3):
    want = oracle(f.box, f.score, f.valid, f.reset, params.iou_min[b], params.score_min[b])
    assert np.array_equal(res.ids[b], want), b
print("toy == oracle")
""")
