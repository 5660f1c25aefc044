"""Where a sweep's chunks run: this process (:class:`LocalBackend`, the default) or a Ray cluster
(:class:`RayBackend`, implemented in :mod:`dfrmot_jax.sweep.ray_backend`).

Either way the driver plans the chunks, skips finished ones and is the only writer of the store, and
a chunk's table is computed by the same code (``runner._ChunkRunner``): the store does not care which
backend wrote a chunk, so a sweep started on one backend can be finished on the other.
"""

from __future__ import annotations

from dataclasses import dataclass

from .spec import SweepConfigError

BACKENDS = ("local", "ray")


@dataclass(frozen=True)
class LocalBackend:
    """Track in this process (batches split over the host devices); ``workers``: metric processes
    beside the tracker (``None``: 2 for large sweeps, 0: in-process)."""

    workers: int | None = None
    name: str = "local"


@dataclass(frozen=True)
class RayBackend:
    """Track on a Ray cluster: one long-lived worker (a Ray actor) per ``worker_cpus`` CPUs of each
    node (default: one per node, with all of its CPUs).

    ``address``: the cluster (``"auto"``, ``"HOST:PORT"``, ``"ray://HOST:10001"``); ``None`` starts
    a local Ray instance, or uses the one this process is already connected to."""

    address: str | None = None
    worker_cpus: int | None = None
    name: str = "ray"


def make_backend(backend="local", *, workers: int | None = None, address: str | None = None,
                 worker_cpus: int | None = None):
    """A backend from its name (``"local"`` | ``"ray"``) and settings, or the backend object itself."""
    if isinstance(backend, (LocalBackend, RayBackend)):
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
