"""dfrmot_jax: the DFR-FastMOT camera+LiDAR tracker as batched JAX, built for parameter sweeps.

Importing the package changes no environment variable or global state, and imports nothing heavy:
the public API (``__all__``) is imported on first use (PEP 562), so that ``import dfrmot_jax`` and
the parts that need no JAX (``dfrmot --help``, ``dfrmot eval``, ``dfrmot report``,
:mod:`dfrmot_jax.report`, :mod:`dfrmot_jax.metrics`) start without it. The first tracking call
asks JAX for one CPU device per core (``setup_host_devices``; ``DFRMOT_HOST_DEVICES=1`` opts out),
so that a batch of settings is split over all cores; that works only before the process's first
JAX operation, so call ``dfrmot_jax.setup_host_devices()`` right after import if your own code runs
JAX first (it warns when JAX already runs on fewer devices).
"""

from .version import __version__

__all__ = ["Options", "Params", "Split", "TrackResult", "default_capacity", "default_data_root", "load_split",
           "prepare_frames", "preset", "setup_host_devices", "stack_params", "track", "__version__", "run_sweep",
           "sweep", "sweep_report", "tune", "ab3dmot", "bytetrack", "dfr"]


def __getattr__(name: str):
    """A name of the public API, imported when first asked for (then kept in the module)."""
    if name in ("default_capacity", "track"):
        from .trackers.dfr import track as home
    elif name == "TrackResult":
        from .trackers import protocol as home
    elif name == "setup_host_devices":
        from . import devices as home
    elif name in ("Split", "load_split"):
        from . import data as home
    elif name == "prepare_frames":
        from .trackers.dfr import frames as home
    elif name == "ab3dmot":       # each tracker family's folder, by its name (``from dfrmot_jax import ab3dmot``)
        from .trackers import ab3dmot as value
        globals()[name] = value
        return value
    elif name == "dfr":
        from .trackers import dfr as value
        globals()[name] = value
        return value
    elif name == "bytetrack":
        from .trackers import bytetrack as value
        globals()[name] = value
        return value
    elif name == "default_data_root":
        from . import paths as home
    elif name in ("Options", "Params", "preset", "stack_params"):
        from .trackers.dfr import config as home
    elif name in ("run_sweep", "sweep_report", "sweep"):
        # importing the sweep package binds it here as ``sweep`` (its function ``sweep`` is a deprecated alias)
        from .sweep import run_sweep, sweep_report
        globals().update(run_sweep=run_sweep, sweep_report=sweep_report)
        return globals()[name]
    elif name == "tune":
        from .tuning import run_tune
        globals()["tune"] = run_tune
        return run_tune
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(home, name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
