"""Running a sweep's chunks on a Ray cluster (``run_sweep(backend="ray")``, ``dfrmot sweep --backend ray``).

The driver (the process calling ``run_sweep``) reads the files, plans, skips finished chunks and is
the only writer of the store. Workers are long-lived Ray actors, by default one per node with all of
its CPUs (``worker_cpus``: one per that many CPUs). Each holds, per class's data settings, the packed
split and the prepared ground truth, put in the object store once by the driver as NumPy arrays (so
the nodes need no copy of the KITTI files, except for distortion studies, which read the ground-truth
labels at the split's root), and computes chunk tables with the local backend's code
(:class:`dfrmot_jax.sweep.chunks.ChunkRunner`): one compilation per option group and worker, reused across chunks,
sweeps and tune batches; the same tables to the bit.

JAX in a worker: the actor's process starts with environment variables set by its ``runtime_env``
before anything imports JAX: ``JAX_PLATFORMS=cpu``, ``DFRMOT_HOST_DEVICES`` = its CPUs (a chunk's
batch is split over that many XLA host devices, as locally), ``OMP_NUM_THREADS`` = its CPUs, and the
driver's ``XLA_FLAGS`` if set. ``DFRMOT_RAY_ENV`` (``NAME=VALUE,NAME=VALUE``) adds or overrides
variables.

Losing a worker or a node: actors are created with ``max_restarts=0`` and their tasks with
``max_task_retries=0``; a chunk whose worker died comes back to the driver as an error and is queued
again for the others, and a new worker is placed on any alive node without one. (Ray's own restarts
are not used: restarting an actor needs its CPUs free on some node, and with every CPU of the cluster
held by workers that wait never ends: ray-project/ray#15045.) A chunk's table is written only when it
arrives whole, so nothing is lost or written twice; a killed driver resumes from the store.
"""

from __future__ import annotations

import logging
import os
import socket
import threading
import time
import uuid
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Sequence

import jax
import pandas as pd

from ..devices import setup_host_devices
from ..metrics.kitti2d.evaluate import worker_pool
from ..checks import SweepConfigError
from .chunks import ChunkRunner, Keep, load_data
from .plan import Chunk, DataSettings

# Ray is an optional dependency (``pip install "dfrmot_jax[ray]"``): imported where it is used.

#: chunks queued per worker (one running, one waiting: the worker never idles on the driver)
QUEUE_PER_WORKER = 2
#: seconds a new worker may take to start (Ray places it when its CPUs are free; JAX is imported)
START_TIMEOUT = float(os.environ.get("DFRMOT_RAY_START_TIMEOUT", "120"))


class _ChunkWorker:
    """A Ray actor: the data of each class it was given, the run it is part of, chunk tables.

    Two ``compute`` calls run at once (its "compute" concurrency group; one chunk running, one
    queued): while one chunk's outputs are scored, in metric processes beside it when the worker
    has 2 or more CPUs (as the local backend's), the next chunk is tracked. Tracking and the
    runner's state (the scorer's memo too) are taken one call at a time (``lock``). The two calls'
    chunks complete in any order, so each scores all of its new outputs itself
    (:meth:`~dfrmot_jax.sweep.scoring.ChunkScorer.start`). ``info`` / ``load`` / ``begin`` run in
    their own group ("control"), in the order sent; a ``compute`` waits for its run's ``begin``."""
    def __init__(self, cpus: int = 1):
        self.devices = setup_host_devices()
        self.cpus = cpus
        self.data: dict[DataSettings, tuple] = {}
        self.pools: dict[DataSettings, Any] = {}   # data -> metric process pool (cpus >= 2)
        self.run_key = None
        self.runner = None
        self.pool = None
        self.lock = threading.Lock()
        self.begun = threading.Condition(self.lock)

    def info(self) -> dict:
        import ray

        return {"node": ray.get_runtime_context().get_node_id(), "pid": os.getpid(), "devices": self.devices,
                "jax_devices": jax.local_device_count()}

    def load(self, data: DataSettings, split, gt) -> None:
        with self.lock:
            self.data[data] = (split, gt)
            if self.cpus >= 2 and data not in self.pools:
                self.pools[data] = worker_pool(gt, min(2, self.cpus))

    def begin(self, run_key: str, spec, table: pd.DataFrame, data: DataSettings, todo: Sequence[Chunk],
              compact: bool) -> None:
        with self.lock:
            split, gt = self.data[data]
            runner = ChunkRunner.load(spec, table, data, todo, compact=compact, split=split, gt=gt)
            self.runner, self.run_key, self.pool = runner, run_key, self.pools.get(data)
            self.begun.notify_all()

    def compute(self, run_key: str, chunk: Chunk) -> pd.DataFrame:
        with self.lock:
            if not self.begun.wait_for(lambda: self.run_key == run_key, timeout=START_TIMEOUT):
                raise RuntimeError("a chunk reached this worker before its run began")
            runner, pool = self.runner, self.pool
            p, res = runner.track_chunk(chunk)
            # this actor's chunks complete in any order (two calls at once, the driver takes each
            # table as it comes): so each scores all of its new outputs itself, relying on no other
            # chunk in flight (the local backend's in-order rule, sweep.scoring.InOrderScoring, does
            # not hold here); an output two chunks score at once is stored once
            runner.scoring.start(p, res, pool)
            del res                              # (its per-row arrays: not held while the pool scores)
        if p.future is not None:
            p.future.result()                    # scored in the pool while the other call tracks
        with self.lock:
            return runner.chunk_table(p, *runner.scoring.finish(p))


