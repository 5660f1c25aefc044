"""Where a sweep's chunks run: this process (:class:`LocalBackend`, the default) or a Ray cluster
(:class:`RayBackend`, implemented in :mod:`dfrmot_jax.sweep.ray_backend`).

Both have the same two calls, so the run loop (:func:`dfrmot_jax.sweep.runner.run_sweep`) names no
backend: ``check()`` before anything is written (an unreachable cluster is refused there), and
``run_chunks(spec, table, data, todo, keep, bar, log, compact=...)``, which computes the chunks'
tables and hands each to ``keep(chunk, table)``. Either way the driver plans the chunks, skips finished
ones and is the only writer of the store, and a chunk's table is computed by the same code
(:class:`dfrmot_jax.sweep.chunks.ChunkRunner`): the store does not care which backend wrote a chunk,
so a sweep started on one backend can be finished on the other.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Sequence

import pandas as pd

from . import ray_backend
from ..checks import SweepConfigError
from ..choices import BACKENDS
from ..devices import chosen_platform
from .chunks import ChunkRunner, Keep
from .plan import Chunk, DataSettings
from .spec import SweepSpec



@dataclass(frozen=True)
class LocalBackend:
    """Track in this process (batches split over the host devices); ``workers``: metric processes
    beside the tracker (``None``: 2 for large sweeps, 0: in-process)."""

    workers: int | None = None
    name: str = "local"

    def check(self) -> None:
        """The platform this process tracks on (``$DFRMOT_DEVICE``, :func:`~dfrmot_jax.devices.chosen_platform`):
        ``gpu`` where JAX sees none is refused before anything is written."""
        chosen_platform()

    def run_chunks(self, spec: SweepSpec, table: pd.DataFrame, data: DataSettings, todo: Sequence[Chunk],
                   keep: Keep, bar, log, *, compact: bool = True) -> None:
        """Track and score ``todo`` here; ``keep(chunk, table)`` each in order."""
        ChunkRunner.load(spec, table, data, todo, compact=compact).run(keep, bar, log, self.workers)


@dataclass(frozen=True)
class RayBackend:
    """Track on a Ray cluster: one long-lived worker (a Ray actor) per ``worker_cpus`` CPUs of each
    node (default: one per node, with all of its CPUs).

    ``address``: the cluster (``"auto"``, ``"HOST:PORT"``, ``"ray://HOST:10001"``); ``None`` starts
    a local Ray instance, or uses the one this process is already connected to."""

    address: str | None = None
    worker_cpus: int | None = None
    name: str = "ray"

    def check(self) -> None:
        """Connect now: an unreachable cluster is refused before anything is written."""
        ray_backend.connect(self.address, self.worker_cpus)

    def run_chunks(self, spec: SweepSpec, table: pd.DataFrame, data: DataSettings, todo: Sequence[Chunk],
                   keep: Keep, bar, log, *, compact: bool = True) -> None:
        """Compute ``todo``'s tables on the cluster; ``keep(chunk, table)`` each as it arrives."""
        ray_backend.run_chunks(self.address, self.worker_cpus, spec, table, data, todo, keep, bar, log,
                               compact=compact)


def make_backend(backend="local", *, workers: int | None = None, address: str | None = None,
                 worker_cpus: int | None = None):
    """A backend from its name (``"local"`` | ``"ray"``) and settings, or the backend object itself
    (a :class:`LocalBackend` given with ``workers`` takes that number of metric processes)."""
    if isinstance(backend, LocalBackend):
        return backend if workers is None else replace(backend, workers=workers)
    if isinstance(backend, RayBackend):
        return backend
    if backend == "local":
        if address is not None or worker_cpus is not None:
            raise SweepConfigError("backend", "--address and --worker-cpus need --backend ray")
        return LocalBackend(workers)
    if backend == "ray":
        if worker_cpus is not None and worker_cpus < 1:
            raise SweepConfigError("worker_cpus", f"{worker_cpus}: expected an integer >= 1")
        return RayBackend(address, worker_cpus)
    raise SweepConfigError("backend", f"{backend!r}: expected one of {', '.join(BACKENDS)}")
