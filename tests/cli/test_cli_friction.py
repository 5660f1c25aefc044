"""Friendly inputs and output of the ``dfrmot`` command (issue 10, items 11 and 18), at CLI level:
unreadable files, byte-order marks, non-UTF-8 sweep files, detector directories given by relative
path, a wrong data root, 3D rows of an unknown type, report lines that fit 120 columns, the README
options table and the demo's work directory (kept: --out, else results/demo)."""

import builtins
import io
import re
import shutil
from pathlib import Path

import pytest

from dfrmot_jax.cli import main
from dfrmot_jax.trackers.dfr.config import Options, Params
from dfrmot_jax.testing.cli import error_line, run_cli

REPO = Path(__file__).resolve().parents[2]
BOM = "\ufeff"


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    from dfrmot_jax.synthetic import make_scene

    return make_scene(tmp_path_factory.mktemp("friction") / "scene", n_sequences=2, n_frames=30, seed=4)


@pytest.fixture
def copy_of(scene, tmp_path):
    """A fresh copy of the scene, free to edit."""
    root = tmp_path / "scene"
    shutil.copytree(scene, root)
    return root


def _track(root, out, *extra, det2d="synth2d", det3d="synth3d"):
    return ["track", "--data", str(root), "--det2d", str(det2d), "--det3d", str(det3d), "--out", str(out), *extra]


