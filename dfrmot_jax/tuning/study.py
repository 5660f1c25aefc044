"""Batched ask/tell: an Optuna study whose every batch of trials is ONE vmapped track + score call.

A tune directory holds::

    journal.log            the Optuna study (JournalStorage): every trial, its params and values
    batches/NNNN.json      the trials of search batch NNNN (written after they are asked)
    batches/NNNN/          the batch's configs run as a sweep (chunk files: the resume unit)
    batches/rNNNN/         refinement step NNNN, the same way
    results.parquet        the tidy table of every evaluated config (per sequence + COMBINED) with
                           ``trial``, ``phase``, ``batch``, ``sampler``; ``dfrmot report DIR`` reads it
    trials.parquet         one row per trial (duplicates of a config included) and its objectives
    manifest.json          kind "tune", the tune's identity (a different tune refuses the directory)

Resume: a rerun loads the study. Trials left RUNNING by a kill are settled first: those of a batch
whose record was written are evaluated (finished chunks are read back, not recomputed) and told;
the others (a batch killed while being asked) are failed and the batch is asked again. Every batch
asks with a sampler seeded by (seed, batch) and sees exactly the completed trials of the earlier
batches, so an interrupted tune ends with the same table as an uninterrupted one.

Repeats: a proposal whose config was evaluated already (or was asked earlier in its batch; keyed by
its ``config_hash``, which names every parameter, option and extra axis of the config: the data and
scoring are the tune's own, fixed by its folder's identity) is told
FAIL at once (user attribute ``phase`` "repeat": samplers ignore failed trials) and the sampler asks
again, so the budget buys distinct configs (samplers re-propose points of discrete spaces: batched
TPE over a 1,024-point grid re-proposed about half of its trials). After ``REPEAT_ASKS`` x batch
repeats in one batch the repeats are kept (their rows are looked up, not run).
"""

from __future__ import annotations

import json
import sys
import warnings
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import optuna
import pandas as pd
from optuna.storages import JournalStorage
from optuna.storages.journal import JournalFileBackend
from optuna.trial import TrialState
from tqdm import tqdm

from ..io.atomic import write_parquet_atomic, write_text_atomic
from ..sweep.runner import run_sweep
from ..sweep.spec import SweepSpec
from ..table_columns import COMBINED
from ..trackers.registry import family_of
from .pairwise import pairwise_sampler
from .settings import TuneSettings
from .space import SearchSpace

STUDY = "tune"
#: repeats refused per batch (times its size) before re-proposals are accepted (module docstring)
REPEAT_ASKS = 10


def make_sampler(settings: TuneSettings, space: SearchSpace, batch: int):
    """The Optuna sampler of search batch ``batch`` (seeded by (seed, batch); see the module docstring)."""
    seed = int(np.random.SeedSequence([settings.seed, batch]).generate_state(1)[0])
    name = settings.sampler
    if name == "tpe":
        return optuna.samplers.TPESampler(seed=seed, multivariate=True, constant_liar=True,
                                          n_startup_trials=min(settings.batch, 32))
    if name == "cmaes":
        return optuna.samplers.CmaEsSampler(seed=seed, popsize=settings.batch, n_startup_trials=settings.batch,
                                            warn_independent_sampling=False,
                                            independent_sampler=optuna.samplers.RandomSampler(seed=seed))
    if name == "gp":
        try:
            import torch  # noqa: F401
        except ImportError:
            raise ValueError("tune.sampler = \"gp\" needs PyTorch (Optuna's GPSampler): pip install torch, or use "
                             "\"tpe\" / \"cmaes\"") from None
        return optuna.samplers.GPSampler(seed=seed, n_startup_trials=min(settings.batch, 32),
                                         warn_independent_sampling=False)
    if name == "pairwise":
        return pairwise_sampler(space.distributions(), seed, n_startup=settings.batch)
    if name == "nsga2":
        return optuna.samplers.NSGAIISampler(seed=seed, population_size=settings.batch)
    if name == "random":
        return optuna.samplers.RandomSampler(seed=seed)
    if name == "grid":
        return BoundedGridSampler(space.grid(), seed=seed)
    raise AssertionError(name)


