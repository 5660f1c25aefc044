"""One class's chunks of a sweep, tracked and scored: :class:`ChunkRunner`, the unit every backend
runs (the local backend in this process, the Ray backend inside its workers), and the data it runs on.

Per chunk: :func:`dfrmot_jax.track` on one [B] batch (track capacity: the tracker's own policy,
``api.default_capacity`` for the option group and ``track(grow=True)``; the capacity a chunk grew
to is kept for the group's later chunks), then the metrics
(:class:`dfrmot_jax.metrics.lane_scorer.LaneScorer`: each distinct output of each sequence scored
once, in-process or in a metric worker pool beside the tracker), then the chunk's table
(:func:`dfrmot_jax.sweep.store.chunk_frame`), handed to the caller's ``keep``.
"""

from __future__ import annotations

import os
import sys
import threading
import time
import warnings
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import jax
import numpy as np
import pandas as pd
from tqdm import tqdm

from .. import distort
from ..api import TrackResult, default_capacity, track
from ..config import Options
from ..data import cached_split, compact_split, prepare_frames
from ..lidar import LIDAR_PREFIX, lidar_dir, simulate_cached
from ..metrics.ab3dmot.prep import cached_ab3dmot_gt
from ..metrics.kitti2d.evaluate import cached_gt, worker_pool
from ..metrics.kitti2d.lane_scorer import LaneScorer
from ..version import __version__
from .ab3dmot_lanes import Ab3dmotLanes, add_columns
from .distortion import DistortionAxes
from .lidar_axes import key_settings
from .plan import Chunk, DataSettings, option_groups
from .spec import SweepSpec
from .store import chunk_frame
from .table import params_of

#: lanes per compiled tracker call (the batch is split over the host devices)
TRACK_CHUNK = 32

#: ``keep(chunk, table)``: what a backend does with a finished chunk's table (write it, or hold it)
Keep = Callable[[Chunk, pd.DataFrame], None]


def versions() -> tuple[str, str]:
    """(dfrmot_jax version, JAX version): columns of every result row."""
    return __version__, jax.__version__


def progress_bar(progress: bool, total: int, done: int, label: str):
    """A tqdm bar over configs on stderr, or None without ``progress``."""
    if not progress:
        return None
    return tqdm(total=total, initial=done, unit="cfg", desc=label, dynamic_ncols=True, smoothing=0.05, file=sys.stderr)


def load_data(d: DataSettings):
    """The packed split and the prepared ground truth of one class's data settings, checked to agree
    (both memoised on the settings and their files' sizes and mtimes). A LiDAR setting
    (``d.lidar``): the 2D detections lifted with its lifting settings, from the scans of ``lidar:DIR``
    or, simulated, from ``DIR/simulated/<name>/`` (simulated there once, :func:`lidar.simulate_cached`)."""
    det3d, lift = d.det3d, None
    if d.lidar is not None:
        lift, sim, seed = key_settings(d.lidar)
        if sim is not None:
            scans = simulate_cached(lidar_dir(d.det3d), d.root, d.sequences, d.lengths, sim, seed)
            det3d = f"{LIDAR_PREFIX}{scans}"
    split = cached_split(d.root, d.det2d, det3d, d.cls, d.sequences, lift=lift)
    gt = cached_gt(d.root, d.cls, list(d.sequences))
    if tuple(gt.sequences) != tuple(split.names) or not np.array_equal(gt.lengths, split.lengths):
        raise RuntimeError("ground truth and detections disagree on the sequences or their lengths")
    return split, gt


