"""``dfrmot lidar``: simulated LiDAR scans and the lifted 3D detections of a 2D detector.

``dfrmot lidar simulate --data ROOT --out DIR [--seqs ...] [--beams 32] [--seed S]`` writes one scan
per frame, ``DIR/velodyne/SSSS/FFFFFF.bin`` (KITTI's layout: float32 x y z reflectance), ray-cast
from the labelled 3D boxes (``dfrmot_jax.lidar.simulate``). ``dfrmot lidar lift --data ROOT --det2d
rrc --scans DIR --out DETDIR [--set shrink=0.2 ...]`` writes the lifted boxes as a 3D detection
folder (``DETDIR/SSSS.txt``, the 15 PointRCNN columns); ``dfrmot track --det3d lidar:DIR`` lifts
on the fly instead (cached per setting).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from ..data import detection_dir, load_sequences
from ..io.kitti import read_calib, read_tracking_labels, sequence_lengths
from ..lidar import LiftSettings, SimSettings, simulate_to_folder, with_setting, write_detections3d
from ..paths import ENV_VAR, default_data_root
from .args import seed_arg
from .commands import HELP
from .errors import guarded
from .track_parser import parse_seqs, seqs_arg

__all__ = ["add_parser", "run", "run_simulate", "run_lift", "lift_settings"]

DESCRIPTION = ("simulate: write one scan per frame, OUT/velodyne/SSSS/FFFFFF.bin (KITTI's layout: float32 x y z "
               "reflectance), ray-cast from the labelled 3D boxes. lift: write the 3D boxes lifted from scans for a 2D "
               "detector as a 3D detection folder (OUT/SSSS.txt, the 15 PointRCNN columns); 'dfrmot track --det3d "
               "lidar:DIR' lifts on the fly instead.")


def lift_settings(items) -> LiftSettings:
    """``--set NAME=VALUE`` items (``shrink=0.1``, ``lift.tolerance=0.4``, ``crop_lo=0.5,-20,-1.2``)."""
    s = LiftSettings()
    for item in items or []:
        name, eq, raw = item.partition("=")
        if not eq:
            raise ValueError(f"--set {item!r}: expected name=value")
        s = with_setting(s, name, raw.strip())
    return s


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
    p.set_defaults(func=guarded(run))
    return p


def run(args) -> int:
    """``dfrmot lidar ACTION``."""
    return run_simulate(args) if args.lidar_command == "simulate" else run_lift(args)


def run_simulate(args) -> int:
    root = Path(args.data) if args.data else default_data_root()
    settings = SimSettings(beams=args.beams, range_noise=args.noise, dropout=args.dropout, clutter=args.clutter,
                           fov=args.fov).validate()
    lengths = sequence_lengths(root, parse_seqs(args.seqs))
    t0, total = time.perf_counter(), 0
    for name, n in lengths.items():
        labels = read_tracking_labels(root / "label_02" / f"{name}.txt")
        calib = read_calib(root / "calib" / f"{name}.txt")
        pts = simulate_to_folder(args.out, labels, calib, n, name, settings, seed=args.seed)
        total += n
        print(f"{name}: {n} scans, {pts / max(n, 1):.0f} points per scan")
    print(f"wrote {total} scans to {Path(args.out) / 'velodyne'} in {time.perf_counter() - t0:.1f} s")
    return 0


def run_lift(args) -> int:
    root = Path(args.data) if args.data else default_data_root()
    settings = lift_settings(args.set)
    detection_dir(root, args.det2d, args.cls)                      # a bad detector name fails before any work
    t0 = time.perf_counter()
    seqs = load_sequences(root, args.det2d, f"lidar:{args.scans}", args.cls, parse_seqs(args.seqs), lift=settings)
    out = Path(args.out)
    n = 0
    for s in seqs:
        write_detections3d(out / f"{s.name}.txt", s.det3d)
        n += s.det3d.frame.size
    print(f"lifted {n} of the 2D detections ({', '.join(f'{k}={v}' for k, v in settings._asdict().items())}) "
          f"into {len(seqs)} files in {out} in {time.perf_counter() - t0:.1f} s")
    return 0
