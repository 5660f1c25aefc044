"""``dfrmot demo``: the main job on a synthetic scene, no data needed. A synthetic KITTI-layout scene
(labels, calibration, 2D and 3D detections: :func:`~dfrmot_jax.synthetic.make_scene`) is written to
``DIR/scene``, a sweep file over it to ``DIR/demo.toml`` (the dfr2023 preset as baseline and a grid
of :data:`GRID`; with ``--family ab3dmot`` AB3DMOT's car preset and its grid, ``GRIDS``), and the
sweep is run as ``dfrmot sweep`` runs it (:func:`~dfrmot_jax.sweep.run_sweep`:
every config tracked in one vmapped call and scored) into ``DIR/sweep``; the best configs are printed
beside the baseline, and the report of the folder (computed once, :func:`~dfrmot_jax.sweep.sweep_report`)
is written next to its results as ``DIR/sweep/report.html``.

A rerun in the same ``DIR`` starts the demo's own sweep over (its scene was just rewritten); a
folder ``DIR/sweep`` of another sweep is refused, as ``dfrmot sweep`` refuses it.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from ..trackers.registry import family_config
from ..io.lock import folder_lock
from ..report import SweepReport, sweep_report, write_html
from ..report.analysis import fmt_value
from ..report.text import paragraph, text_table
from ..sweep import load_spec, run_sweep
from ..sweep.folder import clear, read_old_manifest
from ..synthetic import make_scene
from .demo_parser import BASELINES, GRID, GRIDS, NAME, default_out, grid_shape

__all__ = ["run", "GRID", "sweep_file"]

#: the columns printed beside the swept axes
SHOWN = ["HOTA", "DetA", "AssA", "MOTA", "IDF1", "IDSW"]


def run(args) -> int:
    """Scene, sweep file, sweep, report; prints the best configs beside the baseline."""
    if args.sequences < 1:
        raise ValueError(f"--sequences {args.sequences}: expected a whole number >= 1")
    if args.frames < 1:
        raise ValueError(f"--frames {args.frames}: expected a whole number >= 1 (frames per sequence)")
    if args.top < 1:
        raise ValueError(f"--top {args.top}: expected a whole number >= 1 (configs printed)")
    work = Path(args.out) if args.out is not None else default_out(getattr(args, "family", "dfr"))
    root = make_scene(work / "scene", n_sequences=args.sequences, n_frames=args.frames, seed=args.seed)
    names = [f"{s:04d}" for s in range(args.sequences)]
    print(f"scene: {len(names)} synthetic sequences x {args.frames} frames in KITTI layout (labels, calib, 2D and 3D "
          f"detections) -> {root}")
    family = getattr(args, "family", "dfr")
    toml = work / f"{NAME}.toml"
    toml.write_text(sweep_file(root.resolve(), names, family))
    print(f"sweep file: {toml}: {family_config(family).title}, the {BASELINES[family]} preset as baseline + a "
          f"{grid_shape(family)} grid of {', '.join(GRIDS[family])}")
    out = work / "sweep"
    _restart(out, toml)
    df = run_sweep(load_spec(toml), out, progress=False, workers=0, log=lambda m: print(paragraph(m)))
    rep = sweep_report(out, objective="HOTA", top=args.top)
    _print_report(rep, args.top, family)
    page = write_html(rep, out / "report.html")
    print(f"\nHTML report: {page}")
    print(f"full report: dfrmot report {out}; rerun: dfrmot sweep {toml} --out {out}")
    over = df[(df["sequence"] == "COMBINED") & (df["overflow"] > 0)]
    if len(over):
        print(f"warning: {len(over)} config(s) overflowed their track memory (column 'overflow')", file=sys.stderr)
        return 3
    return 0


def sweep_file(root: Path, sequences: list[str], family: str = "dfr") -> str:
    """The demo's sweep file (TOML): the scene, the family's baseline preset and its grid
    (:data:`~.demo_parser.GRIDS`), and folds min(5, sequences) for the report (none for one
    sequence). A family reading 3D detections only names no 2D detector."""
    folds = min(5, len(sequences))
    grid = "\n".join(f"{k} = [{', '.join(map(repr, v))}]" for k, v in _grid_on_baseline(family).items())
    shape, axes, base = grid_shape(family), ", ".join(GRIDS[family]), BASELINES[family]
    fc = family_config(family)
    det2d = "det2d = \"synth2d\"\n" if "2d" in fc.detections else ""
    det3d = "det3d = \"synth3d\"\n" if "3d" in fc.detections else ""
    options = f"\n[options]\nfamily = {json.dumps(family)}\n" if family != "dfr" else ""
    return (f"# dfrmot demo: {fc.title}, the {base} preset and a {shape} grid of {axes} on a synthetic scene.\n"
            f"name = {json.dumps(NAME)}\n"
            f"description = \"the {base} baseline + a {shape} grid of {axes} (dfrmot demo)\"\n"
            f"chunk = 64\n\n[data]\nroot = {json.dumps(str(root))}\n{det2d}{det3d}"
            f"class = \"car\"\nsequences = {json.dumps(sequences)}\n\n[baseline]\npreset = \"{base}\"\n\n"
            f"[params]\n# values equal to the preset's are written as its exact constants (the authors' float gains)\n"
            f"{grid}\n{options}" + (f"\n[report]\nfolds = {folds}\n" if folds >= 2 else ""))


def _grid_on_baseline(family: str = "dfr") -> dict[str, list[float]]:
    """The family's grid with each value equal to its baseline preset's at float32 precision replaced
    by the preset's own (DFR's: the C++ code's float gains, e.g. 0.9 as 0.89999998...): the baseline
    is then a point of the grid, and each axis has its three values, not a fourth one next to the
    preset's."""
    base = family_config(family).preset(BASELINES[family], "car")[0]
    return {k: [type(v)(getattr(base, k)) if np.float32(v) == np.float32(getattr(base, k)) else v for v in vs]
            for k, vs in GRIDS[family].items()}


