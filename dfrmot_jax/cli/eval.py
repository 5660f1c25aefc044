"""``dfrmot eval``: TrackEval-identical KITTI evaluation of result folders from the command line.

Usage: ``dfrmot eval RESULTS_DIR [RESULTS_DIR ...] [--data ROOT] [--class car[,pedestrian]]
[--seqs 0000,0002] [--allow-missing] [--per-seq] [--csv F]``. Each class is scored on its own rows
of the result files (one file may hold ``Car`` and ``Pedestrian`` rows), by default on the
sequences whose ground truth has the class (car: 20 of KITTI's 21, pedestrian: 15); ``--seqs``
scores every class on exactly those. With several classes each tracker also gets a class average
row (``class = average``: ratio fields averaged over the classes, counts summed; TrackEval's class
average). Prints a compact table (COMBINED per tracker and class; also every sequence with
``--per-seq``) and writes a CSV with one row per (tracker, class, sequence), each class's COMBINED
and the average, columns ``tracker, class, seq`` then every summary field.

A score is never silently wrong. Refused (exit 2, one message listing every problem of a folder):

* a sequence to evaluate without a result file (``--allow-missing`` scores it as an empty output,
  with a warning), and a result file name that is a directory or a dangling symlink (always);
* without ``--seqs``, ``*.txt`` files that are no sequence of the ground truth (``0099.txt``,
  ``foo.txt``: stale or foreign files). A file of a ``label_02`` sequence without the class is
  fine (not scored); ``--seqs`` restricts both sides: other files are not looked at;
* a folder with no row of an evaluated class in any of its files while the ground truth has the
  class (e.g. car results with ``--class pedestrian``): the message names the classes the files
  hold; ``--allow-missing`` scores it as an empty output, with a warning.

Result files are read as TrackEval reads them (:mod:`dfrmot_jax.io.result_rows`: rows in any
order, ``x2 < x1`` allowed, ...); what TrackEval cannot read is refused with file, line and field.
With ``--per-seq``, a sequence whose ground truth has nothing of the class to evaluate (given by
``--seqs``, e.g. 0017 for car) is marked ``*``: its rows can only be false positives, which
COMBINED counts as TrackEval does for the same sequence list.
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

import pandas as pd

from ..io.kitti import KittiFormatError
from ..io.result_rows import read_result_rows
from ..metrics.evaluate import (
    AVERAGE,
    EVAL_CLASSES,
    cached_class_sequences,
    cached_gt,
    class_average,
    evaluate_dets,
    parse_classes,
)
from ..metrics.kitti import CLASS_NAME_TO_ID, inspect_results, read_tracker_files
from ..metrics.table import COMPACT_FIELDS, COUNT_FIELDS, classes_table
from ..paths import default_data_root
from .errors import guarded
from .track import parse_seqs

__all__ = ["add_parser", "run"]


def _tracker_name(d: Path) -> str:
    d = Path(d)
    return d.parent.name if d.name == "data" and d.parent.name else d.name


def _classes_arg(text: str) -> tuple:
    try:
        return parse_classes(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``eval`` on an argparse ``subparsers`` object; returns its parser."""
    p = sub.add_parser(
        "eval",
        help="evaluate KITTI tracking result folders (TrackEval's KITTI 2D box HOTA/CLEAR/Identity)",
        description="Evaluate KITTI tracking results (RESULTS_DIR/SSSS.txt) exactly like TrackEval's Kitti2DBox "
                    "(files are read as TrackEval reads them: rows in any order, x2 < x1 allowed). Refused: a "
                    "sequence without a result file (see --allow-missing), a result file name that is a "
                    "directory or a dangling symlink, *.txt files that are no sequence of the ground truth "
                    "(unless --seqs), and results with no row of an evaluated class while the ground truth "
                    "has it (wrong --class?). With --per-seq, '*' marks a sequence without ground truth "
                    "of the class (its rows can only be false positives).",
    )
    p.add_argument("results", nargs="+", metavar="RESULTS_DIR", help="folder(s) with SSSS.txt result files")
    p.add_argument("--data", default=None, metavar="ROOT",
                   help=f"KITTI tracking training root (default: $DFRMOT_DATA or {default_data_root()})")
    p.add_argument("--class", dest="cls", default=("car",), type=_classes_arg, metavar="CLASSES",
                   help="class or comma-separated classes: car, pedestrian or car,pedestrian (default car); "
                        "several classes add a class average row per tracker")
    p.add_argument("--seqs", default=None,
                   help="comma-separated sequences, e.g. 0000,0002, for every class (default: per class the "
                        "sequences whose ground truth has it); other result files are not looked at")
    p.add_argument("--allow-missing", action="store_true",
                   help="score a sequence without a result file, or a class without a row in any file, as an "
                        "empty output (with a warning) instead of refusing")
    p.add_argument("--per-seq", action="store_true", help="also print every sequence")
    p.add_argument("--csv", default=None, metavar="F",
                   help="write all metrics, one row per (tracker, class, sequence) with columns tracker, class, seq")
    p.set_defaults(func=guarded(run))
    return p


def _fmt_table(df) -> str:
    cols = [c for c in COMPACT_FIELDS if c in df.columns]
    keys = [c for c in ("tracker", "class") if c in df.columns]
    out = df.set_index("seq")[keys + cols] if "seq" in df.columns else df[keys + cols]
    fmt = {c: (lambda v: f"{int(v)}") if c in COUNT_FIELDS else (lambda v: f"{v:.2f}") for c in cols}
    return out.to_string(formatters=fmt)


def _names(items, most: int = 30) -> str:
    items = list(items)
    return ", ".join(items[:most]) + (f", ... ({len(items) - most} more)" if len(items) > most else "")


