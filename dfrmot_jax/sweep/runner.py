"""Running a sweep: ``run_sweep`` (expand, plan, skip finished chunks, run the rest, gather the table)
and the run loop of one class's chunks (:class:`_ChunkRunner`).

Per chunk: :func:`dfrmot_jax.track` on one [B] batch (track capacity: the tracker's own policy,
``api.default_capacity`` for the option group and ``track(grow=True)``; the capacity a chunk grew
to is kept for the group's later chunks), then the metrics (:class:`dfrmot_jax.metrics.evaluate.LaneScorer`:
identical outputs scored once, in-process or in a metric worker pool beside the tracker), then the
chunk's table (:func:`dfrmot_jax.sweep.store._chunk_frame`) written atomically or kept in memory.
"""

from __future__ import annotations

import os
import sys
import time
import warnings
from collections import deque
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import pandas as pd

from ..config import Options
from .backend import LocalBackend, RayBackend, make_backend
from .distortion import DistortionAxes
from .plan import Chunk, DataSettings, _groups, check_memory, plan, resolve_data_all
from .spec import SweepConfigError, SweepSpec, _as_spec
from .store import (
    _chunk_frame,
    _chunk_path,
    _finish,
    finished_chunks,
    write_chunk,
    write_manifest,
    write_results,
)
from .table import RAW_COLUMN, _params_of, expand, n_settings

#: lanes per compiled tracker call (the batch is split over the host devices)
TRACK_CHUNK = 32
#: track each class on its split compacted to the table's loosest score thresholds
#: (:func:`dfrmot_jax.data.compact_split`: the same results, fewer dead detection slots)
COMPACT = True


