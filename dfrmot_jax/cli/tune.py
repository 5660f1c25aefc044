"""``dfrmot tune``: batched Optuna search over a tune file, resumable, with nested cross-validation.

Usage::

    dfrmot tune sweeps/kitti_tune.toml --out results/tune [--sampler tpe] [--budget 256] [--batch 128]
                [--folds 5] [--seed 0] [--refine-steps 8] [--force]

Prints the best config, its in-sample figure beside the baseline's and (with folds) the nested
cross-validated one; the last line is one JSON object. Exit status 0 ok, 2 bad file / data /
arguments, 3 some config overflowed its track memory.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from ..tuning import load_tune, run_tune
from .backend import backend_from

__all__ = ["run"]


def _positive(name: str, v, minimum: int = 1):
    if v is not None and v < minimum:
        raise ValueError(f"--{name} {v}: expected a whole number >= {minimum}")


def run(args) -> int:
    """Run ``tune`` for parsed ``args`` and print the best config: 0, 3 when a config overflowed its track
    memory, or raises."""
    for name, minimum in (("budget", 2), ("batch", 1), ("folds", 2), ("seed", 0), ("refine_steps", 0)):
        _positive(name.replace("_", "-"), getattr(args, name), minimum)
    spec, settings = load_tune(args.file)
    out = Path(args.out) if args.out else Path("results") / "tunes" / spec.name
    res = run_tune((spec, settings), out, data_root=args.data, sampler=args.sampler, budget=args.budget,
                   batch=args.batch, folds=args.folds, seed=args.seed, refine_steps=args.refine_steps,
                   progress=not args.no_progress, backend=backend_from(args), force=args.force)
    s = res.summary()
    obj = res.settings.objectives[0]
    print(f"tune {spec.name}: {s['evaluated_configs']:,} configs ({res.settings.sampler}, batches of "
          f"{res.settings.batch}) -> {out}")
    base = s.get("baseline")
    print(f"best {obj}: {s['in_sample']:.3f} in-sample " + (f"(baseline {base:.3f})" if base is not None else
                                                           "(the baseline lies outside the search space: not a trial)"))
    print("best config: " + ", ".join(f"{k} = {v:.4g}" if isinstance(v, float) else f"{k} = {v}"
                                      for k, v in res.best.items()))
    if res.nested is not None:
        n = res.nested
        print(f"nested {n['folds']}-fold cross-validated {obj}: {n['cross_validated']:.3f} (baseline "
              f"{n['baseline']:.3f} on the same sequences)")
    if len(res.settings.objectives) == 2:
        print("Pareto front:")
        print(res.pareto[["trial"] + list(res.settings.objectives)].to_string(index=False))
    print(json.dumps(s, default=str))
    over = res.table[(res.table["sequence"] == "COMBINED") & (res.table["overflow"] > 0)]
    if len(over):
        print(f"warning: {len(over)} config(s) overflowed their track memory (column 'overflow')", file=sys.stderr)
        return 3
    return 0
