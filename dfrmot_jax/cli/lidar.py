"""``dfrmot lidar``: simulated LiDAR scans and the lifted 3D detections of a 2D detector.

``dfrmot lidar simulate --data ROOT --out DIR [--seqs ...] [--beams 32] [--seed S]`` writes one scan
per frame, ``DIR/velodyne/SSSS/FFFFFF.bin`` (KITTI's layout: float32 x y z reflectance), ray-cast
from the labelled 3D boxes (``dfrmot_jax.lidar.simulate``). ``dfrmot lidar lift --data ROOT --det2d
rrc --scans DIR --out DETDIR [--set shrink=0.2 ...]`` writes the lifted boxes as a 3D detection
folder (``DETDIR/SSSS.txt``, the 15 PointRCNN columns); ``dfrmot track --det3d lidar:DIR`` lifts
on the fly instead (cached per setting).
"""

from __future__ import annotations

import time
from pathlib import Path

from ..data import detection_dir, load_sequences
from ..io.kitti import read_calib, read_tracking_labels, sequence_lengths
from ..lidar import LiftSettings, SimSettings, simulate_to_folder, with_setting, write_detections3d
from ..paths import default_data_root
from .args import parse_seqs

__all__ = ["run", "run_simulate", "run_lift", "lift_settings"]


def lift_settings(items) -> LiftSettings:
    """``--set NAME=VALUE`` items (``shrink=0.1``, ``lift.tolerance=0.4``, ``crop_lo=0.5,-20,-1.2``)."""
    s = LiftSettings()
    for item in items or []:
        name, eq, raw = item.partition("=")
        if not eq:
            raise ValueError(f"--set {item!r}: expected name=value")
        s = with_setting(s, name, raw.strip())
    return s


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
