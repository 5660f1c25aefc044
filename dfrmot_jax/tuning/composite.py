"""Held-out AB3DMOT figures of a nested cross-validation (an AB3DMOT objective such as ``sAMOTA``).

AB3DMOT's figures are not sums over sequences: its recall thresholds come from the scores of all
sequences together, so a figure over a set of sequences must be computed on that set's rows at
once (a table's per-sequence rows cannot be re-combined, as TrackEval's can). Here each chosen
config and the baseline are tracked once over the whole split (``track(detail=True)``), their rows
turned into the values a ``--columns kitti`` file carries (:func:`dfrmot_jax.trackers.dfr.results.kitti_row_arrays`),
and scored with :func:`dfrmot_jax.metrics.samota.arrays.evaluate_ab3dmot_arrays`:

- ``held_out`` of fold f: config f on fold f's sequences together;
- ``cross_validated``: every sequence with the rows of the config chosen without it, all sequences
  scored together (directly comparable to a config's COMBINED figure, as for the 2D objectives);
- ``baseline`` / ``baseline_held_out``: the baseline on the same sequences.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
import pandas as pd

from ..data import cached_split
from ..trackers.protocol import DEFAULT_FAMILY
from ..trackers.registry import family_of
from ..metrics.samota.arrays import evaluate_ab3dmot_arrays
from ..metrics.samota.prep import cached_ab3dmot_gt
from ..metrics.samota.sums import DEFAULT_SUM
from ..metrics.samota.table import ab3dmot_columns
from ..sweep.plan import DataSettings, option_groups
from ..sweep.table import params_of


def _lane_rows(split, table: pd.DataFrame, cls: str, columns: str, family: str = DEFAULT_FAMILY) -> list[tuple]:
    """(ids [T, K], boxes [T, K, 4], scores [T, K], box3d [T, K, 7]) of each config row of ``table``,
    tracked by the tracker ``family`` (its rows as its result files carry them)."""
    out: list = [None] * len(table)
    fam = family_of(family)
    for options, rows in option_groups(table, family).items():
        pos = [int(np.flatnonzero(table["config"].to_numpy() == r)[0]) for r in rows]
        res = fam.track(split, params_of(table, pos, cls, family), options, detail=True)
        boxes, scores, box3d = fam.row_arrays(split, res, columns)
        for j, p in enumerate(pos):
            out[p] = (res.ids[j], boxes[j], scores[j], box3d[j])
    return out


def _stack(parts: Sequence[tuple]) -> tuple:
    """Lanes of different slot counts K as one [B, T, K_max] batch (empty slots: id -1, NaN)."""
    k = max(p[0].shape[1] for p in parts)

    def pad(a, fill):
        w = [(0, 0)] * a.ndim
        w[1] = (0, k - a.shape[1])
        return np.pad(a, w, constant_values=fill)

    return tuple(np.stack([pad(p[i], -1 if i == 0 else np.nan) for p in parts]) for i in range(4))


def ab3dmot_held_out(data: DataSettings, table: pd.DataFrame, folds: Sequence[Sequence[str]], iou: str,
                     objective: str, columns: str = "kitti", sum_mode: str = DEFAULT_SUM,
                     family: str = DEFAULT_FAMILY) -> dict:
    """The nested cross-validation's held-out figures of an AB3DMOT ``objective`` (module docstring).

    ``table``: the config table of the k chosen configs (row f chosen without fold f) and, last, the
    baseline, configs of the tracker ``family``; ``sum_mode`` the evaluator's sum of track scores. Returns ``cross_validated``, ``baseline``, ``mean_held_out`` and ``per_fold`` (each
    ``held_out``, ``baseline_held_out``), as :func:`dfrmot_jax.tuning.nested.held_out_scores`."""
    split = cached_split(data.root, data.det2d, data.det3d, data.cls, data.sequences)
    names = list(split.names)
    lanes = _lane_rows(split, table, data.cls, columns, family)
    k = len(folds)

    def score(rows_of_seq: Sequence[int], seqs: Sequence[str]) -> float:
        """``objective`` over ``seqs`` together, sequence s tracked by lane ``rows_of_seq[j]``."""
        idx = [names.index(s) for s in seqs]
        gt = cached_ab3dmot_gt(data.root, data.cls, list(seqs))
        ids, boxes, scores, box3d = _stack([lanes[r] for r in dict.fromkeys(rows_of_seq)])
        which = {r: i for i, r in enumerate(dict.fromkeys(rows_of_seq))}
        comp = [np.full_like(a[:1], -1 if a is ids else np.nan) for a in (ids, boxes, scores, box3d)]
        for s, r in zip(idx, rows_of_seq):
            sl = slice(int(split.offsets[s]), int(split.offsets[s] + split.lengths[s]))
            for c, a in zip(comp, (ids, boxes, scores, box3d)):
                c[0, sl] = a[which[r], sl]
        res = evaluate_ab3dmot_arrays(gt, *comp, seq_offsets=split.offsets[idx], iou=iou, sum_mode=sum_mode)[0]
        return float(ab3dmot_columns(res)[objective])

    per_fold = []
    for f, test in enumerate(folds):
        per_fold.append({"held_out": score([f] * len(test), test), "baseline_held_out": score([k] * len(test), test)})
    fold_of = {s: f for f, test in enumerate(folds) for s in test}
    return {"cross_validated": score([fold_of[s] for s in names], names), "baseline": score([k] * len(names), names),
            "mean_held_out": float(np.mean([q["held_out"] for q in per_fold])), "per_fold": per_fold}