class BoundedGridSampler(optuna.samplers.GridSampler):
    """Optuna's grid sampler for batched ask/tell: its ``after_trial`` stops the study once the grid
    is done, which Optuna refuses outside ``study.optimize`` (RuntimeError); the tune's loop is
    bounded by its budget instead, so that step is left out."""

    def after_trial(self, study, trial, state, values) -> None:
        pass


def trial_index(settings: TuneSettings, phase: str, batch: int, slot: int, step_size: int = 1) -> int:
    """A trial's place in the tune (the ``trial`` column): search batch b's slot i is b * batch + i;
    refinement step k's slot i comes after the budget, at budget + k * step_size + i."""
    if phase == "search":
        return batch * settings.batch + slot
    return settings.budget + batch * step_size + slot


def open_study(outdir: Path | None, settings: TuneSettings):
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    warnings.filterwarnings("ignore", category=optuna.exceptions.ExperimentalWarning)
    storage = None
    if outdir is not None:
        outdir.mkdir(parents=True, exist_ok=True)
        storage = JournalStorage(JournalFileBackend(str(outdir / "journal.log")))
    return optuna.create_study(storage=storage, study_name=STUDY, directions=list(settings.directions),
                               load_if_exists=True)


@dataclass
class Evaluator:
    """Runs configs as sweeps (one call per batch) and keeps every config's rows by hash."""
    spec: SweepSpec
    space: SearchSpace
    settings: TuneSettings
    outdir: Path | None
    data_root: Any = None
    backend: Any = None                          # sweep.backend object (None: local)
    log: Any = None

    def __post_init__(self):
        self.rows: dict[str, pd.DataFrame] = {}      # config_hash -> its rows (sequences + COMBINED)
        self.first: dict[str, tuple] = {}            # config_hash -> (trial, phase, batch) of its first evaluation

    def run(self, name: str, values: Sequence[dict], baseline: Sequence[bool], trials: Sequence[int],
            phase: str, batch: int) -> np.ndarray:
        """Objective values [n, n_objectives] of configs (dicts of dim values), one batched call."""
        table = self.space.table([self.space.row(v) for v in values], baseline)
        new = table[~table["config_hash"].isin(self.rows)].drop_duplicates("config_hash")
        if len(new):
            new = new.assign(config=np.arange(len(new), dtype=np.int64)).reset_index(drop=True)
            out = None if self.outdir is None else self.outdir / "batches" / name
            df = run_sweep(self.spec, out, data_root=self.data_root, progress=False, backend=self.backend or "local",
                           log=lambda m: None, table=new)
            for h, g in df.groupby("config_hash", sort=False):
                self.rows[h] = g.reset_index(drop=True)
        out = np.zeros((len(table), len(self.settings.objectives)))
        for i, h in enumerate(table["config_hash"]):
            self.first.setdefault(h, (int(trials[i]), phase, batch))
            comb = self.rows[h]
            comb = comb[comb["sequence"] == COMBINED].iloc[0]
            out[i] = [float(comb[o]) for o in self.settings.objectives]
        return out

    def table(self) -> pd.DataFrame:
        """The tidy table: every evaluated config once (in order of first evaluation), renumbered."""
        parts = []
        for c, (h, (trial, phase, batch)) in enumerate(self.first.items()):
            g = self.rows[h].copy()
            g["config"] = np.int64(c)
            g["trial"] = np.int64(trial)
            g["phase"] = phase
            g["batch"] = np.int64(batch)
            g["sampler"] = self.settings.sampler if phase == "search" else "gradient"
            g["sweep"] = self.spec.name
            parts.append(g)
        return pd.concat(parts, ignore_index=True)