def _warn(message: str) -> None:
    print(f"dfrmot eval: warning: {message}", file=sys.stderr)


def _check_folder(d: Path, found, n_seqs: int, label_dir: Path, allow_missing: bool) -> None:
    """Raise ValueError naming everything wrong with result folder ``d`` (a ``metrics.kitti.ResultFolder``
    for ``n_seqs`` sequences); with ``allow_missing`` warn about missing files instead."""
    problems = [f"{path} {why}, not a result file" for path, why in found.unreadable]
    missing = f"no result file for {len(found.missing)} of {n_seqs} sequences ({_names(found.missing)})"
    if found.missing and not allow_missing:
        problems.append(f"{missing} (--allow-missing scores them as empty outputs; --seqs evaluates only some "
                        f"sequences)")
    if found.unexpected:
        problems.append(f"unexpected files, no sequence of {label_dir}: {_names(found.unexpected)} (stale results? "
                        f"remove them, or name the sequences to evaluate with --seqs)")
    if problems:
        raise ValueError(f"{d}: " + "; ".join(problems))
    if found.missing:
        _warn(f"{d}: {missing}: scored as empty outputs")


def _class_hint(d: Path, sequences, cls: str) -> str:
    """What the result files of ``sequences`` in ``d`` hold instead of ``cls``, and the --class to try."""


    held = Counter()
    for name in sequences:
        if (d / f"{name}.txt").is_file():
            held.update(read_result_rows(d / f"{name}.txt").type.tolist())
    if not held:
        return "the files hold no row with an id >= 0"
    ids = {CLASS_NAME_TO_ID.get(t.lower()) for t in held}
    other = [c for c in EVAL_CLASSES if c != cls and CLASS_NAME_TO_ID[c] in ids]
    text = "the files hold " + ", ".join(f"{n} {t}" for t, n in held.most_common()) + " rows"
    return text + (f" (evaluate with --class {other[0]}?)" if other else "")


def _mark_empty_gt(shown):
    """``--per-seq`` table: sequences without ground truth of their class (GT_Dets 0) marked ``*``;
    returns (table, footnote or '')."""
    marked = (shown["seq"] != "COMBINED") & (shown["GT_Dets"] == 0)
    if not marked.any():
        return shown, ""
    shown = shown.copy()
    shown.loc[marked, "seq"] = shown.loc[marked, "seq"] + "*"
    where = "; ".join(f"{c} {', '.join(g['seq'].str.rstrip('*').unique())}" for c, g in shown[marked].groupby(
        "class", sort=False))
    return shown, (f"* no ground truth of the class to evaluate (GT_Dets 0): {where}; their rows can only be "
                   f"false positives, counted in COMBINED as TrackEval counts them for the same sequences")


def run(args) -> int:
    """Run ``eval`` for parsed ``args``: 0, or raises (bad ground truth, results or arguments)."""


    root = Path(args.data) if args.data else default_data_root()
    label_dir = root / "label_02"
    if not label_dir.is_dir():
        raise ValueError(f"no ground truth at {label_dir} (use --data or set DFRMOT_DATA)")

    seqs = parse_seqs(args.seqs)
    try:
        classes = parse_classes(args.cls)
        gts = {}
        for c in classes:
            cs = seqs if seqs is not None else cached_class_sequences(root, c)
            if not cs:
                raise ValueError(f"no sequence of {label_dir} has ground truth of class {c!r}")
            gts[c] = cached_gt(root, c, cs)
    except (KittiFormatError, FileNotFoundError, ValueError) as e:
        raise ValueError(f"ground truth: {e}") from e
    wanted = sorted({s for gt in gts.values() for s in gt.sequences})
    known = None if seqs is not None else sorted(p.stem for p in label_dir.glob("*.txt"))
    folders = [Path(d) for d in args.results]
    for d in folders:
        if not d.is_dir():
            raise ValueError(f"not a directory: {d}")
    for d in folders:
        _check_folder(d, inspect_results(d, wanted, known), len(wanted), label_dir, args.allow_missing)
    tables = []
    names = []
    for d in folders:
        name = _tracker_name(d)
        if name in names:
            name = str(d)
        names.append(name)
        dets = {c: read_tracker_files(d, gt) for c, gt in gts.items()}
        for c, gt in gts.items():
            n_gt = int(gt.n_gt_dets.sum())
            if dets[c].frame.size or not n_gt:
                continue
            what = f"{d}: no {c} row in any result file, but the ground truth has {n_gt} {c} objects to evaluate"
            if not args.allow_missing:
                raise ValueError(f"{what}; {_class_hint(d, gt.sequences, c)} (--allow-missing scores it as an "
                                 f"empty output)")
            _warn(f"{what}: scored as an empty output")
        res = {c: evaluate_dets(gt, dets[c]) for c, gt in gts.items()}
        if len(res) > 1:
            res[AVERAGE] = {"COMBINED": class_average({c: r["COMBINED"] for c, r in res.items()})}
        tables.append(classes_table(res, tracker=name))
    df = pd.concat(tables, ignore_index=True)
    shown, note = _mark_empty_gt(df) if args.per_seq else (df[df["seq"] == "COMBINED"], "")
    split = "; ".join(f"{c}, {len(gt.sequences)} sequences, {gt.n_frames} frames" for c, gt in gts.items())
    note_avg = "; average: ratios averaged over the classes, counts summed" if len(gts) > 1 else ""
    print(f"{split} (TrackEval Kitti2DBox; HOTA/DetA/AssA = mean over alphas, %{note_avg})")
    print(_fmt_table(shown))
    if note:
        print(note)
    if args.csv:
        out = Path(args.csv)
        out.parent.mkdir(parents=True, exist_ok=True)
        df.to_csv(out, index=False)
        print(f"wrote {out}")
    return 0
