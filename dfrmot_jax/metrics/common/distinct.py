"""Distinct rows of float arrays, told apart bit for bit: many outputs of a sweep carry the same
boxes, and both metric families compute what depends on a box once per distinct (frame, box)
(TrackEval's IoU table, :mod:`dfrmot_jax.metrics.kitti2d.box_table`; AB3DMOT's rows,
:mod:`dfrmot_jax.metrics.ab3dmot.arrays`) or per distinct 3D box (:func:`row_ids`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

__all__ = ["row_ids", "distinct_rows"]


def _mix(x: np.ndarray) -> np.ndarray:
    """SplitMix64's finaliser on [N] uint64 (in place): every input bit reaches every output bit
    (float64 values of float32 data have 29 zero low bits, which a plain multiplicative hash loses)."""
    x ^= x >> np.uint64(30)
    x *= np.uint64(0xBF58476D1CE4E5B9)
    x ^= x >> np.uint64(27)
    x *= np.uint64(0x94D049BB133111EB)
    x ^= x >> np.uint64(31)
    return x


def row_ids(vals: np.ndarray) -> np.ndarray:
    """[N, C] float rows -> [N] int64 ids ``0..U-1``, equal ids for equal rows (bit for bit).

    A hash of each row's bits, factorised with pandas' hash table (O(N), where sorting the hashes
    costs several times more on sweep-sized inputs), then checked: if two different rows ever
    share a hash, the exact ``np.unique(axis=0)`` decides."""
    vals = np.ascontiguousarray(vals, dtype=np.float64)
    bits = vals.view(np.uint64)
    h = np.zeros(len(vals), dtype=np.uint64)
    with np.errstate(over="ignore"):
        for j in range(bits.shape[1]):
            h = _mix(h ^ bits[:, j])
    codes = pd.factorize(h)[0].astype(np.int64)
    first = np.empty(int(codes.max(initial=-1)) + 1, dtype=np.int64)
    first[codes[::-1]] = np.arange(len(codes))[::-1]
    if np.array_equal(vals[first][codes].view(np.uint64), bits):
        return codes
    return np.unique(vals, axis=0, return_inverse=True)[1].reshape(-1).astype(np.int64)


def distinct_rows(frame: np.ndarray, vals: np.ndarray, key: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Distinct (frame, value row) of [R] frames and [R, C] rows -> (first row of each [U], id of each
    row [R]); with ``key`` [R] (non-negative; equal keys within a frame mean equal values) the
    distinct (frame, key) instead, without reading the values."""
    if key is not None and len(key):
        ids = pd.factorize(frame.astype(np.int64) * (int(key.max()) + 1) + key)[0].astype(np.int64)
    else:
        ids = row_ids(np.concatenate([frame[:, None].astype(np.float64), vals], axis=1))
    first = np.full(int(ids.max(initial=-1)) + 1, -1, dtype=np.int64)
    first[ids[::-1]] = np.arange(len(ids))[::-1]
    return first, ids
