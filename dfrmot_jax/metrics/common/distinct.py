"""Distinct rows of float arrays, told apart bit for bit: many outputs of a sweep carry the same
boxes, and both metric families compute what depends on a box once per distinct (frame, box)
(TrackEval's IoU table, :mod:`dfrmot_jax.metrics.kitti2d.box_table`; AB3DMOT's rows,
:mod:`dfrmot_jax.metrics.samota.arrays`) or per distinct 3D box (:func:`row_ids`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from dfrmot_jax.metrics.common.kernel_cache import cached_njit

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
    row [R]; ids numbered in order of first appearance, as ``pd.factorize``); with ``key`` [R]
    (non-negative; equal keys within a frame mean equal values) the distinct (frame, key) instead,
    without reading the values. Values are told apart bit for bit (:func:`_factorize_rows`)."""
    if key is not None and len(key):
        ids = pd.factorize(frame.astype(np.int64) * (int(key.max()) + 1) + key)[0].astype(np.int64)
        first = np.full(int(ids.max(initial=-1)) + 1, -1, dtype=np.int64)
        first[ids[::-1]] = np.arange(len(ids))[::-1]
        return first, ids
    vals = np.ascontiguousarray(vals, dtype=np.float64)
    bits = (vals if vals.ndim == 2 else vals.reshape(len(frame), -1)).view(np.uint64)
    ids, first = _factorize_rows(np.ascontiguousarray(frame, dtype=np.int64), bits)
    return first, ids


@cached_njit(nogil=True)
def _factorize_rows(frame, bits):
    """(ids [R], first [U]): rows (``frame`` [R] int64, ``bits`` [R, C] uint64) numbered in order of
    first appearance, equal ids exactly for equal rows: an open-addressing hash table of each
    distinct row's first index, keyed by SplitMix64 mixes of the row's words, every probe compared
    word for word (so a shared hash never merges two rows). Why by hand: ``pd.factorize`` takes one
    key per row, and a row's several words would have to be hashed (and the hash checked) first."""
    n, c = bits.shape
    size = 1
    while size < 2 * n:
        size *= 2
    mask = np.uint64(size - 1)
    table = np.full(size, -1, np.int64)
    ids = np.empty(n, np.int64)
    first = np.empty(n, np.int64)
    u = 0
    for i in range(n):
        h = np.uint64(frame[i])
        for j in range(c + 1):
            if j > 0:
                h ^= bits[i, j - 1]
            h ^= h >> np.uint64(30)
            h *= np.uint64(0xBF58476D1CE4E5B9)
            h ^= h >> np.uint64(27)
            h *= np.uint64(0x94D049BB133111EB)
            h ^= h >> np.uint64(31)
        slot = h & mask
        while True:
            r = table[slot]
            if r < 0:
                table[slot] = i
                ids[i] = u
                first[u] = i
                u += 1
                break
            same = frame[r] == frame[i]
            j = 0
            while same and j < c:
                same = bits[r, j] == bits[i, j]
                j += 1
            if same:
                ids[i] = ids[r]
                break
            slot = (slot + np.uint64(1)) & mask
    return ids, first[:u]
