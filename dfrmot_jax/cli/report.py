"""``dfrmot report``: best configs, baseline, sensitivity and cross-validation of a sweep directory.

Usage::

    dfrmot report results/grid [--objective HOTA|MOTA|IDF1|AssA|IDSW] [--folds 5] [--top 10]
    dfrmot report results/classes --class pedestrian      # several classes: one class, or average (default)
    dfrmot report results/robustness --contrast epsilon:30,60/1,2,3:filter    # distortion sweeps
    dfrmot report results/grid --html results/grid.html   # also one self-contained page to open and share

The report's last line is one JSON object.
"""

from __future__ import annotations

import sys
from pathlib import Path

from ..metrics.columns import canonical_objective
from ..report import RAW_COLUMN, load_results, read_manifest, report_folds, sweep_report, write_html

__all__ = ["run", "parse_contrast"]


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
    if args.objective is not None:      # an empty --objective is refused, not read as "the file's"
        try:
            objective = canonical_objective(args.objective)
        except ValueError as e:
            raise ValueError(f"--objective {args.objective!r}: {str(e).partition(': ')[2]}") from None
    else:
        objective = _manifest_objective(args.dir)
    folds, note = report_folds(args.dir, args.folds, objective) if html is not None else (args.folds, "")
    rep = sweep_report(Path(args.dir), objective=objective, folds=folds,
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
