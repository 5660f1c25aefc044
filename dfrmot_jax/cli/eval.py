"""``dfrmot eval``: TrackEval-identical KITTI evaluation of result folders from the command line.

Usage: ``dfrmot eval RESULTS_DIR [RESULTS_DIR ...] [--data ROOT] [--class car[,pedestrian]]
[--seqs 0000,0002 | --seqmap FILE] [--metrics kitti2d,ab3dmot] [--ab3dmot-iou 3d:0.25]
[--ab3dmot-sum compensated|sequential] [--recall-table F] [--similarity 2d|3d|bev] [--allow-missing]
[--per-seq] [--csv F]``. Each class is scored on its own rows
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

``--metrics`` picks the metric families: ``kitti2d`` (TrackEval's, the default) and ``ab3dmot``
(AB3DMOT's KITTI sAMOTA / AMOTA / AMOTP and its best-threshold MOTA, MOTP, IDS, FRAG, FP, FN:
:mod:`dfrmot_jax.metrics.samota.evaluate`, IoU from ``--ab3dmot-iou``, ``2d:T`` or ``3d:T``, default
``3d:0.25``), which adds the columns of :mod:`dfrmot_jax.metrics.samota.table` to the CSV (on the
``COMBINED`` rows; percent like the other ratio columns). ``--seqmap FILE`` evaluates the sequences
of a KITTI seqmap (e.g. AB3DMOT's validation split), like ``--seqs``; a seqmap naming a sequence
without ground truth is refused with its file and line.

AB3DMOT's evaluator averages track scores with Python's ``sum``, whose float arithmetic changed in
CPython 3.12 (:mod:`dfrmot_jax.metrics.samota.sums`): ``--ab3dmot-sum compensated`` (the default,
CPython >= 3.12) or ``sequential`` (CPython <= 3.11, with the drift that drops tracks at their own
threshold). Where the other sum gives other figures, one line after the table says what they are
(the CSV holds them as ``other_sAMOTA other_AMOTA other_ab3dmot_MOTA``, and the sum as
``ab3dmot_sum``). ``--recall-table F`` (implies ``--metrics ab3dmot``) writes where the recall
points go: per tracker, class, sum and recall point, the threshold, recall, counts, sMOTA, the
matches to ignored ground truth and the tracks dropped by the drift
(:func:`dfrmot_jax.metrics.samota.table.recall_table`).
"""

from __future__ import annotations

import sys
from collections import Counter
from pathlib import Path

import pandas as pd

from ..choices import DEFAULT_SUM, EVAL_CLASSES, parse_classes
from ..io.kitti import KittiFormatError
from ..io.result_rows import read_result_rows
from ..metrics.samota.prep import read_seqmap
from ..metrics.samota.table import (AB3DMOT_COLUMNS, ab3dmot_table, add_ab3dmot_columns, evaluate_ab3dmot_classes, other_sum_line, recall_table)
from ..metrics.common.sequences import CLASS_NAME_TO_ID, cached_class_sequences
from ..metrics.kitti2d.evaluate import AVERAGE, cached_gt, class_average, evaluate_dets
from ..metrics.kitti2d.table import COMPACT_FIELDS, COUNT_FIELDS, classes_table
from ..metrics.kitti2d.tracker_files import inspect_results, read_tracker_files
from ..paths import default_data_root
from .args import ab3dmot_settings, check_output_files, parse_seqs

__all__ = ["run", "check_folder", "check_folders", "check_class_rows", "chosen_sequences", "ground_truth",
           "empty_sequence_lines",
           "label_root", "tracker_name"]


def tracker_name(d: Path) -> str:
    d = Path(d)
    return d.parent.name if d.name == "data" and d.parent.name else d.name


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


def check_folder(d: Path, found, n_seqs: int, label_dir: Path, allow_missing: bool) -> None:
    """Raise ValueError naming everything wrong with result folder ``d`` (a
    ``metrics.kitti2d.tracker_files.ResultFolder`` for ``n_seqs`` sequences); with ``allow_missing`` warn about missing files instead."""
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


def label_root(data) -> tuple[Path, Path]:
    """(KITTI root, its label_02 folder) from ``--data`` (default: $DFRMOT_DATA or the shared data);
    ValueError when there is no ground truth."""
    root = Path(data) if data else default_data_root()
    label_dir = root / "label_02"
    if not label_dir.is_dir():
        raise ValueError(f"no ground truth at {label_dir} (use --data or set DFRMOT_DATA)")
    return root, label_dir


