"""AB3DMOT's figures of a chunk's lanes, from the tracker's arrays (``metrics.ab3dmot = "3d:0.25"`` or
an AB3DMOT objective in a sweep or tune).

Each lane is scored on the values its ``--columns kitti`` result file would carry
(:func:`dfrmot_jax.results.kitti_row_arrays`: the row's own 3D detection, or the filtered box with
``output = "filtered"``; rows without one count as unmatched in 3D; every value as the file reads
it back), against the class's
ground truth over the split's sequences together (:func:`dfrmot_jax.metrics.ab3dmot_arrays.
evaluate_ab3dmot_arrays`): the same figures as ``dfrmot eval --metrics ab3dmot`` of the written
files. AB3DMOT's figures exist for a whole sequence list only, so they fill a config's ``COMBINED``
row; its per-sequence rows hold NaN. Identical outputs (the same rows, boxes and scores) are
scored once.
"""

from __future__ import annotations

import hashlib
from typing import Sequence

import numpy as np
import pandas as pd

from ..api import TrackResult
from ..data import Split
from ..metrics.ab3dmot_arrays import evaluate_ab3dmot_arrays
from ..metrics.ab3dmot_prep import Ab3dGT
from ..metrics.ab3dmot_table import ab3dmot_columns
from ..metrics.table import AB3DMOT_COLUMNS, AB3DMOT_COUNT_COLUMNS
from ..results import kitti_row_arrays
from .table import COMBINED


class Ab3dmotLanes:
    """AB3DMOT scoring of lanes on one split: ``gt`` its ground truth (the split's sequences, in
    order), ``iou`` ``"3d:0.25"`` / ``"2d:0.5"``, ``columns`` the result columns scored (``"kitti"``
    or ``"kitti-stale"``); :meth:`score` gives each lane's columns."""

    def __init__(self, gt: Ab3dGT, split: Split, iou: str, columns: str = "kitti"):
        if tuple(gt.sequences) != tuple(split.names):
            raise RuntimeError("AB3DMOT ground truth and detections disagree on the sequences")
        self.gt, self.split, self.iou, self.columns = gt, split, iou, columns
        self.memo: dict[bytes, dict] = {}

    def score(self, res: TrackResult) -> list[dict]:
        """{column: value} of AB3DMOT's figures for each lane of ``res`` (``track(detail=True)``)."""
        ids = res.ids
        boxes, scores, box3d = kitti_row_arrays(self.split, res, self.columns)
        digests = []
        for b in range(ids.shape[0]):
            rows = ids[b] >= 0
            h = hashlib.sha1(np.ascontiguousarray(ids[b]).tobytes())
            for a in (boxes[b][rows], scores[b][rows], box3d[b][rows]):
                h.update(np.ascontiguousarray(a).tobytes())
            digests.append(h.digest())
        new = [b for b, d in enumerate(digests) if d not in self.memo and d not in digests[:b]]
        if new:
            out = evaluate_ab3dmot_arrays(self.gt, ids[new], boxes[new], scores[new], box3d[new], self.split.offsets,
                                          iou=self.iou)
            for b, r in zip(new, out):
                self.memo[digests[b]] = ab3dmot_columns(r)
        return [self.memo[d] for d in digests]


def add_columns(df: pd.DataFrame, per_config: Sequence[dict]) -> pd.DataFrame:
    """A chunk's table (configs in order, each its sequences then COMBINED) with AB3DMOT's columns:
    the config's figures on its COMBINED row, NaN (counts: missing) on its per-sequence rows."""
    comb = (df["sequence"] == COMBINED).to_numpy()
    if comb.sum() != len(per_config):
        raise RuntimeError("one COMBINED row per config expected")
    for col in AB3DMOT_COLUMNS:
        full = np.full(len(df), np.nan)
        full[comb] = [c[col] for c in per_config]
        df[col] = pd.Series(full, index=df.index).astype("Int64") if col in AB3DMOT_COUNT_COLUMNS else full
    return df
