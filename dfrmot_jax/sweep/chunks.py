"""One class's chunks of a sweep, tracked and scored: :class:`ChunkRunner`, the unit every backend
runs (the local backend in this process, the Ray backend inside its workers), and the data it runs on.

The steps, each a method of its own:

- :meth:`ChunkRunner.load`: the data step, once per class and run: the packed split (compacted to
  the table's loosest score thresholds) and its prepared ground truth, loaded here (:func:`load_data`)
  or given (a Ray worker's), AB3DMOT's ground truth, the scorer (:class:`~.scoring.ChunkScorer`);
- :meth:`ChunkRunner.track_chunk`: the sweep's tracker family's ``track`` on one chunk's [B] batch
  (track capacity: the family's own policy, its ``default_capacity`` for the option group and
  ``track(grow=True)``; the capacity a chunk grew to is kept for the group's later chunks);
- scoring (:mod:`dfrmot_jax.sweep.scoring`): the metrics (each distinct output of each sequence
  scored once, in-process or in a metric worker pool beside the tracker) and AB3DMOT's figures;
- :meth:`ChunkRunner.chunk_table`: the chunk's table (:func:`dfrmot_jax.sweep.store.chunk_frame`),
  handed to the caller's ``keep``.

:meth:`ChunkRunner.run` is the local backend's loop: chunks tracked in order, each scored beside the
tracking of the next ones and completed in order (:class:`~.scoring.InOrderScoring`). A Ray worker
(:mod:`dfrmot_jax.sweep.ray_backend`) calls the steps itself, one chunk per call.
"""

from __future__ import annotations

import os
import sys
import threading
import time
import warnings
from dataclasses import dataclass, field
from typing import Callable, Sequence

import jax
import numpy as np
import pandas as pd
from tqdm import tqdm

from .. import distort
from ..trackers.protocol import TrackResult
from ..devices import chosen_platform, default_lanes_per_call
from ..data import Split, cached_split
from ..trackers.protocol import TrackerFamily
from ..trackers.registry import family_of
from ..lidar import LIDAR_PREFIX, lidar_dir, simulate_cached
from ..metrics.samota.prep import cached_ab3dmot_gt
from ..metrics.kitti2d.evaluate import cached_gt
from ..metrics.kitti2d.kitti import PreparedGT
from ..metrics.kitti2d.lane_scorer import LaneScorer
from ..version import __version__
from .samota_lanes import Ab3dmotLanes, add_columns
from .distortion import DistortionAxes
from .lidar_axes import key_settings
from .malloc import fixed_mmap_threshold
from .plan import Chunk, DataSettings, option_groups
from .scoring import ChunkScorer, InOrderScoring, Pending, Timing
from .spec import SweepSpec
from .store import chunk_frame
from .table import params_of

#: lanes per compiled tracker call on the CPU (``track(lanes_per_call=...)``; the batch is split over the host
#: devices); on a GPU ``devices.default_lanes_per_call()``; a quarter as many with AB3DMOT's figures, whose
#: 3D detail makes each call's output 2.5x larger (grid sweep with AB3DMOT: peak RSS 2.2-2.3 GB at 32 lanes per
#: call, 1.8 GB at 16 (2.0 GB with the three small-frame sizes of 2026-11-27), 1.84 GB at 8, in the same time
#: within noise)
LANES_PER_CALL = 32

#: config-frames of a class's chunks from which the metrics run in worker processes by default
POOL_MIN_CONFIG_FRAMES = 2_000_000

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


def warm_scoring_kernels(scorer: LaneScorer) -> threading.Thread:
    """Start compiling the scoring kernels (:meth:`LaneScorer.warm`, on a scorer of its own) in a
    daemon thread, beside the split's compaction and the first chunk's tracking (XLA's compilation and
    run release the GIL, as do LLVM's passes of numba's compilation): after an install the kernels'
    one-time compilation, most of a first run's time, then overlaps the tracker's instead of following
    it. Where they are cached already it scores one small lane. A failure here is the scoring's to
    meet again, and to report, on the real outputs."""
    def run() -> None:
        try:
            scorer.warm()
        except Exception:           # (the real scoring meets it again, and reports it)
            pass

    t = threading.Thread(target=run, name="dfrmot-warm-kernels", daemon=True)
    t.start()
    return t


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


def distort_of(table: pd.DataFrame, rows: Sequence[int], dist: DistortionAxes):
    """``DistortParams [B]`` of the table rows (their distortion.kind / level / seed)."""
    sub = table.iloc[list(rows)]
    return distort.stack_distort([dist.lane(k, v, s) for k, v, s in zip(
        sub["distortion.kind"], sub["distortion.level"], sub["distortion.seed"])])




def metric_workers(workers: int | None, config_frames: int) -> int:
    """Metric processes beside the tracker: ``workers``, or by default (None) 2 (at most the CPUs)
    for runs of at least ``POOL_MIN_CONFIG_FRAMES`` config-frames, else 0 (in-process)."""
    if workers is not None:
        return workers
    return min(2, os.cpu_count() or 1) if config_frames >= POOL_MIN_CONFIG_FRAMES else 0


