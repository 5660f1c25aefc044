"""Scoring a sweep's tracked chunks: :class:`ChunkScorer` (what scores one class's chunks: the
metrics' memo of scored sequence outputs, AB3DMOT's figures, the timings) and :class:`InOrderScoring`
(how the local backend overlaps that scoring with the tracking of the next chunks: its executors and
the in-order rule that makes the overlap safe).

A tracked chunk's scoring has three steps (:class:`Pending` carries its state between them):

1. ``plan``: the per-sequence digests of its lanes' outputs and, per sequence, the lanes whose
   output it scores itself (``todo``: the new ones; :meth:`LaneScorer.new_items
   <dfrmot_jax.metrics.kitti2d.lane_scorer.LaneScorer.new_items>`);
2. ``launch``: the metrics of those outputs started (in a metric process pool, or computed here) and
   its AB3DMOT figures (in their thread, or computed here);
3. ``finish``: once all of that is in, the new outputs' scores stored in the memo and every lane's
   scores gathered from it.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, Iterator

from ..trackers.protocol import TrackResult
from ..metrics.kitti2d.evaluate import worker_pool
from ..metrics.kitti2d.kitti import PreparedGT
from ..metrics.kitti2d.lane_scorer import LaneScorer
from .samota_lanes import Ab3dmotLanes
from .plan import Chunk


@dataclass
class Timing:
    """Seconds spent per step of one class's chunks (the run's log line)."""
    setup: float = 0.0
    track: float = 0.0
    metrics: float = 0.0
    wait: float = 0.0
    write: float = 0.0


@dataclass
class Pending:
    """A tracked chunk waiting for its metrics. ``res``: its :class:`~dfrmot_jax.trackers.protocol.TrackResult`
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
    prep: Future | None = None      # the scoring's start (plan and launch), when made in a thread

    def ready(self) -> bool:
        """Its scores are in (nothing left to wait for)."""
        if self.prep is not None and not self.prep.done():
            return False
        scored = self.future is None or self.future.done()
        return scored and not (isinstance(self.ab3dmot, Future) and not self.ab3dmot.done())


@dataclass
class ChunkScorer:
    """The scoring of one class's tracked chunks: ``scorer`` (the metrics, each distinct output of
    each sequence once; its memo is the class's), ``ab3dmot`` (AB3DMOT's figures with ``[metrics]
    ab3dmot``, else None; its own memo, written by :meth:`Ab3dmotLanes.score`) and ``timing``.

    :meth:`start` is the scoring of a chunk that relies on no other: what a chunk that may complete
    in any order does (a Ray actor's). :class:`InOrderScoring` runs the same steps in another order."""

    scorer: LaneScorer
    ab3dmot: Ab3dmotLanes | None
    timing: Timing

    def plan(self, p: Pending, res: TrackResult, busy=frozenset()) -> set:
        """Step 1: ``p.digests`` and ``p.todo``, its new outputs less ``busy`` (the ``(sequence,
        digest)`` pairs an earlier chunk in flight scores); returns the pairs ``p`` scores."""
        p.digests = self.scorer.seq_digests(res.ids, res.boxes)
        p.todo = self.scorer.new_items(p.digests, busy)
        return self.scorer.item_keys(p.digests, p.todo)

    def launch(self, p: Pending, res: TrackResult, pool=None, ab3dmot_thread: ThreadPoolExecutor | None = None) -> None:
        """Step 2: start scoring ``p.todo`` (in ``pool``, or here) and the AB3DMOT figures of
        ``p``'s lanes (in ``ab3dmot_thread``, or here)."""
        if self.ab3dmot is not None:
            lanes = self.scorer.lane_digests(p.digests)      # (the split's frames are its sequences')
            if ab3dmot_thread is not None:
                p.ab3dmot = ab3dmot_thread.submit(self.ab3dmot.score, res, lanes)
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

    def start(self, p: Pending, res: TrackResult, pool=None) -> None:
        """Steps 1 and 2 for a chunk that scores all of its new outputs itself (relying on no chunk
        in flight), the metrics in ``pool`` or here, AB3DMOT's figures here."""
        self.plan(p, res)
        self.launch(p, res, pool)

    def finish(self, p: Pending) -> tuple[dict, list | None]:
        """Step 3: wait for ``p``'s scores, store its new outputs' in the memo and return (every
        lane's scores, :meth:`LaneScorer.gather`; its AB3DMOT columns or None)."""
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
        return self.scorer.gather(p.digests), p.ab3dmot


