"""One tune on one set of sequences: batched search, then the optional gradient refinement
(:func:`tune_once`), and what it returns (:class:`TuneResult`). :func:`dfrmot_jax.tuning.run.run_tune`
runs it once on the tune's sequences, :func:`dfrmot_jax.tuning.nested.nested_cv` once per fold."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import optuna
import pandas as pd
from optuna.trial import TrialState

from ..sweep.spec import SweepSpec
from ..sweep.store import jsonable
from .gradient import Refinement, refine
from .plots import pareto_front
from .settings import TuneSettings
from .space import SearchSpace
from .study import Evaluator, search, trial_index, write_tables


@dataclass
class TuneResult:
    """A finished tune: ``table`` (tidy rows of every evaluated config, ``dfrmot report`` reads the
    same from ``results.parquet``), ``trials`` (one row per trial), ``best`` (the chosen config's
    dim values) and ``best_value`` (its in-sample objective), the Optuna ``study``, the
    ``refinement`` (if any) and, with folds, ``nested`` (:func:`dfrmot_jax.tuning.nested.nested_cv`)."""
    spec: SweepSpec
    settings: TuneSettings
    table: pd.DataFrame
    trials: pd.DataFrame
    best: dict
    best_value: float
    study: Any
    refinement: Refinement | None = None
    nested: dict | None = None
    out: Path | None = None
    transfer: dict | None = None

    @property
    def pareto(self) -> pd.DataFrame:
        """The Pareto front (two objectives): the non-dominated trials, sorted by the first objective."""
        return pareto_front(self.trials, self.settings)

    def summary(self) -> dict:
        d = {"name": self.spec.name, "sampler": self.settings.sampler, "budget": self.settings.budget,
             "batch": self.settings.batch, "objectives": list(self.settings.objectives),
             "evaluated_configs": int(self.table["config"].nunique()), "best": jsonable(self.best),
             "in_sample": self.best_value}
        base = self.table[self.table["baseline"] & (self.table["sequence"] == "COMBINED")]
        if len(base):
            d["baseline"] = float(base.iloc[0][self.settings.objectives[0]])
        if self.refinement is not None:
            d["refined_steps"] = len(self.refinement.steps)
        if self.nested is not None:
            d["cross_validated"] = self.nested["cross_validated"]
            d["baseline_cross_validated"] = self.nested.get("baseline")
            d["folds"] = self.nested["folds"]
        if self.transfer is not None:
            d["transfer"] = self.transfer
        return d



def tune_once(spec: SweepSpec, settings: TuneSettings, space: SearchSpace, outdir: Path | None, data_root,
              backend, progress: bool, log) -> TuneResult:
    """Search (and refine) on ``spec``'s sequences; tables written to ``outdir``."""
    ev = Evaluator(spec, space, settings, outdir, data_root, backend, log)
    study = search(spec, settings, outdir, ev, progress, log)
    first = settings.objectives[0]
    maximize = settings.directions[0] == "maximize"
    best_t = _best_trial(study, settings)
    best, best_value = dict(best_t.params), float(best_t.values[0])
    refinement = None
    if settings.refine is not None:
        refinement = _refine(study, ev, space, settings, best, best_value, maximize, log)
        if (refinement.best_value > best_value) if maximize else (refinement.best_value < best_value):
            best, best_value = refinement.best, refinement.best_value
    table, trials = write_tables(outdir, ev, study, settings)
    log(f"tune {spec.name}: {table['config'].nunique():,} configs evaluated; best {first} {best_value:.3f}")
    return TuneResult(spec, settings, table, trials, best, best_value, study, refinement, out=outdir)


def _best_trial(study, settings: TuneSettings):
    """The best trial by the first objective (of the Pareto front with two)."""
    trials = study.best_trials if len(settings.objectives) > 1 else [study.best_trial]
    sign = -1 if settings.directions[0] == "maximize" else 1
    return min(trials, key=lambda t: (sign * t.values[0], t.number))


def _refine(study, ev: Evaluator, space: SearchSpace, settings: TuneSettings, start: dict, start_value: float,
            maximize: bool, log) -> Refinement:
    """Gradient refinement from ``start``; its evaluations become trials (phase "refine") of the study."""
    dists = space.distributions()
    r = settings.refine
    size = 2 * r.pairs + 1
    known = {(t.user_attrs.get("batch"), t.user_attrs.get("slot")) for t in study.get_trials(
        deepcopy=False, states=(TrialState.COMPLETE,)) if t.user_attrs.get("phase") == "refine"}

    def evaluate(configs, k):
        index = [trial_index(settings, "refine", k, i, size) for i in range(len(configs))]
        vals = ev.run(f"r{k:04d}", configs, [False] * len(configs), index, "refine", k)
        for i, (c, v) in enumerate(zip(configs, vals)):
            if (k, i) not in known:
                study.add_trial(optuna.trial.create_trial(
                    params={d.name: c[d.name] for d in space.dims}, distributions=dists, values=list(v),
                    user_attrs={"phase": "refine", "batch": k, "slot": i, "step_size": size}))
        return vals[:, 0]

    return refine(evaluate, start, start_value, space.dims, r, settings.seed, maximize, log)
