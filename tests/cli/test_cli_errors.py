"""The ``dfrmot`` command's contract: help and version, one error handler (exit 2 one line for bad
input, exit 1 with the --debug hint for anything else, 130 for Ctrl-C), clear --set messages."""

import os
import subprocess
import sys
from argparse import Namespace

import numpy as np
import pytest

import dfrmot_jax
from dfrmot_jax.cli import args as cli_args
from dfrmot_jax.cli import build_parser, main
from dfrmot_jax.cli import track as track_cmd
from dfrmot_jax.cli import track_parser
from dfrmot_jax.trackers.dfr.config import PRESETS, Options, Params
from dfrmot_jax.testing.cli import error_line, run_cli

COMMANDS = ("track", "demo", "eval", "compare", "sweep", "tune", "report", "lidar")


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    from dfrmot_jax.synthetic import make_scene

    return make_scene(tmp_path_factory.mktemp("cli") / "scene", n_sequences=1, n_frames=30, seed=4)


# ---- help and version ---------------------------------------------------------------------------

@pytest.mark.parametrize("argv", [["--help"]] + [[c, "--help"] for c in COMMANDS])
def test_every_help_works_without_rst_markup(argv, capsys):
    status, out, err = run_cli(capsys, argv)
    assert status == 0 and not err
    assert out.startswith("usage: dfrmot") and "`" not in out


@pytest.mark.parametrize("argv", [[c, "--help"] for c in COMMANDS])
def test_help_shows_no_escaped_percent_or_internal_name(argv, capsys):
    """``compare --help`` printed "95 %%" (a description is not %-formatted); ``track --help`` an
    internal constant's name, ``(INHERITED_PARAMS)``."""
    _, out, _ = run_cli(capsys, argv)
    assert "%%" not in out and "INHERITED_PARAMS" not in out


def test_top_help_lists_commands_and_exit_statuses(capsys):
    _, out, _ = run_cli(capsys, ["--help"])
    for c in COMMANDS:
        assert f"    {c} " in out
    assert "--debug" in out and "--version" in out and "130" in out


def test_version(capsys):
    status, out, _ = run_cli(capsys, ["--version"])
    assert status == 0 and out.strip() == f"dfrmot {dfrmot_jax.__version__}"


def test_track_help_lists_parameters_options_presets(capsys):
    _, out, _ = run_cli(capsys, ["track", "--help"])
    for name in Params._fields + Options._fields + tuple(PRESETS):
        assert f"\n  {name} " in out, name
    meanings = dict((n, m) for names, m in track_parser.docstring_fields(Params.__doc__, Params._fields) for n in names)
    assert set(meanings) == set(Params._fields)
    assert meanings["a_c"] == "camera gate: IoU below a_c counts as 0 in M_c"
    assert " ".join(meanings["a_c"].split()) in " ".join(out.split())
    assert "integer in [0, 4096]" in out                       # capacity, config.MAX_CAPACITY
    assert "fixed_gain | kalman" in out and "a_l=10 centroid=head" in out
    options = {n for names, _ in track_parser.docstring_fields(Options.__doc__, Options._fields) for n in names}
    assert options == set(Options._fields)


def test_docstring_fields_read_indented_and_dedented_docstrings():
    """Python >= 3.13 compiles a docstring with its common indentation stripped, earlier versions
    keep it: both forms give the same entries (on whichever interpreter runs the test)."""
    indented = """Settings.

        a_c:   camera gate: IoU below a_c
               counts as 0. Second sentence.
        b, c:  both (e.g. b. c) here.

        Not_a: field line.
        """
    dedented = "Settings.\n\na_c:   camera gate: IoU below a_c\n       counts as 0. Second sentence.\nb, c:  both (e.g. b. c) here.\n\nNot_a: field line.\n"
    expected = [(("a_c",), "camera gate: IoU below a_c counts as 0"), (("b", "c"), "both (e.g. b. c) here")]
    for doc in (indented, dedented):
        assert track_parser.docstring_fields(doc, ("a_c", "b", "c")) == expected


# ---- bad input: exit 2, one line -----------------------------------------------------------------

