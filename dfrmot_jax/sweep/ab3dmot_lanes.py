"""AB3DMOT's figures of a chunk's lanes, from the tracker's arrays (``metrics.ab3dmot = "3d:0.25"`` or
an AB3DMOT objective in a sweep or tune).

Each lane is scored on the values its ``--columns kitti`` result file would carry
(its tracker family's ``rows``, DFR-FastMOT's :func:`dfrmot_jax.results.kitti_rows`: the row's own
3D detection, or the filtered box with ``output = "filtered"``; rows without one count as unmatched in 3D; every value as the file reads
it back), against the class's
ground truth over the split's sequences together (:func:`dfrmot_jax.metrics.ab3dmot.arrays.
evaluate_ab3dmot_rows`): the same figures as ``dfrmot eval --metrics ab3dmot`` of the written
files. AB3DMOT's figures exist for a whole sequence list only, so they fill a config's ``COMBINED``
row; its per-sequence rows hold NaN. Identical outputs (the same ids and 3D sources per row; with
output "filtered" the same boxes too) are scored once, and only their rows are built.
"""

from __future__ import annotations

import hashlib
from typing import Sequence

import numpy as np
import pandas as pd

from ..api import TrackResult
from ..data import Split
from ..families import family_of
from ..metrics.ab3dmot.arrays import evaluate_ab3dmot_rows
from ..metrics.ab3dmot.prep import Ab3dGT
from ..metrics.ab3dmot.sums import DEFAULT_SUM
from ..metrics.ab3dmot.table import AB3DMOT_COLUMNS, AB3DMOT_COUNT_COLUMNS, AB3DMOT_OTHER_COLUMNS, ab3dmot_columns
from ..metrics.kitti2d.lane_scorer import LaneScorer
from ..rows import Rows, lane_values
from ..report.columns import COMBINED


#: lanes whose rows are built and scored together (each lane's figures are its own; fewer at a time
#: hold less memory: a chunk's 64 filtered lanes at once took ~0.9 GB more)
LANES_PER_PASS = 16


class Ab3dmotLanes:
    """AB3DMOT scoring of lanes on one split: ``gt`` its ground truth (the split's sequences, in
    order), ``iou`` ``"3d:0.25"`` / ``"2d:0.5"``, ``columns`` the result columns scored (``"kitti"``
    or ``"kitti-stale"``), ``sum_mode`` the evaluator's sum of track scores (the figures with the
    other sum too, as :data:`~dfrmot_jax.metrics.ab3dmot.table.AB3DMOT_OTHER_COLUMNS`), ``rows`` the
    tracker family's rows of its output (``TrackerFamily.rows``; None: the default family's,
    :func:`dfrmot_jax.results.kitti_rows`); :meth:`score` gives each lane's columns."""

    def __init__(self, gt: Ab3dGT, split: Split, iou: str, columns: str = "kitti", sum_mode: str = DEFAULT_SUM,
                 rows=None):
        if tuple(gt.sequences) != tuple(split.names):
            raise RuntimeError("AB3DMOT ground truth and detections disagree on the sequences")
        self.gt, self.split, self.iou, self.columns, self.sum_mode = gt, split, iou, columns, sum_mode
        self.rows = family_of().rows if rows is None else rows
        self.memo: dict[bytes, dict] = {}

    def digests(self, res: TrackResult, base: Sequence[bytes] | None = None) -> list[bytes]:
        """One digest per lane of what its rows carry, the key of :attr:`memo`: the options, ids, the
        image boxes (the lane's own, or the ones the lanes share, whole) and, per row, the 3D source
        (``src3``, ``own3``); with output "filtered" also the lane's own 3D boxes. (With output
        "detections" a row's score and 3D box follow from the options, its slot and its 3D source,
        on the one split; the split, ground truth, IoU, columns and sum are the instance's own.) ``base``: the lanes' digests of ids and own image boxes
        (:meth:`dfrmot_jax.metrics.kitti2d.lane_scorer.LaneScorer.digests` or ``lane_digests``, made here
        when not given), extended here instead of hashing them again."""
        ids = np.asarray(res.ids)
        if base is None:
            base = LaneScorer.digests(ids, res.boxes if isinstance(res.boxes, Rows) else np.asarray(res.boxes))
        rows = ids >= 0
        filtered = res.options.output == "filtered"
        src, own = np.asarray(res.src3), np.asarray(res.own3)
        out = []
        for b in range(ids.shape[0]):
            r = rows[b]
            h = hashlib.sha1(repr(res.options).encode())
            h.update(base[b])
            h.update(src[b][r].astype(np.int32).tobytes())
            h.update(np.packbits(own[b][r]).tobytes())
            if filtered:
                h.update(np.ascontiguousarray(lane_values(res.box3, ids, b)).tobytes())
            out.append(h.digest())
        return out

    def score(self, res: TrackResult, base: Sequence[bytes] | None = None) -> list[dict]:
        """{column: value} of AB3DMOT's figures for each lane of ``res`` (``track(detail=True)``);
        ``base`` as in :meth:`digests`."""
        digests = self.digests(res, base)
        new = [b for b, d in enumerate(digests) if d not in self.memo and d not in digests[:b]]
        for at in range(0, len(new), LANES_PER_PASS):     # (a few lanes' rows at a time: memory)
            part = new[at:at + LANES_PER_PASS]
            rows = self.rows(self.split, res, self.columns, lanes=part)
            out = evaluate_ab3dmot_rows(self.gt, **rows._asdict(), seq_offsets=self.split.offsets, iou=self.iou,
                                        check_ids=False, sum_mode=self.sum_mode, other=True)
            for b, r in zip(part, out):
                self.memo[digests[b]] = ab3dmot_columns(r)
        return [self.memo[d] for d in digests]


def add_columns(df: pd.DataFrame, per_config: Sequence[dict]) -> pd.DataFrame:
    """A chunk's table (configs in order, each its sequences then COMBINED) with AB3DMOT's columns:
    the config's figures on its COMBINED row, NaN (counts: missing) on its per-sequence rows."""
    comb = (df["sequence"] == COMBINED).to_numpy()
    if comb.sum() != len(per_config):
        raise RuntimeError("one COMBINED row per config expected")
    for col in AB3DMOT_COLUMNS + AB3DMOT_OTHER_COLUMNS:
        full = np.full(len(df), np.nan)
        full[comb] = [c[col] for c in per_config]
        df[col] = pd.Series(full, index=df.index).astype("Int64") if col in AB3DMOT_COUNT_COLUMNS else full
    return df
