"""AB3DMOT's figures of a chunk's lanes, from the tracker's arrays (``metrics.ab3dmot = "3d:0.25"`` or
an AB3DMOT objective in a sweep or tune).

Each lane is scored on the values its ``--columns kitti`` result file would carry
(its tracker family's ``rows``, DFR-FastMOT's :func:`dfrmot_jax.trackers.dfr.results.kitti_rows`: the row's own
3D detection, or the filtered box with ``output = "filtered"``; rows without one count as unmatched in 3D; every value as the file reads
it back), against the class's
ground truth over the split's sequences together (:func:`dfrmot_jax.metrics.samota.arrays.
evaluate_ab3dmot_rows`): the same figures as ``dfrmot eval --metrics ab3dmot`` of the written
files. AB3DMOT's figures exist for a whole sequence list only, so they fill a config's ``COMBINED``
row; its per-sequence rows hold NaN. Identical outputs (the same ids and 3D sources per row; with
output "filtered" the same boxes too) are scored once, and only their rows are built.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
import pandas as pd

from ..trackers.protocol import TrackResult
from ..data import Split
from ..trackers.registry import family_of
from ..trackers.protocol import TrackerFamily
from ..metrics.samota.arrays import evaluate_ab3dmot_rows
from ..metrics.samota.prep import Ab3dGT
from ..metrics.samota.sums import DEFAULT_SUM
from ..metrics.samota.table import AB3DMOT_COLUMNS, AB3DMOT_COUNT_COLUMNS, AB3DMOT_OTHER_COLUMNS, ab3dmot_columns
from ..metrics.kitti2d.lane_scorer import LaneScorer
from ..rows import Rows
from ..table_columns import COMBINED


#: lanes whose rows are built and scored together (each lane's figures are its own; fewer at a time
#: hold less memory: a chunk's 64 filtered lanes at once took ~0.9 GB more)
LANES_PER_PASS = 16


class Ab3dmotLanes:
    """AB3DMOT scoring of lanes on one split: ``gt`` its ground truth (the split's sequences, in
    order), ``iou`` ``"3d:0.25"`` / ``"2d:0.5"``, ``columns`` the result columns scored (``"kitti"``
    or ``"kitti-stale"``), ``sum_mode`` the evaluator's sum of track scores (the figures with the
    other sum too, as :data:`~dfrmot_jax.metrics.samota.table.AB3DMOT_OTHER_COLUMNS`), ``family``
    the tracker family whose output it scores (its ``rows`` and ``lane_keys``; None: the default
    family); :meth:`score` gives each lane's columns."""

    def __init__(self, gt: Ab3dGT, split: Split, iou: str, columns: str = "kitti", sum_mode: str = DEFAULT_SUM,
                 family: TrackerFamily | None = None):
        if tuple(gt.sequences) != tuple(split.names):
            raise RuntimeError("AB3DMOT ground truth and detections disagree on the sequences")
        self.gt, self.split, self.iou, self.columns, self.sum_mode = gt, split, iou, columns, sum_mode
        self.family = family_of() if family is None else family
        self.rows = self.family.rows
        self.memo: dict[bytes, dict] = {}

    def digests(self, res: TrackResult, base: Sequence[bytes] | None = None) -> list[bytes]:
        """One digest per lane of what its rows carry, the key of :attr:`memo`: the tracker family's
        :attr:`~dfrmot_jax.trackers.protocol.TrackerFamily.lane_keys` (ids, image boxes and all the rows carry
        beyond; the split, ground truth, IoU, columns and sum are the instance's own). ``base``: the
        lanes' digests of ids and own image boxes (:meth:`dfrmot_jax.metrics.kitti2d.lane_scorer.LaneScorer.digests`
        or ``lane_digests``, made here when not given), extended instead of hashing them again."""
        if base is None:
            ids = np.asarray(res.ids)
            base = LaneScorer.digests(ids, res.boxes if isinstance(res.boxes, Rows) else np.asarray(res.boxes))
        return self.family.lane_keys(res, base)

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
