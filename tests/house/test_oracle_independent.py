"""The NumPy oracle (``testing.reference``) shares no code with the tracker (``core``).

The parity tests compare the tracker with the oracle; they mean something only when the two are
independent implementations. So the oracle imports nothing that (transitively) imports
``dfrmot_jax.trackers.dfr``, and it keeps its own copies of the box rules the tracker takes from
``core.boxes`` (the IoU and the loaders' integer truncation). These copies are checked here
against the tracker's on random and edge-case boxes.
"""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import dfrmot_jax
from dfrmot_jax import boxes as core_boxes
from dfrmot_jax.testing import reference as ref

PKG = Path(dfrmot_jax.__file__).resolve().parent
ORACLE = "dfrmot_jax.testing.reference"

# Imports the oracle in a fresh interpreter and prints the package modules it loaded. The package
# root (``dfrmot_jax/__init__.py``) imports the whole public API by design, so it is replaced by a
# bare package object: what is measured is the oracle's own import closure (with the
# ``__init__`` of every subpackage on the way, ``testing`` and ``io``).
_PROBE = f"""
import importlib.util, json, sys, types
spec = importlib.util.find_spec("dfrmot_jax")
root = types.ModuleType("dfrmot_jax")
root.__path__ = list(spec.submodule_search_locations)
sys.modules["dfrmot_jax"] = root
import {ORACLE}
print(json.dumps(sorted(m for m in sys.modules if m == "dfrmot_jax" or m.startswith("dfrmot_jax."))))
"""


def _module_file(name: str) -> Path:
    rel = Path(*name.split(".")[1:])
    pkg_init = PKG / rel / "__init__.py"
    return pkg_init if pkg_init.exists() else (PKG / rel).with_suffix(".py")


def _imports(name: str) -> set[str]:
    """Package modules that module ``name`` imports anywhere in its source (also inside functions),
    with the packages on the way (``a.b.c`` imports ``a.b``'s ``__init__`` too)."""
    path = _module_file(name)
    is_pkg = path.name == "__init__.py"
    here = name.split(".") if is_pkg else name.split(".")[:-1]
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        targets = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(here[:len(here) - node.level + 1] + ([base] if base else []))
            targets = [base] + [f"{base}.{a.name}" for a in node.names]
        for t in targets:
            if t.startswith("dfrmot_jax.") and _module_file(t).exists():
                parts = t.split(".")
                out.update(".".join(parts[:k]) for k in range(2, len(parts) + 1))
    return out


def _closure(name: str) -> set[str]:
    seen, todo = set(), [name]
    while todo:
        m = todo.pop()
        if m not in seen:
            seen.add(m)
            todo.extend(_imports(m) - seen)
    return seen


def _tracker(module: str) -> bool:
    """A module of DFR-FastMOT's tracker (its folder, but for its settings, ``config``, which the
    oracle takes its parameters as)."""
    return module.startswith("dfrmot_jax.trackers.dfr.") and module != "dfrmot_jax.trackers.dfr.config"


def test_importing_the_oracle_loads_no_tracker_module():
    proc = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True, timeout=120,
                          cwd=PKG.parent)
    assert proc.returncode == 0, proc.stderr
    loaded = set(json.loads(proc.stdout.strip().splitlines()[-1]))
    assert ORACLE in loaded
    assert not {m for m in loaded if _tracker(m)}, loaded
    # and no loaded package module imports the tracker itself (say lazily, inside a function)
    importers = {m: sorted(i for i in _imports(m) if _tracker(i)) for m in loaded if m != "dfrmot_jax"}
    assert not {m: i for m, i in importers.items() if i}


def test_oracle_import_closure_is_core_free_statically():
    """Every import in the oracle's closure, also those inside functions (which a fresh import
    does not run)."""
    closure = _closure(ORACLE)
    assert "dfrmot_jax.io.sequence" in closure and "dfrmot_jax.geometry" in closure  # the walk works
    assert not {m for m in closure if _tracker(m)}, sorted(closure)
    for banned in ("dfrmot_jax.data", "dfrmot_jax.trackers.dfr.track", "dfrmot_jax.distort"):
        assert banned not in closure


# ---------------------------------------------------------------------------------------------
# The oracle's own box rules against the tracker's


def _edge_boxes() -> np.ndarray:
    vals = [0.0, -0.0, 0.5, -0.5, 0.49999999999999994, 1.0, -1.0, 1.5, -1.5, 2.5, -2.5, 9.999999, -9.999999,
            10.0, 1241.5, -7.25, 3e6 + 0.5, np.nextafter(1.0, 0.0), np.nextafter(-1.0, 0.0)]
    rng = np.random.default_rng(3)
    out = [[a, b, c, d] for a, b, c, d in rng.choice(vals, size=(400, 4))]
    out += [[10.0, 20.0, 5.0, 8.0],                       # inverted (x2 < x1, y2 < y1)
            [-3.5, -2.5, -10.5, 4.5], [5.0, 5.0, 5.0, 5.0],
            [np.nan, 1.0, 2.0, 3.0], [1.0, 2.0, np.nan, 3.0], [np.nan] * 4,
            [np.inf, 0.0, 1.0, 1.0], [0.0, 0.0, np.inf, 1.0], [-np.inf, 0.0, 1.0, 1.0]]
    return np.array(out, np.float64)


