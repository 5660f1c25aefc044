"""The ``dfrmot demo`` parser and the demo's grid, apart from the command (:mod:`dfrmot_jax.cli.demo`),
which is imported when it runs (``errors.run_later``): ``dfrmot demo --help`` imports no sweep."""

from __future__ import annotations

import argparse
from pathlib import Path

from .args import seed_arg
from .commands import HELP
from .errors import run_later

__all__ = ["add_parser", "GRID", "GRIDS", "BASELINES", "NAME", "grid_shape", "default_out"]

#: the demo's grid: the 2D score threshold and the fixed-gain filter's beta and gamma (27 settings)
GRID = {"score_2d": [0.35, 0.45, 0.55], "gain_beta": [0.5, 0.7, 0.9], "gain_gamma": [0.02, 0.05, 0.1]}
#: each tracker family's demo grid (``--family``; 27 settings each): DFR-FastMOT's :data:`GRID`;
#: AB3DMOT's threshold (generalised 3D IoU), min_hits and max_age around its car preset; ByteTrack's
#: track_thresh, match_thresh and track_buffer around its defaults
GRIDS = {"dfr": GRID,
         "ab3dmot": {"threshold": [-0.4, -0.2, 0.0], "min_hits": [1, 2, 3], "max_age": [2, 3, 4]},
         "bytetrack": {"track_thresh": [0.4, 0.5, 0.6], "match_thresh": [0.7, 0.8, 0.9], "track_buffer": [10, 30, 60]}}
#: each family's baseline preset (a point of its grid)
BASELINES = {"dfr": "dfr2023", "ab3dmot": "ab3dmot_car", "bytetrack": "bytetrack_car"}
#: the demo sweep's name, and its work directory's under ``results/``
NAME = "demo"


def default_out(family: str = "dfr") -> Path:
    """The demo's work directory when ``--out`` is not given: ``results/demo`` for DFR-FastMOT, the
    default family, and ``results/demo_FAMILY`` for another (each family's demo its own folder, so
    that one does not replace the other's sweep and page)."""
    return Path("results") / (NAME if family == "dfr" else f"{NAME}_{family}")


def grid_shape(family: str = "dfr") -> str:
    """The family's demo grid's shape, e.g. ``3 x 3 x 3``."""
    return " x ".join(str(len(v)) for v in GRIDS[family].values())


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``demo`` on an argparse ``subparsers`` object; returns its parser."""
    d = sub.add_parser("demo", help=HELP["demo"],
                       description="Generate a synthetic KITTI-layout scene, sweep a grid of settings over it "
                                   f"(the dfr2023 preset as baseline and a {grid_shape()} grid of {', '.join(GRID)}, "
                                   "tracked in one vmapped call and scored), print the best configs "
                                   "beside the baseline and write the HTML report next to the results; no data "
                                   "needed.")
    d.add_argument("--out", metavar="DIR", default=None,
                   help="work directory, kept: DIR/scene, DIR/demo.toml, DIR/sweep (results and report.html) "
                        f"(default: {default_out()}; with --family ab3dmot {default_out('ab3dmot')})")
    d.add_argument("--sequences", type=int, default=4, help="synthetic sequences (default 4)")
    d.add_argument("--frames", type=int, default=120, help="frames per sequence (default 120)")
    d.add_argument("--seed", type=seed_arg, default=0, help="scene seed, >= 0 (default 0)")
    d.add_argument("--top", type=int, default=5, help="configs printed above the baseline (default 5)")
    d.add_argument("--family", choices=list(GRIDS), default="dfr",
                   help="the tracker family swept: dfr (DFR-FastMOT, the default: " + ", ".join(GRID) + "), "
                        "ab3dmot (AB3DMOT, from its 3D detections: " + ", ".join(GRIDS["ab3dmot"]) + ") or "
                        "bytetrack (ByteTrack, from its 2D detections: " + ", ".join(GRIDS["bytetrack"]) + "), its "
                        "preset " + " / ".join(BASELINES.values()) + " as the baseline")
    d.set_defaults(func=run_later("dfrmot_jax.cli.demo"))
    return d
