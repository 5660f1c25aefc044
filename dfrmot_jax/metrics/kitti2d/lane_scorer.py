"""Padded tracker output of many lanes scored against prepared ground truth, each distinct output
of each sequence once: :class:`LaneScorer` (what sweeps score with) and :func:`evaluate_arrays`."""

from __future__ import annotations

import hashlib
import os
import warnings
from concurrent.futures import ProcessPoolExecutor
from typing import Sequence

import numpy as np

from dfrmot_jax.io.columns import as_written, as_written_fixed
from dfrmot_jax.metrics.common.pairs import segment_starts
from dfrmot_jax.metrics.kitti2d.evaluate import (PoolParts, combine_sequences, evaluate_lanes, lane_slice, result_dicts,
                                                 run_in_worker, worker_pool)
from dfrmot_jax.metrics.kitti2d.kitti import PreparedGT, TrackerDets
from dfrmot_jax.metrics.kitti2d.padded import check_arrays, frames_aligned, tracker_dets_from_arrays
from dfrmot_jax.metrics.kitti2d.similarity import parse_similarity
from dfrmot_jax.rows import Rows, lane_values

__all__ = ["LaneScorer", "evaluate_arrays", "REPEATS_WORTH"]

#: :func:`evaluate_arrays` packs the new outputs into virtual lanes when at most this share of the
#: (config, sequence) outputs is new (gathering the rows costs ~0.1 of scoring them)
REPEATS_WORTH = 0.9


def _output_digest(ids: np.ndarray, own: Sequence[np.ndarray], shared: bytes = b"") -> bytes:
    """The digest of one output: ``ids`` [T, K] (contiguous), of each of its own box arrays the
    boxes of its rows (ids >= 0; ``own``: each array's rows, :func:`dfrmot_jax.rows.lane_values`), and ``shared``:
    the digest of the box arrays it shares with other lanes on the same frames (:func:`_shared_digest`)."""
    h = hashlib.sha1(ids.tobytes())
    for rows in own:
        h.update(np.ascontiguousarray(rows).tobytes())
    h.update(shared)
    return h.digest()


def _per_lane(bx) -> bool:
    """A lane's own box array ([B, T, K, ...] or rows only), not one shared by the lanes ([T, K, ...])."""
    return isinstance(bx, Rows) or bx.ndim == 4


def _shared_digest(shared: Sequence[np.ndarray]) -> bytes:
    """The digest of box arrays shared by the lanes ([T, K, ...] each, on one span of frames): their
    shapes, dtypes and every value (live or not: the rows that read them differ per lane)."""
    h = hashlib.sha1()
    for bx in shared:
        a = np.ascontiguousarray(bx)
        h.update(repr((a.shape, a.dtype.str)).encode())
        h.update(a.tobytes())
    return h.digest()