@dataclass
class Pending:
    """A tracked chunk waiting for its metrics. ``res``: its :class:`~dfrmot_jax.api.TrackResult`
    without the per-row arrays (the counts the table needs: dropped, overflow, peak, capacity);
    ``digests``: its lanes' per-sequence digests (``LaneScorer.seq_digests``); ``todo``: per
    sequence, the lanes whose output it scores itself (``LaneScorer.new_items``), the others are
    scored already or by an earlier chunk in flight."""

    chunk: Chunk
    res: TrackResult
    digests: list
    todo: list
    future: Any = None
    result: Any = None
    ab3dmot: list | Future | None = None    # AB3DMOT's columns of each lane (metrics.ab3dmot), or their future
    prep: Future | None = None      # the scoring's start (digests, todo, future), when made in a thread

    def ready(self) -> bool:
        """Its scores are in (nothing left to wait for)."""
        if self.prep is not None and not self.prep.done():
            return False
        scored = self.future is None or self.future.done()
        return scored and not (isinstance(self.ab3dmot, Future) and not self.ab3dmot.done())


def distort_of(table: pd.DataFrame, rows: Sequence[int], dist: DistortionAxes):
    """``DistortParams [B]`` of the table rows (their distortion.kind / level / seed)."""
    sub = table.iloc[list(rows)]
    return distort.stack_distort([dist.lane(k, v, s) for k, v, s in zip(
        sub["distortion.kind"], sub["distortion.level"], sub["distortion.seed"])])


@dataclass
class Timing:
    setup: float = 0.0
    track: float = 0.0
    metrics: float = 0.0
    wait: float = 0.0
    write: float = 0.0