def run_sweep(spec, out=None, *, data_root=None, chunk: int | None = None, folds: int | None = None,
              progress: bool = True, workers: int | None = None, log=None, raw: bool = True,
              table: pd.DataFrame | None = None, max_configs: int | None = None, max_memory: float | None = None,
              force: bool = False, backend="local", address: str | None = None,
              worker_cpus: int | None = None) -> pd.DataFrame:
    """Run a sweep (TOML path, dict or :class:`SweepSpec`) and return its tidy table.

    One row per (config, sequence) and one ``COMBINED`` row per config, with every parameter and
    option, the metrics (TrackEval summary names, as ``dfrmot eval``), overflow counts, versions and
    ``config_hash``. ``out``: a directory; each finished chunk is written there as Parquet and a
    rerun skips finished chunks (resume); ``results.parquet`` holds the final table. Without
    ``out`` nothing is written. ``data_root`` / ``chunk`` override the file; ``folds`` is stored for
    the report (``sweep_report``); ``workers``: metric processes running beside the tracker
    (default: 2 for large sweeps, 0 = in-process); ``raw=False`` drops the per-alpha column
    ``_hota_alpha`` (needed for cross-validation).
    ``table``: run these configs (a config table as :func:`expand` makes, e.g. a tuner's batch)
    instead of the file's expansion; the spec then gives the data, baseline and chunking.
    Bad files fail before any work with a :class:`SweepConfigError` naming the key, and so do
    sweeps of more than ``max_configs`` configs (default ``MAX_CONFIGS``) or whose chunks would hold
    more than ``max_memory`` GB of tracker output (default ``plan.MAX_MEMORY_GB``).

    ``out`` belongs to one sweep: another sweep's directory is refused (``SweepDirectoryError``)
    unless ``force``, which deletes that sweep's files first. A chunk file whose bytes do not match
    its ledger record (truncated, changed, never recorded) is reported through ``log`` and recomputed.

    ``backend``: ``"local"`` (this process) or ``"ray"`` (a Ray cluster at ``address``, default a
    local instance; one worker per ``worker_cpus`` CPUs of a node, default one per node), or a
    :mod:`~dfrmot_jax.sweep.backend` object. Tables and store are the same either way.

    Several classes (``data.class = ["car", "pedestrian"]``): every config is run for every class,
    each on its own split; rows carry their ``class``, and each config gets one more row, ``class =
    "average"``, ``sequence = COMBINED``: the class average (TrackEval's / KITTI's: ratios averaged
    over the classes, counts summed; :func:`dfrmot_jax.metrics.evaluate.class_average`).
    """
    spec = _as_spec(spec)
    backend = make_backend(backend, workers=workers, address=address, worker_cpus=worker_cpus)
    if isinstance(backend, LocalBackend) and workers is None:
        workers = backend.workers
    if chunk is not None:
        if chunk < 1:
            raise SweepConfigError("chunk", f"{chunk}: expected an integer >= 1", spec.source)
        spec = replace(spec, chunk=int(chunk))
    if folds is not None:
        spec = replace(spec, folds=int(folds))
    log = log if log is not None else (lambda msg: print(msg, file=sys.stderr, flush=True))
    table = expand(spec, max_configs=max_configs) if table is None else table
    datas = resolve_data_all(spec, data_root)
    n_seq = min(len(d.sequences) for d in datas)
    if spec.folds is not None and not 2 <= spec.folds <= n_seq:
        raise SweepConfigError("folds", f"{spec.folds}: expected 2 .. {n_seq} (the sequences"
                               + (" of the class with the fewest)" if len(datas) > 1 else ")"), spec.source)
    chunks = plan(table, datas, spec.chunk, spec.distortion)
    check_memory(chunks, datas, spec.distortion, max_memory, spec.source)
    if isinstance(backend, RayBackend):         # an unreachable cluster is refused before anything is written
        from .ray_backend import connect

        connect(backend)
    outdir = Path(out) if out is not None else None
    done: set[str] = set()
    if outdir is not None:
        legacy = write_manifest(outdir, spec, datas, table, chunks, force=force)
        done, damaged = finished_chunks(outdir, table, chunks, datas, legacy)
        if damaged:
            log(f"sweep {spec.name}: {len(damaged)} chunk file(s) damaged or not recorded, recomputed: "
                + "; ".join(damaged))
    frames_out: dict[str, pd.DataFrame] = {}
    for d in datas:
        cchunks = [c for c in chunks if c.cls == d.cls]
        todo = [c for c in cchunks if c.id not in done]
        n_done = sum(len(c.configs) for c in cchunks if c.id in done)
        total_cf = len(table) * sum(d.lengths)
        n_groups = len({c.group for c in cchunks})
        lanes = ""
        if spec.distortion is not None:
            n_set = n_settings(table)
            lanes = (f" = {n_set:,} settings x {spec.distortion.n_lanes} distortion lanes (kinds "
                     f"{', '.join(k for k, _ in spec.distortion.kinds)}; {len(spec.distortion.seeds)} seeds)")
        name = spec.name if len(datas) == 1 else f"{spec.name} [{d.cls}]"
        log(f"sweep {name}: {len(table):,} configs{lanes} ({n_groups} option group(s), {len(cchunks)} chunks of <= "
            f"{spec.chunk}; {sum(c.id in done for c in cchunks)} done) x {len(d.sequences)} sequences / "
            f"{sum(d.lengths):,} frames = {total_cf / 1e6:.1f} M config-frames" + (f" -> {outdir}" if outdir else ""))
        if todo and isinstance(backend, RayBackend):
            from .ray_backend import run_chunks

            def keep(c: Chunk, df: pd.DataFrame) -> None:
                if outdir is not None:
                    write_chunk(outdir, c, df)
                else:
                    frames_out[c.id] = df

            bar = _progress_bar(progress, len(table), n_done, name)
            try:
                run_chunks(backend, spec, table, d, todo, keep, bar, log)
            finally:
                if bar is not None:
                    bar.close()
        elif todo:
            runner = _ChunkRunner(spec, table, d, outdir, workers)
            runner.run(todo, n_done, len(table), progress, log)
            frames_out.update(runner.tables)
    if outdir is None:
        df = pd.concat([frames_out[c.id] for c in chunks], ignore_index=True)
    else:
        df = pd.concat([pd.read_parquet(_chunk_path(outdir, c)) for c in chunks], ignore_index=True)
        df["sweep"] = spec.name             # (a renamed sweep keeps its directory and chunks)
    df = _finish(df, spec.classes)
    if outdir is not None:
        write_results(outdir, df)
    if not raw:
        df = df.drop(columns=[RAW_COLUMN])
    return df


def sweep(*args, **kwargs) -> pd.DataFrame:
    """Deprecated alias of :func:`run_sweep` (kept for one release)."""
    warnings.warn("dfrmot_jax.sweep.sweep(...) / dfrmot_jax.sweep(...) is deprecated: use "
                  "dfrmot_jax.run_sweep(...) (dfrmot_jax.sweep is the sweep package)", DeprecationWarning,
                  stacklevel=2)
    return run_sweep(*args, **kwargs)


def _versions() -> tuple[str, str]:
    import jax

    from .. import __version__

    return __version__, jax.__version__


def _progress_bar(progress: bool, total: int, done: int, label: str):
    if not progress:
        return None
    from tqdm import tqdm

    return tqdm(total=total, initial=done, unit="cfg", desc=label, dynamic_ncols=True, smoothing=0.05, file=sys.stderr)