def _random_boxes(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-100, 1300, size=(n, 2))
    wh = rng.uniform(-20, 300, size=(n, 2))                       # some inverted
    b = np.concatenate([xy, xy + wh], axis=1)
    half = rng.random(n) < 0.2
    b[half] = np.round(b[half]) + 0.5                             # exact .5 cases
    return b


def test_oracle_truncation_agrees_with_the_loaders():
    boxes = np.concatenate([_edge_boxes(), _random_boxes(2000, 0)])
    for mine, theirs in ((ref.truncate_2d, core_boxes.truncate_2d_box), (ref.truncate_3d, core_boxes.truncate_3d_box)):
        got = np.stack([mine(b) for b in boxes])
        with np.errstate(invalid="ignore"):                      # inf - inf in the NaN / inf rows
            want = theirs(boxes)
        np.testing.assert_array_equal(got, want)                 # NaN == NaN, -0.0 == 0.0
        with jax.enable_x64(True):
            np.testing.assert_array_equal(got, np.asarray(theirs(jnp.asarray(boxes))))


def test_oracle_truncation_known_values():
    # C++ (int): towards zero, so -0.5 -> 0 and -1.5 -> -1 (not floor)
    np.testing.assert_array_equal(ref.truncate_2d([-1.5, -0.5, 9.7, 5.5]), [-1, 0, 9, 5])
    np.testing.assert_array_equal(ref.truncate_3d([-1.5, -0.5, 9.7, 5.5]), [-1, 0, 9, 5])   # w = (int) 10.7, h = (int) 5.5
    # inverted boxes: the width |x - x2| is added to x; the two loaders differ when x2 has a fraction
    np.testing.assert_array_equal(ref.truncate_2d([10.0, 20.0, 5.0, 8.0]), [10, 20, 15, 32])
    np.testing.assert_array_equal(ref.truncate_2d([5.0, 0.0, 2.5, 0.0]), [5, 0, 8, 0])       # |5 - 2|
    np.testing.assert_array_equal(ref.truncate_3d([5.0, 0.0, 2.5, 0.0]), [5, 0, 7, 0])       # (int) 2.5
    assert np.isnan(ref.truncate_2d([np.nan, 1.0, 2.0, 3.0])[[0, 2]]).all()
    np.testing.assert_array_equal(ref.predicted_box(np.array([10.9, 20.2, 50.7, 80.99]), True), [10, 20, 50, 80])


def test_oracle_iou_agrees_with_the_trackers():
    a = np.concatenate([_edge_boxes()[::3], _random_boxes(300, 1)])
    b = np.concatenate([_random_boxes(200, 2), _edge_boxes()[1::5]])
    with np.errstate(invalid="ignore"):                          # inf - inf in the inf rows
        got = ref.iou_matrix(a, b)
        # the tracker's rule: raw areas (an inverted box has a negative area), 0 for a non-positive union
        np.testing.assert_array_equal(got, core_boxes.iou(a[:, None], b[None], clip_areas=False))
    with jax.enable_x64(True):
        traced = np.asarray(jax.jit(core_boxes.iou_matrix)(jnp.asarray(a), jnp.asarray(b)))
    np.testing.assert_allclose(got, traced, rtol=1e-12, atol=0)
    assert np.array_equal(got == 0, traced == 0)
    assert np.isfinite(got).all()


def test_oracle_iou_known_values():
    a = [0.0, 0.0, 10.0, 10.0]
    assert ref.iou(a, a) == 1.0
    assert ref.iou(a, [5.0, 0.0, 15.0, 10.0]) == 50 / 150
    assert ref.iou(a, [10.0, 0.0, 20.0, 10.0]) == 0.0                    # touching
    assert ref.iou([-4.0, -4.0, 4.0, 4.0], [0.0, 0.0, 8.0, 8.0]) == 16 / (64 + 64 - 16)
    assert ref.iou([1.0, 1.0, 1.0, 1.0], [1.0, 1.0, 1.0, 1.0]) == 0.0    # empty union
    assert ref.iou(a, [np.nan] * 4) == 0.0
    # an inverted box keeps its (negative) area in the union, as the tracker computes it:
    # inter = 0 (no positive overlap), so the IoU is 0 whatever the union's sign
    assert ref.iou(a, [8.0, 8.0, 2.0, 2.0]) == 0.0
