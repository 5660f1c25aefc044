"""The metrics' compiled kernels and numba's disk cache (``metrics.common.kernel_cache.cached_njit``):
with no writable cache location the command line still works (the kernels kept in a temporary
folder, else compiled in memory, one warning line); a damaged cache entry is compiled anew and
replaced, with one warning naming it. Each case runs in a fresh process, as a user's run would."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

KERNEL_MOD = '''from dfrmot_jax.metrics.common.kernel_cache import cached_njit


@cached_njit(nogil=True)
def kernel(x):
    return x + 1.0


print(kernel(1.0), kernel.stats.cache_hits.total(), kernel.stats.cache_misses.total())
'''

#: no writable location for numba's cache, as root can have it: the package's __pycache__ refused as a
#: read-only install refuses it (root may write anywhere else), the home and NUMBA_CACHE_DIR below a file
NO_LOCATION = ("import numba.core.caching as c\n"
               "c.InTreeCacheLocator.from_function = classmethod(lambda cls, f, p: None)\n")
NO_TEMP = "import tempfile\ntempfile.tempdir = '/dev/null'\n"
CLI = "import sys\nfrom dfrmot_jax.cli import main\nsys.exit(main(sys.argv[1:]))\n"
REPO = Path(__file__).resolve().parents[3]


def _run(code: str, tmp_path: Path, *args, **env) -> subprocess.CompletedProcess:
    e = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), str(REPO)]), TMPDIR=str(tmp_path / "tmp"), **env)
    (tmp_path / "tmp").mkdir(exist_ok=True)
    return subprocess.run([sys.executable, "-c", code, *args], env=e, capture_output=True, text=True, cwd=tmp_path,
                          timeout=600)


def _no_location(**more) -> dict:
    return dict(HOME="/dev/null", XDG_CACHE_HOME="/dev/null/cache", NUMBA_CACHE_DIR="/dev/null/numba", **more)


def _warnings(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if "Warning" in line or ": warning: " in line]


@pytest.mark.slow
def test_the_command_line_works_without_a_writable_cache_location(tmp_path):
    """``$NUMBA_CACHE_DIR``, the package's ``__pycache__`` and the home cache unwritable: ``dfrmot eval
    --help`` was a traceback (``cannot cache function ...: no locator available``, raised while the
    metrics are imported). The kernels are kept in a folder of the temporary directory, one warning
    (``eval --help`` no longer imports the metrics: ``eval`` of a missing folder does, then refuses it)."""
    r = _run(NO_LOCATION + CLI, tmp_path, "eval", str(tmp_path / "none"), **_no_location())
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    root = tmp_path / "tmp" / f"dfrmot_jax-numba-{os.getuid()}"
    assert r.stderr.splitlines() == [f"dfrmot eval: warning: no writable cache for the compiled scoring kernels "
                                      f"($NUMBA_CACHE_DIR, the package's __pycache__, the home cache): kept in {root}",
                                      f"dfrmot eval: error: not a directory: {tmp_path / 'none'}"]
    (tmp_path / "kmod.py").write_text(KERNEL_MOD)
    first = _run(NO_LOCATION + "import kmod\n", tmp_path, **_no_location())
    again = _run(NO_LOCATION + "import kmod\n", tmp_path, **_no_location())
    assert first.stdout.split() == ["2.0", "0", "1"] and again.stdout.split() == ["2.0", "1", "0"], again.stderr
    assert len(_warnings(first.stderr)) == 1 and str(root) in first.stderr


@pytest.mark.slow
def test_without_a_temporary_folder_the_kernels_compile_in_memory(tmp_path):
    r = _run(NO_LOCATION + NO_TEMP + CLI, tmp_path, "eval", str(tmp_path / "none"), **_no_location())
    assert r.returncode == 2 and len(r.stderr.splitlines()) == 2, r.stderr
    assert r.stderr.startswith("dfrmot eval: warning: no writable cache for the compiled scoring kernels") and \
        "compiled in memory, for this run only" in r.stderr
    (tmp_path / "kmod.py").write_text(KERNEL_MOD)
    for _ in range(2):
        r = _run(NO_LOCATION + NO_TEMP + "import kmod\n", tmp_path, **_no_location())
        assert r.stdout.split() == ["2.0", "0", "1"] and len(_warnings(r.stderr)) == 1, r.stderr


def _truncate(p: Path) -> None:
    p.write_bytes(p.read_bytes()[: len(p.read_bytes()) // 2])


def _garble(p: Path) -> None:
    data = bytearray(p.read_bytes())
    data[len(data) // 2:] = b"\xff" * (len(data) - len(data) // 2)
    p.write_bytes(bytes(data))


@pytest.mark.parametrize("which", ["nbi", "nbc"])
@pytest.mark.parametrize("damage", [_truncate, pytest.param(lambda p: p.write_bytes(b""), marks=pytest.mark.slow),
                                    pytest.param(_garble, marks=pytest.mark.slow)],
                         ids=["truncated", "emptied", "garbled"])
@pytest.mark.slow
def test_a_damaged_cache_entry_is_compiled_anew_and_replaced(which, damage, tmp_path):
    """A truncated, emptied or garbled index (.nbi) or data file (.nbc) was exit 1 (UnpicklingError,
    EOFError) or a UTF-8 message naming no file, in every later run until deleted by hand: now one
    warning naming the file, the kernel compiled anew, and the next run loads the replaced entry."""
    (tmp_path / "kmod.py").write_text(KERNEL_MOD)
    env = dict(NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    first = _run("import kmod\n", tmp_path, **env)
    assert first.stdout.split() == ["2.0", "0", "1"], first.stderr
    [path] = (tmp_path / "cache").rglob(f"kmod.kernel-*.{which}")
    damage(path)
    r = _run("import kmod\n", tmp_path, **env)
    assert r.returncode == 0 and r.stdout.split() == ["2.0", "0", "1"], r.stderr
    [line] = _warnings(r.stderr)
    assert f"damaged compiled-kernel cache entry {path} (" in line and "compiled anew and replaced" in line
    again = _run("import kmod\n", tmp_path, **env)
    assert again.stdout.split() == ["2.0", "1", "0"] and not _warnings(again.stderr), again.stderr


RACE_MOD = '''import os
import sys
import time

import numpy as np

from dfrmot_jax.metrics.common.kernel_cache import cached_njit


@cached_njit(nogil=True)
def kernel(x):
    out = np.zeros((len(x), len(x)))
    for i in range(len(x)):
        for j in range(len(x)):
            out[i, j] = np.sqrt(abs(x[i] - x[j])) + np.exp(-x[i] * x[j])
    return out.sum()


open(sys.argv[1], "w").close()                  # ready
while not os.path.exists("go"):
    time.sleep(0.01)
print(round(kernel(np.arange(3.0)), 6), kernel.stats.cache_hits.total(), kernel.stats.cache_misses.total())
'''


@pytest.mark.slow
def test_processes_missing_a_kernel_at_once_compile_it_once(tmp_path):
    """Two processes that need a kernel missing from the cache at the same moment (a sweep's metric
    workers, the demo's warm-up process and its scoring) compiled it both, racing to write it: now
    the first takes the kernel's lock and compiles it, the second waits for the lock and loads it."""
    (tmp_path / "kmod.py").write_text(RACE_MOD)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), str(REPO)]),
               NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    procs = [subprocess.Popen([sys.executable, "-c", "import kmod", f"ready{k}"], env=env, cwd=tmp_path,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for k in range(2)]
    try:
        deadline = time.monotonic() + 300
        while not all((tmp_path / f"ready{k}").exists() for k in range(2)):
            assert time.monotonic() < deadline and all(p.poll() is None for p in procs), procs[0].stderr.read()
            time.sleep(0.05)
        (tmp_path / "go").touch()
        outs = [p.communicate(timeout=300) for p in procs]
    finally:
        for p in procs:
            p.kill()
    value = {o.split()[0] for o, _ in outs}
    assert len(value) == 1 and sorted(tuple(o.split()[1:]) for o, _ in outs) == [("0", "1"), ("1", "0")], outs



DEMO_SIGNATURES = '''import sys
from numba.core.registry import CPUDispatcher
from dfrmot_jax.cli import main
status = main(["demo", "--out", sys.argv[1], "--sequences", "2", "--frames", "30"])
print("status", status)
for name, mod in sorted(sys.modules.items()):
    if name.startswith("dfrmot_jax.metrics"):
        for k, v in vars(mod).items():
            if isinstance(v, CPUDispatcher) and v.py_func.__module__ == name and v.signatures:
                print("signatures", name + "." + k, len(v.signatures), any("Literal" in str(s) for s in v.signatures))
'''


@pytest.mark.slow
def test_the_demo_compiles_each_kernel_once(tmp_path):
    """A first demo run (no cache) compiles each kernel of its scoring for one signature, none for a
    literal argument: numba compiles a kernel anew for each literal value a compiled caller passes
    (solve_block was compiled three times, _align, _matching_value, workspace, _solve, ... twice)."""
    r = _run(DEMO_SIGNATURES, tmp_path, str(tmp_path / "demo"), NUMBA_CACHE_DIR=str(tmp_path / "cache"),
             DFRMOT_COMPILE_CACHE="off")
    assert r.returncode == 0 and "status 0" in r.stdout.splitlines(), r.stderr
    sigs = {w[1]: (int(w[2]), w[3]) for w in map(str.split, r.stdout.splitlines()) if w[:1] == ["signatures"]}
    for name in ("common.assignment.solve_block", "kitti2d.hota._hota_kernel", "kitti2d.identity._identity_kernel"):
        assert "dfrmot_jax.metrics." + name in sigs, sorted(sigs)
    assert {n: s for n, s in sigs.items() if s != (1, "False")} == {}