@dataclass
class _Worker:
    handle: Any
    node: str
    cpus: int = 1
    loaded: set = field(default_factory=set)     # the DataSettings it holds
    run: str | None = None                       # run key it has begun
    busy: int = 0


@dataclass
class _Pool:
    """The workers of one (cluster, worker_cpus), kept for the life of the driver process."""
    worker_cpus: int | None
    workers: list = field(default_factory=list)
    refs: dict = field(default_factory=dict)     # DataSettings -> (split ref, gt ref)
    lost: set = field(default_factory=set)       # nodes a worker was lost on: none placed there again

    def fill(self, log) -> None:
        """Place workers on every alive node's free CPUs (one per ``worker_cpus``, or one per node)
        and wait for them to start."""
        self.wait_started(self.spawn(), log)

    def spawn(self) -> list:
        """Ask Ray for the missing workers (they start in the background)."""
        import ray
        from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

        new = []
        for node in ray.nodes():
            cpus = int(node.get("Resources", {}).get("CPU", 0))
            if not node.get("Alive") or cpus < 1 or node["NodeID"] in self.lost:
                continue
            per = min(self.worker_cpus or cpus, cpus)
            have = sum(w.node == node["NodeID"] for w in self.workers)
            for _ in range(cpus // per - have):
                cls = ray.remote(concurrency_groups={"control": 1, "compute": QUEUE_PER_WORKER})(_ChunkWorker)
                actor = cls.options(
                    num_cpus=per, max_restarts=0, max_task_retries=0,
                    runtime_env={"env_vars": _worker_env(per)},
                    scheduling_strategy=NodeAffinitySchedulingStrategy(node["NodeID"], soft=False)).remote(per)
                new.append(_Worker(actor, node["NodeID"], cpus=per))
        return new

    def wait_started(self, new: list, log) -> None:
        import ray

        if not new and not self.workers:
            raise SweepConfigError("backend", "the Ray cluster has no alive node with a CPU to run workers on")
        # Wait for the new workers: one that cannot be placed (its node's CPUs held by another job)
        # would hold its chunks forever.
        infos = {_call(w, "info"): w for w in new}
        ready, late = ray.wait(list(infos), num_returns=len(infos), timeout=START_TIMEOUT)
        for ref in ready:
            try:
                info = ray.get(ref)
            except ray.exceptions.RayActorError:
                continue
            w = infos[ref]
            self.workers.append(w)
            log(f"ray: worker on node {w.node[:12]} (pid {info['pid']}, {w.cpus} CPU(s), "
                f"{info['jax_devices']} JAX device(s))")
        for ref in late:
            ray.kill(infos[ref].handle, no_restart=True)
        if not self.workers:
            raise SweepConfigError("backend", f"no Ray worker started within {START_TIMEOUT:g} s: are the cluster's "
                                              f"CPUs held by another job? (see `ray status`; "
                                              f"$DFRMOT_RAY_START_TIMEOUT sets the wait)")

    def lose(self, w: _Worker, log, why: str) -> None:
        import ray

        self.lost.add(w.node)
        if w in self.workers:
            self.workers.remove(w)
            log(f"ray: lost the worker on node {w.node[:12]} ({why}); its chunks run elsewhere")
            try:
                ray.kill(w.handle, no_restart=True)
            except Exception:       # already gone with its node
                pass


_POOLS: dict[tuple, _Pool] = {}


def release() -> None:
    """Stop this process's Ray workers (they also stop when the process exits)."""
    import ray

    for pool in _POOLS.values():
        for w in pool.workers:
            try:
                ray.kill(w.handle, no_restart=True)
            except Exception:
                pass
    _POOLS.clear()


def _worker_env(cpus: int) -> dict[str, str]:
    env = {"JAX_PLATFORMS": "cpu", "DFRMOT_HOST_DEVICES": str(cpus), "OMP_NUM_THREADS": str(cpus)}
    if os.environ.get("XLA_FLAGS"):
        env["XLA_FLAGS"] = os.environ["XLA_FLAGS"]
    for item in filter(None, os.environ.get("DFRMOT_RAY_ENV", "").split(",")):
        name, sep, value = item.partition("=")
        if not sep:
            raise SweepConfigError("DFRMOT_RAY_ENV", f"{item!r}: expected NAME=VALUE[,NAME=VALUE...]")
        env[name.strip()] = value
    return env


def connect(address: str | None, worker_cpus: int | None) -> _Pool:
    """Connect to the cluster at ``address`` (None: start a local instance, or keep the one this
    process is connected to) and return the worker pool of (that cluster, ``worker_cpus``)."""
    try:
        import ray
    except ImportError:
        raise SweepConfigError("backend", "the Ray backend needs Ray: pip install \"dfrmot_jax[ray]\"") from None
    if not ray.is_initialized():
        _check_reachable(address)
        try:
            # "local": a new instance on this machine (a bare ray.init() would join the last cluster
            # `ray start` made here, even one that is gone since; $RAY_ADDRESS still wins)
            ray.init(address=address or "local", logging_level=logging.WARNING, configure_logging=True,
                     include_dashboard=False if address is None else None)
        except (ConnectionError, RuntimeError, ValueError) as e:
            where = address or "a local instance"
            raise SweepConfigError("address", f"{where}: cannot connect to a Ray cluster: {e}") from None
    gcs = ray.get_runtime_context().gcs_address
    if address not in (None, "auto") and address.rpartition(":")[2] != gcs.rpartition(":")[2]:
        raise SweepConfigError("address", f"{address}: this process is connected to the Ray cluster at "
                                          f"{gcs} already (one cluster per process)")
    key = (gcs, worker_cpus)
    return _POOLS.setdefault(key, _Pool(worker_cpus))


def _check_reachable(address: str | None, timeout: float = 5.0) -> None:
    """A HOST:PORT (or ray://HOST:PORT) nobody listens on is an error now (Ray itself retries forever)."""
    if address is None or address == "auto":
        return
    hostport = address.split("://", 1)[-1]
    host, sep, port = hostport.rpartition(":")
    if not sep or not port.isdigit():
        raise SweepConfigError("address", f"{address!r}: expected HOST:PORT, ray://HOST:PORT or auto")
    try:
        socket.create_connection((host, int(port)), timeout=timeout).close()
    except OSError as e:
        raise SweepConfigError("address", f"{address}: no Ray cluster answers there ({e.strerror or e}); start one "
                                          f"with `ray start --head --port={port}`") from None


def run_chunks(address: str | None, worker_cpus: int | None, spec, table: pd.DataFrame, data: DataSettings,
               todo: Sequence[Chunk], keep: Keep, bar, log, *, compact: bool = True) -> None:
    """Compute ``todo``'s chunk tables on the cluster at ``address`` (workers of ``worker_cpus``
    CPUs); ``keep(chunk, table)`` each as it arrives; ``bar``: a progress bar or None."""
    import ray
    from ray.exceptions import ObjectLostError, RayActorError, RayTaskError

    pool = connect(address, worker_cpus)
    starting = pool.spawn() if not pool.workers else []      # workers start while the data load
    if data not in pool.refs:
        split, gt = load_data(data)
        pool.refs[data] = (ray.put(split), ray.put(gt))
    if starting:
        pool.wait_started(starting, log)
    run_key = uuid.uuid4().hex
    table_ref = ray.put(table)
    queue = deque(todo)
    inflight: dict = {}             # ObjectRef -> (worker, chunk)
    for w in pool.workers:          # (an interrupted earlier run's chunks are not waited for)
        w.busy = 0
    t0 = time.perf_counter()
    n_workers = 0
    while queue or inflight:        # (``fill`` raises when no worker is left, so there always is one here)
        for w in list(pool.workers):
            if queue and w.run != run_key:
                if data not in w.loaded:
                    _call(w, "load", data, *pool.refs[data])
                    w.loaded.add(data)
                _call(w, "begin", run_key, spec, table_ref, data, list(todo), compact)
                w.run = run_key
            while queue and w.busy < QUEUE_PER_WORKER:
                c = queue.popleft()
                inflight[_call(w, "compute", run_key, c)] = (w, c)
                w.busy += 1
        n_workers = max(n_workers, len(pool.workers))
        ready, _ = ray.wait(list(inflight), num_returns=1)
        ref = ready[0]
        w, c = inflight.pop(ref)
        w.busy -= 1
        try:
            df = ray.get(ref)
        except RayActorError as e:
            queue.appendleft(c)
            pool.lose(w, log, type(e).__name__)
            for r, (w2, c2) in list(inflight.items()):      # the dead worker's other chunks: back too
                if w2 is w:
                    del inflight[r]
                    queue.appendleft(c2)
            pool.fill(log)
            continue
        except ObjectLostError:         # the table was held by a node that died since: compute it again
            queue.appendleft(c)
            continue
        except RayTaskError as e:       # the chunk itself failed: raise what the local backend raises
            cause = getattr(e, "cause", None)
            if isinstance(cause, Exception):
                raise cause from None
            raise
        keep(c, df)
        if bar is not None:
            bar.update(len(c.configs))
    n = sum(len(c.configs) for c in todo)
    dt = time.perf_counter() - t0
    if n:
        log(f"ray: {n:,} configs tracked and scored by {n_workers} worker(s) in {dt:.1f} s ({n / dt:.1f} configs/s)")


def _call(w: _Worker, method: str, *args):
    """``w.method.remote(*args)`` in the method's concurrency group."""
    group = "compute" if method == "compute" else "control"
    return getattr(w.handle, method).options(concurrency_group=group).remote(*args)
