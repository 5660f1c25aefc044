"""One XLA CPU device per core, so that a batch of settings is split over the cores.

Nothing happens at import: ``setup_host_devices`` runs at the first tracking call (or call it
yourself right after ``import dfrmot_jax``). It can only take effect before JAX initialises its
backend, i.e. before the process runs its first JAX operation; later it warns once when JAX runs
on fewer devices than asked for.
"""

from __future__ import annotations

import os
import warnings

import jax

ENV_VAR = "DFRMOT_HOST_DEVICES"
_FORCE_FLAG = "xla_force_host_platform_device_count"
_warned = False


def wanted_devices() -> int:
    """``$DFRMOT_HOST_DEVICES``, else one per core (at most 8)."""
    return int(os.environ.get(ENV_VAR, "0") or 0) or min(os.cpu_count() or 1, 8)


def setup_host_devices(n: int | None = None) -> int:
    """Ask JAX for ``n`` CPU devices (default :func:`wanted_devices`); returns the devices in use.

    A ``--xla_force_host_platform_device_count`` in ``XLA_FLAGS`` wins. Once JAX's backend is
    running the count cannot change: then a RuntimeWarning says so (once) if it is smaller.
    """
    global _warned
    want = wanted_devices() if n is None else int(n)
    if _FORCE_FLAG not in os.environ.get("XLA_FLAGS", ""):
        try:
            jax.config.update("jax_num_cpu_devices", want)
        except RuntimeError:      # the backend is already initialised: nothing can change now
            pass
    have = jax.local_device_count()
    if have < want and jax.default_backend() == "cpu" and not _warned:
        _warned = True
        warnings.warn(f"JAX was initialised with {have} CPU device(s) before dfrmot_jax could ask for {want}: "
                      f"batches run on {have} core(s). Call dfrmot_jax.setup_host_devices() right after import, "
                      f"before any JAX operation, or set XLA_FLAGS=--{_FORCE_FLAG}={want}.",
                      RuntimeWarning, stacklevel=3)
    return have
