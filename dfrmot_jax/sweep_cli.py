"""``dfrmot sweep`` and ``dfrmot report``: run a declarative sweep file, report its results.

Wire into an argparse CLI with::

    sub = parser.add_subparsers(dest="command")
    add_sweep_parser(sub)         # "sweep", set_defaults(func=run_sweep_command)
    add_report_parser(sub)        # "report", set_defaults(func=run_report_command)

Usage::

    dfrmot sweep sweeps/kitti_dfr_grid.toml --out results/grid [--folds 5] [--summary]
    dfrmot report results/grid [--objective HOTA|MOTA|IDF1|AssA|IDSW] [--folds 5] [--top 10]
    dfrmot report results/classes --class pedestrian      # several classes: one class, or average (default)
    dfrmot report results/robustness --contrast epsilon:30,60/1,2,3:filter    # distortion sweeps

Exit status: 0 ok, 2 bad sweep file / data / arguments (nothing was run), 3 some config overflowed
its track memory (the ``overflow`` column says which). The report's last line is one JSON object.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

__all__ = ["add_sweep_parser", "add_report_parser", "run_sweep_command", "run_report_command", "main"]


def add_sweep_parser(subparsers) -> argparse.ArgumentParser:
    """Register the ``sweep`` subcommand on an argparse ``subparsers`` object; returns its parser."""
    p = subparsers.add_parser(
        "sweep", help="run a sweep file (tracking + metrics for every config), resumable",
        description="Expand a sweep file (sweeps/*.toml) into configs, track and score them in chunks "
                    "(one compilation per static option value), append each finished chunk to Parquet under "
                    "--out; a rerun skips finished chunks. The result is one tidy table: one row per "
                    "(config, sequence) plus a COMBINED row per config (OUT/results.parquet).")
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
    p.add_argument("--workers", type=int, help="metric processes beside the tracker (default: 2 for large sweeps)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--dry-run", action="store_true", help="check the file and data, print the plan, run nothing")
    p.set_defaults(func=run_sweep_command)
    return p


def add_report_parser(subparsers) -> argparse.ArgumentParser:
    """Register the ``report`` subcommand; returns its parser."""
    p = subparsers.add_parser(
        "report", help="best configs, baseline, sensitivity and cross-validation of a sweep directory",
        description="Print the best configs of a sweep (by --objective), the baseline row beside them, how "
                    "sensitive the score is to each swept axis and, with --folds, the cross-validated best. "
                    "The last line is one JSON object.")
    p.add_argument("dir", metavar="DIR", help="a sweep result directory (dfrmot sweep --out DIR)")
    p.add_argument("--objective", help="HOTA (default), MOTA, IDF1, AssA, DetA, IDSW (minimised), ...")
    p.add_argument("--folds", type=int, help="k-fold cross-validation over sequences (default: the sweep's --folds)")
    p.add_argument("--top", type=int, help="configs listed (default 10)")
    p.add_argument("--class", dest="cls", metavar="CLASS",
                   help="sweeps over several classes: rank on one class (its own parameter values) or on "
                        "'average' (ratios averaged over the classes, counts summed; the default unless the file's "
                        "report.class says otherwise)")
    p.add_argument("--csv", metavar="F", help="also write the tidy table (without the per-alpha column) as CSV")
    p.add_argument("--contrast", metavar="AXIS:HIGH/LOW[:BY]",
                   help="distortion sweeps: the gap between two groups of an axis per level, paired by seed, e.g. "
                        "epsilon:30,60/1,2,3:filter (long minus short memory, per filter); default: the sweep "
                        "file's report.contrast")
    p.set_defaults(func=run_report_command)
    return p


def _error(cmd: str, e: Exception) -> int:
    print(f"dfrmot {cmd}: error: {e}", file=sys.stderr)
    return 2


def run_sweep_command(args) -> int:
    from .io.kitti import KittiFormatError
    from .sweep import (OPTION_NAMES, class_columns, expand, load_spec, n_settings, plan, resolve_data_all, sweep,
                        sweep_report)

    try:
        spec = load_spec(args.file)
        out = Path(args.out) if args.out else Path("results") / "sweeps" / spec.name
        if args.dry_run:
            table = expand(spec)
            datas = resolve_data_all(spec, args.data)
            chunks = plan(table, datas, args.chunk or spec.chunk, spec.distortion)
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
        df = sweep(spec, out, data_root=args.data, chunk=args.chunk, folds=args.folds,
                   progress=not args.no_progress, workers=args.workers)
        print(f"{df['config'].nunique():,} configs x {df['sequence'].nunique() - 1} sequences -> "
              f"{out / 'results.parquet'}")
        if args.summary:
            rep = sweep_report(df, objective=args.objective or spec.objective,
                               folds=args.folds if args.folds is not None else spec.folds, top=args.top or spec.top,
                               contrast=spec.contrast, cls=args.cls or spec.report_class)
            print(rep.text)
    except (KittiFormatError, ValueError, FileNotFoundError) as e:
        return _error("sweep", e)
    over = df[(df["sequence"] == "COMBINED") & (df["overflow"] > 0)]
    if len(over):
        print(f"warning: {len(over)} config(s) overflowed their track memory (column 'overflow'); "
              f"set options.capacity", file=sys.stderr)
        return 3
    return 0


def parse_contrast(text: str) -> dict:
    """``AXIS:HIGH/LOW[:BY]`` -> {axis, high, low, by}: values comma-separated (numbers or names),
    e.g. ``epsilon:30,60/1,2,3:filter``."""
    parts = text.split(":")
    if len(parts) not in (2, 3) or "/" not in parts[1]:
        raise ValueError(f"--contrast {text!r}: expected AXIS:HIGH/LOW[:BY], e.g. epsilon:30,60/1,2,3:filter")

    def values(s):
        out = []
        for v in (x.strip() for x in s.split(",") if x.strip()):
            try:
                f = float(v)
                out.append(int(f) if f.is_integer() and "." not in v else f)
            except ValueError:
                out.append(v)
        return out

    high, low = parts[1].split("/", 1)
    by = [b.strip() for b in parts[2].split(",") if b.strip()] if len(parts) == 3 else []
    return {"axis": parts[0].strip(), "high": values(high), "low": values(low), "by": by}


def run_report_command(args) -> int:
    from .sweep import RAW_COLUMN, load_results, sweep_report

    try:
        contrast = parse_contrast(args.contrast) if getattr(args, "contrast", None) else None
        rep = sweep_report(Path(args.dir), objective=args.objective or _manifest_objective(args.dir),
                           folds=args.folds, top=args.top or 10, contrast=contrast, cls=getattr(args, "cls", None))
        print(rep.text)
        if args.csv:
            df = load_results(args.dir, allow_partial=True)
            df.drop(columns=[RAW_COLUMN], errors="ignore").to_csv(args.csv, index=False)
    except (ValueError, FileNotFoundError) as e:
        return _error("report", e)
    return 0


def _manifest_objective(d) -> str:
    import json

    path = Path(d) / "manifest.json"
    try:
        return json.loads(path.read_text()).get("objective") or "HOTA"
    except (OSError, ValueError):
        return "HOTA"


def main(argv=None) -> int:
    """Standalone entry: ``python -m dfrmot_jax.sweep_cli sweep FILE ...`` / ``... report DIR``."""
    p = argparse.ArgumentParser(prog="dfrmot", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True)
    add_sweep_parser(sub)
    add_report_parser(sub)
    args = p.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
