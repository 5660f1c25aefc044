"""The similarity HOTA / CLEAR / Identity score with: image IoU, 3D IoU or bird's-eye-view IoU.

``'2d'`` is TrackEval's image-box IoU (computed bit-identically by :mod:`dfrmot_jax.metrics.kitti2d.boxes`
inside :func:`dfrmot_jax.metrics.kitti2d.kitti.preprocess`); ``'3d'`` the IoU of the rotated KITTI 3D boxes
and ``'bev'`` their ground-plane IoU (:mod:`dfrmot_jax.metrics.common.box3d`, the one rotated-box overlap
of the package, also AB3DMOT's). A pair where either side has no 3D box has similarity 0.
Many outputs of a sweep carry the same boxes: :func:`pair_similarity_3d` computes each distinct
(ground-truth row, box) pair once, boxes told apart by :func:`row_ids`.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from dfrmot_jax.metrics.common.box3d import bev_iou, iou_3d

__all__ = ["SIMILARITIES", "parse_similarity", "row_ids", "distinct_rows", "pair_similarity_3d"]

#: the similarities HOTA / CLEAR / Identity can use: image-box IoU, 3D IoU of rotated boxes, BEV IoU
SIMILARITIES = ("2d", "3d", "bev")


def parse_similarity(similarity) -> str:
    """``'2d'`` / ``'3D'`` / ``'bev'`` -> the lower-case name in :data:`SIMILARITIES`; ValueError otherwise."""
    s = str(similarity).strip().lower()
    if s not in SIMILARITIES:
        raise ValueError(f"similarity {similarity!r}: expected one of {', '.join(SIMILARITIES)}")
    return s


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


def pair_similarity_3d(a_box3d: np.ndarray, a_has3d: np.ndarray, ia: np.ndarray, b_box3d: np.ndarray,
                       b_has3d: np.ndarray, ib: np.ndarray, kind: str = "3d") -> np.ndarray:
    """3D (``'3d'``) or BEV (``'bev'``) IoU of the pairs ``(A[ia[p]], B[ib[p]])`` -> [P] float64.

    a_box3d [NA, 7], b_box3d [NB, 7] ``h w l x y z rot_y``; a_has3d [NA], b_has3d [NB] bool (False:
    no 3D box, similarity 0); ia, ib [P] int. Each distinct (A row, B box value) pair is computed once."""
    out = np.zeros(len(ia))
    live = np.flatnonzero(a_has3d[ia] & b_has3d[ib])
    if live.size:
        r, c = ia[live], ib[live]
        box_id = row_ids(b_box3d)
        key = r * (int(box_id.max()) + 1) + box_id[c]
        _, first, inv = np.unique(key, return_index=True, return_inverse=True)
        fn = iou_3d if kind == "3d" else bev_iou
        out[live] = fn(a_box3d[r[first]], b_box3d[c[first]])[inv.reshape(-1)]
    return out
