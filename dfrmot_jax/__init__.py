"""dfrmot_jax: the DFR-FastMOT camera+LiDAR tracker as batched JAX, built for parameter sweeps.

On import (before JAX is imported) the CPU is exposed as one XLA device per core, so that a batch
of settings is split over all cores. Set ``DFRMOT_HOST_DEVICES=1`` (or your own
``--xla_force_host_platform_device_count`` in ``XLA_FLAGS``) to opt out.
"""

import os as _os
import sys as _sys


def _configure_host_devices() -> None:
    flags = _os.environ.get("XLA_FLAGS", "")
    if "jax" in _sys.modules or "xla_force_host_platform_device_count" in flags:
        return
    n = int(_os.environ.get("DFRMOT_HOST_DEVICES", "0") or 0) or min(_os.cpu_count() or 1, 8)
    _os.environ["XLA_FLAGS"] = f"{flags} --xla_force_host_platform_device_count={n}".strip()


_configure_host_devices()

__version__ = "0.1.0"

from .api import TrackResult, default_capacity, track  # noqa: E402
from .data import Split, load_split, prepare_frames  # noqa: E402
from .params import Options, Params, preset, stack_params  # noqa: E402
from .sweep import sweep, sweep_report  # noqa: E402

__all__ = ["Options", "Params", "Split", "TrackResult", "default_capacity", "load_split", "prepare_frames",
           "preset", "stack_params", "track", "__version__", "sweep", "sweep_report"]
