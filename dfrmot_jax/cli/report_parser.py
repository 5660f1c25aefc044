"""The ``dfrmot report`` parser, apart from the command (:mod:`dfrmot_jax.cli.report`), which is imported
when it runs (``errors.run_later``): ``dfrmot report --help`` imports none of the report."""

from __future__ import annotations

import argparse

from .args import output_file
from .commands import FAMILIES, HELP, OBJECTIVES
from .errors import run_later

__all__ = ["add_parser"]


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``report`` on an argparse ``subparsers`` object; returns its parser."""
    p = sub.add_parser(
        "report", help=HELP["report"],
        description=f"Print the best configs of a sweep or tune directory of any tracker family ({FAMILIES}) "
                    "by --objective, the baseline row beside them, how "
                    "sensitive the score is to each swept axis and, with --folds, the cross-validated best "
                    "(a tune directory: also its own figures). The last line is one JSON object. With --html, "
                    "also one self-contained page to open in a browser and share.")
    p.add_argument("dir", metavar="DIR", help="a sweep or tune directory (dfrmot sweep / tune --out DIR)")
    p.add_argument("--objective", help=f"{OBJECTIVES} (default: the file's objective, else HOTA)")
    p.add_argument("--folds", type=int, help="k-fold cross-validation over sequences (default: the sweep's --folds)")
    p.add_argument("--top", type=int, help="configs listed (default 10)")
    p.add_argument("--class", dest="cls", metavar="CLASS",
                   help="sweeps over several classes: rank on one class (its own parameter values) or on "
                        "'average' (ratios averaged over the classes, counts summed; the default unless the file's "
                        "report.class says otherwise)")
    p.add_argument("--csv", metavar="F", type=output_file,
                   help="also write the tidy table (without the per-alpha column) as CSV")
    p.add_argument("--contrast", metavar="AXIS:HIGH/LOW[:BY]",
                   help="distortion sweeps: the gap between two groups of an axis per level, paired by seed, e.g. "
                        "epsilon:30,60/1,2,3:filter (long minus short memory, per filter); default: the sweep "
                        "file's report.contrast")
    p.add_argument("--html", metavar="OUT.html", type=output_file,
                   help="also write the report as one self-contained HTML page (figures as inline SVG; no script, "
                        "no network): the run's identity, top configs beside the baseline, sensitivity per axis, "
                        "the objective per sequence, the cross-validated figure (the file's --folds, else min(5, "
                        "sequences), printed too: the page and the printed report are one report) and, where the "
                        "directory holds them, robustness curves and contrast, the tune's history and Pareto front")
    p.set_defaults(func=run_later("dfrmot_jax.cli.report"))
    return p