def load_data(d: DataSettings):
    """The packed split and the prepared ground truth of one class's data settings, checked to agree
    (both memoised on the settings and their files' sizes and mtimes)."""
    from ..data import cached_split
    from ..metrics import cached_gt

    split = cached_split(d.root, d.det2d, d.det3d, d.cls, d.sequences)
    gt = cached_gt(d.root, d.cls, list(d.sequences))
    if tuple(gt.sequences) != tuple(split.names) or not np.array_equal(gt.lengths, split.lengths):
        raise RuntimeError("ground truth and detections disagree on the sequences or their lengths")
    return split, gt


@dataclass
class _Slim:
    dropped: np.ndarray
    overflow: np.ndarray
    peak: np.ndarray
    capacity: np.ndarray


@dataclass
class _Pending:
    """A tracked chunk waiting for its metrics (``todo``: the lanes it scores itself, the others are
    scored already or by an earlier chunk in flight)."""

    chunk: Chunk
    res: _Slim
    digests: list
    todo: list
    future: Any = None
    result: Any = None


def _distort_of(table: pd.DataFrame, rows: Sequence[int], dist: DistortionAxes):
    """``DistortParams [B]`` of the table rows (their distortion.kind / level / seed)."""
    from .. import distort

    sub = table.iloc[list(rows)]
    return distort.stack_distort([dist.lane(k, v, s) for k, v, s in zip(
        sub["distortion.kind"], sub["distortion.level"], sub["distortion.seed"])])


@dataclass
class _Timing:
    setup: float = 0.0
    track: float = 0.0
    metrics: float = 0.0
    wait: float = 0.0
    write: float = 0.0


