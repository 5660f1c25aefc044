from pathlib import Path

import pytest

from dfrmot_jax import setup_host_devices
from dfrmot_jax.paths import ENV_VAR, data_available, default_data_root

# One XLA device per core for the whole session, before any test runs a JAX operation.
setup_host_devices()


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