def chosen_sequences(seqs_text, seqmap, root: Path, default=None):
    """The sequences ``--seqs`` or ``--seqmap`` name (not both), else ``default`` (None: per class those
    whose ground truth has it)."""
    seqs = parse_seqs(seqs_text)
    if seqmap:
        if seqs is not None:
            raise ValueError("--seqs and --seqmap both name the sequences: give one")
        return list(read_seqmap(seqmap, root))
    return default if seqs is None else seqs


def check_folders(folders, label_dir: Path, seq_lists: dict, seqs, allow_missing: bool) -> None:
    """Every result folder a directory, then each checked (:func:`check_folder`) for the sequences of
    ``seq_lists``; without explicit ``seqs`` a file of no ground-truth sequence is refused too."""
    wanted = sorted({s for cs in seq_lists.values() for s in cs})
    known = None if seqs is not None else sorted(p.stem for p in label_dir.glob("*.txt"))
    for d in folders:
        if not d.is_dir():
            raise ValueError(f"not a directory: {d}")
    for d in folders:
        check_folder(d, inspect_results(d, wanted, known), len(wanted), label_dir, allow_missing)


def check_class_rows(d: Path, cls: str, sequences, n_gt: int, n_rows: int, allow_missing: bool,
                     command: str = "eval") -> None:
    """Refuse (ValueError) a folder ``d`` with no row of class ``cls`` while the ground truth has
    ``n_gt`` objects of it (wrong --class?); with ``allow_missing`` warn instead (an empty output)."""
    if n_rows or not n_gt:
        return
    what = f"{d}: no {cls} row in any result file, but the ground truth has {n_gt} {cls} objects to evaluate"
    if not allow_missing:
        raise ValueError(f"{what}; {_class_hint(d, sequences, cls)} (--allow-missing scores it as an empty output)")
    print(f"dfrmot {command}: warning: {what}: scored as an empty output", file=sys.stderr)


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


def _ab3dmot(d: Path, root: Path, seq_lists: dict, iou: str, sum_mode: str) -> dict:
    """AB3DMOT's figures of folder ``d`` per class, both sums (missing files were checked by the caller)."""
    return evaluate_ab3dmot_classes(d, root, seq_lists, iou=iou, sum_mode=sum_mode, other=True)


def _print_ab3dmot(df, seq_lists: dict, iou: str, note_avg: str, others: list) -> None:
    split = "; ".join(f"{c}, {len(s)} sequences" for c, s in seq_lists.items())
    rows = df[df["seq"] == "COMBINED"]
    cols = [c for c in ("tracker", "class") if c in rows.columns] + list(AB3DMOT_COLUMNS)
    fmt = {c: (lambda v: f"{int(v)}") if c.endswith(("IDS", "FRAG", "FP", "FN")) else (lambda v: f"{v:.2f}")
           for c in AB3DMOT_COLUMNS}
    sums = ", ".join(sorted(set(rows["ab3dmot_sum"]))) if "ab3dmot_sum" in rows.columns else DEFAULT_SUM
    print(f"{split} (AB3DMOT KITTI, IoU {iou}, {sums} sum; sAMOTA/AMOTA/AMOTP and the best-threshold ab3dmot_* "
          f"figures, %{note_avg})")
    print(rows[cols].to_string(index=False, formatters=fmt))
    for line in others:
        print(line)


def empty_sequence_lines(root: Path, seq_lists: dict) -> list[str]:
    """One line per class for the sequences named (``--seqs``, ``--seqmap``) whose ground truth holds no
    object of it: every row there can only be a false positive (e.g. 0003 and pedestrians)."""
    out = []
    for c, named in seq_lists.items():
        held = set(cached_class_sequences(root, c))
        empty = [s for s in named if s not in held]
        if empty:
            out.append(f"note: {len(empty)} of the {len(named)} sequences named hold no {c} in their ground truth "
                       f"({_names(empty)}): their {c} rows can only be false positives"
                       + ("; no sequence named holds one" if len(empty) == len(named) else "")
                       + f" (sequences with {c}: {_names(sorted(held), 25)})")
    return out


