"""Issue 29, item 5: start-up a user does not wait for. ``import dfrmot_jax`` names its API lazily and
imports nothing heavy; ``dfrmot --help`` imports none of the commands' dependencies, ``dfrmot track
--help`` only ``config``; ``dfrmot eval`` and ``dfrmot report`` (whose package, ``report/``, reaches
no JAX: item 2) run in a process where JAX cannot be imported, with the same output as in-process.
Issue 41, item 15: every ``dfrmot CMD --help`` (and ``dfrmot lidar ACTION --help``) imports none of
the heavy packages, nor the command's own module (its parser module alone). Each check runs a fresh
interpreter (``sys.modules`` of this one holds everything)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from dfrmot_jax.cli.commands import HELP
from dfrmot_jax.synthetic import make_scene
from dfrmot_jax.testing.cli import run_cli

ROOT = Path(__file__).resolve().parents[2]
HEAVY = ("jax", "jaxlib", "optax", "pandas", "pyarrow", "scipy", "optuna", "matplotlib")
#: run in the child before anything else: importing JAX (or what is built on it) fails there
NO_JAX = "import sys\nfor _m in ('jax', 'jaxlib', 'optax'):\n    sys.modules[_m] = None\n"


def _child(code: str, *args, timeout: float = 300) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, env=env, cwd=ROOT)


def _held_after(code: str, modules) -> list[str]:
    """Those of ``modules`` a fresh interpreter holds after running ``code`` (``SystemExit`` allowed)."""
    probe = (f"import sys, json\ntry:\n    {code}\nexcept SystemExit:\n    pass\n"
             f"print(json.dumps(sorted(m for m in {tuple(modules)!r} if m in sys.modules)))")
    out = _child(probe)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def _heavy_after(code: str) -> list[str]:
    """The heavy packages a fresh interpreter holds after running ``code`` (``SystemExit`` allowed)."""
    return _held_after(code, HEAVY)


def test_import_of_the_package_imports_nothing_heavy():
    assert _heavy_after("import dfrmot_jax") == []


def test_the_public_api_is_named_lazily_and_complete():
    import dfrmot_jax

    assert set(dfrmot_jax.__all__) <= set(dir(dfrmot_jax))
    for name in dfrmot_jax.__all__:
        assert getattr(dfrmot_jax, name) is not None, name
    assert dfrmot_jax.sweep.__name__ == "dfrmot_jax.sweep" and dfrmot_jax.tune.__name__ == "run_tune"
    with pytest.raises(AttributeError, match="no attribute 'nosuch'"):
        dfrmot_jax.nosuch


def test_help_imports_none_of_the_commands_dependencies():
    assert _heavy_after("from dfrmot_jax.cli import main; main(['--help'])") == []


def test_track_help_needs_only_config():
    """``dfrmot track --help`` lists every parameter, option and preset (``config``: NumPy only)."""
    assert _heavy_after("from dfrmot_jax.cli import main; main(['track', '--help'])") == []


#: every command's ``--help``, and each ``lidar`` action's
HELPS = [[name, "--help"] for name in HELP] + [["lidar", action, "--help"] for action in ("simulate", "lift")]


@pytest.mark.parametrize("argv", HELPS, ids=[" ".join(a[:-1]) for a in HELPS])
def test_every_commands_help_imports_nothing_heavy_nor_the_command(argv):
    """``dfrmot CMD --help`` builds the command's whole parser from its parser module (``CMD_parser``)
    alone: none of :data:`HEAVY` is imported, nor the command's own module (imported when it runs)."""
    parser, command = f"dfrmot_jax.cli.{argv[0]}_parser", f"dfrmot_jax.cli.{argv[0]}"
    held = _held_after(f"from dfrmot_jax.cli import main; main({argv!r})", HEAVY + (parser, command))
    assert held == [parser]


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    """A synthetic scene, one ``dfrmot track`` output of it and a 2-config sweep folder over it."""
    from dfrmot_jax.sweep import run_sweep

    d = tmp_path_factory.mktemp("startup")
    root = make_scene(d / "scene", n_sequences=2, n_frames=40, n_cars=3, seed=5)
    from dfrmot_jax.cli import main

    assert main(["track", "--data", str(root), "--det2d", "synth2d", "--det3d", "synth3d", "--out", str(d / "out")]) == 0
    run_sweep({"name": "startup", "chunk": 8, "data": {"root": str(root), "det2d": "synth2d", "det3d": "synth3d"},
               "params": {"a_l": [2.0, 8.0]}}, d / "sweep", progress=False, workers=0, log=lambda m: None)
    return root, d


@pytest.mark.slow
def test_eval_runs_where_jax_cannot_be_imported(folders, capsys):
    root, d = folders
    _, want, _ = run_cli(capsys, ["eval", d / "out", "--data", root])
    code = NO_JAX + "from dfrmot_jax.cli import main\nsys.exit(main(sys.argv[1:]))\n"
    out = _child(code, "eval", d / "out", "--data", root)
    assert out.returncode == 0, out.stderr
    assert out.stdout == want and "COMBINED" in want


@pytest.mark.slow
def test_report_runs_where_jax_cannot_be_imported(folders, tmp_path, capsys):
    """``dfrmot report DIR --html PAGE`` in a process without JAX: the same text, the same page (but
    its time stamp) as in this process."""
    _, d = folders
    _, want, _ = run_cli(capsys, ["report", d / "sweep", "--html", tmp_path / "here.html"])
    code = NO_JAX + "from dfrmot_jax.cli import main\nsys.exit(main(sys.argv[1:]))\n"
    out = _child(code, "report", d / "sweep", "--html", tmp_path / "there.html")
    assert out.returncode == 0, out.stderr
    assert out.stdout == want and "sensitivity" in want

    def page(name):
        text = (tmp_path / name).read_text()
        return [line for line in text.splitlines() if " UTC<" not in line]

    assert page("there.html") == page("here.html")