def test_bad_input_on_each_command_is_one_line_exit_2(scene, tmp_path, capsys):
    track = ["track", "--data", str(scene), "--det2d", "synth2d", "--det3d", "synth3d", "--out", str(tmp_path / "o")]
    status, _, err = run_cli(capsys, track[:4] + ["nope"] + track[5:])
    assert status == 2 and "unknown detector 'nope'" in error_line(err, "track", alone=True)

    status, _, err = run_cli(capsys, ["demo", "--out", str(tmp_path / "d"), "--frames", "0"])
    assert status == 2 and "--frames 0" in error_line(err, "demo", alone=True)

    res = tmp_path / "res"
    res.mkdir()
    (res / "0000.txt").write_text("0 1 Bus -1 -1 -10 100 100 200 200 -1 -1 -1 -1000 -1000 -1000 -10 1\n")
    status, _, err = run_cli(capsys, ["eval", str(res), "--data", str(scene)])
    line = error_line(err, "eval", alone=True)
    assert status == 2 and "0000.txt:1" in line and "'Bus'" in line
    status, _, err = run_cli(capsys, ["eval", str(tmp_path / "missing"), "--data", str(scene)])
    assert status == 2 and "not a directory" in error_line(err, "eval", alone=True)

    status, _, err = run_cli(capsys, ["sweep", str(tmp_path / "missing.toml")])
    assert status == 2 and "missing.toml" in error_line(err, "sweep", alone=True)
    bad = tmp_path / "bad.toml"
    bad.write_text("this is [ not toml\n")
    status, _, err = run_cli(capsys, ["sweep", str(bad), "--dry-run"])
    assert status == 2 and "not valid TOML" in error_line(err, "sweep", alone=True)

    status, _, err = run_cli(capsys, ["report", str(tmp_path)])
    assert status == 2 and "not a sweep directory" in error_line(err, "report", alone=True)
    status, _, err = run_cli(capsys, ["report", str(tmp_path), "--contrast", "foo"])
    assert status == 2 and "--contrast" in error_line(err, "report", alone=True)


def test_argument_errors_are_one_line_exit_2(capsys):
    status, _, err = run_cli(capsys, ["track"])
    assert status == 2 and "--out" in error_line(err, "track", alone=True) and "dfrmot track --help" in err[0]
    status, _, err = run_cli(capsys, ["demo", "--frames", "many"])
    assert status == 2 and "--frames" in error_line(err, "demo", alone=True)
    status, _, err = run_cli(capsys, ["nope"])
    assert status == 2 and len(err) == 1 and err[0].startswith("dfrmot: error:")


def test_bad_input_in_a_real_process_has_no_traceback(scene, tmp_path):
    out = subprocess.run([sys.executable, "-m", "dfrmot_jax.cli", "track", "--data", str(scene), "--det2d", "nope",
                          "--out", str(tmp_path / "o")], capture_output=True, text=True, timeout=300)
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert out.stderr.strip().splitlines()[-1].startswith("dfrmot track: error: ")


def test_file_errors_name_the_file(monkeypatch, capsys):
    def denied(args):
        raise PermissionError(13, "Permission denied", "/results/0000.txt")

    monkeypatch.setattr(track_cmd, "run", denied)
    status, _, err = run_cli(capsys, ["track", "--out", "x"])
    assert status == 2 and error_line(err, "track", alone=True).endswith("/results/0000.txt: Permission denied")


def test_messages_carry_no_numpy_reprs(monkeypatch, capsys):
    def bad(args):
        raise ValueError(f"unknown type {np.str_('Bus')!r} at {np.float64(2.5)!r}\nsecond line")

    monkeypatch.setattr(track_cmd, "run", bad)
    status, _, err = run_cli(capsys, ["track", "--out", "x"])
    assert status == 2
    assert error_line(err, "track", alone=True) == "dfrmot track: error: unknown type 'Bus' at 2.5; second line"


# ---- unexpected errors: exit 1 and the --debug hint; --debug lets the traceback through -----------

def test_unexpected_error_hint_and_debug(monkeypatch, capsys):
    def boom(args):
        raise RuntimeError("boom")

    monkeypatch.setattr(track_cmd, "run", boom)
    status, _, err = run_cli(capsys, ["track", "--out", "x"])
    assert status == 1 and len(err) == 1
    assert err[0] == "dfrmot track: internal error: RuntimeError: boom (rerun with --debug for the traceback)"
    with pytest.raises(RuntimeError, match="boom"):
        main(["--debug", "track", "--out", "x"])
    with pytest.raises(RuntimeError, match="boom"):
        main(["track", "--debug", "--out", "x"])


