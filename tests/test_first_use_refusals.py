"""Issue 51, the first-use finds around the second family: refusals that wrote first (items 2, 3),
settings that did nothing (4, 5, 6), outputs that overwrote what they should not (7, 8), and the
messages and help a new user read (10, 14, 15, 16, 19). Each test failed on the code before the fix."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from dfrmot_jax.cli import main
from dfrmot_jax.testing.cli import error_line, run_cli


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    from dfrmot_jax.synthetic import make_scene

    return make_scene(tmp_path_factory.mktemp("first_use") / "scene", n_sequences=2, n_frames=20, seed=5)


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def _ab3dmot_sweep(root, extra_options="", extra="") -> str:
    return f"""
name = "first_use_ab"
[data]
root = "{root}"
det3d = "synth3d"
class = "car"
[baseline]
preset = "ab3dmot_car"
[params]
threshold = [-0.2, 0.0]
[options]
family = "ab3dmot"
{extra_options}
{extra}
"""


def _nothing_written(out: Path) -> None:
    assert not out.exists() or not any(p.name != ".dfrmot.lock" for p in out.iterdir()), sorted(out.iterdir())


# -- item 2: an AB3DMOT sweep with boxes = false is refused before anything is written -------------------------

def test_ab3dmot_sweep_without_boxes_refused_before_writing(scene, tmp_path, capsys):
    toml = _write(tmp_path / "ab.toml", _ab3dmot_sweep(scene, "boxes = false"))
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, ["sweep", str(toml), "--out", str(out), "--no-progress"])
    assert code == 2
    line = error_line(err, "sweep")
    assert "options.boxes" in line and "boxes = false" in line
    assert err[0].startswith("dfrmot sweep: error:"), err      # the error first, not the plan
    _nothing_written(out)


def test_ab3dmot_track_without_boxes_refused_before_writing(scene, tmp_path, capsys):
    out = tmp_path / "t"
    code, _, err = run_cli(capsys, ["track", "--preset", "ab3dmot_car", "--data", str(scene), "--det3d", "synth3d",
                                    "--set", "boxes=false", "--out", str(out)])
    assert code == 2 and "boxes = false" in error_line(err, "track")
    _nothing_written(out)


# -- item 3: tune --folds beyond the sequences is refused before batch 0 runs ---------------------------------

def _tune(root) -> str:
    return f"""
name = "first_use_tune"
[data]
root = "{root}"
det2d = "synth2d"
det3d = "synth3d"
[params]
score_2d = [0.3, 0.5, 0.7]
[tune]
sampler = "grid"
budget = 3
batch = 3
"""


@pytest.mark.parametrize("where", ["flag", "file"])
def test_tune_folds_beyond_sequences_refused_before_writing(scene, tmp_path, capsys, where):
    text = _tune(scene) + ("folds = 5\n" if where == "file" else "")
    toml = _write(tmp_path / "t.toml", text)
    out = tmp_path / "out"
    argv = ["tune", str(toml), "--out", str(out), "--no-progress"] + (["--folds", "5"] if where == "flag" else [])
    code, _, err = run_cli(capsys, argv)
    assert code == 2
    line = error_line(err, "tune")
    assert ("--folds 5" if where == "flag" else "tune.folds") in line and "expected 2 .. 2" in line
    _nothing_written(out)
