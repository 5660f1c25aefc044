"""``dfrmot sweep``: run a declarative sweep file (tracking + metrics for every config), resumable.

Usage::

    dfrmot sweep sweeps/kitti_dfr_grid.toml --out results/grid [--folds 5] [--summary]

Exit status: 0 ok, 2 bad sweep file / data / arguments / output directory (a full disk, a
directory of another sweep without ``--force``; nothing was run, or the finished chunks are kept),
3 some config overflowed its track memory (the ``overflow`` column says which).
"""

from __future__ import annotations

import sys
from pathlib import Path

from ..metrics.columns import canonical_objective
from ..trackers.protocol import DEFAULT_FAMILY
from ..table_columns import option_names
from ..sweep import class_columns, load_spec, n_settings, prepare_sweep, run_sweep, sweep_report
from .backend import backend_from

__all__ = ["run"]


def run(args) -> int:
    """Run ``sweep`` for parsed ``args`` (``--dry-run``: print the plan, run nothing): 0, 3 when a config
    overflowed its track memory, or raises."""
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
        groups = table.groupby(list(option_names(spec.family)), sort=False).size().rename("configs")
        frames = sum(sum(d.lengths) for d in datas)
        if len(datas) == 1:
            where = f"{len(datas[0].sequences)} sequences / {frames:,} frames"
        else:
            where = "classes " + ", ".join(f"{d.cls} ({len(d.sequences)} sequences / {sum(d.lengths):,} frames)"
                                           for d in datas)
        family = "" if spec.family == DEFAULT_FAMILY else f" of tracker family {spec.family!r}"
        print(f"sweep {spec.name}{family}: {len(table):,} configs, {len(groups)} option group(s), {len(chunks)} "
              f"chunks, {where} ({len(table) * frames / 1e6:.1f} M config-frames) -> {out}")
        if class_columns(table.columns, spec.family):
            print(f"per-class columns: {', '.join(class_columns(table.columns, spec.family))}")
        print(groups.to_string())
        if spec.distortion is not None:
            d = spec.distortion
            print(f"distortion: {n_settings(table, spec.family)} settings x {d.n_lanes} lanes (level 0 once, undistorted; "
                  f"{len(d.seeds)} seeds per nonzero level): "
                  + "; ".join(f"{k} {', '.join(f'{v:g}' for v in lv)}" for k, lv in d.kinds))
        return 0
    df = run_sweep(spec, out, data_root=args.data, chunk=args.chunk, folds=args.folds,
                   progress=not args.no_progress, backend=backend, max_configs=args.max_configs,
                   max_memory=args.max_memory, force=args.force)
    print(f"{df['config'].nunique():,} configs x {df['sequence'].nunique() - 1} sequences -> "
          f"{out / 'results.parquet'}")
    if args.summary:
        rep = sweep_report(out, objective=args.objective or spec.objective,
                           folds=args.folds if args.folds is not None else spec.folds, top=spec.top if args.top is None else args.top,
                           contrast=spec.contrast, cls=args.cls or spec.report_class, family=spec.family)
        print(rep.text)
    over = df[(df["sequence"] == "COMBINED") & (df["overflow"] > 0)]
    if len(over):
        print(f"warning: {len(over)} config(s) overflowed their track memory (column 'overflow'); "
              f"set options.capacity", file=sys.stderr)
        return 3
    return 0
