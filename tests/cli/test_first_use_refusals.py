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


# -- items 4, 6: settings that do nothing are said: --det2d to a 3D-only family, a preset of another class --

def test_det2d_and_a_preset_of_another_class_are_warned_about(scene, tmp_path, capsys):
    out = tmp_path / "t"
    code, _, err = run_cli(capsys, ["track", "--preset", "ab3dmot_pedestrian", "--class", "car", "--data", str(scene),
                                    "--det3d", "synth3d", "--det2d", "/no/such/dir", "--seqs", "0000", "--out", str(out)])
    assert code == 0, err
    warnings = [s for s in err if s.startswith("dfrmot track: warning: ")]
    assert len(warnings) == 2, err
    assert any("--det2d /no/such/dir" in s and "AB3DMOT reads 3D detections only" in s for s in warnings), warnings
    assert any("'ab3dmot_pedestrian'" in s and "chosen for pedestrian" in s and "car" in s for s in warnings), warnings


def test_a_sweep_baseline_of_another_class_is_warned_about(scene, tmp_path, capsys):
    text = _ab3dmot_sweep(scene).replace('preset = "ab3dmot_car"', 'preset = "ab3dmot_pedestrian"')
    toml = _write(tmp_path / "ab.toml", text)
    code, _, err = run_cli(capsys, ["sweep", str(toml), "--dry-run"])
    assert code == 0, err
    assert any(s.startswith("dfrmot sweep: warning: ") and "chosen for pedestrian" in s for s in err), err


def test_family_records_name_the_class_of_each_one_class_preset():
    from dfrmot_jax.trackers.protocol import config_problems
    from dfrmot_jax.trackers.registry import CONFIGS

    ab = CONFIGS["ab3dmot"]
    assert ab.preset_classes["ab3dmot_pedestrian"] == "pedestrian" and ab.preset_classes["ab3dmot_car"] == "car"
    assert all(not config_problems(fc) for fc in CONFIGS.values())


# -- item 5: AB3DMOT's options without its figures, an empty --objective ------------------------------------

@pytest.mark.parametrize("command", ["eval", "compare"])
@pytest.mark.parametrize("flag", [["--ab3dmot-sum", "sequential"], ["--ab3dmot-iou", "3d:0.5"],
                                  ["--ab3dmot-resamples", "10"]])
def test_ab3dmot_options_without_its_metrics_are_refused(tmp_path, capsys, command, flag):
    if command == "eval" and flag[0] == "--ab3dmot-resamples":
        pytest.skip("eval has no --ab3dmot-resamples")
    d = tmp_path / "r"
    d.mkdir()
    folders = [str(d)] if command == "eval" else [str(d), str(d)]
    code, _, err = run_cli(capsys, [command, *folders, *flag])
    assert code == 2
    line = error_line(err, command)
    assert flag[0] in line and "--metrics kitti2d,ab3dmot" in line


def test_report_empty_objective_is_refused(tmp_path, capsys):
    code, _, err = run_cli(capsys, ["report", str(tmp_path), "--objective", ""])
    assert code == 2 and "--objective ''" in error_line(err, "report")


# -- item 7: an output naming another output or an input ------------------------------------------------------

@pytest.mark.parametrize("command", ["eval", "compare"])
def test_outputs_naming_one_file_or_an_input_are_refused_before_anything(tmp_path, capsys, command):
    d = tmp_path / "r"
    d.mkdir()
    (d / "0006.txt").write_text("")
    folders = [str(d)] if command == "eval" else [str(d), str(d)]
    f = tmp_path / "t.csv"
    code, out, err = run_cli(capsys, [command, *folders, "--recall-table", str(f), "--csv", str(f)])
    assert code == 2 and "name one file" in error_line(err, command) and not f.exists() and "wrote" not in out
    code, out, err = run_cli(capsys, [command, *folders, "--recall-table", str(d / "0006.txt")])
    assert code == 2 and "result folder" in error_line(err, command)
    assert (d / "0006.txt").read_text() == ""