def test_interrupt_is_130(monkeypatch, capsys):
    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(track_cmd, "run", interrupted)
    status, _, err = run_cli(capsys, ["track", "--out", "x"])
    assert status == 130 and err == ["dfrmot track: interrupted"]


_BOOM = ("import sys, dfrmot_jax.cli.track as t\n"
         "def boom(args):\n    raise RuntimeError('boom')\n"
         "t.run = boom\nfrom dfrmot_jax.cli import main\nsys.exit(main(sys.argv[1:]))\n")


@pytest.mark.slow
def test_traceback_only_with_debug_in_a_real_process():
    plain = subprocess.run([sys.executable, "-c", _BOOM, "track", "--out", "x"], capture_output=True, text=True,
                           timeout=300)
    assert plain.returncode == 1 and "Traceback" not in plain.stderr
    assert "rerun with --debug for the traceback" in plain.stderr
    debug = subprocess.run([sys.executable, "-c", _BOOM, "--debug", "track", "--out", "x"], capture_output=True,
                           text=True, timeout=300)
    assert debug.returncode == 1 and "Traceback" in debug.stderr and "RuntimeError: boom" in debug.stderr


# ---- --set values --------------------------------------------------------------------------------

@pytest.mark.parametrize("item, want", [
    ("capacity=abc", "--set capacity=abc: not a number; expected an integer from 0 to 4096"),
    ("epsilon=2.5", "--set epsilon=2.5: not an integer; expected an integer from 0 to 10000"),
    ("min_hits=x", "--set min_hits=x: not a number; expected an integer from 1 to 10000"),
    ("capacity=2147483648", "--set capacity=2147483648: above the maximum capacity 4096 (config.MAX_CAPACITY)"),
    ("car.capacity=1e9", "--set car.capacity=1e9: write it without a decimal point or exponent"),
])
def test_set_integer_messages(item, want, scene, tmp_path, capsys):
    status, _, err = run_cli(capsys, ["track", "--data", str(scene), "--det2d", "synth2d", "--det3d", "synth3d",
                                   "--set", item, "--out", str(tmp_path / "o")])
    assert status == 2 and want in error_line(err, "track", alone=True)
    assert "invalid literal" not in err[0]


@pytest.mark.parametrize("item, want", [
    ("pedestrian.nosuch=1", "--set pedestrian.nosuch: unknown; parameters are"),
    ("pedestrian.a_l=0", "--set pedestrian.a_l=0: parameter a_l=0.0: outside the valid range"),
    ("pedestrian.shrink=0.1", "--set pedestrian.shrink=0.1: 'shrink' is a lifting setting, one for every class"),
    ("pedestrian.a_l=2", "--set pedestrian.a_l=2: class 'pedestrian' is not tracked (--class car)"),
])
def test_settings_of_a_class_not_tracked_are_checked_then_refused(item, want, scene, tmp_path, capsys):
    """``--class car --set pedestrian.X=V`` was accepted silently, whatever X and V: a bad one is its
    own error, a valid one is refused (it would be ignored), before any work."""
    out = tmp_path / "o"
    status, _, err = run_cli(capsys, ["track", "--data", str(scene), "--det2d", "synth2d", "--det3d", "synth3d",
                                      "--class", "car", "--set", "epsilon=20", "--set", item, "--out", str(out)])
    assert status == 2 and want in error_line(err, "track", alone=True)
    assert not out.exists()


def test_set_capacity_bounds_are_inclusive():
    from dfrmot_jax.trackers.dfr.track import MAX_CAPACITY

    args = Namespace(preset="dfr2023", set=[f"capacity={MAX_CAPACITY}", "epsilon=0"])
    params, options = track_cmd.class_settings(args)
    assert options.capacity == MAX_CAPACITY and params.epsilon == 0
    with pytest.raises(ValueError, match="above the maximum capacity"):
        track_cmd.class_settings(Namespace(preset="dfr2023", set=[f"capacity={MAX_CAPACITY + 1}"]))


