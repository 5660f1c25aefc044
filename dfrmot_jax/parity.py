"""Compare the JAX tracker with the NumPy reference, lane by lane (used by tests and tooling)."""

from __future__ import annotations

import multiprocessing
from concurrent.futures import Executor, ProcessPoolExecutor

import numpy as np

from .api import TrackResult
from .data import SequenceDets, Split
from .params import Options, Params
from .reference import track_sequence
from .results import lane_rows


def reference_pool(workers: int = 2) -> ProcessPoolExecutor:
    """Worker processes for the reference, started with "spawn" (forking a process that runs JAX
    threads can deadlock)."""
    return ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"))


def reference_rows(seqs: list[SequenceDets], params: Params, options: Options,
                   pool: Executor | None = None) -> list[list[tuple]]:
    """Reference output rows per sequence (frame, id, x1, y1, x2, y2, ...) for one setting;
    sequences run on ``pool`` when given (see ``reference_pool``)."""
    if pool is None:
        return [track_sequence(s, params, options) for s in seqs]
    longest_first = sorted(range(len(seqs)), key=lambda i: -seqs[i].n_frames)
    futures = {i: pool.submit(track_sequence, seqs[i], params, options) for i in longest_first}
    return [futures[i].result() for i in range(len(seqs))]


def lane_mismatches(split: Split, res: TrackResult, b: int, ref: list[list[tuple]], tol: float = 1e-4) -> dict:
    """Count lines of lane b that differ from the reference: {'lines', 'missing', 'extra', 'id', 'box'}."""
    boxes = res.lane_boxes(b)
    out = {"lines": 0, "missing": 0, "extra": 0, "id": 0, "box": 0}
    for s in range(len(split.names)):
        r = lane_rows(split, s, res.ids[b], boxes)
        mine = {}
        for f, i, bx in zip(r.frame.tolist(), r.track_id.tolist(), r.box):
            mine.setdefault((f, i), []).append(bx)
        theirs = {}
        for row in ref[s]:
            theirs.setdefault((row[0], row[1]), []).append(np.array(row[2:6]))
        out["lines"] += len(ref[s])
        for key, bxs in theirs.items():
            got = mine.get(key)
            if got is None:
                out["missing"] += len(bxs)
                continue
            if len(got) != len(bxs):
                out["id"] += abs(len(got) - len(bxs))
            for a, c in zip(sorted(map(tuple, got)), sorted(map(tuple, bxs))):
                if np.max(np.abs(np.subtract(a, c))) > tol:
                    out["box"] += 1
        out["extra"] += sum(len(v) for k, v in mine.items() if k not in theirs)
    return out
