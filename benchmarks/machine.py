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
    """CPU, core count, JAX and package versions, the tracker's platform (``$DFRMOT_DEVICE``), its
    devices and their kind (asks for one CPU device per core first: querying JAX initialises its
    backend, after which the count is fixed)."""
    import jax

    import dfrmot_jax

    from dfrmot_jax.devices import batch_devices, chosen_platform

    dfrmot_jax.setup_host_devices()
    where = chosen_platform()
    devices = batch_devices(where)
    return {"machine": platform.processor() or platform.machine(), "cpu_model": cpu_model(), "cpus": os.cpu_count(),
            "jax": jax.__version__, "dfrmot_jax": dfrmot_jax.__version__, "devices": len(devices),
            "platform": where, "device_kind": devices[0].device_kind}


def cpu_time() -> float:
    """CPU time (user + system) of this process and of every process it started, running or ended:
    the metric workers too, which run under multiprocessing's forkserver (children of the forkserver,
    so ``RUSAGE_CHILDREN`` never sees them): each live descendant counts with the ended children it
    has reaped (``psutil``: ``children_user`` / ``children_system``), so nothing is counted twice. A
    descendant that ends and is reaped between two calls is counted through its parent."""
    import psutil

    total = 0.0
    for p in [psutil.Process()] + psutil.Process().children(recursive=True):
        try:
            t = p.cpu_times()
        except (psutil.NoSuchProcess, psutil.AccessDenied):
            continue
        total += t.user + t.system + t.children_user + t.children_system
    return total


def cold_output_dir(out: str | None, prefix: str) -> Path:
    """The results folder of a cold run: ``out`` emptied (no chunk to resume), or a new temporary one."""
    import shutil
    import tempfile

    if not out:
        return Path(tempfile.mkdtemp(prefix=prefix))
    path = Path(out)
    if path.exists():
        shutil.rmtree(path)
    return path


def peak_rss_mb() -> float:
    """Peak resident memory of this process so far, MB (``ru_maxrss``; the metric workers not included)."""
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
