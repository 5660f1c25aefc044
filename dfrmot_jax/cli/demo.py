"""``dfrmot demo``: generate a synthetic scene, track it with the dfr2023 settings and score it (no data needed)."""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from ..api import track
from ..config import Options, Params
from ..data import load_split
from ..metrics import evaluate_files, metrics_table
from ..results import write_lane
from ..synthetic import make_scene
from .errors import guarded

__all__ = ["add_parser", "run"]


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``demo`` on an argparse ``subparsers`` object; returns its parser."""
    d = sub.add_parser("demo", help="generate a synthetic scene, track it and score it (no data needed)",
                       description="Generate a synthetic KITTI-layout scene, track it with the dfr2023 settings "
                                   "and score it (HOTA, MOTA, IDF1); no data needed.")
    d.add_argument("--out", help="work directory, kept (default: a temporary directory, removed at the end)")
    d.add_argument("--sequences", type=int, default=2, help="synthetic sequences (default 2)")
    d.add_argument("--frames", type=int, default=120, help="frames per sequence (default 120)")
    d.add_argument("--seed", type=int, default=0, help="scene seed, >= 0 (default 0)")
    d.set_defaults(func=guarded(run))
    return d


def run(args) -> int:
    """Run the demo in ``--out`` (kept), else in a temporary directory removed at the end."""
    if args.out:
        return _demo(Path(args.out), args, kept=True)
    with tempfile.TemporaryDirectory(prefix="dfrmot_demo_") as work:
        return _demo(Path(work), args, kept=False)


def _demo(work: Path, args, kept: bool) -> int:
    root = make_scene(work / "scene", n_sequences=args.sequences, n_frames=args.frames, seed=args.seed)
    split = load_split(root, "synth2d", "synth3d", "car")
    params, options = Params(), Options()
    res = track(split, params, options)
    write_lane(work / "results", split, res.frames, options, res.ids[0])
    where = "" if kept else " (a temporary directory, removed at the end: --out DIR keeps the files)"
    print(f"synthetic scene: {len(split.names)} sequences, {split.n_frames} frames at {root}")
    print(f"tracked with the dfr2023 settings -> {work / 'results'}{where}")
    table = metrics_table(evaluate_files(work / "results", root, "car"))
    cols = ["HOTA", "DetA", "AssA", "MOTA", "IDF1", "IDSW"]
    print(table[cols].to_string(float_format=lambda v: f"{v:.2f}"))
    return 0
