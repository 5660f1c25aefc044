"""``sampler = "pairwise"``: a batched model-based sampler for finite spaces (lists, grids, options,
variants) that fits the objective as main effects + pairwise interactions of the settings and asks
for the best predicted configs not yet evaluated.

The first ``n_startup`` trials (the first batch) are random draws. After that, every ask fits a ridge
regression of the completed trials' objective on the effect-coded settings (a level of a k-level
setting is k - 1 columns: indicators, the last level -1 in all of them; two levels: +-1) and their
pairwise products, and returns the point of the space with the best prediction that no trial
(completed, running or failed) holds yet. Asked in a batch, the running trials carry no value, so the
fit is the same for the whole batch and the batch is the top predicted configs: one model per batch,
as the batched tune asks.

Why by hand: Optuna has no surrogate for categorical spaces that models interactions (TPE's
multivariate Parzen estimators put mass on good regions; its ``GPSampler`` needs PyTorch), and the
model is a closed-form ridge solve of a few hundred columns (NumPy); the sampler is an Optuna
``BaseSampler``, so a study, the journal storage, resume and the batched ask / tell are Optuna's.
Meant for spaces like a sweep grid: on the 1,024-config KITTI grid every fold's training optimum was
found within 256 configs in 13 of 15 replayed seeds x batch sizes, where batched TPE over the same
points often settled on a near tie (5 of 15; ``benchmarks/RESULTS.md``, "Tuning").
"""

from __future__ import annotations

import itertools
from typing import Any, Sequence

import numpy as np
import optuna
from optuna.distributions import CategoricalDistribution, IntDistribution
from optuna.trial import TrialState

#: the most points a finite space may have (the sampler scores every one of them per ask)
MAX_POINTS = 200_000


def _effect_codes(n_levels: int) -> np.ndarray:
    """[L, L - 1]: level i < L - 1 -> unit vector i, the last level -> all -1 (two levels: +1 / -1)."""
    if n_levels == 1:
        return np.zeros((1, 0))
    return np.concatenate([np.eye(n_levels - 1), -np.ones((1, n_levels - 1))])


def design_matrix(levels: np.ndarray, sizes: Sequence[int]) -> np.ndarray:
    """Features [P, 1 + main + pairwise] of points ``levels`` [P, D] (level index of each setting)."""
    mains = [_effect_codes(k)[levels[:, d]] for d, k in enumerate(sizes)]
    cols = [np.ones((len(levels), 1))] + mains
    for a, b in itertools.combinations(range(len(sizes)), 2):
        cols.append((mains[a][:, :, None] * mains[b][:, None, :]).reshape(len(levels), -1))
    return np.concatenate(cols, axis=1)


def ridge_fit(x: np.ndarray, y: np.ndarray, lam: float) -> np.ndarray:
    """Coefficients of ridge regression of centred ``y`` [n] on ``x`` [n, F] (F may exceed n)."""
    return np.linalg.solve(x.T @ x + lam * np.eye(x.shape[1]), x.T @ (y - y.mean()))


def pairwise_sampler(distributions: dict, seed: int, n_startup: int, lam: float = 1.0):
    """An Optuna sampler over ``distributions`` (all categorical or integer, at most ``MAX_POINTS``
    points) as the module docstring says; ``n_startup`` random trials first; ridge penalty ``lam``."""
    names = list(distributions)
    choices: list[list[Any]] = []
    for n in names:
        d = distributions[n]
        if isinstance(d, CategoricalDistribution):
            choices.append(list(d.choices))
        elif isinstance(d, IntDistribution):
            choices.append(list(range(d.low, d.high + 1, d.step)))
        else:
            raise ValueError(f"sampler \"pairwise\" needs lists, grids or integer ranges, not {n!r} ({d})")
    sizes = [len(c) for c in choices]
    if int(np.prod(sizes, dtype=np.float64)) > MAX_POINTS:
        raise ValueError(f"sampler \"pairwise\" scores every point of the space: {int(np.prod(sizes)):,} > "
                         f"{MAX_POINTS:,}")
    grid = np.array(list(itertools.product(*[range(k) for k in sizes])), dtype=np.int64).reshape(-1, len(sizes))
    features = design_matrix(grid, sizes)
    strides = np.cumprod([1] + sizes[:0:-1])[::-1]               # point index of a level vector

    def index_of(params: dict) -> int | None:
        try:
            return int(sum(choices[d].index(params[n]) * strides[d] for d, n in enumerate(names)))
        except (KeyError, ValueError):
            return None

    class PairwiseSampler(optuna.samplers.BaseSampler):
        def __init__(self):
            self._random = optuna.samplers.RandomSampler(seed=seed)

        def infer_relative_search_space(self, study, trial):
            return dict(distributions)

        def sample_relative(self, study, trial, search_space):
            trials = study.get_trials(deepcopy=False)
            done = [t for t in trials if t.state == TrialState.COMPLETE]
            if len(done) < n_startup:
                return {}
            taken = np.zeros(len(grid), bool)
            for t in trials:
                if t.number != trial.number:
                    i = index_of(t.params)
                    if i is not None:
                        taken[i] = True
            if taken.all():
                return {}
            rows = [index_of(t.params) for t in done]
            keep = [k for k, i in enumerate(rows) if i is not None]
            sign = 1.0 if study.directions[0] == optuna.study.StudyDirection.MAXIMIZE else -1.0
            y = sign * np.array([done[k].values[0] for k in keep])
            coef = ridge_fit(features[[rows[k] for k in keep]], y, lam)
            pred = features @ coef
            pred[taken] = -np.inf
            best = grid[int(np.argmax(pred))]
            return {n: choices[d][best[d]] for d, n in enumerate(names)}

        def sample_independent(self, study, trial, param_name, param_distribution):
            return self._random.sample_independent(study, trial, param_name, param_distribution)

    return PairwiseSampler()