def _restart(out: Path, toml: Path) -> None:
    """A previous run of this demo's sweep file in ``out`` is cleared (the scene was rewritten, maybe
    with another seed, so its chunks are stale); any other sweep there is left to ``run_sweep``."""
    old, _ = read_old_manifest(out)
    if old is not None and old.get("name") == NAME and Path(old.get("source") or "").resolve() == toml.resolve():
        with folder_lock(out, "demo"):
            clear(out, {"sweep"})


def _print_report(rep: SweepReport, top: int, family: str = "dfr") -> None:
    """The best ``top`` configs beside the baseline, the gain and the cross-validated figure."""
    s = rep.summary
    axes = [a for a in GRIDS[family] if a in rep.top.columns]
    table = rep.top_with_baseline(top)[["rank", "config", *SHOWN, *axes]]
    print(f"\ntop {len(table) - (rep.baseline is not None)} of {s['configs']} configs by HOTA (COMBINED over "
          f"{s['sequences']} sequences, in-sample) and the baseline (preset {BASELINES[family]}):")
    print(text_table(table, keys=("rank",), float_format=lambda v: f"{v:.2f}"))
    best, base = rep.top.iloc[0], rep.baseline
    if base is not None:
        changed = [f"{a} {fmt_value(base[a])} -> {fmt_value(best[a])}" for a in axes if best[a] != base[a]]
        print(f"best vs baseline: HOTA {best['HOTA']:.2f} vs {base['HOTA']:.2f} ({best['HOTA'] - base['HOTA']:+.2f}); "
              f"changed: {', '.join(changed) or 'nothing (the baseline is the best)'}")
    if rep.cv is not None:
        print(f"{s['folds']}-fold cross-validated HOTA {rep.cv['cross_validated']:.2f} (each sequence scored with the "
              f"config chosen on the others)" + (f" vs baseline {base['HOTA']:.2f}" if base is not None else ""))