def _values_of(t) -> list:
    return list(t.values) if t.values is not None else []


def _settle(study, outdir: Path | None, ev: Evaluator, space: SearchSpace, settings: TuneSettings, log) -> None:
    """Finish or fail the trials a killed run left RUNNING (module docstring)."""
    running = [t for t in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,))]
    by_batch: dict[int, list] = {}
    for t in running:
        by_batch.setdefault(t.user_attrs.get("batch", -1), []).append(t)
    for b, ts in sorted(by_batch.items()):
        rec = _read_record(outdir, b) if b >= 0 else None
        if rec is not None:                 # written once the whole batch was asked
            log(f"tune: resuming batch {b} ({len(rec['trials'])} trials asked before the interruption)")
            _evaluate_batch(study, ev, space, settings, b, rec)
        else:
            for t in ts:
                study.tell(t.number, state=TrialState.FAIL)


def _read_record(outdir: Path | None, b: int) -> dict | None:
    if outdir is None:
        return None
    path = outdir / "batches" / f"{b:04d}.json"
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def _evaluate_batch(study, ev: Evaluator, space: SearchSpace, settings: TuneSettings, b: int, rec: dict) -> None:
    """Evaluate batch ``b``'s trials in one call and tell them; trials the tracker family knows to be
    useless (``TrackerFamily.failing_rows``; DFR-FastMOT: fixed gains that make the filter unstable,
    :func:`dfrmot_jax.trackers.dfr.family.unstable_rows`: boxes grow without bound) are told FAIL without being run:
    they do not count towards the budget (the log says how many)."""


    frozen = {t.number: t for t in study.get_trials(deepcopy=False)}
    trials = [frozen[n] for n in rec["trials"]]
    values = [t.params for t in trials]
    bad = family_of(space.family).failing_rows(space.table([space.row(v) for v in values]))
    for t, u in zip(trials, bad):
        if u and t.state == TrialState.RUNNING:
            study.tell(t.number, state=TrialState.FAIL)
    keep = [i for i in range(len(trials)) if not bad[i]]
    if bad.any() and ev.log is not None:
        ev.log(f"tune: batch {b}: {int(bad.sum())} trial(s) with unstable fixed gains failed without a run")
    if not keep:
        return
    base = [bool(trials[i].user_attrs.get("baseline", False)) for i in keep]
    index = [trial_index(settings, "search", b, i) for i in keep]
    out = ev.run(f"{b:04d}", [values[i] for i in keep], base, index, "search", b)
    for i, v in zip(keep, out):
        if trials[i].state == TrialState.RUNNING:
            study.tell(trials[i].number, list(v) if len(v) > 1 else float(v[0]))


def search(spec: SweepSpec, settings: TuneSettings, outdir: Path | None, ev: Evaluator, progress: bool, log):
    """The batched ask/tell loop until ``settings.budget`` search trials are complete."""
    space = ev.space
    dists = space.distributions()
    study = open_study(outdir, settings)
    # completed batches of an earlier run first, in order: their rows are read back (finished chunks
    # are not recomputed) and the configs are numbered as in an uninterrupted run
    done = _search_done(study)
    for b in sorted({t.user_attrs["batch"] for t in done}):
        rec = _read_record(outdir, b)
        if rec is not None:
            _evaluate_batch(study, ev, space, settings, b, rec)
    _settle(study, outdir, ev, space, settings, log)
    done = _search_done(study)
    bar = None
    if progress:
        bar = tqdm(total=settings.budget, initial=len(done), unit="cfg", desc=f"tune {spec.name}",
                   dynamic_ncols=True, file=sys.stderr)
    try:
        while len(done) < settings.budget:
            b = _next_batch(study, outdir)
            size = min(settings.batch, settings.budget - len(done))
            study.sampler = make_sampler(settings, space, b)
            trials_now = study.get_trials(deepcopy=False)
            if b == 0 and not any(t.state == TrialState.WAITING for t in trials_now):
                base = space.baseline_values()
                if space.contains(base):        # else the baseline is outside the space: not a trial
                    study.enqueue_trial(base, user_attrs={"baseline": True})
            asked = _ask_batch(study, dists, space, set(ev.rows), b, size)
            rec = {"batch": b, "trials": [t.number for t in asked], "params": [t.params for t in asked]}
            if outdir is not None:
                (outdir / "batches").mkdir(parents=True, exist_ok=True)
                write_text_atomic(outdir / "batches" / f"{b:04d}.json", json.dumps(rec, default=str), parents=False)
            _evaluate_batch(study, ev, space, settings, b, rec)
            done = _search_done(study)
            if bar is not None:
                bar.update(size)
            best = _best_text(study, settings)
            log(f"tune {spec.name}: batch {b} ({size} configs) done, {len(done)}/{settings.budget}; {best}")
    finally:
        if bar is not None:
            bar.close()
    return study