@dataclass
class ChunkRunner:
    """One class's chunks: their data (made by :meth:`load`), their tracking, the chunk tables.

    ``split``: the class's packed split, compacted to the table's loosest score thresholds
    (:func:`dfrmot_jax.data.compact_split`: the same results, fewer dead detection slots; never with
    a distortion, whose draws are keyed by slot), ``gt`` its prepared ground truth; ``todo``: the
    chunks of this run; ``scoring``: their scorer (:class:`~.scoring.ChunkScorer`, sharing
    ``timing``); ``lanes_per_call``: lanes per compiled tracker call; ``groups``: with a distortion,
    the table's option groups (every lane of a group, for its one ``DistortSpec``); ``family``: the
    sweep's tracker family (``spec.family``), which tracks, sizes and compacts.

    State kept across chunks: per option group the track capacity (``caps``) and the distortion
    spec (``dspecs``); ``frames``: (options, the split prepared for them) of the last group tracked."""

    spec: SweepSpec
    table: pd.DataFrame
    data: DataSettings
    split: Split
    gt: PreparedGT
    todo: tuple[Chunk, ...]
    scoring: ChunkScorer
    lanes_per_call: int
    groups: dict
    timing: Timing
    family: TrackerFamily
    versions: tuple[str, str] = field(default_factory=versions)
    caps: dict = field(default_factory=dict)
    dspecs: dict = field(default_factory=dict)
    frames: tuple | None = None

    @classmethod
    def load(cls, spec: SweepSpec, table: pd.DataFrame, data: DataSettings, todo: Sequence[Chunk], *,
             compact: bool = True, split: Split | None = None, gt: PreparedGT | None = None) -> "ChunkRunner":
        """The data step: load (or take: ``split`` and ``gt``) the class's split and prepared
        ground truth, compact the split (``compact``, no distortion), load AB3DMOT's ground truth
        (``[metrics] ab3dmot``) and make the scorer; ``todo``: the chunks to run."""
        t0 = time.perf_counter()
        fixed_mmap_threshold()      # freed arrays given back to the system (sweep.malloc: ~300 MB less)
        family = family_of(spec.family)
        if split is None:
            split, gt = load_data(data)
        if compact and spec.distortion is None:     # (distortion draws are keyed by slot)
            split = family.compact_split(split, params_of(table, range(len(table)), data.cls, spec.family))
        ab3dmot = None
        if spec.ab3dmot is not None:
            gt3 = cached_ab3dmot_gt(data.root, data.cls, list(split.names))
            ab3dmot = Ab3dmotLanes(gt3, split, spec.ab3dmot, spec.ab3dmot_columns, spec.ab3dmot_sum, family)
        timing = Timing()
        scorer = LaneScorer(gt, split.offsets, as_written=family.box_format)     # rows as the files carry them
        warm_scoring_kernels(LaneScorer(gt, split.offsets, as_written=family.box_format))
        per_call = LANES_PER_CALL if chosen_platform() == "cpu" else default_lanes_per_call()
        if spec.ab3dmot is not None:        # the rows' 3D detail: each call's device output 2.5x larger
            per_call = max(1, per_call // 4)      # (8 lanes per call on the CPU)
        groups = option_groups(table, spec.family) if spec.distortion is not None else {}
        runner = cls(spec, table, data, split, gt, tuple(todo), ChunkScorer(scorer, ab3dmot, timing),
                     max(1, min(spec.chunk, per_call)), groups, timing, family)
        timing.setup = time.perf_counter() - t0
        return runner

    def run(self, keep: Keep, bar, log, workers: int | None = None) -> None:
        """Track and score every chunk of ``todo``, handing each chunk's table to ``keep`` in order
        (:class:`~.scoring.InOrderScoring`); ``bar``: a progress bar (or None) advanced by each
        chunk's configs; ``workers``: metric processes (None: :func:`metric_workers`' default)."""
        t0 = time.perf_counter()
        n_configs = sum(len(c.configs) for c in self.todo)
        workers = metric_workers(workers, n_configs * self.split.n_frames)
        with InOrderScoring(self.scoring, self.gt, workers) as scoring:
            for c in self.todo:
                scoring.submit(*self.track_chunk(c))
                for p, scores, ab3dmot in scoring.completed():
                    self.complete(p, scores, ab3dmot, keep, bar)
            for p, scores, ab3dmot in scoring.drain():
                self.complete(p, scores, ab3dmot, keep, bar)
        self.log_run(n_configs, self.timing.setup + time.perf_counter() - t0, log, workers)

    def log_run(self, n: int, dt: float, log, workers: int = 0) -> None:
        """The run's line: ``n`` configs in ``dt`` seconds, and where the time went. Without metric
        workers the metrics run in the scoring thread beside the tracking, and the wait is for that
        thread (the same seconds, in part: not a second cost); with them, the wait is for the workers."""
        label = self.spec.name if len(self.spec.classes) == 1 else f"{self.spec.name} [{self.data.cls}]"
        tm = self.timing
        if workers:
            metrics = f"metrics {tm.metrics:.1f} s in-process + {tm.wait:.1f} s waiting for {workers} worker(s)"
        else:
            metrics = f"metrics {tm.metrics:.1f} s in the scoring thread ({tm.wait:.1f} s waited for)"
        log(f"sweep {label}: {n:,} configs tracked and scored in {dt:.1f} s ({n / dt:.1f} configs/s, "
            f"{n * self.split.n_frames / dt / 1e3:.0f} k config-frames/s; setup {tm.setup:.1f} s, tracking "
            f"{tm.track:.1f} s, {metrics}, tables {tm.write:.1f} s; {len(self.scoring.scorer):,} distinct "
            f"sequence outputs scored)")

    def frames_of(self, options):
        """The split prepared for ``options`` (kept while consecutive chunks share them)."""
        if self.frames is None or self.frames[0] != options:
            self.frames = (options, self.family.prepare_frames(self.split, options))
        return self.frames[1]

    def track_chunk(self, c: Chunk) -> tuple[Pending, TrackResult]:
        """Track chunk ``c``: its :class:`~.scoring.Pending` (scoring not started) and the whole
        :class:`~dfrmot_jax.trackers.protocol.TrackResult` (what the scoring's start reads)."""
        frames = self.frames_of(c.options)
        params = params_of(self.table, c.configs, self.data.cls, self.spec.family)
        track = self.family.track
        dps = self.distortion_of(c, frames)
        opts = self.track_options(c, frames)
        tt = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)   # overflow is a column of the table
            if dps is None:
                res = track(frames, params, opts, lanes_per_call=self.lanes_per_call, grow=True,
                            detail=self.scoring.ab3dmot is not None, rows_only=True)
            else:       # each lane's own distorted detections; per-lane output boxes (and rows' 3D values)
                res = track(self.split, params, opts, lanes_per_call=self.lanes_per_call, grow=True,
                            detail=self.scoring.ab3dmot is not None, distortion=dps, spec=self.dspecs[c.options],
                            rows_only=True)
        if c.options.capacity == 0:         # start the group's later chunks where track grew to
            self.caps[c.options] = max(self.caps[c.options], int(res.capacity.max(initial=0)))
        self.timing.track += time.perf_counter() - tt
        slim = res._replace(ids=None, boxes=None, frames=None, src3=None, own3=None, box3=None, distortion=None)
        return Pending(c, slim, [], []), res

    def distortion_of(self, c: Chunk, frames):
        """Chunk ``c``'s ``DistortParams [B]`` (None without a distortion), its option group's
        ``DistortSpec`` made on the group's first chunk: one spec covering every lane of the group
        (all of the table, not only the chunks left to run), one compilation whatever is resumed."""
        dist = self.spec.distortion
        if dist is None:
            return None
        if c.options not in self.dspecs:
            self.dspecs[c.options] = dist.make_spec(c.options, frames=frames, family=self.family,
                                                    dps=distort_of(self.table, self.groups[c.options], dist))
        return distort_of(self.table, c.configs, dist)

    def track_options(self, c: Chunk, frames):
        """Chunk ``c``'s options with its track slots: its own, or (capacity 0) the tracker's
        data-sized default for the whole option group (one compilation; room for a distortion's
        clutter) or the capacity an earlier chunk of the group grew to. Results never depend on it:
        ``track`` re-runs an overflowing lane with twice the slots."""
        if c.options.capacity != 0:
            return c.options
        if c.options not in self.caps:
            dist = self.spec.distortion
            self.caps[c.options] = self.family.default_capacity(frames, self.group_params(c.options), c.options,
                                                                clutter_slots=dist.clutter_slots if dist is not None else 0)
        return c.options._replace(capacity=self.caps[c.options])

    def group_params(self, options):
        """The parameters of every chunk left to run with these options."""
        return params_of(self.table, [i for c in self.todo if c.options == options for i in c.configs],
                         self.data.cls, self.spec.family)

    def chunk_table(self, p: Pending, scores: dict, ab3dmot: list | None) -> pd.DataFrame:
        """A tracked chunk's table from its scores (:meth:`~.scoring.ChunkScorer.finish`)."""
        df = chunk_frame(self.table, p.chunk, self.data, self.split.names, self.split.lengths,
                         scores, p.res, self.versions, self.spec.name, self.spec.family)
        return df if ab3dmot is None else add_columns(df, ab3dmot)

    def complete(self, p: Pending, scores: dict, ab3dmot: list | None, keep: Keep, bar) -> None:
        """Hand a scored chunk's table to ``keep``."""
        df = self.chunk_table(p, scores, ab3dmot)
        tw = time.perf_counter()
        keep(p.chunk, df)
        self.timing.write += time.perf_counter() - tw
        if bar is not None:
            bar.update(len(p.chunk.configs))
