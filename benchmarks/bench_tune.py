"""Search methods at equal budgets, judged by nested cross-validation on KITTI car (RRC + PointRCNN).

For each method and each budget n (evaluated configs) the 5-fold cross-validated best HOTA: every
held-out fold is scored with the config the method chose from its first n configs using only the
other folds' sequences.

* grid:   the 1,024-config grid (``sweeps/kitti_dfr_grid.toml``), n configs subsampled (seeded, the
          baseline always in); selection per fold on the training sequences' rows of the one table.
* random: n random draws from the tune space (``sweeps/kitti_tune.toml``), one table as for grid
          (random draws do not depend on scores, so one table serves every fold honestly).
* tpe, cmaes: batched Optuna search (batches of ``--batch``), run once per fold on the training
          sequences only (``DIR/<method>/fold_F``, resumable); at budget n the best of the fold's
          first n trials by the training objective is its choice.
* tpe+refine: tpe's choice at n - R followed by gradient refinement (R evaluations: ``--refine-steps``
          steps of 2 x ``--pairs`` samples + the centre) on the same training sequences.
* tpe-grid, pairwise-grid: batched TPE / the pairwise-interaction sampler (``tuning.pairwise``) over
          the grid's own 1,024 points (``kitti_dfr_grid.toml`` as a tune file: its two-level axes
          categorical, its gain variants one ``variant`` dim), batches of ``--grid-batch``,
          once per fold on the training sequences (``--grid-budget`` distinct configs: the tune refuses
          re-proposals of evaluated configs). ``--replay-seeds K`` replays the same search (the tune's
          own ``search`` loop) for seeds 0..K-1 and batches 16 / 32 / 64 with the objective read from
          the scored grid table (the values a tune computes for those configs), and checks that the
          replay of the run's seed and batch asks exactly the run's trials.

The chosen configs of every method, budget and fold are scored on every sequence in one batched
call. The last line is one JSON object: ``cv_best`` (best cross-validated HOTA of any method and
budget), ``evals_to_grid_cv_best`` (fewest evaluated configs with which a model-based method (tpe,
cmaes, tpe+refine, tpe-grid, pairwise-grid) reached the full grid's cross-validated best; null if
never), ``curves`` ({method: {n: cv}}), ``grid_space_replay`` (every replayed seed and batch),
``seconds`` per method, machine and load.

    python benchmarks/bench_tune.py [--work DIR] [--budgets 64,128,256,512,1024] [--adaptive-max 512]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from machine import machine_info

HERE = Path(__file__).resolve().parent
GRID = HERE.parent / "sweeps" / "kitti_dfr_grid.toml"
SPACE = HERE.parent / "sweeps" / "kitti_tune.toml"
MODEL_BASED = ("tpe", "cmaes", "tpe+refine", "tpe-grid", "pairwise-grid")


def _subsample_cv(df, n: int, folds: int, seed: int) -> tuple[float, float]:
    """(cross-validated best, in-sample best) of n configs of a table (the baseline always in)."""
    from dfrmot_jax.sweep import cross_validate

    configs = df["config"].unique()
    base = int(df.loc[df["baseline"], "config"].iloc[0])
    rest = np.setdiff1d(configs, [base])
    pick = np.concatenate([[base], np.random.default_rng(seed).permutation(rest)[:n - 1]])
    sub = df[df["config"].isin(pick)]
    cv = cross_validate(sub, folds, "HOTA")
    return cv["cross_validated"], float(sub.loc[sub["sequence"] == "COMBINED", "HOTA"].max())


def _distinct_cut(hashes, n: int) -> int:
    """How many trials (in order) it takes to evaluate n distinct configs (all of them if fewer)."""
    _, first = np.unique(np.asarray(hashes), return_index=True)
    first = np.sort(first)
    return int(first[n - 1]) + 1 if len(first) >= n else len(hashes)


def _replay_on_grid(grid, spec, space, folds, sampler: str, batch: int, seed: int, budget: int, budgets) -> dict:
    """The tune's own batched search (``tuning.study.search``) over the grid's points, per fold, with
    the training objective read from the scored grid table instead of tracking; returns the trials'
    params per fold, the cross-validated best at each budget and the distinct configs each fold
    needed to reach its training optimum (None: not within ``budget``)."""
    from dfrmot_jax.report.analysis import objective_on, per_sequence_arrays, pooled_objective
    from dfrmot_jax.tuning.settings import TuneSettings
    from dfrmot_jax.tuning.study import Evaluator, search, trials_frame

    comb, names, _, arrays = per_sequence_arrays(grid)
    row_of = {h: i for i, h in enumerate(comb["config_hash"])}

    class Lookup(Evaluator):
        def run(self, name, values, baseline, trials, phase, batch):
            hs = [self.space.config_hash(v) for v in values]
            self.rows.update(dict.fromkeys(hs))
            return np.array([[self.score[row_of[h]]] for h in hs])

    settings = TuneSettings(sampler=sampler, batch=batch, seed=seed, budget=budget)
    asked, reach, chosen = [], [], {n: np.zeros(len(names), np.int64) for n in budgets}
    for test in folds:
        te = [names.index(q) for q in test]
        ev = Lookup(spec, space, settings, None)
        ev.score = objective_on(arrays, [i for i in range(len(names)) if i not in te], "HOTA")
        t = trials_frame(search(spec, settings, None, ev, False, lambda m: None), settings)
        params = [{d.name: p[d.name] for d in space.dims} for p in t.to_dict("records")]
        rows = np.array([row_of[space.config_hash(p)] for p in params])
        asked.append(params)
        best = np.flatnonzero(ev.score[rows] == ev.score.max())
        reach.append(None if not best.size else len(np.unique(rows[:best[0] + 1])))
        for n in budgets:
            h = rows[:_distinct_cut(rows, n)]
            chosen[n][te] = h[np.argmax(ev.score[h])]
    cv = {n: pooled_objective(arrays, chosen[n], range(len(names)), "HOTA") for n in budgets}
    return {"asked": asked, "cv": cv, "distinct_to_train_best": reach}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--work", default=str(HERE / ".cache" / "tune"), help="resumable work directory")
    ap.add_argument("--space", default=str(SPACE), help="tune file of random / tpe / cmaes (default kitti_tune.toml)")
    ap.add_argument("--budgets", default="64,128,256,512,1024")
    ap.add_argument("--adaptive-max", type=int, default=1024, help="largest budget run for tpe / cmaes")
    ap.add_argument("--batch", type=int, default=64)
    ap.add_argument("--folds", type=int, default=5)
    ap.add_argument("--refine-steps", type=int, default=6)
    ap.add_argument("--pairs", type=int, default=6)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--grid-batch", type=int, default=32, help="tpe-grid / pairwise-grid: configs per ask")
    ap.add_argument("--grid-budget", type=int, default=256, help="tpe-grid / pairwise-grid: configs per fold")
    ap.add_argument("--replay-seeds", type=int, default=5, help="*-grid: seeds replayed on the grid table")
    ap.add_argument("--methods", default="grid,random,tpe,cmaes,tpe+refine,tpe-grid,pairwise-grid")
    args = ap.parse_args(argv)

    from dfrmot_jax.paths import data_available, default_data_root
    from dfrmot_jax.sweep import cross_validate, load_spec, make_folds, resolve_data, run_sweep
    from dfrmot_jax.tuning import load_tune, search_space
    from dfrmot_jax.tuning.gradient import refine
    from dfrmot_jax.tuning.nested import held_out_scores
    from dfrmot_jax.tuning.run import tune_once
    from dfrmot_jax.tuning.settings import RefineSettings
    from dfrmot_jax.tuning.study import Evaluator

    machine = machine_info()
    if not data_available(default_data_root()):
        print(json.dumps({"skipped": "no KITTI data", **machine}))
        return 0
    budgets = [int(b) for b in args.budgets.split(",")]
    methods = args.methods.split(",")
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    log = lambda m: None                                                        # noqa: E731
    load0 = os.getloadavg()[0]
    curves: dict[str, dict[int, float]] = {}
    in_sample: dict[str, dict[int, float]] = {}
    seconds: dict[str, float] = {}

    spec, settings = load_tune(args.space)
    settings = replace(settings, batch=args.batch, seed=args.seed)
    space = search_space(spec)
    data = resolve_data(spec)
    folds = make_folds(list(data.sequences), list(data.lengths), args.folds)

    if "grid" in methods:
        t0 = time.perf_counter()
        grid = run_sweep(load_spec(GRID), work / "grid", progress=False, log=log)
        seconds["grid"] = time.perf_counter() - t0
        curves["grid"], in_sample["grid"] = {}, {}
        for n in budgets:
            curves["grid"][n], in_sample["grid"][n] = _subsample_cv(grid, min(n, grid["config"].nunique()),
                                                                    args.folds, args.seed)
        print(f"grid: {curves['grid']}", flush=True)
    if "random" in methods:
        # random draws do not depend on scores: one in-sample run serves every fold honestly
        t0 = time.perf_counter()
        r = tune_once(spec, replace(settings, sampler="random", budget=max(budgets)), space, work / "random", None,
                      None, False, log)
        seconds["random"] = time.perf_counter() - t0
        curves["random"], in_sample["random"] = {}, {}
        for n in budgets:
            sub = r.table[r.table["config"] < n]
            curves["random"][n] = cross_validate(sub, args.folds, "HOTA")["cross_validated"]
            in_sample["random"][n] = float(sub.loc[sub["sequence"] == "COMBINED", "HOTA"].max())
        print(f"random: {curves['random']}", flush=True)

    chosen: dict[tuple[str, int], list[dict]] = {}
    adaptive = [b for b in budgets if b <= args.adaptive_max]
    for method in [m for m in methods if m in ("tpe", "cmaes")]:
        t0 = time.perf_counter()
        s = replace(settings, sampler=method, budget=max(adaptive))
        per_fold_trials = []
        for f, test in enumerate(folds):
            train = [q for q in data.sequences if q not in test]
            sub = work / method / f"fold_{f}"
            sub.mkdir(parents=True, exist_ok=True)
            r = tune_once(replace(spec, sequences=tuple(train)), s, space, sub, None, None, False, log)
            per_fold_trials.append(r)
        seconds[method] = time.perf_counter() - t0
        for n in adaptive:
            chosen[(method, n)] = []
            for r in per_fold_trials:
                t = r.trials[r.trials["trial"] < n]
                best = t.loc[t["HOTA"].idxmax()]
                chosen[(method, n)].append({d.name: best[d.name] for d in space.dims})
        if method == "tpe" and "tpe+refine" in methods:
            t0 = time.perf_counter()
            rs = RefineSettings(steps=args.refine_steps, pairs=args.pairs, sigma=0.15, learning_rate=0.1, patience=3)
            cost = args.refine_steps * (2 * args.pairs + 1)
            for n in [b for b in adaptive if b > cost]:
                chosen[("tpe+refine", n)] = []
                for f, r in enumerate(per_fold_trials):
                    t = r.trials[r.trials["trial"] < n - cost]
                    best = t.loc[t["HOTA"].idxmax()]
                    start = {d.name: best[d.name] for d in space.dims}
                    train = [q for q in data.sequences if q not in folds[f]]
                    ev = Evaluator(replace(spec, sequences=tuple(train)), space, s,
                                   work / "tpe+refine" / f"n{n}_fold_{f}", None, None, log)

                    def evaluate(configs, k, ev=ev):
                        return ev.run(f"r{k:04d}", configs, [False] * len(configs), list(range(len(configs))),
                                      "refine", k)[:, 0]

                    out = refine(evaluate, start, float(best["HOTA"]), space.dims, rs, args.seed)
                    chosen[("tpe+refine", n)].append(out.best)
            seconds["tpe+refine"] = time.perf_counter() - t0
    # chosen configs as full rows from here on (tpe-grid searches another space)
    chosen = {k: [space.row(c) for c in v] for k, v in chosen.items()}
    replay: dict = {}
    gspec, _ = load_tune(GRID)                   # the grid file as a tune space (its variants: one dim)
    gspace = search_space(gspec)
    for sampler in [m.removesuffix("-grid") for m in methods if m.endswith("-grid")]:
        method = f"{sampler}-grid"
        gs = replace(settings, sampler=sampler, batch=args.grid_batch, budget=args.grid_budget)
        t0 = time.perf_counter()
        runs = []
        for f, test in enumerate(folds):
            train = [q for q in data.sequences if q not in test]
            sub = work / f"{method}_b{args.grid_batch}" / f"fold_{f}"
            sub.mkdir(parents=True, exist_ok=True)
            runs.append(tune_once(replace(gspec, sequences=tuple(train)), gs, gspace, sub, None, None, False, log))
        seconds[method] = time.perf_counter() - t0
        for n in [b for b in budgets if b <= args.grid_budget]:
            chosen[(method, n)] = []
            for r in runs:
                t = r.trials.sort_values("trial")
                t = t.iloc[:_distinct_cut([gspace.config_hash(p) for p in t.to_dict("records")], n)]
                chosen[(method, n)].append(gspace.row(t.loc[t["HOTA"].idxmax()].to_dict()))
        if "grid" in methods and args.replay_seeds:
            for b in (16, 32, 64):
                for sd in range(args.replay_seeds):
                    replay[(method, b, sd)] = _replay_on_grid(grid, gspec, gspace, folds, sampler, b, sd,
                                                              args.grid_budget,
                                                              [x for x in budgets if x <= args.grid_budget])
            mine = replay[(method, args.grid_batch, args.seed)]
            run_params = [[{d.name: p[d.name] for d in gspace.dims} for p in
                           r.trials.sort_values("trial").to_dict("records")] for r in runs]
            replay[(method, "matches_run")] = mine["asked"] == run_params
    if chosen:
        keys = list(chosen)
        rows = [c for k in keys for c in chosen[k]] + [space.fixed]
        flags = [False] * (len(rows) - 1) + [True]
        need = space.table(rows, flags)
        hashes = list(need["config_hash"])
        need = need.drop_duplicates("config_hash").reset_index(drop=True)
        need["config"] = np.arange(len(need), dtype=np.int64)
        # one directory per set of chosen configs: a rerun with other methods or budgets does not meet
        # another set's store (which would refuse it), an identical rerun reads its chunks back
        key = hashlib.sha1(" ".join(need["config_hash"]).encode()).hexdigest()[:12]
        table = run_sweep(spec, work / "heldout_rows" / key, table=need, progress=False, log=log)
        for i, (method, n) in enumerate(keys):
            hs = hashes[i * args.folds:(i + 1) * args.folds]
            curves.setdefault(method, {})[n] = held_out_scores(table, folds, hs, hashes[-1], "HOTA")["cross_validated"]
    grid_best = curves.get("grid", {}).get(1024)
    reached = [n for m in MODEL_BASED for n, v in curves.get(m, {}).items()
               if grid_best is not None and v >= grid_best - 1e-9]
    cv_best = max(v for c in curves.values() for v in c.values())
    replay_out = None
    if replay:
        grid_cv = curves["grid"][1024]
        replay_out = {"budget": args.grid_budget, "runs": []}
        for key, r in sorted(replay.items(), key=str):
            if key[1] == "matches_run":
                replay_out[f"{key[0]}_matches_run"] = r
                continue
            hit_at = min((n for n, v in sorted(r["cv"].items()) if v >= grid_cv - 1e-9), default=None)
            replay_out["runs"].append({"method": key[0], "batch": key[1], "seed": key[2], "reached_at": hit_at,
                                       "cv": {str(n): v for n, v in r["cv"].items()},
                                       "distinct_to_train_best": r["distinct_to_train_best"]})
        for m in sorted({r["method"] for r in replay_out["runs"]}):
            for b in (16, 32, 64):
                hits = [r["reached_at"] for r in replay_out["runs"] if r["method"] == m and r["batch"] == b]
                print(f"replay {m} batch {b}: reaches {grid_cv:.3f} at {hits}", flush=True)
    for m, c in curves.items():
        print(f"{m:>11}: " + "  ".join(f"{n}: {v:.3f}" for n, v in sorted(c.items())), flush=True)
    print(json.dumps({"cv_best": cv_best, "grid_cv_best": grid_best,
                      "evals_to_grid_cv_best": min(reached) if reached else None,
                      "curves": {m: {str(n): v for n, v in sorted(c.items())} for m, c in curves.items()},
                      "in_sample": {m: {str(n): v for n, v in sorted(c.items())} for m, c in in_sample.items()},
                      "seconds": seconds, "grid_space_replay": replay_out, "grid_batch": args.grid_batch,
                      "space": Path(args.space).name, "batch": args.batch, "folds": args.folds, "adaptive_max": args.adaptive_max,
                      "load_before": load0, "load_after": os.getloadavg()[0], **machine}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
