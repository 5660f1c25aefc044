"""The ``dfrmot tune`` parser, apart from the command (:mod:`dfrmot_jax.cli.tune`), which is imported
when it runs (``errors.run_later``): ``dfrmot tune --help`` imports no tuner (nor Optuna)."""

from __future__ import annotations

import argparse

from ..choices import SAMPLERS
from .args import add_backend_arguments
from .commands import FAMILIES, HELP
from .errors import run_later

__all__ = ["add_parser"]


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``tune`` on an argparse ``subparsers`` object; returns its parser."""
    p = sub.add_parser(
        "tune", help=HELP["tune"],
        description=f"Search the [params] / [options] of a tune file (a sweep file with a [tune] table; tracker "
                    f"family {FAMILIES}, picked by [options] family) with an "
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
    p.set_defaults(func=run_later("dfrmot_jax.cli.tune"))
    return p