# -- item 8: each family's demo its own folder; item 15: --frames named ---------------------------------------

@pytest.mark.parametrize("family, folder", [("dfr", "results/demo"), ("ab3dmot", "results/demo_ab3dmot")])
def test_each_familys_demo_has_its_own_folder(tmp_path, capsys, monkeypatch, family, folder):
    import dfrmot_jax.cli.demo as demo

    seen = []

    def fake_scene(directory, **kwargs):
        seen.append(Path(directory))
        raise ValueError("stop here")

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(demo, "make_scene", fake_scene)
    code, _, err = run_cli(capsys, ["demo", "--family", family])
    assert code == 2 and seen == [Path(folder) / "scene"]


def test_demo_frames_zero_names_the_flag(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli(capsys, ["demo", "--family", "ab3dmot", "--frames", "0"])
    assert code == 2 and "--frames 0" in error_line(err, "demo", alone=True)
    assert not (tmp_path / "results").exists()


# -- item 16: the help names the families, the AB3DMOT objectives and metrics ---------------------------------

def test_help_names_the_families(capsys):
    from dfrmot_jax.trackers.registry import CONFIGS

    for argv in ([], ["sweep"], ["tune"], ["report"]):
        code, out, _ = run_cli(capsys, [*argv, "--help"])
        assert code == 0
        flat = " ".join(out.split())
        for name, fc in CONFIGS.items():
            assert name in flat and fc.title in flat, (argv, name)
    _, out, _ = run_cli(capsys, ["report", "--help"])
    assert "sAMOTA" in " ".join(out.split())
    _, out, _ = run_cli(capsys, ["--help"])
    eval_line = " ".join(out.split()).split(" eval ", 1)[1].split(" compare ", 1)[0]
    assert "sAMOTA" in eval_line


# -- items 10, 14, 19: an AB3DMOT sweep's summary, report and progress bar ----------------------------------

@pytest.fixture(scope="module")
def ab3dmot_sweep(scene, tmp_path_factory):
    """An AB3DMOT sweep with AB3DMOT's figures and the file's folds, run by ``dfrmot sweep --summary``
    with its progress bar: (folder, stdout, stderr)."""
    import contextlib
    import io

    tmp = tmp_path_factory.mktemp("first_use_sweep")
    toml = _write(tmp / "ab.toml", _ab3dmot_sweep(scene, extra='[metrics]\nab3dmot = "3d:0.25"\n[report]\n'
                                                              'objective = "HOTA"\nfolds = 2\n'))
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["sweep", str(toml), "--out", str(tmp / "o"), "--summary"])
    assert code == 0, err.getvalue()
    return tmp / "o", out.getvalue(), err.getvalue()


def test_sweep_summary_names_the_sum_the_manifest_names(ab3dmot_sweep):
    folder, out, _ = ab3dmot_sweep
    import json

    assert json.loads((folder / "manifest.json").read_text())["ab3dmot_sum"] == "compensated"
    flat = " ".join(out.split())
    assert "before the sum was a setting" not in flat
    assert "compensated sum of track scores" in flat


def test_progress_bar_does_not_run_into_the_summary_line(ab3dmot_sweep):
    _, _, err = ab3dmot_sweep
    lines = [s for s in err.split("\n") if "tracked and scored in" in s]
    assert lines and all(s.startswith("sweep ") for s in lines), lines


def test_report_by_samota_says_why_there_is_no_cross_validation(ab3dmot_sweep, tmp_path, capsys):
    folder, _, _ = ab3dmot_sweep
    page = tmp_path / "r.html"
    code, out, err = run_cli(capsys, ["report", str(folder), "--objective", "sAMOTA", "--html", str(page)])
    assert code == 0, err
    flat = " ".join(out.split())
    assert "no cross-validation: the sweep file's folds (2) are not used for sAMOTA" in flat
    html = page.read_text()
    assert "cross-validated figure below" not in html and "Cross-validated</h2>" not in html
    assert "No cross-validation" in html
