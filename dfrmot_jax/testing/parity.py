"""Compare the JAX tracker with the NumPy reference, lane by lane (used by tests and tooling)."""

from __future__ import annotations

import multiprocessing
from concurrent.futures import Executor, ProcessPoolExecutor
from typing import NamedTuple

import numpy as np

from ..trackers.protocol import TrackResult
from ..data import SequenceDets, Split
from ..trackers.dfr.config import Options, Params
from .reference import track_sequence
from ..trackers.dfr.results import lane_rows


def reference_pool(workers: int = 2) -> ProcessPoolExecutor:
    """Worker processes for the reference, started with "spawn" (forking a process that runs JAX
    threads can deadlock)."""
    return ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"))


def reference_rows(seqs: list[SequenceDets], params: Params, options: Options,
                   pool: Executor | None = None) -> list[list[tuple]]:
    """Reference output rows per sequence (frame, id, x1, y1, x2, y2, kind, index, row3, own3, box3;
    see ``reference.track_sequence``) for one setting; sequences run on ``pool`` when given (see
    ``reference_pool``)."""
    if pool is None:
        return [track_sequence(s, params, options) for s in seqs]
    longest_first = sorted(range(len(seqs)), key=lambda i: -seqs[i].n_frames)
    futures = {i: pool.submit(track_sequence, seqs[i], params, options) for i in longest_first}
    return [futures[i].result() for i in range(len(seqs))]


def lane_mismatches(split: Split, res: TrackResult, b: int, ref: list[list[tuple]], tol: float = 1e-4,
                    sequences: list[int] | None = None) -> dict:
    """Count lines of lane b that differ from the reference: {'lines', 'missing', 'extra', 'id', 'box'}.
    ``sequences``: the split's sequences compared (default: all), ``ref[j]`` the rows of ``sequences[j]``."""
    boxes = res.lane_boxes(b)
    out = {"lines": 0, "missing": 0, "extra": 0, "id": 0, "box": 0}
    for j, s in enumerate(range(len(split.names)) if sequences is None else sequences):
        r = lane_rows(split, s, res.ids[b], boxes)
        mine = {}
        for f, i, bx in zip(r.frame.tolist(), r.track_id.tolist(), r.box):
            mine.setdefault((f, i), []).append(bx)
        theirs = {}
        for row in ref[j]:
            theirs.setdefault((row[0], row[1]), []).append(np.array(row[2:6]))
        out["lines"] += len(ref[j])
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


class ReferenceLane(NamedTuple):
    """The oracle's rows of a whole split as one lane's padded arrays, like the tracker's output.

    ids [T, K] int32 (-1 none); boxes [T, K, 4] float64; src3 [T, K] int64 (global 3D index
    ``t * M3 + slot`` into the split's [T, M3] arrays of the 3D detection the row carries, -1 none);
    own3 [T, K] bool; box3 [T, K, 6] float64 (output "filtered": filtered 3D corners; NaN none).
    Slots: output "detections" = object slots (``trackers.dfr.frames.object_boxes``: fused 2D slots then 3D slots);
    "filtered" = the frame's rows in the oracle's order.
    """

    ids: np.ndarray
    boxes: np.ndarray
    src3: np.ndarray
    own3: np.ndarray
    box3: np.ndarray


def _file_row_index(rows: np.ndarray, n: int, offset: int, width: int, flat: bool) -> np.ndarray:
    """[n] per file row of one sequence: its slot (flat=False) or global index t * width + slot."""
    out = np.full(n, -1, np.int64)
    t, k = np.nonzero(rows >= 0)
    out[rows[t, k]] = (offset + t) * width + k if flat else k
    return out


def reference_lane(split: Split, seqs: list[SequenceDets], ref: list[list[tuple]], options: Options) -> ReferenceLane:
    """Pack ``reference_rows`` output (one list per sequence of the split) into a ``ReferenceLane``."""
    T, m2, m3 = split.n_frames, split.valid2d.shape[1], split.valid3d.shape[1]
    if options.output == "detections":
        base3 = 0 if options.modality == "3d" else m2
        k = {"2d": m2, "3d": m3}.get(options.modality, m2 + m3)
    else:
        k = 1
        for rows in ref:
            frames = np.array([r[0] for r in rows], np.int64)
            k = max(k, int(np.bincount(frames).max(initial=0)) if frames.size else 0)
    ids = np.full((T, k), -1, np.int32)
    boxes = np.zeros((T, k, 4))
    src3 = np.full((T, k), -1, np.int64)
    own3 = np.zeros((T, k), bool)
    box3 = np.full((T, k, 6), np.nan)
    for s, (seq, rows) in enumerate(zip(seqs, ref)):
        sl = split.sequence_slice(s)
        o = int(split.offsets[s])
        slot2 = _file_row_index(split.row2d[sl], len(seq.det2d.frame), o, m2, False)
        slot3 = _file_row_index(split.row3d[sl], len(seq.det3d.frame), o, m3, False)
        glob3 = _file_row_index(split.row3d[sl], len(seq.det3d.frame), o, m3, True)
        used: dict[int, int] = {}
        for r in rows:
            t = o + r[0]
            kind, index, row3, own, b3 = r[6], r[7], r[8], r[9], r[10]
            if kind == "2d":
                slot = int(slot2[index])
            elif kind == "3d":
                slot = base3 + int(slot3[index])
            else:
                slot = used.get(t, 0)
                used[t] = slot + 1
            ids[t, slot] = r[1]
            boxes[t, slot] = r[2:6]
            src3[t, slot] = glob3[row3] if row3 >= 0 else -1
            own3[t, slot] = own
            if b3 is not None:
                box3[t, slot] = b3
    return ReferenceLane(ids, boxes, src3, own3, box3)
