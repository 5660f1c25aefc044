"""``dfrmot eval``: TrackEval-identical KITTI evaluation of result folders from the command line.

Usage: ``dfrmot eval RESULTS_DIR [RESULTS_DIR ...] [--data ROOT] [--class car[,pedestrian]]
[--seqs 0000,0002] [--per-seq] [--csv F]``. Each class is scored on its own rows of the result files
(one file may hold ``Car`` and ``Pedestrian`` rows), by default on the sequences whose ground truth
has the class (car: 20 of KITTI's 21, pedestrian: 15); ``--seqs`` scores every class on exactly
those. With several classes each tracker also gets a class average row (``class = average``:
ratio fields averaged over the classes, counts summed; TrackEval's class average). Prints a compact
table (COMBINED per tracker and class; also every sequence with ``--per-seq``) and writes a CSV with
one row per (tracker, class, sequence), each class's COMBINED and the average, columns
``tracker, class, seq`` then every summary field.
"""

from __future__ import annotations

import argparse
from pathlib import Path

__all__ = ["add_parser", "run"]


def _tracker_name(d: Path) -> str:
    d = Path(d)
    return d.parent.name if d.name == "data" and d.parent.name else d.name


def _classes_arg(text: str) -> tuple:
    from ..metrics.evaluate import parse_classes

    try:
        return parse_classes(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``eval`` on an argparse ``subparsers`` object; returns its parser."""
    from . import guarded
    from ..paths import default_data_root

    p = sub.add_parser(
        "eval",
        help="evaluate KITTI tracking result folders (TrackEval's KITTI 2D box HOTA/CLEAR/Identity)",
        description="Evaluate KITTI tracking results (RESULTS_DIR/SSSS.txt) exactly like TrackEval's Kitti2DBox. "
                    "A sequence without a result file counts as an empty output.",
    )
    p.add_argument("results", nargs="+", metavar="RESULTS_DIR", help="folder(s) with SSSS.txt result files")
    p.add_argument("--data", default=None, metavar="ROOT",
                   help=f"KITTI tracking training root (default: $DFRMOT_DATA or {default_data_root()})")
    p.add_argument("--class", dest="cls", default=("car",), type=_classes_arg, metavar="CLASSES",
                   help="class or comma-separated classes: car, pedestrian or car,pedestrian (default car); "
                        "several classes add a class average row per tracker")
    p.add_argument("--seqs", default=None,
                   help="comma-separated sequences, e.g. 0000,0002, for every class (default: per class the "
                        "sequences whose ground truth has it)")
    p.add_argument("--per-seq", action="store_true", help="also print every sequence")
    p.add_argument("--csv", default=None, metavar="F",
                   help="write all metrics, one row per (tracker, class, sequence) with columns tracker, class, seq")
    p.set_defaults(func=guarded(run))
    return p


def _fmt_table(df) -> str:
    from ..metrics.table import COMPACT_FIELDS, COUNT_FIELDS

    cols = [c for c in COMPACT_FIELDS if c in df.columns]
    keys = [c for c in ("tracker", "class") if c in df.columns]
    out = df.set_index("seq")[keys + cols] if "seq" in df.columns else df[keys + cols]
    fmt = {c: (lambda v: f"{int(v)}") if c in COUNT_FIELDS else (lambda v: f"{v:.2f}") for c in cols}
    return out.to_string(formatters=fmt)


def run(args) -> int:
    """Run ``eval`` for parsed ``args``: 0, or raises (bad ground truth, results or arguments)."""
    import pandas as pd

    from ..io.kitti import KittiFormatError
    from ..metrics.evaluate import (AVERAGE, cached_class_sequences, cached_gt, class_average, evaluate_files,
                                    parse_classes)
    from ..metrics.table import classes_table
    from ..paths import default_data_root

    root = Path(args.data) if args.data else default_data_root()
    if not (root / "label_02").is_dir():
        raise ValueError(f"no ground truth at {root / 'label_02'} (use --data or set DFRMOT_DATA)")
    from .track import parse_seqs

    seqs = parse_seqs(args.seqs)
    try:
        classes = parse_classes(args.cls)
        gts = {}
        for c in classes:
            cs = seqs if seqs is not None else cached_class_sequences(root, c)
            if not cs:
                raise ValueError(f"no sequence of {root / 'label_02'} has ground truth of class {c!r}")
            gts[c] = cached_gt(root, c, cs)
    except (KittiFormatError, FileNotFoundError, ValueError) as e:
        raise ValueError(f"ground truth: {e}") from e
    tables = []
    names = []
    for d in args.results:
        d = Path(d)
        if not d.is_dir():
            raise ValueError(f"not a directory: {d}")
        name = _tracker_name(d)
        if name in names:
            name = str(d)
        names.append(name)
        res = {c: evaluate_files(d, gt) for c, gt in gts.items()}
        if len(res) > 1:
            res[AVERAGE] = {"COMBINED": class_average({c: r["COMBINED"] for c, r in res.items()})}
        tables.append(classes_table(res, tracker=name))
    df = pd.concat(tables, ignore_index=True)
    shown = df if args.per_seq else df[df["seq"] == "COMBINED"]
    split = "; ".join(f"{c}, {len(gt.sequences)} sequences, {gt.n_frames} frames" for c, gt in gts.items())
    note = "; average: ratios averaged over the classes, counts summed" if len(gts) > 1 else ""
    print(f"{split} (TrackEval Kitti2DBox; HOTA/DetA/AssA = mean over alphas, %{note})")
    print(_fmt_table(shown))
    if args.csv:
        out = Path(args.csv)
        out.parent.mkdir(parents=True, exist_ok=True)
        df.to_csv(out, index=False)
        print(f"wrote {out}")
    return 0