class InOrderScoring:
    """The local backend's scoring of one class's chunks, overlapped with their tracking, and the
    rule that makes the overlap safe. Use it as a context manager: its executors shut down on exit.

    Executors: ``prep`` (one thread: each chunk's scoring start, :meth:`ChunkScorer.plan` and
    :meth:`ChunkScorer.launch`), ``ab3dmot`` (one thread: AB3DMOT's figures, with ``[metrics]
    ab3dmot``) and ``pool`` (``workers`` metric processes, or None: the metrics computed in the
    ``prep`` thread).

    What may overlap: a chunk's scoring (start, metrics, AB3DMOT figures) with the tracking of the
    next chunks (the tracker's compiled code runs without Python's lock); the metric processes with
    the tracker; at most ``max(1, workers)`` chunks in flight while the next one tracks (one with
    AB3DMOT's figures, whose one thread scores one chunk at a time).

    What happens in order: the ``prep`` and ``ab3dmot`` threads take the chunks one at a time in
    submission order (so AB3DMOT's memo is written in order, by its thread alone), and chunks
    complete (:meth:`completed`, :meth:`drain`) in submission order, so a chunk may rely on an
    earlier chunk in flight: an output that an earlier chunk scores (``busy``: the ``(sequence,
    digest)`` pairs each chunk in flight scores) is left out of its own ``todo`` and read from
    the memo when it completes, after the earlier one.

    Who writes the metrics' memo: only the completing step (:meth:`ChunkScorer.finish`), in order,
    in the driver thread (the one calling :meth:`submit` and :meth:`completed`); a chunk's pairs
    leave ``busy`` only after they are in the memo, so the ``prep`` thread finds each pair in one
    or the other.

    On Ray (:mod:`dfrmot_jax.sweep.ray_backend`) none of this holds: an actor runs two chunks at
    once and they complete in any order, so no chunk may rely on another in flight; each scores all
    of its new outputs itself (:meth:`ChunkScorer.start`), and an output two chunks scored at once is
    stored once."""

    def __init__(self, scoring: ChunkScorer, gt: PreparedGT, workers: int):
        self.scoring = scoring
        # chunks in flight before the oldest is waited for; with AB3DMOT's figures one: its thread
        # takes one chunk at a time, so a second chunk in flight would only wait there, held in memory
        self.limit = 1 if scoring.ab3dmot is not None else max(1, workers)
        self.pool = worker_pool(gt, workers) if workers > 0 else None
        self.prep = ThreadPoolExecutor(1, "scoring")
        self.ab3dmot = ThreadPoolExecutor(1, "ab3dmot") if scoring.ab3dmot is not None else None
        self.inflight: deque[Pending] = deque()     # submitted, not completed: in submission order
        self.busy: dict[int, set] = {}              # id(chunk in flight) -> the (sequence, digest) pairs it scores
        self.lock = threading.Lock()                # guards ``busy`` (the driver and the prep thread)

    def __enter__(self) -> "InOrderScoring":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Shut the executors down (waiting for what runs, cancelling what waits)."""
        for ex in (self.pool, self.prep, self.ab3dmot):
            if ex is not None:
                ex.shutdown(wait=True, cancel_futures=True)

    def submit(self, p: Pending, res: TrackResult) -> None:
        """Start scoring a tracked chunk in the ``prep`` thread, after every chunk submitted before."""
        p.prep = self.prep.submit(self._start, p, res)
        self.inflight.append(p)

    def _start(self, p: Pending, res: TrackResult) -> None:
        """(In the ``prep`` thread.) Plan ``p`` around the pairs in flight, mark its own, launch it."""
        with self.lock:
            busy = set().union(*self.busy.values())
        keys = self.scoring.plan(p, res, busy)
        with self.lock:
            self.busy[id(p)] = keys
        self.scoring.launch(p, res, self.pool, self.ab3dmot)

    def completed(self) -> Iterator[tuple[Pending, dict, list | None]]:
        """The chunks to complete now, oldest first, each as (chunk, scores, AB3DMOT columns) as
        :meth:`ChunkScorer.finish` gives them: the oldest ones whose scores are in, then as many more
        (waiting for them) as keep at most ``limit`` in flight."""
        while self.inflight and self.inflight[0].ready():
            yield self._complete()
        while len(self.inflight) > self.limit:
            yield self._complete()

    def drain(self) -> Iterator[tuple[Pending, dict, list | None]]:
        """Every chunk still in flight, oldest first, as :meth:`completed` gives them."""
        while self.inflight:
            yield self._complete()

    def _complete(self) -> tuple[Pending, dict, list | None]:
        p = self.inflight.popleft()
        scores, ab3dmot = self.scoring.finish(p)
        with self.lock:
            self.busy.pop(id(p), None)
        return p, scores, ab3dmot