class LaneScorer:
    """Scores lanes of padded tracker output against prepared ground truth, each distinct output of
    each sequence once.

    Every metric field of a sequence depends on that sequence's rows only, and a lane's combined
    fields are :func:`combine_sequences` of its per-sequence ones: so a sequence's output is
    identified by a digest of all that its scores depend on (:meth:`seq_digests`: its ids on the
    sequence's frames, the boxes its rows carry, the lane's own or the ones the lanes share, and
    how they are scored), and only the (sequence, output) pairs not seen before are scored. The
    ground truth and the frame offsets are the scorer's own: one memo per scorer. They
    are packed into as few virtual lanes as the most varied sequence needs (:meth:`new_items`,
    :meth:`dets`: virtual lane v holds, for each sequence, its v-th new output, or nothing);
    :meth:`store` keeps their per-sequence fields and :meth:`gather` returns every lane's fields,
    combined. In a grid sweep of KITTI car, 1,024 configs give 832 distinct lanes but 2.4x fewer
    distinct sequence-frames to score. similarity: ``'2d'`` (default), ``'3d'`` or ``'bev'`` (then
    :meth:`seq_digests` and :meth:`dets` take ``box3d``, [B, T, K, 7] or [T, K, 7] shared by the
    lanes). as_written: score each box as a result file prints it, so that a sweep's row is what
    its files score: True or ``"g6"`` 6 significant digits (:func:`dfrmot_jax.io.columns.as_written`),
    ``"f6"`` ``%f`` (:func:`~dfrmot_jax.io.columns.as_written_fixed`, AB3DMOT's files); False as given.
    :meth:`digests` (one per whole lane) is what other memos of lanes build on."""
    def __init__(self, gt: PreparedGT, offsets, lanes_per_batch: int = 16, similarity: str = "2d",
                 as_written: bool | str = False):
        self.gt = gt
        self.as_written = as_written if isinstance(as_written, str) else "g6" if as_written else None
        if self.as_written not in (None, "g6", "f6"):
            raise ValueError(f"as_written={as_written!r}: expected False, True (\"g6\") or \"f6\"")
        self.offsets = np.asarray(offsets, np.int64)
        self.lanes_per_batch = lanes_per_batch
        self.similarity = parse_similarity(similarity)
        self.memo: dict[tuple[int, bytes], int] = {}     # (sequence, digest) -> row of the store
        self._rows: dict[str, list] = {}                 # per field, the stored rows' blocks
        self._table: dict[str, np.ndarray] | None = None

    def __len__(self) -> int:
        return len(self.memo)

    @staticmethod
    def digests(ids: np.ndarray, boxes: np.ndarray, box3d: np.ndarray | None = None) -> list[bytes]:
        """One digest per lane of ``ids`` [B, T, K] and its boxes: the lane's own ([B, T, K, 4] / 3D
        boxes [B, T, K, 7]) on its rows, and the boxes shared by the lanes ([T, K, ...]) whole."""
        arrays = [bx for bx in (boxes, box3d) if bx is not None]
        own = [bx for bx in arrays if _per_lane(bx)]
        shared = _shared_digest([bx for bx in arrays if not _per_lane(bx)])
        return [_output_digest(np.ascontiguousarray(ids[b]), [lane_values(bx, ids, b) for bx in own], shared)
                for b in range(ids.shape[0])]

    def seq_digests(self, ids: np.ndarray, boxes: np.ndarray | None, box3d: np.ndarray | None = None) -> list[tuple]:
        """Per lane of ``ids`` [B, T, K], one digest per sequence of all that its scores depend on
        there: its ids on the sequence's frames, the boxes its rows carry (its own, [B, T, K, ...],
        on its rows; boxes shared by the lanes, [T, K, ...], the sequence's whole slice) and how they
        are scored (``similarity``, ``as_written``). ``boxes=None`` digests the ids alone (a cheap
        pre-check: equal outputs have equal ids). Returns B tuples of S digests."""
        arrays = [bx for bx in (boxes, box3d if self.similarity != "2d" else None) if bx is not None]
        own = [bx for bx in arrays if _per_lane(bx)]
        spans = [(int(a), int(a + n)) for a, n in zip(self.offsets, self.gt.lengths)]
        how = repr((self.similarity, self.as_written, boxes is None)).encode()
        shared = [how + _shared_digest([bx[a:e] for bx in arrays if not _per_lane(bx)]) for a, e in spans]
        ids = np.asarray(ids)
        out = []
        for b in range(ids.shape[0]):
            lane = np.ascontiguousarray(ids[b])
            rows = [lane_values(bx, ids, b) for bx in own]          # the lane's rows once, cut per sequence
            at = segment_starts(np.count_nonzero(lane >= 0, axis=1)) if own else None
            out.append(tuple(_output_digest(lane[a:e], [r[at[a]:at[e]] for r in rows], sh)
                             for (a, e), sh in zip(spans, shared)))
        return out

    @staticmethod
    def lane_digests(seq_digests: Sequence[tuple]) -> list[bytes]:
        """One digest per lane from its :meth:`seq_digests`: what :meth:`digests` identifies (its ids
        and own boxes) on the sequences' frames, without hashing the arrays again."""
        return [hashlib.sha1(b"".join(per)).digest() for per in seq_digests]

    def new_items(self, seq_digests: Sequence[tuple], busy=frozenset()) -> list[list[int]]:
        """Per sequence, the first lane of each of its digests not scored yet and not in ``busy``
        (``(sequence, digest)`` pairs being scored elsewhere)."""
        out = []
        for s in range(len(self.gt.sequences)):
            seen: set[bytes] = set()
            lanes = []
            for i, per in enumerate(seq_digests):
                key = (s, per[s])
                if key not in self.memo and per[s] not in seen:
                    seen.add(per[s])
                    if key not in busy:
                        lanes.append(i)
            out.append(lanes)
        return out

    @staticmethod
    def item_keys(seq_digests: Sequence[tuple], items: Sequence[Sequence[int]]) -> set:
        """The ``(sequence, digest)`` pairs ``items`` (from :meth:`new_items`) score."""
        return {(s, seq_digests[lane][s]) for s, lanes in enumerate(items) for lane in lanes}

    def dets(self, ids, boxes, items, box3d=None) -> TrackerDets:
        """The virtual lanes of ``items`` (from :meth:`new_items`): lane v holds, on each sequence's
        frames, that sequence's v-th new output (or nothing). ids [B, T, K], boxes [B, T, K, 4] or
        [T, K, 4] shared by the lanes. (The lanes' rows are flattened once; a (lane, sequence) is a
        run of them, and the virtual lanes are these runs in (v, sequence) order; their ``configs``
        name each run's lane in error messages.)"""
        if self.similarity != "2d" and box3d is None:
            raise ValueError(f"similarity {self.similarity!r} needs box3d")
        ids = np.asarray(ids)

        def per_lane(a):
            if isinstance(a, Rows):
                return a
            a = np.asarray(a)
            return a if a.ndim == 4 else np.broadcast_to(a, (ids.shape[0],) + a.shape)

        # every lane flattened (no copy of a subset; a problem is named by its own lane, and the first
        # lane with it is always among the items: its duplicates are later, or scored already)
        b3 = per_lane(box3d) if box3d is not None and self.similarity != "2d" else None
        flat = tracker_dets_from_arrays(self.gt, ids, per_lane(boxes), self.offsets, b3)
        F, S = self.gt.n_frames, len(self.gt.sequences)
        bounds = np.searchsorted(flat.lane * F + flat.frame,
                                 (np.arange(ids.shape[0]) * F)[:, None] + self.gt.offsets[None, :])   # [B, S + 1]
        V = max((len(lanes) for lanes in items), default=0)
        start = np.zeros((V, S), np.int64)
        size = np.zeros((V, S), np.int64)
        configs = np.full((V, S), -1, np.int64)         # (error messages name the lane of each run)
        for s, lanes in enumerate(items):
            u = np.asarray(lanes, np.int64)
            configs[:len(u), s] = lanes
            start[:len(u), s] = bounds[u, s]
            size[:len(u), s] = bounds[u, s + 1] - bounds[u, s]
        size, start = size.reshape(-1), start.reshape(-1)
        idx = np.arange(int(size.sum()), dtype=np.int64) - np.repeat(segment_starts(size)[:-1] - start, size)
        box = flat.box[idx]
        if self.as_written == "g6":     # what the lanes' result files carry (their 2D box printed with %g)
            box = as_written(np.asarray(box, np.float64), 6)
        elif self.as_written == "f6":   # (printed with %f: AB3DMOT's files)
            box = as_written_fixed(np.asarray(box, np.float64), 6)
        return flat._replace(n_lanes=V, lane=np.repeat(np.arange(V, dtype=np.int64), size.reshape(V, S).sum(1)),
                             frame=flat.frame[idx], track_id=flat.track_id[idx], box=box,
                             source=flat.source[idx], box3d=None if flat.box3d is None else flat.box3d[idx],
                             has3d=None if flat.has3d is None else flat.has3d[idx], configs=configs)

    def evaluate(self, dets: TrackerDets) -> dict:
        return evaluate_lanes(self.gt, dets, self.lanes_per_batch, self.similarity)

    def warm(self, frames: int = 60) -> None:
        """Compile (or load from numba's cache) the scoring kernels this scorer's lanes call, by scoring
        one made-up lane as a tracker's would be: the ground truth's own rows on each sequence's first
        ``frames`` frames (ids int32 [1, T, K] and float32 boxes as a tracker writes them, every other
        frame's last row dropped and a shifted copy added, so that matches, misses and false positives
        all occur), through :meth:`seq_digests`, :meth:`new_items`, :meth:`dets` and :meth:`evaluate`.
        Nothing is kept (call it on a scorer of its own). Run in a thread beside data loading and the
        tracker's compilation, it moves the kernels' one-time compilation (~20 s of CPU after an
        install) off the critical path: numba compiles under one lock, so a scoring call that needs a
        kernel meanwhile waits for it and then uses it."""
        gt = self.gt
        if self.similarity != "2d" or not len(gt.sequences):
            return
        T = int(self.offsets.max() + gt.lengths[int(np.argmax(self.offsets))]) if len(self.offsets) else 0
        keep = np.zeros(gt.n_frames, bool)
        for s in range(len(gt.sequences)):
            keep[gt.offsets[s]:gt.offsets[s] + min(int(gt.lengths[s]), frames)] = True
        counts = np.where(keep, gt.eval_count, 0)
        K = int(counts.max(initial=0)) + 1
        if T == 0 or K == 1:
            return
        ids = np.full((1, T, K), -1, np.int32)
        boxes = np.zeros((1, T, K, 4), np.float32)
        eval_box = gt.row_box[gt.row_eval]
        for s in range(len(gt.sequences)):
            for f in range(gt.offsets[s], gt.offsets[s + 1]):
                n = int(counts[f])
                if not n:
                    continue
                t = int(self.offsets[s] + f - gt.offsets[s])
                rows = slice(int(gt.eval_start[f]), int(gt.eval_start[f]) + n)
                n_kept = n - (f % 2 and n > 1)
                ids[0, t, :n_kept] = gt.gid_label[gt.eval_gid[rows]][:n_kept]
                boxes[0, t, :n_kept] = eval_box[rows][:n_kept]
                ids[0, t, n_kept] = 100_000 + f % 7                 # a false positive beside them
                boxes[0, t, n_kept] = eval_box[rows][0] + np.float32(37.0)
        rows = Rows.of(ids, boxes)
        digests = self.seq_digests(ids, rows)
        self.evaluate(self.dets(ids, rows, self.new_items(digests)))

    def submit(self, pool: ProcessPoolExecutor, dets: TrackerDets) -> "PoolParts":
        """Score ``dets`` in the pool, ``lanes_per_batch`` lanes per task (a sweep chunk's lanes spread over
        every process): a future-like :class:`PoolParts` whose ``result()`` equals :meth:`evaluate`'s."""
        n = self.lanes_per_batch
        return PoolParts(pool.submit(run_in_worker, lane_slice(dets, a, min(a + n, dets.n_lanes)), self.similarity)
                      for a in range(0, dets.n_lanes, n))

    def store(self, seq_digests: Sequence[tuple], items: Sequence[Sequence[int]], result: dict) -> None:
        """Keep the per-sequence fields of ``result`` (:func:`evaluate_lanes` of :meth:`dets` of
        ``items``) under their ``(sequence, digest)`` pairs."""
        vs, ss = [], []
        for s, lanes in enumerate(items):
            for v, lane in enumerate(lanes):
                key = (s, seq_digests[lane][s])
                if key not in self.memo:
                    self.memo[key] = len(self.memo)
                    vs.append(v)
                    ss.append(s)
        if vs:
            for f, val in result["seq"].items():
                self._rows.setdefault(f, []).append(np.asarray(val)[vs, ss])
            self._table = None

    def gather(self, seq_digests: Sequence[tuple]) -> dict:
        """The fields of every lane (all scored): ``{'seq': {f: [B, S(, 19)]}, 'comb': {f: [B(, 19)]}}``."""
        if self._table is None:
            self._table = {f: np.concatenate(parts) for f, parts in self._rows.items()}
        rows = np.array([[self.memo[(s, d)] for s, d in enumerate(per)] for per in seq_digests], np.int64)
        seq = {f: t[rows] for f, t in self._table.items()}
        return {"seq": seq, "comb": combine_sequences(seq)}


