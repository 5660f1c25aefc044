"""A per-lane output array kept at its rows only: :class:`Rows`.

The tracker writes each lane's output into fixed slots, ``ids [B, T, K]`` with -1 where a slot holds
no row, and per-slot arrays beside it (``boxes [B, T, K, 4]``, ``box3 [B, T, K, 6]``). Every reader of
a batch (the metrics, the digests of the sweep's memos, the result rows) reads those arrays at the
rows only, in (lane, frame, slot) order: ``a[ids >= 0]``. With output ``"filtered"`` a slot is a track
and most slots hold no row (a grid sweep's chunk: about 1 in 8), so a sweep keeps these arrays as
their rows' values (``track(rows_only=True)``): a chunk of 64 lanes over KITTI's 7,863 frames holds
~100 MB of them instead of ~770 MB. Reading ``Rows.values`` gives exactly the bytes ``a[ids >= 0]``
gives, so every digest, score and file is the same.
"""

from __future__ import annotations

from typing import NamedTuple, Sequence

import numpy as np

__all__ = ["KittiRows", "Rows", "RowSelection", "lane_values", "padded_rows", "row_starts"]


def row_starts(ids: np.ndarray) -> np.ndarray:
    """[B * T + 1] int64: the first row of lane b's frame t at ``b * T + t`` (rows: ``ids [B, T, K]``
    >= 0 in (lane, frame, slot) order); the last entry is the number of rows."""
    ids = np.asarray(ids)
    counts = (ids >= 0).sum(axis=2, dtype=np.int64).reshape(-1)
    out = np.zeros(counts.size + 1, np.int64)
    np.cumsum(counts, out=out[1:])
    return out


class Rows(NamedTuple):
    """A per-lane array [B, T, K, ...] at its rows (``ids >= 0``) only.

    values [R, ...]: the rows' values in (lane, frame, slot) order, as ``a[ids >= 0]``;
    start [B * T + 1] int64: :func:`row_starts` of the ids (lane b's frame t holds rows
    ``start[b * T + t] : start[b * T + t + 1]``); n_frames: T."""

    values: np.ndarray
    start: np.ndarray
    n_frames: int

    @classmethod
    def of(cls, ids: np.ndarray, dense: np.ndarray) -> "Rows":
        """The rows of ``dense`` [B, T, K, ...] where ``ids`` [B, T, K] >= 0."""
        ids, dense = np.asarray(ids), np.asarray(dense)
        live = ids >= 0
        if dense.flags.c_contiguous and dense.shape[:3] == ids.shape:     # (3.5x the boolean mask's speed)
            values = np.take(dense.reshape((-1,) + dense.shape[3:]), np.flatnonzero(live), axis=0)
        else:
            values = dense[live]
        return cls(values, row_starts(ids), ids.shape[1])

    @property
    def n_lanes(self) -> int:
        return (self.start.size - 1) // self.n_frames if self.n_frames else 0

    def lane(self, b: int, t0: int = 0, t1: int | None = None) -> np.ndarray:
        """Lane ``b``'s rows on frames ``t0 : t1`` (default: all), a view of ``values``."""
        t1 = self.n_frames if t1 is None else t1
        base = b * self.n_frames
        return self.values[self.start[base + t0]:self.start[base + t1]]

    def lanes(self, chosen: Sequence[int]) -> np.ndarray:
        """The rows of lanes ``chosen``, lane after lane in that order."""
        chosen = np.asarray(chosen, np.int64)
        first, last = self.start[chosen * self.n_frames], self.start[(chosen + 1) * self.n_frames]
        size = last - first
        idx = np.arange(int(size.sum()), dtype=np.int64) + np.repeat(first - np.cumsum(size) + size, size)
        return self.values[idx]

    def lane_dense(self, b: int, ids: np.ndarray, fill=np.nan) -> np.ndarray:
        """Lane ``b`` as [T, K, ...] (``ids``: its [T, K]), ``fill`` off its rows."""
        ids = np.asarray(ids)
        out = np.full(ids.shape + self.values.shape[1:], fill, self.values.dtype)
        out[ids >= 0] = self.lane(b)
        return out

    def dense(self, ids: np.ndarray, fill=np.nan) -> np.ndarray:
        """[B, T, K, ...] with the rows' values at ``ids >= 0`` and ``fill`` elsewhere."""
        ids = np.asarray(ids)
        out = np.full(ids.shape + self.values.shape[1:], fill, self.values.dtype)
        out[ids >= 0] = self.values
        return out


