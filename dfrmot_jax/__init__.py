"""dfrmot_jax: the DFR-FastMOT camera+LiDAR tracker as batched JAX, built for parameter sweeps.

Importing the package changes no environment variable or global state. The first tracking call
asks JAX for one CPU device per core (``setup_host_devices``; ``DFRMOT_HOST_DEVICES=1`` opts
out), so that a batch of settings is split over all cores; that works only before the process's
first JAX operation, so call ``dfrmot_jax.setup_host_devices()`` right after import if your own
code runs JAX first (it warns when JAX already runs on fewer devices).
"""

from .version import __version__

from .api import TrackResult, default_capacity, track
from .core.devices import setup_host_devices
from .data import Split, load_split, prepare_frames
from .paths import default_data_root
from .config import Options, Params, preset, stack_params
from .sweep import run_sweep, sweep_report   # binds dfrmot_jax.sweep, the sweep package
from .tuning import run_tune as tune

__all__ = ["Options", "Params", "Split", "TrackResult", "default_capacity", "default_data_root", "load_split",
           "prepare_frames", "preset", "setup_host_devices", "stack_params", "track", "__version__", "run_sweep",
           "sweep", "sweep_report", "tune"]
