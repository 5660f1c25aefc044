"""AB3DMOT's figures of two outputs with paired bootstrap intervals over sequences, each resample rescored.

AB3DMOT's sAMOTA / AMOTA are not sums over sequences: its recall thresholds come from the scores of every
sequence together, and tracks are dropped whole by their mean score. A resample is therefore scored anew:
its drawn sequences (a sequence drawn twice is two sequences, with its own tracks) read as one split
(:func:`~dfrmot_jax.metrics.samota.prep.prepare_ab3dmot_gt` of the names, repeats included, and each
output's files for them) and evaluated exactly as ``dfrmot eval --metrics ab3dmot`` evaluates a split.
That costs a full evaluation per resample and output (about 0.2 s each for AB3DMOT's 11 validation
sequences on 2 cores), so fewer resamples are drawn than for the 2D family; the table says how many.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Sequence

import numpy as np
from tqdm import tqdm

from ..choices import AB3DMOT_MAX_RESAMPLES, AB3DMOT_RESAMPLES
from ..metrics.samota.evaluate import evaluate_ab3dmot
from ..metrics.samota.prep import prepare_ab3dmot_gt, read_ab3dmot_results
from ..metrics.samota.sums import DEFAULT_SUM
from ..metrics.samota.table import ab3dmot_columns
from ..metrics.kitti2d.bootstrap import resample_indices

__all__ = ["AB3DMOT_BOOTSTRAP_FIELDS", "AB3DMOT_RESAMPLES", "AB3DMOT_MAX_RESAMPLES", "ab3dmot_rows", "split_results",
           "split_figures"]

#: the AB3DMOT columns a comparison reports (``dfrmot eval --metrics ab3dmot``'s names, percent and counts)
AB3DMOT_BOOTSTRAP_FIELDS = ("sAMOTA", "AMOTA", "ab3dmot_MOTA", "ab3dmot_IDS", "ab3dmot_FP", "ab3dmot_FN")
_LOWER = frozenset({"ab3dmot_IDS", "ab3dmot_FP", "ab3dmot_FN"})


def split_results(root, cls: str, names: Sequence[str], folders: Sequence[Path], iou: str,
                  sum_mode: str = DEFAULT_SUM, other: bool = False) -> list[dict]:
    """AB3DMOT's result dicts (``evaluate_ab3dmot``, with ``sum_mode`` and, with ``other``, the other
    sum's figures) of each folder on the split of ``names`` (repeats are sequences of their own)."""
    gt = prepare_ab3dmot_gt(root, cls, names)
    return [evaluate_ab3dmot(gt, read_ab3dmot_results(d, gt, need_3d=iou.startswith("3d")), iou, sum_mode, other)
            for d in folders]


def split_figures(root, cls: str, names: Sequence[str], folders: Sequence[Path], iou: str,
                  sum_mode: str = DEFAULT_SUM) -> list[dict]:
    """AB3DMOT's columns (``ab3dmot_columns``) of each folder on the split of ``names`` (repeats are
    sequences of their own)."""
    return [ab3dmot_columns(r) for r in split_results(root, cls, names, folders, iou, sum_mode)]


def ab3dmot_rows(root, cls: str, sequences: Sequence[str], folder_a, folder_b, resamples: int = AB3DMOT_RESAMPLES,
                 seed: int = 0, iou: str = "3d:0.25", level: float = 0.95,
                 sum_mode: str = DEFAULT_SUM, progress: bool = False) -> tuple[list[dict], float, list[dict]]:
    """The ``COMBINED`` rows (``report.compare.COLUMNS``) of AB3DMOT's figures of outputs A and B on
    ``sequences``, with the ``level`` interval of B - A over ``resamples`` paired resamples, each rescored
    (with ``sum_mode``); the seconds one resample took; and A's and B's result dicts on ``sequences``
    (with the other sum's figures and both per-pass tables: ``metrics.ab3dmot.table.recall_table``).
    ``metric`` names carry the IoU (``sAMOTA@3d:0.25``). ``progress``: a bar with the time left on a
    terminal's stderr (tqdm's)."""
    folders = [Path(folder_a), Path(folder_b)]
    points = split_results(root, cls, sequences, folders, iou, sum_mode, other=True)
    a, b = (ab3dmot_columns(r) for r in points)
    idx = resample_indices(len(sequences), resamples, seed)
    boot = {f: np.empty((resamples, 2)) for f in AB3DMOT_BOOTSTRAP_FIELDS}
    t0 = time.perf_counter()
    bar = tqdm(total=resamples, unit="resample", desc=f"{cls}, AB3DMOT", file=sys.stderr, dynamic_ncols=True,
               disable=None if progress else True, leave=False)
    for r, draw in enumerate(idx):
        ra, rb = split_figures(root, cls, [sequences[i] for i in draw], folders, iou, sum_mode)
        for f in AB3DMOT_BOOTSTRAP_FIELDS:
            boot[f][r] = ra[f], rb[f]
        bar.update()
    bar.close()
    per = (time.perf_counter() - t0) / max(1, resamples)
    lo_q = (1 - level) / 2
    rows = []
    for f in AB3DMOT_BOOTSTRAP_FIELDS:
        d = boot[f][:, 1] - boot[f][:, 0]
        better = -d if f in _LOWER else d
        rows.append({"class": cls, "seq": "COMBINED", "metric": f"{f}@{iou}", "a": float(a[f]), "b": float(b[f]),
                     "diff": float(b[f]) - float(a[f]), "ci_low": float(np.quantile(d, lo_q)),
                     "ci_high": float(np.quantile(d, 1 - lo_q)),
                     "p_b_better": float(np.mean(better > 0) + 0.5 * np.mean(better == 0)), "resamples": resamples})
    return rows, per, points
