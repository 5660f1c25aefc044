"""``dfrmot report``: best configs, baseline, sensitivity and cross-validation of a sweep directory.

Usage::

    dfrmot report results/grid [--objective HOTA|MOTA|IDF1|AssA|IDSW] [--folds 5] [--top 10]
    dfrmot report results/classes --class pedestrian      # several classes: one class, or average (default)
    dfrmot report results/robustness --contrast epsilon:30,60/1,2,3:filter    # distortion sweeps
    dfrmot report results/grid --html results/grid.html   # also one self-contained page to open and share

The report's last line is one JSON object.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..report import RAW_COLUMN, load_results, read_manifest, report_folds, sweep_report, write_html
from .args import output_file
from .commands import HELP
from .errors import guarded

__all__ = ["add_parser", "run", "parse_contrast"]


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``report`` on an argparse ``subparsers`` object; returns its parser."""
    p = sub.add_parser(
        "report", help=HELP["report"],
        description="Print the best configs of a sweep (by --objective), the baseline row beside them, how "
                    "sensitive the score is to each swept axis and, with --folds, the cross-validated best "
                    "(a tune directory: also its own figures). The last line is one JSON object. With --html, "
                    "also one self-contained page to open in a browser and share.")
    p.add_argument("dir", metavar="DIR", help="a sweep or tune directory (dfrmot sweep / tune --out DIR)")
    p.add_argument("--objective", help="HOTA (default), MOTA, IDF1, AssA, DetA, IDSW (minimised), ...")
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
    p.set_defaults(func=guarded(run))
    return p


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


def run(args) -> int:
    """Compute the report once, print it and, with ``--html``, draw the page from the same report
    (whose folds, when nobody set them, are then :func:`report_folds`'s, printed too)."""
    contrast = parse_contrast(args.contrast) if getattr(args, "contrast", None) else None
    html = getattr(args, "html", None)
    folds, note = report_folds(args.dir, args.folds) if html is not None else (args.folds, "")
    rep = sweep_report(Path(args.dir), objective=args.objective or _manifest_objective(args.dir), folds=folds,
                       top=10 if args.top is None else args.top, contrast=contrast, cls=getattr(args, "cls", None),
                       folds_note=note)
    print(rep.text)
    if html is not None:
        print(f"dfrmot report: wrote {write_html(rep, html)}", file=sys.stderr)
    if args.csv is not None:
        df = load_results(args.dir, allow_partial=True)
        df.drop(columns=[RAW_COLUMN], errors="ignore").to_csv(args.csv, index=False)
    return 0


def _manifest_objective(d) -> str:
    """The directory's objective (its manifest's), else HOTA; a damaged manifest is a ValueError
    naming it (:func:`~dfrmot_jax.report.read_manifest`); a directory without one is the report's to refuse."""
    try:
        return read_manifest(Path(d)).get("objective") or "HOTA"
    except FileNotFoundError:
        return "HOTA"