def _deny(monkeypatch, path):
    """Reading ``path`` (by builtins.open, io.open or pathlib) raises PermissionError, as for a file
    without read permission (tests run as root, for whom chmod 000 changes nothing)."""
    target = Path(path).resolve()
    real = builtins.open

    def guarded_open(file, *args, **kwargs):
        if isinstance(file, (str, Path)) and Path(file).resolve() == target:
            raise PermissionError(13, "Permission denied", str(file))
        return real(file, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", guarded_open)
    monkeypatch.setattr(io, "open", guarded_open)


def _p2_first(calib, prefix, drop=None):
    """Rewrite a calib file as ``prefix`` + its P2 line + the other lines (without ``drop``)."""
    lines = calib.read_text().splitlines(True)
    p2 = [s for s in lines if s.startswith("P2:")]
    rest = [s for s in lines if not s.startswith("P2:") and not (drop and s.startswith(drop))]
    assert len(p2) == 1 and len(rest) == len(lines) - 1 - bool(drop)
    calib.write_text(prefix + "".join(p2 + rest))


def _results(d):
    return {p.name: p.read_text() for p in sorted(Path(d).iterdir())}


# ---- item 11: unreadable files, byte-order marks, file names in messages --------------------------

@pytest.mark.parametrize("which", ["detections/synth2d/car/0001.txt", "detections/synth3d/car/0000.txt",
                                   "calib/0001.txt", "label_02/0000.txt"])
def test_unreadable_input_of_track_is_exit_2_naming_the_file(which, scene, tmp_path, monkeypatch, capsys):
    _deny(monkeypatch, scene / which)
    status, _, err = run_cli(capsys, _track(scene, tmp_path / "o"))
    line = error_line(err, "track", alone=True)
    assert status == 2 and which in line and "Permission denied" in line


@pytest.mark.slow
@pytest.mark.parametrize("which", ["results", "label_02/0001.txt"])
def test_unreadable_input_of_eval_is_exit_2_naming_the_file(which, copy_of, tmp_path, monkeypatch, capsys):
    assert main(_track(copy_of, tmp_path / "results")) == 0           # a fresh root: no cached ground truth
    capsys.readouterr()
    path = tmp_path / "results" / "0001.txt" if which == "results" else copy_of / which
    _deny(monkeypatch, path)
    status, _, err = run_cli(capsys, ["eval", str(tmp_path / "results"), "--data", str(copy_of)])
    line = error_line(err, "eval", alone=True)
    assert status == 2 and str(path.relative_to(path.parent.parent)) in line and "Permission denied" in line


def test_unreadable_sweep_file_is_exit_2_naming_the_file(scene, tmp_path, monkeypatch, capsys):
    f = tmp_path / "s.toml"
    f.write_text('name = "x"\n')
    _deny(monkeypatch, f)
    status, _, err = run_cli(capsys, ["sweep", str(f), "--dry-run"])
    line = error_line(err, "sweep", alone=True)
    assert status == 2 and str(f) in line and "Permission denied" in line


def test_a_byte_order_mark_is_accepted_by_every_reader(copy_of, scene, tmp_path, capsys):
    """Calib (the BOM used to hide ``P2:``), 2D and 3D detections, labels, result files and sweep
    files: the same output as without the mark."""
    assert main(_track(scene, tmp_path / "plain")) == 0
    _p2_first(copy_of / "calib" / "0000.txt", BOM)
    for rel in ("detections/synth2d/car/0000.txt", "detections/synth3d/car/0001.txt", "label_02/0000.txt",
                "label_02/0001.txt"):
        p = copy_of / rel
        p.write_text(BOM + p.read_text())
    assert main(_track(copy_of, tmp_path / "marks")) == 0
    assert _results(tmp_path / "marks") == _results(tmp_path / "plain")
    capsys.readouterr()

    assert main(["eval", str(tmp_path / "plain"), "--data", str(scene), "--per-seq"]) == 0
    plain = capsys.readouterr().out
    res = tmp_path / "marks"
    (res / "0001.txt").write_text(BOM + (res / "0001.txt").read_text())
    assert main(["eval", str(res), "--data", str(copy_of), "--per-seq"]) == 0
    assert capsys.readouterr().out.replace("marks", "plain") == plain

    f = tmp_path / "s.toml"
    f.write_text(BOM + f'name = "bom"\n[data]\nroot = "{scene}"\ndet2d = "synth2d"\ndet3d = "synth3d"\n'
                 f'[params]\na_l = [4.0, 8.0]\n', encoding="utf-8")
    status, out, err = run_cli(capsys, ["sweep", str(f), "--dry-run"])
    assert status == 0 and not err and "bom" in out


def test_a_calib_file_with_a_bom_still_reports_what_is_missing(copy_of, tmp_path, capsys):
    _p2_first(copy_of / "calib" / "0000.txt", BOM, drop="R0_rect")
    status, _, err = run_cli(capsys, _track(copy_of, tmp_path / "o"))
    line = error_line(err, "track", alone=True)
    assert status == 2 and "0000.txt: field 'R0_rect': missing" in line and "P2" not in line


def test_a_non_utf8_sweep_file_names_the_file(tmp_path, capsys):
    f = tmp_path / "latin1.toml"
    f.write_bytes('name = "café"\n'.encode("latin-1"))
    status, _, err = run_cli(capsys, ["sweep", str(f), "--dry-run"])
    line = error_line(err, "sweep", alone=True)
    assert status == 2 and str(f) in line and "UTF-8" in line


def test_unknown_3d_type_is_exit_2_at_its_line(copy_of, tmp_path, capsys):
    """A 3D row of type 7 is neither used as a car nor dropped silently (cyclist rows, code 3, are
    dropped: tests/trackers/dfr/test_pointgnn.py)."""
    p = copy_of / "detections" / "synth3d" / "car" / "0001.txt"
    lines = p.read_text().splitlines(True)
    lines[2] = re.sub(r"^(\d+),2,", r"\g<1>,7,", lines[2])
    p.write_text("".join(lines))
    status, _, err = run_cli(capsys, _track(copy_of, tmp_path / "o"))
    line = error_line(err, "track", alone=True)
    assert status == 2 and "0001.txt:3: field 'type': unknown 3D detection type '7'" in line


def test_relative_detector_directory_with_class_subfolders(scene, tmp_path, monkeypatch, capsys):
    """``--det2d ../mydets/myrrc`` (holding ``car/``) works as its absolute path does."""
    assert main(_track(scene, tmp_path / "by_name")) == 0
    dets = tmp_path / "mydets"
    shutil.copytree(scene / "detections" / "synth2d", dets / "myrrc")
    shutil.copytree(scene / "detections" / "synth3d" / "car", dets / "my3d")      # the class folder itself
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    assert main(_track(scene, tmp_path / "rel", det2d="../mydets/myrrc", det3d="../mydets/my3d")) == 0
    assert main(_track(scene, tmp_path / "abs", det2d=dets / "myrrc", det3d=dets / "my3d")) == 0
    assert _results(tmp_path / "rel") == _results(tmp_path / "abs") == _results(tmp_path / "by_name")


def test_a_wrong_data_root_is_named_as_such(scene, tmp_path, capsys):
    wrong, no_detections = tmp_path / "not_kitti", tmp_path / "no_detections"
    wrong.mkdir()
    for sub in ("label_02", "calib"):
        shutil.copytree(scene / sub, no_detections / sub)
    for argv in (_track(wrong, tmp_path / "o"), _track(wrong, tmp_path / "o", det2d="rrc", det3d="pointrcnn"),
                 _track(wrong, tmp_path / "o", det2d=scene / "detections" / "synth2d",
                        det3d=scene / "detections" / "synth3d")):
        status, _, err = run_cli(capsys, argv)
        line = error_line(err, "track", alone=True)
        assert status == 2 and f"no label_02/ or detections/ under {wrong}" in line and "unknown detector" not in line
    status, _, err = run_cli(capsys, _track(no_detections, tmp_path / "o", det2d="rrc"))
    line = error_line(err, "track", alone=True)
    assert status == 2 and f"rrc: not a directory, and no label_02/ or detections/ under {no_detections}" in line
    assert main(_track(no_detections, tmp_path / "o", det2d=scene / "detections" / "synth2d",
                       det3d=scene / "detections" / "synth3d")) == 0       # detectors by path need no detections/


# ---- item 18: report width, README options table, the demo's directory ----------------------------

def _report_lines(capsys, argv):
    status, out, err = run_cli(capsys, argv)
    assert status == 0 and not err
    lines = out.rstrip("\n").splitlines()
    return lines[:-1], lines[-1]            # the last line is one JSON object, kept whole


def test_report_lines_fit_120_columns(capsys):
    lines, last = _report_lines(capsys, ["report", str(REPO / "tests" / "fixtures" / "sweep_v1"), "--folds", "2"])
    wide = [s for s in lines if len(s) > 120]
    assert not wide, wide
    assert last.startswith("{") and "sensitivity of HOTA per axis" in "\n".join(lines)


@pytest.mark.slow
def test_report_of_a_wide_sweep_wraps_its_tables(scene, tmp_path, capsys):
    """Eight random axes: the top-configs table is wider than 120 columns unless wrapped."""
    names = ("score_2d", "merge_iou", "a_c", "a_l", "alpha_c", "a_f", "gain_beta", "gain_gamma")
    lows = {"score_2d": 0.3, "merge_iou": 0.2, "a_c": 0.0, "a_l": 4.0, "alpha_c": 0.3, "a_f": 0.0,
            "gain_beta": 0.5, "gain_gamma": 0.05}
    axes = "".join(f"{n} = {{uniform = [{lows[n]}, {lows[n] * 1.2 + 0.1}]}}\n" for n in names)
    f = tmp_path / "wide.toml"
    f.write_text(f'name = "a_rather_long_sweep_name_for_a_wide_report"\nsamples = 5\nseed = 3\n[data]\n'
                 f'root = "{scene}"\ndet2d = "synth2d"\ndet3d = "synth3d"\n[params]\n{axes}')
    assert main(["sweep", str(f), "--out", str(tmp_path / "wide")]) == 0
    capsys.readouterr()
    lines, last = _report_lines(capsys, ["report", str(tmp_path / "wide"), "--folds", "2"])
    wide = [s for s in lines if len(s) > 120]
    assert not wide, wide
    text = "\n".join(lines)
    assert all(n in text for n in names) and "gain_gamma" in last


def _readme_section(heading):
    return (REPO / "README.md").read_text().split(f"\n## {heading}", 1)[1].split("\n## ", 1)[0]


def _readme_table(heading):
    """The first-column names of the table rows of a README section."""
    return re.findall(r"^\| `([a-z_0-9]+)`", _readme_section(heading), flags=re.M)


def test_readme_tables_list_every_parameter_and_option():
    assert _readme_table("Options") == list(Options._fields)
    params = _readme_section("Parameters")
    missing = [name for name in Params._fields if f"`{name}`" not in params]
    assert not missing


@pytest.mark.slow
def test_demo_writes_to_out_else_results_demo_and_leaves_no_temporary_directory(tmp_path, monkeypatch, capsys):
    """The demo's files are its point (the sweep folder and its HTML report): they are kept, in
    --out or in results/demo of the working directory, and nothing is left in the temp dir."""
    import tempfile

    scratch = tmp_path / "tmp"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    monkeypatch.chdir(tmp_path)
    args = ["demo", "--sequences", "1", "--frames", "40"]
    status, kept, err = run_cli(capsys, args + ["--out", str(tmp_path / "demo")])
    assert status == 0 and not err and (tmp_path / "demo" / "sweep" / "report.html").is_file()
    status, default, err = run_cli(capsys, args)
    assert status == 0 and not err and (tmp_path / "results" / "demo" / "sweep" / "report.html").is_file()
    assert list(scratch.iterdir()) == [], "the demo left a temporary directory behind"
    table = [s for s in kept.splitlines() if s.startswith(("rank", "base", "best vs"))]
    assert table and table == [s for s in default.splitlines() if s.startswith(("rank", "base", "best vs"))]


def test_track_refuses_filtered_boxes_with_unstable_fixed_gains_up_front(scene, tmp_path, capsys):
    """Issue 23, bug 6: as a sweep does (same message), before any tracking or writing."""
    out = tmp_path / "out"
    argv = _track(scene, out, "--set", "gain_beta=0.12", "--set", "gain_gamma=0.16", "--set", "output=filtered")
    status, _, err = run_cli(capsys, argv)
    line = error_line(err, "track")
    assert status == 2 and "outside the filter's stability region" in line and "gain_gamma 0.16" in line, err
    assert not out.exists()
    status, _, err = run_cli(capsys, argv[:-2] + ["--set", "output=detections"])      # raw boxes: finite
    assert status == 0, err
