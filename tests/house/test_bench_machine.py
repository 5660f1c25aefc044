"""The benchmarks' accounting of the machine (issue 23, bug 8): ``cpu_seconds`` counts the metric
worker processes, which run under multiprocessing's forkserver (children of the forkserver, not of
the benchmark: ``RUSAGE_CHILDREN`` never sees them)."""

from __future__ import annotations

import multiprocessing as mp
import resource
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

from machine import cpu_time  # noqa: E402


def _self() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def test_cpu_time_counts_forkserver_workers():
    """A pool like ``metrics.kitti2d.evaluate.worker_pool`` (forkserver) burns CPU while this process waits:
    the benchmark's CPU time must grow by about as much as the workers burned."""
    ctx = mp.get_context("forkserver")
    c0, s0 = cpu_time(), _self()
    with ProcessPoolExecutor(max_workers=2, mp_context=ctx) as pool:
        futures = [pool.submit(sum, range(25_000_000)) for _ in range(2)]      # ~0.3-1 s of CPU each
        assert all(f.result() == 25_000_000 * (25_000_000 - 1) // 2 for f in futures)
    workers = (cpu_time() - c0) - (_self() - s0)
    assert workers > 0.3, f"the workers' CPU time was not counted ({workers:.3f} s beside this process')"
