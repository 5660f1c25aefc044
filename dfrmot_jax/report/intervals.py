"""Is the best config really better? Paired bootstrap intervals over sequences in a sweep's report.

From a sweep table's per-sequence fields (the per-alpha HOTA sums and the CLEAR / Identity counts it
stores, :func:`~.analysis.per_sequence_arrays`), R resamples of the sequences (with replacement, the
same draws for every config) are combined as TrackEval combines sequences
(:func:`~dfrmot_jax.metrics.kitti2d.bootstrap.resampled_figure`). Reported:

- best vs baseline: the ``level`` interval of best - baseline and the share of resamples where the
  best is better (:func:`report_intervals`);
- the configs not distinguishable from the best: those whose interval of best - config reaches 0
  (the lower bound at most 0, on the objective's own direction); the best is one of them.

These are in-sample figures like the ranking they qualify (the best was chosen on the same sequences,
which the interval does not undo: the cross-validated figure does). AB3DMOT's figures are not sums over
sequences and get no interval here.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..metrics.samota.table import AB3DMOT_COLUMNS
from ..metrics.kitti2d.bootstrap import counts_of, resample_indices, resampled_figure
from .analysis import objective_direction, per_sequence_arrays, rank_configs
from ..table_columns import RAW_COLUMN

__all__ = ["REPORT_RESAMPLES", "report_intervals", "interval_problem"]

#: resamples of a report's intervals (1,024 configs x 1,000 resamples: ~4 s on 2 cores)
REPORT_RESAMPLES = 1000


def interval_problem(df: pd.DataFrame, objective: str) -> str | None:
    """Why a report gives no interval for this table and objective (None: it does)."""
    if objective in AB3DMOT_COLUMNS:
        return f"{objective} is AB3DMOT's (not a sum over sequences)"
    if RAW_COLUMN not in df.columns:
        return f"the table has no {RAW_COLUMN!r} column (sweep(..., raw=True))"
    return None


def report_intervals(df: pd.DataFrame, objective: str, baseline_config: int | None = None,
                     resamples: int = REPORT_RESAMPLES, seed: int = 0, level: float = 0.95) -> dict:
    """Intervals of one class's table ``df`` (its per-sequence rows and COMBINED rows) for ``objective``.

    Returns {resamples, seed, level, best_config, not_distinguishable: [configs, best first then by
    objective], and with ``baseline_config``: best_minus_baseline [low, high], p_best_better}."""
    comb, names, _, arrays = per_sequence_arrays(df)
    sign = objective_direction(objective)
    counts = counts_of(resample_indices(len(names), resamples, seed), len(names))
    fig = resampled_figure(arrays, counts, objective)                 # [C, R]
    values = comb[objective].to_numpy(np.float64)
    best = int(rank_configs(values, objective)[0])                     # the report's best
    lo_q = (1 - level) / 2
    margin = sign * (fig[best][None] - fig)                             # > 0: the best is better
    tied = np.quantile(margin, lo_q, axis=1) <= 0
    order = np.flatnonzero(tied)[np.argsort(-sign * values[tied], kind="stable")]
    out = {"resamples": int(resamples), "seed": int(seed), "level": level,
           "best_config": int(comb.at[best, "config"]),
           "not_distinguishable": [int(c) for c in comb["config"].to_numpy()[order]]}
    if baseline_config is not None:
        b = int(np.flatnonzero(comb["config"].to_numpy() == baseline_config)[0])
        d = fig[best] - fig[b]
        better = sign * d
        out["best_minus_baseline"] = [float(np.quantile(d, lo_q)), float(np.quantile(d, 1 - lo_q))]
        out["p_best_better"] = float(np.mean(better > 0) + 0.5 * np.mean(better == 0))
    return out
