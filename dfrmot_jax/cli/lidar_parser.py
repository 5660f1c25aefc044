"""The ``dfrmot lidar`` parser (its actions ``simulate`` and ``lift``), apart from the command
(:mod:`dfrmot_jax.cli.lidar`), which is imported when it runs (``errors.run_later``): ``dfrmot lidar
--help`` imports the LiDAR settings (:mod:`dfrmot_jax.lidar_settings`, NumPy only), not the LiDAR code."""

from __future__ import annotations

import argparse

from ..lidar_settings import LiftSettings, SimSettings
from ..paths import ENV_VAR
from .args import seed_arg, seqs_arg
from .commands import HELP
from .errors import run_later

__all__ = ["add_parser", "DESCRIPTION"]

DESCRIPTION = ("simulate: write one scan per frame, OUT/velodyne/SSSS/FFFFFF.bin (KITTI's layout: float32 x y z "
               "reflectance), ray-cast from the labelled 3D boxes. lift: write the 3D boxes lifted from scans for a 2D "
               "detector as a 3D detection folder (OUT/SSSS.txt, the 15 PointRCNN columns); 'dfrmot track --det3d "
               "lidar:DIR' lifts on the fly instead.")


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``lidar`` (``simulate``, ``lift``) on an argparse ``subparsers`` object."""
    p = sub.add_parser("lidar", help=HELP["lidar"],
                       description=DESCRIPTION)
    lsub = p.add_subparsers(dest="lidar_command", required=True, metavar="ACTION")
    data_help = f"KITTI tracking training root (default ${ENV_VAR} or ../shared/data/kitti/training)"

    s = lsub.add_parser("simulate", help="write simulated scans DIR/velodyne/SSSS/FFFFFF.bin from the labels")
    s.add_argument("--data", help=data_help)
    s.add_argument("--seqs", type=seqs_arg, help="comma-separated sequences (default: every sequence of label_02)")
    s.add_argument("--out", required=True, help="output folder (scans go to OUT/velodyne/SSSS/)")
    d = SimSettings()
    s.add_argument("--beams", type=int, default=d.beams, help=f"lasers (default {d.beams})")
    s.add_argument("--seed", type=seed_arg, default=0, help="seed (scans are a function of sequence, frame and seed)")
    s.add_argument("--noise", type=float, default=d.range_noise, help=f"range noise std, m (default {d.range_noise})")
    s.add_argument("--dropout", type=float, default=d.dropout, help="probability a return is lost (default 0)")
    s.add_argument("--clutter", type=float, default=d.clutter, help="probability a ray returns from rain (default 0)")
    s.add_argument("--fov", type=float, default=d.fov,
                   help=f"half-width of the azimuths cast, degrees from forward (default {d.fov:g}: the camera's "
                        f"view; 180: a whole turn)")

    lf = lsub.add_parser("lift", help="write the 3D boxes lifted from scans as a detection folder")
    lf.add_argument("--data", help=data_help)
    lf.add_argument("--det2d", default="rrc", help="2D detector: name under ROOT/detections, or a directory")
    lf.add_argument("--scans", required=True, help="folder holding velodyne/SSSS/FFFFFF.bin")
    lf.add_argument("--class", dest="cls", default="car", help="car | pedestrian")
    lf.add_argument("--seqs", type=seqs_arg, help="comma-separated sequences (default: those whose ground truth has the class)")
    lf.add_argument("--set", action="append", metavar="NAME=VALUE",
                    help="a lifting setting (repeatable): " + ", ".join(LiftSettings._fields))
    lf.add_argument("--out", required=True, help="output folder of SSSS.txt files (15 PointRCNN columns)")
    for action in (s, lf):      # --debug also after the action, as after any command
        action.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help=argparse.SUPPRESS)
    p.set_defaults(func=run_later("dfrmot_jax.cli.lidar"))
    return p
