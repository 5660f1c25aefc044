"""The similarity HOTA / CLEAR / Identity score with: image IoU, 3D IoU or bird's-eye-view IoU.

``'2d'`` is TrackEval's image-box IoU (computed bit-identically by :mod:`dfrmot_jax.metrics.kitti2d.boxes`
inside :func:`dfrmot_jax.metrics.kitti2d.kitti.preprocess`); ``'3d'`` the IoU of the rotated KITTI 3D boxes
and ``'bev'`` their ground-plane IoU (:mod:`dfrmot_jax.metrics.common.box3d`, the one rotated-box overlap
of the package, also AB3DMOT's). A pair where either side has no 3D box has similarity 0.
Many outputs of a sweep carry the same boxes: :func:`pair_similarity_3d` computes each distinct
(ground-truth row, box) pair once, boxes told apart by
:func:`~dfrmot_jax.metrics.common.distinct.row_ids`.
"""

from __future__ import annotations

import numpy as np

from dfrmot_jax.metrics.common.box3d import bev_iou, iou_3d
from dfrmot_jax.metrics.common.distinct import row_ids

__all__ = ["SIMILARITIES", "parse_similarity", "pair_similarity_3d"]

#: the similarities HOTA / CLEAR / Identity can use: image-box IoU, 3D IoU of rotated boxes, BEV IoU
SIMILARITIES = ("2d", "3d", "bev")


def parse_similarity(similarity) -> str:
    """``'2d'`` / ``'3D'`` / ``'bev'`` -> the lower-case name in :data:`SIMILARITIES`; ValueError otherwise."""
    s = str(similarity).strip().lower()
    if s not in SIMILARITIES:
        raise ValueError(f"similarity {similarity!r}: expected one of {', '.join(SIMILARITIES)}")
    return s


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
