"""The ``dfrmot eval`` parser, apart from the command (:mod:`dfrmot_jax.cli.eval`), which is imported
when it runs (``errors.run_later``): ``dfrmot eval --help`` imports none of the metrics."""

from __future__ import annotations

import argparse

from ..choices import DEFAULT_AB3DMOT_IOU, DEFAULT_SUM, SUM_HELP, SUMS
from ..paths import default_data_root
from .args import classes_arg, families_arg, iou_arg, output_file, seqs_arg
from .commands import HELP
from .errors import run_later

__all__ = ["add_parser"]


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``eval`` on an argparse ``subparsers`` object; returns its parser."""
    p = sub.add_parser(
        "eval",
        help=HELP["eval"],
        description="Evaluate KITTI tracking results (RESULTS_DIR/SSSS.txt, of any tracker family or any "
                    "tracker) exactly like TrackEval's Kitti2DBox (and, with --metrics ab3dmot, like AB3DMOT's "
                    "KITTI evaluation: sAMOTA/AMOTA/AMOTP) "
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
    p.add_argument("--class", dest="cls", default=("car",), type=classes_arg, metavar="CLASSES",
                   help="class or comma-separated classes: car, pedestrian or car,pedestrian (default car); "
                        "several classes add a class average row per tracker")
    p.add_argument("--seqs", default=None, type=seqs_arg,
                   help="comma-separated sequences, e.g. 0000,0002, for every class (default: per class the "
                        "sequences whose ground truth has it); other result files are not looked at")
    p.add_argument("--seqmap", default=None, metavar="FILE",
                   help="evaluate the sequences of a KITTI seqmap (NAME empty FIRST LAST a line, e.g. AB3DMOT's "
                        "evaluate_tracking.seqmap.val), like --seqs")
    p.add_argument("--metrics", default=("kitti2d",), type=families_arg, metavar="FAMILIES",
                   help="metric families, comma-separated: kitti2d (TrackEval's HOTA/CLEAR/Identity, default), "
                        "ab3dmot (AB3DMOT's KITTI sAMOTA/AMOTA/AMOTP and best-threshold MOTA/MOTP/IDS/FRAG/FP/FN)")
    p.add_argument("--ab3dmot-iou", dest="ab3dmot_iou", default=None, type=iou_arg, metavar="2d:T|3d:T",
                   help=f"AB3DMOT matching: image-box IoU (2d) or 3D IoU of the rotated boxes (3d) at threshold T "
                        f"(default {DEFAULT_AB3DMOT_IOU}; AB3DMOT uses 2d:0.5 and 3d:0.25/0.5/0.7)")
    p.add_argument("--ab3dmot-sum", dest="ab3dmot_sum", default=None, choices=SUMS,
                   help=f"{SUM_HELP}; where the other gives other figures, a line after the table shows them")
    p.add_argument("--recall-table", dest="recall_table", default=None, metavar="F", type=output_file,
                   help="write AB3DMOT's recall points as CSV (implies --metrics ab3dmot): per tracker, class, sum "
                        "and recall point the score threshold, recall, TP/FP/FN/IDS, sMOTA, the matches to ignored "
                        "ground truth and the tracks dropped by the sequential sum's drift")
    p.add_argument("--similarity", default="2d", choices=("2d", "3d", "bev"),
                   help="kitti2d family: the similarity HOTA / CLEAR / Identity match on: 2d image-box IoU (TrackEval's "
                        "Kitti2DBox, default), 3d IoU of rotated boxes or bev IoU; KITTI's distractor and DontCare "
                        "rules stay 2D; rows without a 3D box are unmatched in 3D")
    p.add_argument("--allow-missing", action="store_true",
                   help="score a sequence without a result file, or a class without a row in any file, as an "
                        "empty output (with a warning) instead of refusing")
    p.add_argument("--per-seq", action="store_true", help="also print every sequence")
    p.add_argument("--csv", default=None, metavar="F", type=output_file,
                   help="write all metrics, one row per (tracker, class, sequence) with columns tracker, class, seq")
    p.set_defaults(func=run_later("dfrmot_jax.cli.eval"))
    return p
