"""The ``dfrmot sweep`` parser, apart from the command (:mod:`dfrmot_jax.cli.sweep`), which is imported
when it runs (``errors.run_later``): ``dfrmot sweep --help`` imports no sweep."""

from __future__ import annotations

import argparse

from .args import add_backend_arguments
from .commands import FAMILIES, HELP, OBJECTIVES
from .errors import run_later

__all__ = ["add_parser"]


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``sweep`` on an argparse ``subparsers`` object; returns its parser."""
    p = sub.add_parser(
        "sweep", help=HELP["sweep"],
        description=f"Expand a sweep file (sweeps/*.toml; tracker family {FAMILIES}, picked by [options] "
                    f"family) into configs, track and score them in chunks "
                    "(one compilation per static option value), append each finished chunk to Parquet under "
                    "--out; a rerun skips finished chunks. The result is one tidy table: one row per "
                    "(config, sequence) plus a COMBINED row per config (OUT/results.parquet). Exit status 2: "
                    "bad sweep file, data or arguments (nothing was run); 3: some config overflowed its track "
                    "memory.")
    p.add_argument("file", metavar="FILE", help="sweep file (TOML; see sweeps/README.md)")
    p.add_argument("--out", metavar="DIR", help="result directory (default: results/sweeps/<name>)")
    p.add_argument("--data", metavar="ROOT", help="KITTI tracking training root (overrides the file and $DFRMOT_DATA)")
    p.add_argument("--chunk", type=int, help="configs per chunk (overrides the file)")
    p.add_argument("--folds", type=int, help="k-fold cross-validation over sequences in the report (k >= 2)")
    p.add_argument("--summary", action="store_true", help="print the report when the sweep is done")
    p.add_argument("--objective", help=f"report objective (default: the file's, else HOTA): {OBJECTIVES}")
    p.add_argument("--top", type=int, help="configs listed in the report (default 10)")
    p.add_argument("--class", dest="cls", metavar="CLASS",
                   help="report on one class of the sweep, or 'average' (default for several classes: the "
                        "class average; else the file's report.class)")
    add_backend_arguments(p)
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--dry-run", action="store_true", help="check the file and data, print the plan, run nothing")
    p.add_argument("--force", action="store_true",
                   help="--out holds another sweep: delete its chunks and results and run this one (without it: "
                        "refused)")
    p.add_argument("--max-configs", type=int, metavar="N",
                   help="refuse sweeps of more configs, before expanding them (default 250,000)")
    p.add_argument("--max-memory", type=float, metavar="GB",
                   help="refuse chunks whose tracker output (configs x frames x track slots) would exceed this "
                        "(default 2 GB)")
    p.set_defaults(func=run_later("dfrmot_jax.cli.sweep"))
    return p
