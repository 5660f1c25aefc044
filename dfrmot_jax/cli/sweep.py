"""``dfrmot sweep``: run a declarative sweep file (tracking + metrics for every config), resumable.

Usage::

    dfrmot sweep sweeps/kitti_dfr_grid.toml --out results/grid [--folds 5] [--summary]

Exit status: 0 ok, 2 bad sweep file / data / arguments / output directory (a full disk, a
directory of another sweep without ``--force``; nothing was run, or the finished chunks are kept),
3 some config overflowed its track memory (the ``overflow`` column says which).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..metrics.columns import canonical_objective
from ..sweep import OPTION_NAMES, class_columns, load_spec, n_settings, prepare_sweep, run_sweep, sweep_report
from .backend import add_backend_arguments, backend_from
from .commands import HELP
from .errors import guarded

__all__ = ["add_parser", "run"]


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``sweep`` on an argparse ``subparsers`` object; returns its parser."""
    p = sub.add_parser(
        "sweep", help=HELP["sweep"],
        description="Expand a sweep file (sweeps/*.toml) into configs, track and score them in chunks "
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
    p.add_argument("--objective", help="report objective (default: the file's, else HOTA); IDSW etc. are minimised")
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
    p.set_defaults(func=guarded(run))
    return p


def run(args) -> int:
    if args.objective is not None:                  # before any work, not after the sweep
        args.objective = canonical_objective(args.objective)
    if args.top is not None and args.top < 1:
        raise ValueError(f"--top {args.top}: expected a whole number >= 1 (configs listed)")
    if args.max_configs is not None and args.max_configs < 1:
        raise ValueError(f"--max-configs {args.max_configs}: expected a whole number >= 1")
    if args.max_memory is not None and not args.max_memory > 0:
        raise ValueError(f"--max-memory {args.max_memory:g}: expected a number of GB > 0")
    backend = backend_from(args)
    spec = load_spec(args.file)
    out = Path(args.out) if args.out else Path("results") / "sweeps" / spec.name
    if args.dry_run:        # everything run_sweep does before any work, and what it would run
        prep = prepare_sweep(spec, data_root=args.data, chunk=args.chunk, folds=args.folds,
                             max_configs=args.max_configs, max_memory=args.max_memory)
        table, datas, chunks = prep.table, prep.datas, prep.chunks
        groups = table.groupby(list(OPTION_NAMES), sort=False).size().rename("configs")
        frames = sum(sum(d.lengths) for d in datas)
        if len(datas) == 1:
            where = f"{len(datas[0].sequences)} sequences / {frames:,} frames"
        else:
            where = "classes " + ", ".join(f"{d.cls} ({len(d.sequences)} sequences / {sum(d.lengths):,} frames)"
                                           for d in datas)
        print(f"sweep {spec.name}: {len(table):,} configs, {len(groups)} option group(s), {len(chunks)} chunks, "
              f"{where} ({len(table) * frames / 1e6:.1f} M config-frames) -> {out}")
        if class_columns(table.columns):
            print(f"per-class columns: {', '.join(class_columns(table.columns))}")
        print(groups.to_string())
        if spec.distortion is not None:
            d = spec.distortion
            print(f"distortion: {n_settings(table)} settings x {d.n_lanes} lanes (level 0 once, undistorted; "
                  f"{len(d.seeds)} seeds per nonzero level): "
                  + "; ".join(f"{k} {', '.join(f'{v:g}' for v in lv)}" for k, lv in d.kinds))
        return 0
    df = run_sweep(spec, out, data_root=args.data, chunk=args.chunk, folds=args.folds,
                   progress=not args.no_progress, backend=backend, max_configs=args.max_configs,
                   max_memory=args.max_memory, force=args.force)
    print(f"{df['config'].nunique():,} configs x {df['sequence'].nunique() - 1} sequences -> "
          f"{out / 'results.parquet'}")
    if args.summary:
        rep = sweep_report(df, objective=args.objective or spec.objective,
                           folds=args.folds if args.folds is not None else spec.folds, top=spec.top if args.top is None else args.top,
                           contrast=spec.contrast, cls=args.cls or spec.report_class)
        print(rep.text)
    over = df[(df["sequence"] == "COMBINED") & (df["overflow"] > 0)]
    if len(over):
        print(f"warning: {len(over)} config(s) overflowed their track memory (column 'overflow'); "
              f"set options.capacity", file=sys.stderr)
        return 3
    return 0
