import atexit
import gc
import os
import shutil
import tempfile
from pathlib import Path

import pytest

from dfrmot_jax import setup_host_devices
from dfrmot_jax.trackers.dfr.run import clear_programs
from dfrmot_jax.paths import ENV_VAR, data_available, default_data_root

# Compiled programs kept for this test run only, in a folder of its own removed at exit (never
# ~/.cache, where the in-process CLI would keep them): a program compiled again (after
# clear_programs, in another xdist worker, or in a test's subprocess, notebook kernel or Ray worker) is
# taken from there, JAX's own key naming all it depends on (JAX's file cache locks its folder, so the
# processes share it safely); test_devices tests the cache in processes of its own. The process that
# makes the folder (pytest itself, or xdist's controller, whose environment its workers inherit)
# removes it; the workers use it.
_RUN_CACHE_VAR = "DFRMOT_TEST_RUN_COMPILE_CACHE"
if os.environ.get(_RUN_CACHE_VAR) and os.environ.get("PYTEST_XDIST_WORKER"):
    _COMPILE_CACHE = os.environ[_RUN_CACHE_VAR]
else:
    _COMPILE_CACHE = tempfile.mkdtemp(prefix="dfrmot_tests_xla_")
    atexit.register(shutil.rmtree, _COMPILE_CACHE, True)
    os.environ[_RUN_CACHE_VAR] = _COMPILE_CACHE
os.environ["DFRMOT_COMPILE_CACHE"] = _COMPILE_CACHE
# One XLA device per core for the whole session, before any test runs a JAX operation.
setup_host_devices()


#: compiled programs are forgotten after a test module once the process holds this many memory
#: mappings (each program holds some; the kernel's limit, vm.max_map_count, is 65,530 by default,
#: and the whole suite in one process compiles enough programs to reach it)
MAX_MAPPINGS = 20_000


def memory_mappings() -> int:
    """This process's memory mappings (0 where /proc is not there)."""
    try:
        with open(f"/proc/{os.getpid()}/maps") as f:
            return sum(1 for _ in f)
    except OSError:
        return 0


@pytest.fixture(autouse=True, scope="module")
def bounded_memory_mappings():
    """After each test module: the compiled programs go when the mappings near the kernel's limit."""
    yield
    if memory_mappings() > MAX_MAPPINGS:
        clear_programs()
        gc.collect()


@pytest.fixture(scope="session")
def kitti_root() -> Path:
    """The KITTI training root; tests that need it skip with a message when it is absent."""
    root = default_data_root()
    if not data_available(root):
        pytest.skip(f"KITTI data not found at {root} (set {ENV_VAR} to the KITTI tracking training root)")
    return root


@pytest.hookimpl(tryfirst=True)       # before `-m` selects on the markers
def pytest_collection_modifyitems(config, items):
    """Every test that uses the KITTI data (the ``kitti_root`` fixture, directly or through another
    fixture) is marked ``kitti``, so ``-m "not kitti"`` leaves out exactly those."""
    for item in items:
        if "kitti_root" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.kitti)