def test_one_parser_one_handler():
    p = build_parser()
    assert p.prog == "dfrmot"
    sub = next(a for a in p._actions if a.dest == "command")
    assert list(sub.choices) == list(COMMANDS)
    for name, sp in sub.choices.items():
        func = sp.get_default("func")
        # run_later: every parser is built without its command's module, guarded(run) when it runs
        assert func.__name__ == "run" and func.module == f"dfrmot_jax.cli.{name}"


# ---- --seqs --------------------------------------------------------------------------------------

_SEQS_COMMANDS = {
    "track": ["track", "--out", "{tmp}/o"],
    "eval": ["eval", "{tmp}"],
    "compare": ["compare", "{tmp}", "{tmp}"],
    "lidar simulate": ["lidar", "simulate", "--out", "{tmp}/o"],
    "lidar lift": ["lidar", "lift", "--scans", "{tmp}", "--out", "{tmp}/o"],
}


@pytest.mark.parametrize("command", list(_SEQS_COMMANDS))
@pytest.mark.parametrize("seqs, twice", [("0006,0012,0006", "0006"), ("1,0001", "0001")])
def test_a_sequence_listed_twice_in_seqs_is_refused_naming_it(command, seqs, twice, scene, tmp_path, capsys):
    """``--seqs 0006,0012,0006`` scored 0006 twice (COMBINED counted it twice): refused by every
    command with ``--seqs``, naming the flag and the sequence, before anything is written."""
    argv = [a.format(tmp=tmp_path) for a in _SEQS_COMMANDS[command]] + ["--data", str(scene), "--seqs", seqs]
    status, _, err = run_cli(capsys, argv)
    line = error_line(err, command, alone=True)
    assert status == 2 and "--seqs" in line and f"sequence {twice} is listed twice" in line, line
    assert not (tmp_path / "o").exists()
    with pytest.raises(ValueError, match=f"--seqs {seqs}: sequence {twice} is listed twice"):
        cli_args.parse_seqs(seqs)


@pytest.mark.parametrize("argv, command, want", [
    (["eval", "{tmp}", "--seqs", ","], "eval", "argument --seqs: names no sequence"),
    (["compare", "{tmp}", "{tmp}", "--seqs", " , "], "compare", "argument --seqs: names no sequence"),
    (["track", "--out", "{tmp}/o", "--seqs", ""], "track", "argument --seqs: names no sequence"),
    (["compare", "{tmp}", "{tmp}", "--seed", "-1"], "compare", "argument --seed: -1: expected a whole number >= 0"),
    (["demo", "--out", "{tmp}/o", "--seed", "-1"], "demo", "argument --seed: -1: expected a whole number >= 0"),
    (["lidar", "simulate", "--out", "{tmp}/o", "--seed", "-1"], "lidar simulate", "argument --seed: -1"),
    (["eval", "{tmp}", "--csv", ""], "eval", "argument --csv: '': expected a file name"),
])
def test_flags_are_named_not_the_data(argv, command, want, tmp_path, capsys):
    """``--seqs ,`` was blamed on the ground truth (no sequence has the class), ``--seed -1`` was
    NumPy's "expected non-negative integer": each names its flag."""
    status, _, err = run_cli(capsys, [a.format(tmp=tmp_path) for a in argv])
    assert status == 2 and want in error_line(err, command, alone=True)
    assert not (tmp_path / "o").exists()


def test_host_devices_variable_is_named(scene, tmp_path, monkeypatch, capsys):
    """``DFRMOT_HOST_DEVICES=abc``: "invalid literal for int()" named nothing."""
    from dfrmot_jax import devices

    for bad in ("abc", "-2", "1.5"):
        monkeypatch.setenv("DFRMOT_HOST_DEVICES", bad)
        with pytest.raises(ValueError, match=f"DFRMOT_HOST_DEVICES='{bad}': expected a whole number"):
            devices.wanted_devices()
    monkeypatch.setenv("DFRMOT_HOST_DEVICES", "abc")
    status, _, err = run_cli(capsys, ["track", "--data", str(scene), "--det2d", "synth2d", "--det3d", "synth3d",
                                      "--out", str(tmp_path / "o")])
    assert status == 2 and "DFRMOT_HOST_DEVICES='abc'" in error_line(err, "track", alone=True)
    monkeypatch.setenv("DFRMOT_HOST_DEVICES", "")
    assert devices.wanted_devices() == min(os.cpu_count() or 1, 8)
