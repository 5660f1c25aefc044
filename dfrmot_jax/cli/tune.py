"""``dfrmot tune``: batched Optuna search over a tune file, resumable, with nested cross-validation.

Usage::

    dfrmot tune sweeps/kitti_tune.toml --out results/tune [--sampler tpe] [--budget 256] [--batch 128]
                [--folds 5] [--seed 0] [--refine-steps 8] [--force]

Prints the best config, its in-sample figure beside the baseline's and (with folds) the nested
cross-validated one; the last line is one JSON object. Exit status 0 ok, 2 bad file / data /
arguments, 3 some config overflowed its track memory.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ..tuning import load_tune, run_tune
from ..tuning.settings import SAMPLERS
from .backend import add_backend_arguments, backend_from
from .commands import HELP
from .errors import guarded

__all__ = ["add_parser", "run"]


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``tune`` on an argparse ``subparsers`` object; returns its parser."""
    p = sub.add_parser(
        "tune", help=HELP["tune"],
        description="Search the [params] / [options] of a tune file (a sweep file with a [tune] table) with an "
                    "Optuna sampler, each batch of trials tracked and scored in one vmapped call; the study lives "
                    "in --out (a rerun resumes). With --folds, nested cross-validation: the tune runs per fold "
                    "on the training sequences and each chosen config is scored on its held-out fold.")
    p.add_argument("file", metavar="FILE", help="tune file (TOML: a sweep file with a [tune] table; sweeps/README.md)")
    p.add_argument("--out", metavar="DIR", help="tune directory (default: results/tunes/<name>)")
    p.add_argument("--data", metavar="ROOT", help="KITTI tracking training root (overrides the file and $DFRMOT_DATA)")
    p.add_argument("--sampler", choices=SAMPLERS, help="overrides tune.sampler")
    p.add_argument("--budget", type=int, help="configs evaluated (overrides tune.budget)")
    p.add_argument("--batch", type=int, help="configs per ask, one batched call (overrides tune.batch)")
    p.add_argument("--folds", type=int, help="nested cross-validation over sequences (overrides tune.folds)")
    p.add_argument("--seed", type=int, help="overrides tune.seed")
    p.add_argument("--refine-steps", type=int, metavar="N", help="gradient refinement steps (0: none)")
    add_backend_arguments(p)
    p.add_argument("--force", action="store_true", help="replace a different tune's (or a sweep's) --out")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=guarded(run))
    return p


def _positive(name: str, v, minimum: int = 1):
    if v is not None and v < minimum:
        raise ValueError(f"--{name} {v}: expected a whole number >= {minimum}")


def run(args) -> int:
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