@dataclass
class ChunkRunner:
    """The run loop of one class's chunks: tracking, metrics (in-process or a worker pool beside the
    tracker; chunks complete in submission order, a chunk may rely on an earlier one's scores) and
    the chunk tables. Its state is explicit: per option group the track capacity (``caps``) and the
    distortion spec (``dspecs``), the chunks in flight, the timings. AB3DMOT's figures
    (``metrics.ab3dmot``) are computed in a thread of this process while the next chunk tracks (the
    tracker's compiled code runs without Python's lock, so the two overlap; one thread, so chunks
    are scored in order and share one memo).

    ``workers``: metric processes (None: 2 for large runs, 0: in-process). ``compact``: track on the
    split compacted to the table's loosest score thresholds (:func:`dfrmot_jax.data.compact_split`:
    the same results, fewer dead detection slots; never with a distortion, whose draws are keyed by
    slot)."""

    spec: SweepSpec
    table: pd.DataFrame
    data: DataSettings
    workers: int | None = None
    compact: bool = True
    caps: dict = field(default_factory=dict)
    dspecs: dict = field(default_factory=dict)
    inflight: deque = field(default_factory=deque)
    timing: Timing = field(default_factory=Timing)
    ab3dmot_thread: ThreadPoolExecutor | None = None
    prep_thread: ThreadPoolExecutor | None = None
    busy: dict = field(default_factory=dict)        # chunk in flight -> the (sequence, digest) pairs it scores
    lock: threading.Lock = field(default_factory=threading.Lock)

    def setup(self, todo: Sequence[Chunk], split=None, gt=None) -> None:
        """Load (or take) the class's split and prepared ground truth; ``todo``: the chunks to run."""
        if split is None:
            split, gt = load_data(self.data)
        if self.compact and self.spec.distortion is None:     # (distortion draws are keyed by slot)
            every = params_of(self.table, range(len(self.table)), self.data.cls)
            split = compact_split(split, float(np.min(every.score_2d)), float(np.min(every.score_3d)))
        self.split, self.gt = split, gt
        self.frames: tuple | None = None        # (options, prepared frames) of the last option group
        self.todo = list(todo)
        self.versions = versions()
        self.scorer = LaneScorer(self.gt, self.split.offsets, as_written=True)   # rows as the files carry them
        # AB3DMOT needs the rows' 3D detail ([B, T, K, 6] boxes with output "filtered"): the whole
        # chunk in one call, whose output arrays are kept as they come, instead of copying two halves
        per_call = TRACK_CHUNK if self.spec.ab3dmot is None else 2 * TRACK_CHUNK
        self.lanes_per_call = max(1, min(self.spec.chunk, per_call))
        pending_cf = sum(len(c.configs) for c in todo) * self.split.n_frames
        if self.workers is None:
            self.workers = min(2, os.cpu_count() or 1) if pending_cf >= 2_000_000 else 0
        self.groups = option_groups(self.table) if self.spec.distortion is not None else {}
        self.ab3dmot = None
        if self.spec.ab3dmot is not None:
            gt3 = cached_ab3dmot_gt(self.data.root, self.data.cls, list(self.split.names))
            self.ab3dmot = Ab3dmotLanes(gt3, self.split, self.spec.ab3dmot, self.spec.ab3dmot_columns)

    def run(self, todo: Sequence[Chunk], keep: Keep, bar, log) -> None:
        """Track and score ``todo``, handing each chunk's table to ``keep`` in order; ``bar``: a
        progress bar (or None) advanced by each chunk's configs."""
        t0 = time.perf_counter()
        label = self.spec.name if len(self.spec.classes) == 1 else f"{self.spec.name} [{self.data.cls}]"
        self.setup(todo)
        self.timing.setup = time.perf_counter() - t0
        pool = worker_pool(self.gt, self.workers) if self.workers > 0 else None
        self.ab3dmot_thread = ThreadPoolExecutor(1, "ab3dmot") if self.ab3dmot is not None else None
        self.prep_thread = ThreadPoolExecutor(1, "scoring")
        try:
            for c in todo:
                self.inflight.append(self.start(c, self.frames_of(c.options), pool))
                # complete in submission order (a chunk may rely on an earlier one's scores)
                while self.inflight and self.inflight[0].ready():
                    self.complete(self.inflight.popleft(), keep, bar)
                while len(self.inflight) > max(1, self.workers):
                    self.complete(self.inflight.popleft(), keep, bar)
            while self.inflight:
                self.complete(self.inflight.popleft(), keep, bar)
        finally:
            if pool is not None:
                pool.shutdown(wait=True, cancel_futures=True)
            for t in (self.prep_thread, self.ab3dmot_thread):
                if t is not None:
                    t.shutdown(wait=True, cancel_futures=True)
            self.prep_thread = self.ab3dmot_thread = None
        dt = time.perf_counter() - t0
        n = sum(len(c.configs) for c in todo)
        tm = self.timing
        log(f"sweep {label}: {n:,} configs tracked and scored in {dt:.1f} s ({n / dt:.1f} configs/s, "
            f"{n * self.split.n_frames / dt / 1e3:.0f} k config-frames/s; setup {tm.setup:.1f} s, tracking "
            f"{tm.track:.1f} s, metrics {tm.metrics:.1f} s in-process + {tm.wait:.1f} s waiting "
            f"for workers, tables {tm.write:.1f} s; {len(self.scorer):,} distinct sequence outputs scored)")

    def frames_of(self, options: Options):
        """The split prepared for ``options`` (kept while consecutive chunks share them)."""
        if self.frames is None or self.frames[0] != options:
            self.frames = (options, prepare_frames(self.split, options))
        return self.frames[1]

    def compute(self, c: Chunk) -> pd.DataFrame:
        """Chunk ``c``'s table, tracked and scored here."""
        return self.chunk_table(self.start(c, self.frames_of(c.options), None))

    def start(self, c: Chunk, frames, pool) -> Pending:
        """Track chunk ``c`` and start scoring its new outputs (in the pool, or here)."""
        table, dist, cls = self.table, self.spec.distortion, self.data.cls
        params = params_of(table, c.configs, cls)
        opts = c.options
        dps = None
        if dist is not None:
            # one DistortSpec per option group, covering every lane of the group (all of the
            # table, not only the chunks left to run): one compilation, whatever is resumed
            dps = distort_of(table, c.configs, dist)
            if c.options not in self.dspecs:
                self.dspecs[c.options] = dist.make_spec(c.options, frames=frames,
                                                        dps=distort_of(table, self.groups[c.options], dist))
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
                res = track(frames, params, opts, chunk=self.lanes_per_call, grow=True,
                            detail=self.ab3dmot is not None)
            else:       # distortion lanes vmapped with the parameter lanes; per-lane output boxes
                res = track(self.split, params, opts, chunk=self.lanes_per_call, grow=True, distortion=dps,
                            spec=self.dspecs[c.options])
        if c.options.capacity == 0:         # start the group's later chunks where track grew to
            self.caps[c.options] = max(self.caps[c.options], int(res.capacity.max(initial=0)))
        self.timing.track += time.perf_counter() - tt
        slim = res._replace(ids=None, boxes=None, frames=None, src3=None, own3=None, box3=None)
        p = Pending(c, slim, [], [])
        if self.prep_thread is not None:        # while the next chunk tracks (chunks in order: one thread)
            p.prep = self.prep_thread.submit(self.start_scoring, p, res, pool)
        else:
            self.start_scoring(p, res, pool)
        return p

    def start_scoring(self, p: Pending, res: TrackResult, pool) -> None:
        """Start scoring a tracked chunk's new sequence outputs (in the pool, or here) and its AB3DMOT
        figures (in their thread, or here)."""
        digests = self.scorer.seq_digests(res.ids, res.boxes)
        # sequence outputs identical to one still being scored (an earlier chunk in flight) wait for
        # it: only in :meth:`run`, whose chunks complete in submission order (a Ray actor's complete
        # in any order, so each scores all its new outputs itself)
        in_order = self.prep_thread is not None
        with self.lock:
            busy = set().union(*self.busy.values()) if in_order else set()
        p.digests, p.todo = digests, self.scorer.new_items(digests, busy)
        if in_order:
            with self.lock:
                self.busy[id(p)] = self.scorer.item_keys(digests, p.todo)
        if self.ab3dmot is not None:
            lanes = self.scorer.lane_digests(digests)      # (the split's frames are its sequences')
            if self.ab3dmot_thread is not None:
                p.ab3dmot = self.ab3dmot_thread.submit(self.ab3dmot.score, res, lanes)
            else:
                tm = time.perf_counter()
                p.ab3dmot = self.ab3dmot.score(res, lanes)
                self.timing.metrics += time.perf_counter() - tm
        if any(p.todo):
            dets = self.scorer.dets(res.ids, res.boxes, p.todo)
            if pool is not None:
                p.future = self.scorer.submit(pool, dets)
            else:
                tm = time.perf_counter()
                p.result = self.scorer.evaluate(dets)
                self.timing.metrics += time.perf_counter() - tm

    def _group_params(self, options: Options):
        """The parameters of every chunk left to run with these options."""
        return params_of(self.table, [i for c in self.todo if c.options == options for i in c.configs],
                          self.data.cls)

    def chunk_table(self, p: Pending) -> pd.DataFrame:
        """A tracked chunk's table, once its scores are in."""
        tw = time.perf_counter()
        if p.prep is not None:
            p.prep.result()
        if p.future is not None:
            p.result = p.future.result()
        if isinstance(p.ab3dmot, Future):
            p.ab3dmot = p.ab3dmot.result()
        self.timing.wait += time.perf_counter() - tw
        if any(p.todo):
            self.scorer.store(p.digests, p.todo, p.result)
        with self.lock:
            self.busy.pop(id(p), None)
        df = chunk_frame(self.table, p.chunk, self.data, self.split.names, self.split.lengths,
                         self.scorer.gather(p.digests), p.res, self.versions, self.spec.name)
        return df if p.ab3dmot is None else add_columns(df, p.ab3dmot)

    def complete(self, p: Pending, keep: Keep, bar) -> None:
        """Store a chunk's scores and hand its table to ``keep``."""
        df = self.chunk_table(p)
        tw = time.perf_counter()
        keep(p.chunk, df)
        self.timing.write += time.perf_counter() - tw
        if bar is not None:
            bar.update(len(p.chunk.configs))