def evaluate_arrays(gt: PreparedGT, ids, boxes, seq_offsets=None, *, box3d=None, similarity: str = "2d",
                    lanes_per_batch: int = 4, workers: int | None = 1,
                    start_method: str | None = None, chunk: int | None = None) -> list[dict[str, dict[str, object]]]:
    """Evaluate B tracker configs straight from padded output; one result dict per config.

    gt: :class:`PreparedGT` from :func:`prepare_gt`. ids: [B, T, K] int (``-1`` / negative = empty
    slot; ids are per sequence). boxes: [B, T, K, 4] float ``x1, y1, x2, y2`` (float32 is fine;
    values are used as float64). seq_offsets: [S] first frame along T of each of ``gt.sequences``
    (default: the sequences back to back, ``gt.offsets[:-1]``). Within a frame, slots are taken in
    order k = 0..K-1 (the order of rows in a result file; it decides ties exactly as in TrackEval).
    similarity: ``'2d'`` (default), ``'3d'`` or ``'bev'`` (:mod:`~dfrmot_jax.metrics.kitti2d.evaluate`); 3D
    and BEV need box3d: [B, T, K, 7] ``h w l x y z rot_y`` per slot (the 3D box the result file would carry; a
    slot without one holds the placeholder ``-1 -1 -1 -1000 -1000 -1000`` or all NaN: unmatched in 3D).
    lanes_per_batch: configs per vectorised batch (peak memory ~ lanes_per_batch x 60 MB for all of
    KITTI car). workers: processes for the batches (default 1; ``None`` = 2 when B >= 64 and 2+
    CPUs). With workers > 1 a process pool (``start_method``, default ``'forkserver'`` on Linux,
    else ``'spawn'``; both are safe in a process running JAX threads) evaluates batches in parallel; as
    always with these start methods, a calling script needs an ``if __name__ == "__main__":`` guard.
    Each distinct output of each sequence is scored once (:class:`LaneScorer`'s virtual lanes) when
    at least 1 - ``REPEATS_WORTH`` of the (config, sequence) outputs repeat; the results are the same.
    Returns a list of B dicts ``{seq: {field: value}, 'COMBINED': {...}}`` like
    :func:`~dfrmot_jax.metrics.kitti2d.evaluate.evaluate_files`. ``chunk``: deprecated name of
    ``lanes_per_batch`` (kept for one release, with a ``DeprecationWarning``).
    """
    if chunk is not None:
        warnings.warn("evaluate_arrays(chunk=...) is deprecated: use evaluate_arrays(lanes_per_batch=...)",
                      DeprecationWarning, stacklevel=2)
        lanes_per_batch = chunk
    if seq_offsets is None:
        seq_offsets = gt.offsets[:-1]
    similarity = parse_similarity(similarity)
    if similarity != "2d" and box3d is None:
        raise ValueError(f"similarity {similarity!r} needs box3d [B, T, K, 7] (h w l x y z rot_y per slot)")
    box3d = box3d if similarity != "2d" else None
    seq_offsets = check_arrays(gt, ids, boxes, seq_offsets)
    ids = np.asarray(ids)
    B = ids.shape[0]
    if B == 0:
        return []
    if not isinstance(boxes, Rows) and np.ndim(boxes) == 4 and frames_aligned(gt, ids.shape[1], seq_offsets):
        boxes = Rows.of(ids, boxes)      # the rows gathered once, for the digests and the scoring alike
    sc = LaneScorer(gt, seq_offsets, max(1, int(lanes_per_batch)), similarity)
    # a repeated output repeats its ids: the boxes are hashed only when some ids repeat
    by_ids = sc.seq_digests(ids, None)
    S = len(gt.sequences)
    per = sc.seq_digests(ids, boxes, box3d) if any(len({d[s] for d in by_ids}) < B for s in range(S)) else by_ids
    items = sc.new_items(per)
    if sum(map(len, items)) > REPEATS_WORTH * B * S:       # (almost) nothing repeats: the lanes as they are
        dets, items = tracker_dets_from_arrays(gt, ids, boxes, seq_offsets, box3d), None
    else:
        dets = sc.dets(ids, boxes, items, box3d)
    tasks = -(-dets.n_lanes // sc.lanes_per_batch)
    if workers is None:
        workers = 2 if (B >= 64 and (os.cpu_count() or 1) >= 2) else 1
    if workers > 1 and tasks > 1:
        with worker_pool(gt, min(workers, tasks), start_method) as ex:
            out = sc.submit(ex, dets).result()
    else:
        out = sc.evaluate(dets)
    if items is not None:
        sc.store(per, items, out)
        out = sc.gather(per)
    return result_dicts(gt, out)