def lane_values(a, ids: np.ndarray, b: int, t0: int = 0, t1: int | None = None) -> np.ndarray:
    """Lane ``b``'s rows on frames ``t0 : t1`` (default all) of a per-lane array, in (frame, slot)
    order: a :class:`Rows` (a view of its values) or a dense [B, T, K, ...] array at ``ids`` [B, T, K]
    >= 0: the same values either way."""
    if isinstance(a, Rows):
        return a.lane(b, t0, t1)
    return np.asarray(a)[b, t0:t1][np.asarray(ids)[b, t0:t1] >= 0]


class RowSelection(NamedTuple):
    """The rows (``ids >= 0``) of some lanes of an output ``ids [B, T, K]``, in (lane, frame, slot)
    order: ``lane`` [R] (the chosen lanes renumbered 0..L-1 in their order), ``t`` [R], ``slot``
    [R], ``tk`` [R] = ``t K + slot``, ``at`` [R] each row's flat index into [B, T, K]; ``chosen``
    [L] the lanes, ``every``: all lanes in order (no ``lanes`` given). What the result rows of every
    tracker family are read through."""

    lane: np.ndarray
    t: np.ndarray
    slot: np.ndarray
    tk: np.ndarray
    at: np.ndarray
    chosen: np.ndarray
    every: bool

    @classmethod
    def of(cls, ids: np.ndarray, lanes=None) -> "RowSelection":
        """The rows of lanes ``lanes`` (default all) of ``ids`` [B, T, K]."""
        ids = np.asarray(ids)
        _, T, K = ids.shape
        chosen = np.arange(ids.shape[0]) if lanes is None else np.asarray(lanes, np.int64)
        flat = np.flatnonzero((ids if lanes is None else ids[chosen]) >= 0)
        b, tk = np.divmod(flat, T * K)
        t, k = np.divmod(tk, K)
        at = flat if lanes is None else chosen[b] * (T * K) + tk     # the rows in the output's own lanes, flat
        return cls(b, t, k, tk, at, chosen, lanes is None)

    def values(self, a) -> np.ndarray:
        """The rows' values of a [B, T, K, ...] array (or of a :class:`Rows`)."""
        if isinstance(a, Rows):
            return a.values if self.every else a.lanes(self.chosen)
        a = np.asarray(a)
        return a.reshape((-1,) + a.shape[3:])[self.at]


class KittiRows(NamedTuple):
    """The rows of B lanes' ``--columns kitti`` result files as flat arrays, in (lane, frame, slot)
    order (the order of a file's lines): lane [R], t [R] frame along the split, slot [R] output slot,
    ids [R] track id, box [R, 4] image box, score [R], box3d [R, 7] ``h w l x y z rot_y`` (the
    2D-only placeholder where the row carries no 3D box), n_lanes B, n_frames T. box_key / box3d_key [R] int64
    or None: rows of one frame with equal keys carry equal image boxes / 3D boxes (the object slot,
    the 3D detection's index; None with output "filtered" or a distortion, whose boxes are each lane's own), so a
    scorer finds the distinct values from the keys instead of the values' bits."""

    lane: np.ndarray
    t: np.ndarray
    slot: np.ndarray
    ids: np.ndarray
    box: np.ndarray
    score: np.ndarray
    box3d: np.ndarray
    n_lanes: int
    n_frames: int
    box_key: np.ndarray | None = None
    box3d_key: np.ndarray | None = None


def padded_rows(r: KittiRows, shape) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rows ``r`` as padded arrays of an output's ``shape`` (B, T, K): boxes [B, T, K, 4], scores
    [B, T, K] and box3d [B, T, K, 7], float64, NaN where there is no row."""
    out = [np.full(tuple(shape) + tail, np.nan) for tail in ((4,), (), (7,))]
    for a, v in zip(out, (r.box, r.score, r.box3d)):
        a[r.lane, r.t, r.slot] = v
    return out[0], out[1], out[2]