def _ask_batch(study, dists: dict, space: SearchSpace, evaluated: set, b: int, size: int) -> list:
    """``size`` trials of search batch ``b``, repeats of evaluated or already asked configs refused
    (module docstring)."""
    asked, refused = [], 0
    while len(asked) < size:
        t = study.ask(dists)
        h = space.config_hash(t.params)
        if h in evaluated and refused < REPEAT_ASKS * size:
            refused += 1
            t.set_user_attr("phase", "repeat")
            study.tell(t.number, state=TrialState.FAIL)
            continue
        evaluated.add(h)
        t.set_user_attr("batch", b)
        t.set_user_attr("slot", len(asked))
        t.set_user_attr("phase", "search")
        asked.append(t)
    return asked


def _next_batch(study, outdir: Path | None) -> int:
    """The next search batch: after the last one that was asked whole (its record written; trials of a
    batch killed while being asked were failed and that batch is asked again)."""
    asked = {t.user_attrs["batch"] for t in study.get_trials(deepcopy=False)
             if t.user_attrs.get("phase") == "search" and "batch" in t.user_attrs}
    whole = [b for b in asked if outdir is None or _read_record(outdir, b) is not None]
    return max(whole, default=-1) + 1


def _search_done(study) -> list:
    return [t for t in study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))
            if t.user_attrs.get("phase") == "search"]


def _best_text(study, settings: TuneSettings) -> str:
    if len(settings.objectives) == 1:
        t = study.best_trial
        return f"best {settings.objectives[0]} {t.value:.3f} (trial {t.number})"
    return f"Pareto front: {len(study.best_trials)} trials"


def trials_frame(study, settings: TuneSettings) -> pd.DataFrame:
    """One row per completed trial: trial (tune order), phase, batch, slot, config values, objectives."""
    rows = []
    for t in study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,)):
        a = t.user_attrs
        phase, b, slot = a.get("phase", "search"), a.get("batch", -1), a.get("slot", 0)
        rows.append({"trial": trial_index(settings, phase, b, slot, a.get("step_size", 1)), "phase": phase,
                     "batch": b, "slot": slot,
                     "baseline": bool(a.get("baseline", False)), **t.params,
                     **dict(zip(settings.objectives, _values_of(t)))})
    return pd.DataFrame(rows).sort_values("trial", kind="mergesort").reset_index(drop=True)


def write_tables(outdir: Path | None, ev: Evaluator, study, settings: TuneSettings) -> tuple[pd.DataFrame, pd.DataFrame]:
    table = ev.table()
    trials = trials_frame(study, settings)
    if outdir is not None:
        write_parquet_atomic(outdir / "results.parquet", table)
        write_parquet_atomic(outdir / "trials.parquet", trials)
    return table, trials


def replace_sequences(spec: SweepSpec, sequences: Sequence[str]) -> SweepSpec:
    return replace(spec, sequences=tuple(sequences))
