"""Tuning (``dfrmot tune``, ``dfrmot_jax.tune(...)`` = :func:`run_tune`): batched Optuna search, optax gradient refinement and Kalman noise by maximum likelihood.

The pipeline::

    load_tune(FILE) ─▶ (SweepSpec, TuneSettings): a sweep file's [data] [baseline] [params] [options]
        plus a [tune] table (sampler, budget, batch, objectives, folds, seed, refine)
    search_space() ─▶ the axes as Optuna distributions (uniform, loguniform, randint, categorical)
    search() ─▶ per batch: ask ``batch`` trials (sampler seeded by (seed, batch); the baseline is
        trial 0) ─▶ ONE sweep call on their config table (vmapped track + score, option groups
        compiled once) ─▶ tell; the study lives in DIR/journal.log (Optuna JournalStorage)
    refine() ─▶ optax adam on the Gaussian-smoothed objective, antithetic estimates, one call a step
    nested_cv() ─▶ the same tune per fold on the training sequences, chosen configs scored held out

Modules: :mod:`.settings` (the [tune] table), :mod:`.space` (distributions, config tables,
unconstrained coordinates), :mod:`.study` (batched ask/tell, resume), :mod:`.gradient`
(estimator, refinement), :mod:`.nested`, :mod:`.run` (``run_tune``), :mod:`.plots`.
DFR-FastMOT's Kalman noise by maximum likelihood is its family's own
(:mod:`dfrmot_jax.trackers.dfr.kalman_noise`).
"""

from .run import TuneResult, run_tune
from .settings import RefineSettings, TuneSettings, load_tune, parse_tune
from .space import SearchSpace, search_space

__all__ = ["TuneResult", "run_tune", "RefineSettings", "TuneSettings", "load_tune", "parse_tune", "SearchSpace",
           "search_space"]
