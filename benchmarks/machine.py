"""The machine a benchmark ran on, for the JSON line every benchmark prints last."""

from __future__ import annotations

import os
import platform
from pathlib import Path


def cpu_model() -> str:
    """The CPU model from /proc/cpuinfo (``platform.processor()`` is empty on this kind of VM)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine_info() -> dict:
    """CPU, core count, JAX and package versions, XLA devices (imports JAX: call after dfrmot_jax)."""
    import jax

    import dfrmot_jax

    return {"machine": platform.processor() or platform.machine(), "cpu_model": cpu_model(), "cpus": os.cpu_count(),
            "jax": jax.__version__, "dfrmot_jax": dfrmot_jax.__version__, "devices": jax.local_device_count()}
