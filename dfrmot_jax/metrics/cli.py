"""``dfrmot eval``: TrackEval-identical KITTI evaluation of result folders from the command line.

Wire into an argparse CLI with::

    sub = parser.add_subparsers(dest="command")
    add_eval_parser(sub)          # registers "eval", set_defaults(func=run_eval)
    args = parser.parse_args(); sys.exit(args.func(args))

Usage: ``dfrmot eval RESULTS_DIR [RESULTS_DIR ...] [--data ROOT] [--class car] [--seqs 0000,0002]
[--per-seq] [--csv F]``. Prints a compact table (COMBINED per tracker; also every sequence with
``--per-seq``) and writes a CSV with one row per (tracker, sequence) plus COMBINED.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pandas as pd

__all__ = ["add_eval_parser", "run_eval", "main"]


def _tracker_name(d: Path) -> str:
    d = Path(d)
    return d.parent.name if d.name == "data" and d.parent.name else d.name


def add_eval_parser(subparsers) -> argparse.ArgumentParser:
    """Register the ``eval`` subcommand on an argparse ``subparsers`` object; returns its parser."""
    from dfrmot_jax.paths import default_data_root

    p = subparsers.add_parser(
        "eval",
        help="evaluate KITTI tracking result folders (TrackEval's KITTI 2D box HOTA/CLEAR/Identity)",
        description="Evaluate KITTI tracking results (RESULTS_DIR/SSSS.txt) exactly like TrackEval's Kitti2DBox. "
                    "A sequence without a result file counts as an empty output.",
    )
    p.add_argument("results", nargs="+", metavar="RESULTS_DIR", help="folder(s) with SSSS.txt result files")
    p.add_argument("--data", default=None, metavar="ROOT",
                   help=f"KITTI tracking training root (default: $DFRMOT_DATA or {default_data_root()})")
    p.add_argument("--class", dest="cls", default="car", choices=["car", "pedestrian"], help="class (default car)")
    p.add_argument("--seqs", default=None, help="comma-separated sequences, e.g. 0000,0002 (default: all in label_02)")
    p.add_argument("--per-seq", action="store_true", help="also print every sequence")
    p.add_argument("--csv", default=None, metavar="F", help="write all metrics, one row per (tracker, sequence)")
    p.set_defaults(func=run_eval)
    return p


def _fmt_table(df: pd.DataFrame) -> str:
    from dfrmot_jax.metrics.table import COMPACT_FIELDS, COUNT_FIELDS

    cols = [c for c in COMPACT_FIELDS if c in df.columns]
    out = df[["tracker"] + cols].copy() if "tracker" in df.columns else df[cols].copy()
    fmt = {c: (lambda v: f"{int(v)}") if c in COUNT_FIELDS else (lambda v: f"{v:.2f}") for c in cols}
    return out.to_string(formatters=fmt)


def run_eval(args) -> int:
    """Run the ``eval`` subcommand for parsed ``args``; returns the exit status (0 ok, 2 error)."""
    from dfrmot_jax.io.kitti import KittiFormatError
    from dfrmot_jax.metrics.evaluate import cached_gt, evaluate_files
    from dfrmot_jax.metrics.table import metrics_table
    from dfrmot_jax.paths import default_data_root

    root = Path(args.data) if args.data else default_data_root()
    if not (root / "label_02").is_dir():
        print(f"dfrmot eval: no ground truth at {root / 'label_02'} (use --data or set DFRMOT_DATA)", file=sys.stderr)
        return 2
    seqs = [s.strip() for s in args.seqs.split(",") if s.strip()] if args.seqs else None
    try:
        gt = cached_gt(root, args.cls, seqs)
    except (KittiFormatError, FileNotFoundError, ValueError) as e:
        print(f"dfrmot eval: ground truth: {e}", file=sys.stderr)
        return 2
    tables = []
    names = []
    for d in args.results:
        d = Path(d)
        if not d.is_dir():
            print(f"dfrmot eval: not a directory: {d}", file=sys.stderr)
            return 2
        name = _tracker_name(d)
        if name in names:
            name = str(d)
        names.append(name)
        try:
            res = evaluate_files(d, gt)
        except (KittiFormatError, ValueError) as e:
            print(f"dfrmot eval: {e}", file=sys.stderr)
            return 2
        tables.append(metrics_table(res, tracker=name))
    df = pd.concat(tables)
    shown = df if args.per_seq else df.loc[["COMBINED"]]
    print(f"{args.cls}, {len(gt.sequences)} sequences, {gt.n_frames} frames "
          f"(TrackEval Kitti2DBox; HOTA/DetA/AssA = mean over alphas, %)")
    print(_fmt_table(shown))
    if args.csv:
        out = Path(args.csv)
        out.parent.mkdir(parents=True, exist_ok=True)
        df.reset_index().to_csv(out, index=False)
        print(f"wrote {out}")
    return 0


def main(argv=None) -> int:
    """Stand-alone entry: ``python -m dfrmot_jax.metrics.cli eval ...``."""
    parser = argparse.ArgumentParser(prog="dfrmot")
    sub = parser.add_subparsers(dest="command", required=True)
    add_eval_parser(sub)
    args = parser.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