@dataclass
class _ChunkRunner:
    """The run loop of one class's chunks: tracking, metrics (in-process or a worker pool beside the
    tracker; chunks complete in submission order, a chunk may rely on an earlier one's scores) and
    the chunk tables. Its state is explicit: per option group the track capacity (``caps``) and the
    distortion spec (``dspecs``), the chunks in flight, the timings."""

    spec: SweepSpec
    table: pd.DataFrame
    data: DataSettings
    outdir: Path | None
    workers: int | None
    tables: dict = field(default_factory=dict)        # chunk id -> its table (without a directory)
    caps: dict = field(default_factory=dict)
    dspecs: dict = field(default_factory=dict)
    inflight: deque = field(default_factory=deque)
    timing: _Timing = field(default_factory=_Timing)

    def setup(self, todo: Sequence[Chunk], split=None, gt=None) -> None:
        """Load (or take) the class's split and prepared ground truth; ``todo``: the chunks to run."""
        from ..metrics.evaluate import LaneScorer

        if split is None:
            split, gt = load_data(self.data)
        if COMPACT and self.spec.distortion is None:     # (distortion draws are keyed by slot)
            from ..data import compact_split

            every = _params_of(self.table, range(len(self.table)), self.data.cls)
            split = compact_split(split, float(np.min(every.score_2d)), float(np.min(every.score_3d)))
        self.split, self.gt = split, gt
        self.frames: tuple | None = None        # (options, prepared frames) of the last option group
        self.todo = list(todo)
        self.versions = _versions()
        self.scorer = LaneScorer(self.gt, self.split.offsets)
        self.lanes_per_call = max(1, min(self.spec.chunk, TRACK_CHUNK))
        pending_cf = sum(len(c.configs) for c in todo) * self.split.n_frames
        if self.workers is None:
            self.workers = min(2, os.cpu_count() or 1) if pending_cf >= 2_000_000 else 0
        self.groups = _groups(self.table) if self.spec.distortion is not None else {}

    def run(self, todo: Sequence[Chunk], n_done: int, n_total: int, progress: bool, log) -> None:
        from ..metrics.evaluate import worker_pool

        t0 = time.perf_counter()
        label = self.spec.name if len(self.spec.classes) == 1 else f"{self.spec.name} [{self.data.cls}]"
        self.setup(todo)
        self.timing.setup = time.perf_counter() - t0
        pool = worker_pool(self.gt, self.workers) if self.workers > 0 else None
        bar = _progress_bar(progress, n_total, n_done, label)
        try:
            for c in todo:
                self.inflight.append(self.start(c, self.frames_of(c.options), pool))
                # complete in submission order (a chunk may rely on an earlier one's scores)
                while self.inflight and (self.inflight[0].future is None or self.inflight[0].future.done()):
                    self.complete(self.inflight.popleft(), bar)
                while len(self.inflight) > max(1, self.workers):
                    self.complete(self.inflight.popleft(), bar)
            while self.inflight:
                self.complete(self.inflight.popleft(), bar)
        finally:
            if bar is not None:
                bar.close()
            if pool is not None:
                pool.shutdown(wait=True, cancel_futures=True)
        dt = time.perf_counter() - t0
        n = sum(len(c.configs) for c in todo)
        tm = self.timing
        log(f"sweep {label}: {n:,} configs tracked and scored in {dt:.1f} s ({n / dt:.1f} configs/s, "
            f"{n * self.split.n_frames / dt / 1e3:.0f} k config-frames/s; setup {tm.setup:.1f} s, tracking "
            f"{tm.track:.1f} s, metrics {tm.metrics:.1f} s in-process + {tm.wait:.1f} s waiting "
            f"for workers, tables {tm.write:.1f} s; {len(self.scorer):,} distinct outputs scored)")

    def frames_of(self, options: Options):
        """The split prepared for ``options`` (kept while consecutive chunks share them)."""
        from ..data import prepare_frames

        if self.frames is None or self.frames[0] != options:
            self.frames = (options, prepare_frames(self.split, options))
        return self.frames[1]

    def compute(self, c: Chunk) -> pd.DataFrame:
        """Chunk ``c``'s table, tracked and scored here (a Ray worker's unit of work)."""
        return self.chunk_table(self.start(c, self.frames_of(c.options), None))

    def start(self, c: Chunk, frames, pool) -> _Pending:
        """Track chunk ``c`` and start scoring its new outputs (in the pool, or here)."""
        from ..api import default_capacity, track

        table, dist, cls = self.table, self.spec.distortion, self.data.cls
        params = _params_of(table, c.configs, cls)
        opts = c.options
        dps = None
        if dist is not None:
            # one DistortSpec per option group, covering every lane of the group (all of the
            # table, not only the chunks left to run): one compilation, whatever is resumed
            dps = _distort_of(table, c.configs, dist)
            if c.options not in self.dspecs:
                self.dspecs[c.options] = dist.make_spec(c.options, frames=frames,
                                                        dps=_distort_of(table, self.groups[c.options], dist))
        if opts.capacity == 0:
            # Track slots: the tracker's data-sized default for the whole option group (one
            # compilation; room for a distortion's clutter), or the capacity an earlier chunk of the
            # group grew to. Results never depend on it: ``track`` re-runs an overflowing lane with
            # twice the slots.
            if c.options not in self.caps:
                self.caps[c.options] = default_capacity(frames, self._group_params(c.options), opts,
                                                        clutter_slots=dist.clutter_slots if dist is not None else 0)
            opts = opts._replace(capacity=self.caps[c.options])
        tt = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)   # overflow is a column of the table
            if dps is None:
                res = track(frames, params, opts, chunk=self.lanes_per_call, grow=True)
            else:       # distortion lanes vmapped with the parameter lanes; per-lane output boxes
                res = track(self.split, params, opts, chunk=self.lanes_per_call, grow=True, distortion=dps,
                            spec=self.dspecs[c.options])
        if c.options.capacity == 0:         # start the group's later chunks where track grew to
            self.caps[c.options] = max(self.caps[c.options], int(res.capacity.max(initial=0)))
        self.timing.track += time.perf_counter() - tt
        digests = self.scorer.digests(res.ids, res.boxes)
        # lanes identical to one still being scored (an earlier chunk in flight) wait for it
        busy = {q.digests[i] for q in self.inflight for i in q.todo}
        p = _Pending(c, _Slim(res.dropped, res.overflow, res.peak, res.capacity), digests,
                     self.scorer.new_lanes(digests, busy))
        if p.todo:
            dets = self.scorer.dets(res.ids, res.boxes, p.todo)
            if pool is not None:
                p.future = self.scorer.submit(pool, dets)
            else:
                tm = time.perf_counter()
                p.result = self.scorer.evaluate(dets)
                self.timing.metrics += time.perf_counter() - tm
        return p

    def _group_params(self, options: Options):
        """The parameters of every chunk left to run with these options."""
        return _params_of(self.table, [i for c in self.todo if c.options == options for i in c.configs],
                          self.data.cls)

    def chunk_table(self, p: _Pending) -> pd.DataFrame:
        """A tracked chunk's table, once its scores are in."""
        tw = time.perf_counter()
        if p.future is not None:
            p.result = p.future.result()
        self.timing.wait += time.perf_counter() - tw
        if p.todo:
            self.scorer.store(p.digests, p.todo, p.result)
        return _chunk_frame(self.table, p.chunk, self.data, self.split.names, self.split.lengths,
                            self.scorer.gather(p.digests), p.res, self.versions, self.spec.name)

    def complete(self, p: _Pending, bar) -> None:
        """Store a chunk's scores and write its table."""
        df = self.chunk_table(p)
        tw = time.perf_counter()
        if self.outdir is not None:
            write_chunk(self.outdir, p.chunk, df)
        else:
            self.tables[p.chunk.id] = df
        self.timing.write += time.perf_counter() - tw
        if bar is not None:
            bar.update(len(p.chunk.configs))

