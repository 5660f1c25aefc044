"""Report settings are checked before any work and read as a user means them."""

import shutil
from pathlib import Path

import pytest

from dfrmot_jax.cli import main
from dfrmot_jax.io.atomic import atomic_write
from dfrmot_jax.sweep import SweepConfigError, parse_spec, sweep_report
from dfrmot_jax.testing.cli import error_line, run_cli

FIXTURE = Path(__file__).resolve().parents[1] / "fixtures" / "sweep_v1"


def test_a_misspelt_objective_in_a_sweep_file_fails_at_parse_time_naming_the_key():
    with pytest.raises(SweepConfigError, match=r"report\.objective: 'HOTAA': not a metric"):
        parse_spec({"params": {"a_l": [4.0, 8.0]}, "report": {"objective": "HOTAA"}})
    assert parse_spec({"params": {"a_l": [4.0, 8.0]}, "report": {"objective": "idf1"}}).objective == "IDF1"


def test_objective_in_any_case_and_top_zero_refused(tmp_path, capsys):
    d = tmp_path / "sweep"
    shutil.copytree(FIXTURE, d)
    low, up = sweep_report(d, objective="hota"), sweep_report(d, objective="HOTA")
    assert low.summary == up.summary and low.summary["objective"] == "HOTA"
    assert main(["report", str(d), "--objective", "hota"]) == 0
    capsys.readouterr()
    assert main(["report", str(d), "--top", "0"]) == 2
    assert "top" in capsys.readouterr().err
    assert main(["sweep", "sweeps/kitti_smoke.toml", "--out", str(tmp_path / "x"), "--objective", "HOTAA"]) == 2
    assert "HOTAA" in capsys.readouterr().err and not (tmp_path / "x").exists()


@pytest.mark.parametrize("flag", ["--html", "--csv"])
def test_an_empty_output_name_is_refused(flag, capsys):
    """``--html ""`` printed the report, wrote nothing and said nothing (exit 0)."""
    status, out, err = run_cli(capsys, ["report", str(FIXTURE), flag, ""])
    assert status == 2 and not out
    assert f"argument {flag}: '': expected a file name" in error_line(err, "report", alone=True)


def test_an_html_target_that_cannot_be_written_is_named_not_its_temp_file(tmp_path, capsys):
    """The error named the atomic writer's temp file (``.x.html.PID.tmp``), not the file asked for."""
    target = tmp_path / "x.html"
    (target / "inside").mkdir(parents=True)             # a folder where the page should go (fails for root too)
    status, _, err = run_cli(capsys, ["report", str(FIXTURE), "--html", str(target)])
    line = error_line(err, "report", alone=True)
    assert status == 2 and line == f"dfrmot report: error: {target}: Is a directory", line

    def refused(tmp):                                   # what open() raises in a read-only folder
        raise PermissionError(13, "Permission denied", str(tmp))

    with pytest.raises(PermissionError) as e:
        atomic_write(tmp_path / "y.html", refused)
    assert e.value.filename == str(tmp_path / "y.html") and ".tmp" not in str(e.value)


@pytest.mark.parametrize("text, fragment", [
    ("[]", "not a sweep manifest: expected an object, got a list"),
    ("{}", "not a sweep manifest: no 'data' object"),
    ("garbage", ":1: damaged, not valid JSON"),
    ("", ":1: damaged, not valid JSON"),
    ('{"data": {"root": "r", "det2d": "a", "det3d": "b", "sequences": ["0000"]}}', "chunks: missing"),
    ('{"data": {"root": "r", "det2d": "a", "det3d": "b", "sequences": ["0000"]}, "chunks": [], "classes": 3}',
     "classes: a whole number, expected a list"),
])
@pytest.mark.parametrize("command", ["report", "report --html", "compare"])
def test_a_damaged_manifest_is_named(text, fragment, command, tmp_path, capsys):
    """``[]``, ``{}`` or garbage in a sweep's manifest.json: exit 1 (TypeError, KeyError: 'data',
    AttributeError, KeyError: 'chunks') or a JSON parser's message naming no file."""
    d = tmp_path / "sweep"
    shutil.copytree(FIXTURE, d)
    (d / "manifest.json").write_text(text)
    argv = {"report": ["report", d], "report --html": ["report", d, "--html", tmp_path / "p.html"],
            "compare": ["compare", f"{d}:best", f"{d}:baseline"]}[command]
    status, out, err = run_cli(capsys, argv)
    line = error_line(err, command.split()[0], alone=True)
    assert status == 2 and f"{d / 'manifest.json'}" in line and fragment in line, line
    assert not out and not (tmp_path / "p.html").exists()