def ground_truth(root: Path, cls, seqs, kitti2d: bool) -> tuple[dict, dict]:
    """(class -> prepared ground truth, for the kitti2d family only; class -> its sequences: ``seqs``,
    else those whose ground truth has the class); anything wrong with the ground truth is a
    ValueError that says so."""
    try:
        gts, seq_lists = {}, {}
        for c in parse_classes(cls):
            cs = seqs if seqs is not None else cached_class_sequences(root, c)
            if not cs:
                raise ValueError(f"no sequence of {root / 'label_02'} has ground truth of class {c!r}")
            seq_lists[c] = tuple(cs)
            if kitti2d:
                gts[c] = cached_gt(root, c, cs)
    except (KittiFormatError, FileNotFoundError, ValueError) as e:
        raise ValueError(f"ground truth: {e}") from e
    return gts, seq_lists


def run(args) -> int:
    """Run ``eval`` for parsed ``args``: 0, or raises (bad ground truth, results or arguments)."""
    ab3dmot_settings(args)
    check_output_files([("--csv", args.csv), ("--recall-table", getattr(args, "recall_table", None))],
                       [("--seqmap", getattr(args, "seqmap", None))],
                       [("RESULTS_DIR", d) for d in args.results])
    root, label_dir = label_root(args.data)
    check_output_files([("--csv", args.csv), ("--recall-table", getattr(args, "recall_table", None))],
                       input_dirs=[("the ground truth", label_dir)])
    seqs = chosen_sequences(args.seqs, getattr(args, "seqmap", None), root)
    families = getattr(args, "metrics", ("kitti2d",))
    recall_csv = getattr(args, "recall_table", None)
    sum_mode = getattr(args, "ab3dmot_sum", DEFAULT_SUM)
    if recall_csv is not None and "ab3dmot" not in families:
        families = (*families, "ab3dmot")
    gts, seq_lists = ground_truth(root, args.cls, seqs, "kitti2d" in families)
    folders = [Path(d) for d in args.results]
    check_folders(folders, label_dir, seq_lists, seqs, args.allow_missing)
    tables, names, others, recalls = [], [], [], []
    for d in folders:
        name = tracker_name(d)
        if name in names:
            name = str(d)
        names.append(name)
        similarity = getattr(args, "similarity", "2d")
        dets = {c: read_tracker_files(d, gt, need_3d=similarity != "2d") for c, gt in gts.items()}
        ab = _ab3dmot(d, root, seq_lists, args.ab3dmot_iou, sum_mode) if "ab3dmot" in families else {}
        others += [line for c, r in ab.items() if (line := other_sum_line(r, f"{name} {c}")) is not None]
        recalls += [recall_table(r, tracker=name, **{"class": c}) for c, r in ab.items()]
        for c in seq_lists:
            if c in gts:
                n_gt, n_rows = int(gts[c].n_gt_dets.sum()), dets[c].frame.size
            else:
                n_gt, n_rows = ab[c]["n_objects"], ab[c]["n_rows"]
            check_class_rows(d, c, seq_lists[c], n_gt, n_rows, args.allow_missing)
        table = None
        if gts:
            res = {c: evaluate_dets(gt, dets[c], similarity) for c, gt in gts.items()}
            if len(res) > 1:
                res[AVERAGE] = {"COMBINED": class_average({c: r["COMBINED"] for c, r in res.items()})}
            table = classes_table(res, tracker=name)
        if ab:
            table = add_ab3dmot_columns(table, ab3dmot_table(ab, tracker=name))
        tables.append(table)
    df = pd.concat(tables, ignore_index=True)
    note_avg = "; average: ratios averaged over the classes, counts summed" if len(seq_lists) > 1 else ""
    if gts:
        shown, note = _mark_empty_gt(df) if args.per_seq else (df[df["seq"] == "COMBINED"], "")
        split = "; ".join(f"{c}, {len(gt.sequences)} sequences, {gt.n_frames} frames" for c, gt in gts.items())
        sim = {"2d": "", "3d": "; similarity: 3D IoU of rotated boxes", "bev": "; similarity: bird's-eye-view IoU"}[
            getattr(args, "similarity", "2d")]
        print(f"{split} (TrackEval Kitti2DBox{sim}; HOTA/DetA/AssA = mean over alphas, %{note_avg})")
        print(_fmt_table(shown))
        if note:
            print(note)
    if "ab3dmot" in families:
        _print_ab3dmot(df, seq_lists, args.ab3dmot_iou, note_avg, others)
    if seqs is not None:
        for line in empty_sequence_lines(root, seq_lists):
            print(line)
    for path, table in ((args.csv, df), (recall_csv, pd.concat(recalls, ignore_index=True) if recalls else None)):
        if path:
            out = Path(path)
            out.parent.mkdir(parents=True, exist_ok=True)
            table.to_csv(out, index=False)
            print(f"wrote {out}")
    return 0
