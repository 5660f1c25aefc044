"""Nested cross-validation of a tune: the tuner sees only the training folds.

For each of the k folds (:func:`dfrmot_jax.sweep.make_folds`, stratified by frame count) the whole
tune (search, refinement) runs on the other folds' sequences (``DIR/fold_F``) and its chosen
config is scored on the held-out fold. The configs chosen without them score every sequence in
one batched call (``DIR/heldout``); ``cross_validated`` is the objective over all sequences with
each sequence tracked by the config chosen without it (TrackEval's combination of sequences,
directly comparable to a config's COMBINED), beside the baseline's figure on the same sequences.
An AB3DMOT objective (``sAMOTA`` ...) is not a sum over sequences: its held-out figures are scored
on each set of sequences at once (:mod:`dfrmot_jax.tuning.composite`).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from ..metrics.samota.table import AB3DMOT_COLUMNS
from ..report.analysis import make_folds, per_sequence_arrays, pooled_objective
from .composite import ab3dmot_held_out
from .once import tune_once
from .space import SearchSpace
from .study import Evaluator


def nested_cv(spec, settings, space: SearchSpace, data, outdir: Path | None, data_root, backend, progress,
              log) -> dict:
    """Run the k inner tunes and the held-out scoring; returns the figures and per-fold details."""
    k = settings.folds
    names, lengths = list(data.sequences), list(data.lengths)
    folds = make_folds(names, lengths, k)
    inner = replace(settings, folds=None)
    objective = settings.objectives[0]
    chosen, per_fold = [], []
    for f, test in enumerate(folds):
        train = [s for s in names if s not in test]
        log(f"tune {spec.name}: nested fold {f + 1}/{k}: tuning on {len(train)} sequences, holding out "
            f"{', '.join(test)}")
        sub = None if outdir is None else outdir / f"fold_{f}"
        if sub is not None:
            sub.mkdir(parents=True, exist_ok=True)
        r = tune_once(replace(spec, sequences=tuple(train)), inner, space, sub, data_root, backend, progress, log)
        chosen.append(r.best)
        per_fold.append({"fold": f, "test_sequences": test, "train": r.best_value, "config": r.best})
    ev = Evaluator(spec, space, inner, None if outdir is None else outdir / "heldout", data_root, backend, log)
    base = space.baseline_values()
    configs = chosen + [base]
    ev.run("all", configs, [False] * k + [True], list(range(k + 1)), "heldout", 0)
    table = space.table([space.row(c) for c in configs], [False] * k + [True])
    hashes = list(table["config_hash"])
    if objective in AB3DMOT_COLUMNS:        # not a sum over sequences: scored on each set of rows at once
        out = ab3dmot_held_out(data, table, folds, spec.ab3dmot, objective, spec.ab3dmot_columns, spec.ab3dmot_sum,
                               spec.family)
    else:
        out = held_out_scores(ev.table(), folds, hashes[:k], hashes[k], objective)
    for p, q in zip(per_fold, out.pop("per_fold")):
        p.update(q)
    return {"objective": objective, "folds": k, "fold_sequences": folds, **out, "per_fold": per_fold}


def held_out_scores(df, folds, chosen: list[str], baseline: str | None, objective: str) -> dict:
    """Held-out figures from a table scoring (at least) the chosen configs on every sequence.

    ``chosen[f]``: the config_hash chosen without fold ``f``; ``baseline``: the baseline's hash.
    Returns ``cross_validated`` (all sequences, each with its fold's choice; TrackEval's combination
    of sequences), ``baseline`` (the same sequences with the baseline), ``mean_held_out`` and
    per fold ``held_out`` / ``baseline_held_out``."""
    comb, seq_names, _, arrays = per_sequence_arrays(df)
    row_of = {h: i for i, h in enumerate(comb["config_hash"])}

    def score(cfg_of_seq, cols) -> float:
        return pooled_objective(arrays, cfg_of_seq, cols, objective)

    assign = np.zeros(len(seq_names), np.int64)
    per_fold = []
    for f, test in enumerate(folds):
        cols = [seq_names.index(s) for s in test]
        assign[cols] = row_of[chosen[f]]
        q = {"held_out": score(np.full(len(cols), row_of[chosen[f]]), cols)}
        if baseline is not None:
            q["baseline_held_out"] = score(np.full(len(cols), row_of[baseline]), cols)
        per_fold.append(q)
    everything = list(range(len(seq_names)))
    return {"cross_validated": score(assign, everything),
            "baseline": None if baseline is None else score(np.full(len(seq_names), row_of[baseline]), everything),
            "mean_held_out": float(np.mean([q["held_out"] for q in per_fold])), "per_fold": per_fold}
