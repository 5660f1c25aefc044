"""The ``dfrmot compare`` parser, apart from the command (:mod:`dfrmot_jax.cli.compare`), which is
imported when it runs (``errors.run_later``): ``dfrmot compare --help`` imports none of the metrics, the
report or the sweep."""

from __future__ import annotations

import argparse

from ..choices import (AB3DMOT_MAX_RESAMPLES, AB3DMOT_RESAMPLES, DEFAULT_AB3DMOT_IOU, DEFAULT_RESAMPLES, DEFAULT_SUM,
                       SUM_HELP, SUMS)
from ..paths import default_data_root
from .args import classes_arg, families_arg, iou_arg, output_file, seed_arg, seqs_arg
from .commands import HELP
from .errors import run_later

__all__ = ["add_parser", "resamples_arg", "ab3dmot_resamples_arg"]


def resamples_arg(text: str, most: int = 10_000_000) -> int:
    """``--resamples``: a whole number of bootstrap resamples in [1, ``most``]."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number of resamples, got {text!r}") from None
    if not 1 <= n <= most:
        raise argparse.ArgumentTypeError(f"expected 1 to {most:,} resamples, got {n:,}")
    return n


def ab3dmot_resamples_arg(text: str) -> int:
    """``--ab3dmot-resamples``: each a full evaluation of both outputs, so at most AB3DMOT_MAX_RESAMPLES."""
    return resamples_arg(text, AB3DMOT_MAX_RESAMPLES)


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``compare`` on an argparse ``subparsers`` object; returns its parser."""
    p = sub.add_parser("compare", help=HELP["compare"],
                       description="Compare two KITTI result folders on the same sequences: per-sequence "
                                   "differences of HOTA, DetA, AssA, LocA, DetRe, DetPr, AssRe, AssPr, MOTA, "
                                   "IDF1, IDSW, FP, FN, Frag and, on the combined figures, a paired bootstrap "
                                   "over sequences (each resample recombined exactly as TrackEval combines "
                                   "sequences): the 95 % interval of B - A and the share of resamples where B "
                                   "is better. Folders are read and checked as dfrmot eval reads them.")
    p.add_argument("a", metavar="A", help="the first result folder (SSSS.txt files), or a sweep / tune directory's "
                                          "config: DIR:best (as dfrmot report DIR ranks it), DIR:baseline, "
                                          "DIR:config=N (tracked alone, for each class of the directory, on its "
                                          "data; its sequences unless --seqs)")
    p.add_argument("b", metavar="B", help="the second, likewise; differences are B - A")
    p.add_argument("--data", default=None, metavar="ROOT",
                   help=f"KITTI tracking training root (default: a DIR: side's own, else $DFRMOT_DATA or "
                        f"{default_data_root()})")
    p.add_argument("--class", dest="cls", default=("car",), type=classes_arg, metavar="CLASSES",
                   help="class or comma-separated classes (default car)")
    p.add_argument("--seqs", default=None, type=seqs_arg, help="comma-separated sequences (default: per class, those whose "
                                                "ground truth has it)")
    p.add_argument("--seqmap", default=None, metavar="FILE", help="the sequences of a KITTI seqmap, like --seqs")
    p.add_argument("--resamples", default=DEFAULT_RESAMPLES, type=resamples_arg,
                   help=f"bootstrap resamples (default {DEFAULT_RESAMPLES:,})")
    p.add_argument("--seed", default=0, type=seed_arg, help="seed of the resamples (default 0)")
    p.add_argument("--metrics", default=("kitti2d",), type=families_arg, metavar="FAMILIES",
                   help="kitti2d (TrackEval's, default) and/or ab3dmot: AB3DMOT's sAMOTA / AMOTA / MOTA / IDS / FP / FN "
                        "(--ab3dmot-iou), each resample rescored")
    p.add_argument("--ab3dmot-iou", dest="ab3dmot_iou", default=None, type=iou_arg, metavar="2d:T|3d:T",
                   help=f"AB3DMOT's matching (default {DEFAULT_AB3DMOT_IOU})")
    p.add_argument("--ab3dmot-sum", dest="ab3dmot_sum", default=None, choices=SUMS,
                   help=f"{SUM_HELP}; where the other gives other figures, a line shows them")
    p.add_argument("--recall-table", dest="recall_table", default=None, metavar="F", type=output_file,
                   help="write AB3DMOT's recall points of A and B as CSV (implies --metrics ab3dmot; the columns of "
                        "dfrmot eval --recall-table, with tracker A or B)")
    p.add_argument("--ab3dmot-resamples", dest="ab3dmot_resamples", default=None,
                   type=ab3dmot_resamples_arg,
                   help=f"resamples of AB3DMOT's figures, each a full evaluation of both outputs (default "
                        f"{AB3DMOT_RESAMPLES}, at most {AB3DMOT_MAX_RESAMPLES:,}; about 0.2 s each for 11 sequences; "
                        f"a terminal shows a bar with the time left)")
    p.add_argument("--allow-missing", action="store_true",
                   help="score a sequence without a result file as an empty output (with a warning)")
    p.add_argument("--csv", default=None, metavar="OUT", type=output_file, help="write the tidy table: class seq metric a b diff "
                                                               "ci_low ci_high p_b_better resamples")
    p.add_argument("--html", default=None, metavar="OUT.html", type=output_file,
                   help="write one self-contained page: the figures with their intervals, HOTA per sequence, the "
                        "ground-truth tracks treated most differently, their timelines and bird's-eye views")
    p.set_defaults(func=run_later("dfrmot_jax.cli.compare"))
    return p
