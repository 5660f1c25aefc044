import pytest
"""Importing the package changes nothing; the first tracking call asks for one device per core."""

import subprocess
import sys

SCRIPT_IMPORT = """
import os, sys
before = dict(os.environ)
import dfrmot_jax
assert dict(os.environ) == before, "import changed the environment"
assert 'jax' not in sys.modules or not __import__('jax')._src.xla_bridge.backends_are_initialized()
print("ok")
"""

SCRIPT_TRACK = """
import dfrmot_jax as dm, jax
from dfrmot_jax.synthetic import make_scene
import tempfile
root = make_scene(tempfile.mkdtemp(), n_sequences=1, n_frames=20, seed=1)
dm.track(dm.load_split(root, "synth2d", "synth3d", "car"), dm.Params())
print(jax.local_device_count())
"""

SCRIPT_LATE = """
import warnings, jax, jax.numpy as jnp
jnp.zeros(1).block_until_ready()          # the user's own JAX work initialises the backend first
import dfrmot_jax as dm
with warnings.catch_warnings(record=True) as w:
    warnings.simplefilter("always")
    n = dm.setup_host_devices(2)
print(n, any("setup_host_devices" in str(x.message) for x in w))
"""


def _run(script, **env):
    import os
    e = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "DFRMOT_HOST_DEVICES")}
    e.update(env)
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=e, timeout=300)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip().splitlines()[-1]


def test_import_changes_no_environment():
    assert _run(SCRIPT_IMPORT) == "ok"


@pytest.mark.slow
def test_first_tracking_call_uses_one_device_per_core():
    import os
    assert _run(SCRIPT_TRACK) == str(min(os.cpu_count() or 1, 8))
    assert _run(SCRIPT_TRACK, DFRMOT_HOST_DEVICES="1") == "1"


def test_late_setup_warns_and_reports_the_devices_in_use():
    assert _run(SCRIPT_LATE) == "1 True"
