"""Benchmark: peak memory of lifting the longest sequence from full-turn scans at real density.

The longest sequence of ``label_02`` (0019: 1,059 frames) is simulated once with a whole-turn
64-beam sensor (``SimSettings(fov=180, az_step=0.17)``: about 120,000 points per scan, as KITTI's
HDL-64E at 10 Hz; ``--az-step 0.09`` gives about 230,000) into ``--scans`` (default
``/tmp/dfrmot_lidar_memory``, outside the repository: about 2 GB of ``.bin`` files; kept for the
next run, ``lidar.simulate_cached``). Its RRC car detections are then lifted with the default
settings in a fresh child process (``lidar.lift_sequence``: the scans read from their files, as
``det3d="lidar:DIR"`` does), which reports its peak resident memory (``ru_maxrss``), its resident
memory after the imports (JAX included: ``import dfrmot_jax``), and the wall time of the lifting.

``--child-path DIR`` runs the child on another copy of the package (e.g. an older commit extracted
with ``git archive COMMIT dfrmot_jax | tar -x -C DIR``): a before / after on the same scans.
``--estimate`` also counts what the whole-sequence path held at once: the scans of every frame with
a kept detection (bytes of their files) and its ``[N_cropped, D_max, 4]`` int64 box array (N_cropped:
the voxel centroids inside the crop, summed over those frames). ``--set NAME=VALUE`` changes a
lifting setting: ``--set crop_lo=0.5,-20,-2`` keeps the simulated ground (1.73 m below the sensor,
cropped away by the default z >= -1.2 m), so that the crop keeps as many points as a real scan's
walls, poles and vegetation would, and the boxes the ground under each car.

The LAST line is one JSON object: ``peak_rss_mb``, ``import_rss_mb``, ``lift_s``, ``frames``,
``points_per_scan``, ``scan_gb`` (the sequence's files), ``lifted``, the lifting settings changed,
the child's package path and commit, machine info and the load average.

    python benchmarks/bench_lidar_memory.py [--data ROOT] [--scans DIR] [--az-step 0.17] [--set NAME=VALUE]
                                            [--child-path DIR] [--commit C] [--estimate]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

REPO = Path(__file__).resolve().parent.parent


def lift_settings(items: list[str]):
    """``LiftSettings`` from ``NAME=VALUE`` items."""
    from dfrmot_jax.lidar import LiftSettings, with_setting

    settings = LiftSettings()
    for item in items:
        name, _, raw = item.partition("=")
        settings = with_setting(settings, name, raw)
    return settings


def child(root: str, scans: str, seq: str, n: int, sets: list[str]) -> None:
    """In the child process: lift one sequence from its scan files; print one JSON line."""
    import resource

    import dfrmot_jax  # noqa: F401  (the package as every caller has it: JAX included)
    from dfrmot_jax.io.kitti import read_calib, read_detections_2d
    from dfrmot_jax.lidar import lift_sequence

    settings = lift_settings(sets)

    def rss_mb() -> float:
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0

    imported = rss_mb()
    det2 = read_detections_2d(Path(root) / "detections" / "rrc" / "car" / f"{seq}.txt")
    calib = read_calib(Path(root) / "calib" / f"{seq}.txt")
    t = time.perf_counter()
    det3 = lift_sequence(scans, seq, n, det2, calib, settings, "car")
    lift_s = time.perf_counter() - t
    print(json.dumps({"import_rss_mb": round(imported, 1), "peak_rss_mb": round(rss_mb(), 1),
                      "lift_s": round(lift_s, 2), "lifted": int(det3.frame.size),
                      "package": str(Path(dfrmot_jax.__file__).resolve().parent)}))


def git_commit(path: Path) -> str | None:
    """The commit checked out at ``path`` (None outside a git work tree)."""
    try:
        out = subprocess.run(["git", "-C", str(path), "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                             check=True)
    except (OSError, subprocess.CalledProcessError):
        return None
    dirty = subprocess.run(["git", "-C", str(path), "status", "--porcelain", "--untracked-files=no"],
                           capture_output=True, text=True).stdout.strip()
    return out.stdout.strip() + ("-dirty" if dirty else "")


def old_path_estimate(root: Path, scans: Path, seq: str, s) -> dict:
    """What the whole-sequence first stage held at once: the scans of every frame with a kept
    detection (bytes) and its ``[N_cropped, D_max, 4]`` int64 array (N_cropped counted here one scan
    at a time: the voxel centroids inside the crop)."""
    import numpy as np

    from dfrmot_jax.io.kitti import read_detections_2d
    from dfrmot_jax.lidar import read_scan, scan_path
    from dfrmot_jax.lidar.lift import crop_mask, detection_boxes, voxel_grid

    det2 = read_detections_2d(root / "detections" / "rrc" / "car" / f"{seq}.txt")
    keep, _ = detection_boxes(det2.box, det2.score, s.score_cut)
    frames, per_frame = np.unique(det2.frame[keep], return_counts=True)
    held = sum(scan_path(scans, seq, int(f)).stat().st_size for f in frames)
    cropped = 0
    for f in frames:
        pts = read_scan(scan_path(scans, seq, int(f)))[:, :3]
        cent, _ = voxel_grid(pts, np.zeros(pts.shape[0], np.int64), s.leaf)
        cropped += int(crop_mask(cent, s.crop_lo, s.crop_hi).sum())
    d_max = int(per_frame.max(initial=0))
    return {"old_scans_held_mb": round(held / 2**20, 1), "old_cropped_points": cropped, "old_d_max": d_max,
            "old_box_array_mb": round(cropped * d_max * 4 * 8 / 2**20, 1)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=None, help="KITTI tracking training root (default: default_data_root())")
    ap.add_argument("--scans", default="/tmp/dfrmot_lidar_memory", help="scan cache folder (outside the repository)")
    ap.add_argument("--az-step", type=float, default=0.17, help="azimuth step, degrees (default 0.17: ~120k points)")
    ap.add_argument("--seq", default=None, help="the sequence (default: the longest of label_02)")
    ap.add_argument("--child-path", default=str(REPO), help="PYTHONPATH of the child (default: this repository)")
    ap.add_argument("--commit", default=None, help="the commit of --child-path where it is no git work tree")
    ap.add_argument("--estimate", action="store_true", help="also count what the whole-sequence path held")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="a lifting setting (crop_lo=0.5,-20,-2: the ground kept, a crop as full as a real scan's)")
    ap.add_argument("--child", nargs=4, metavar=("ROOT", "SCANS", "SEQ", "N"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        root, scans, seq, n = args.child
        child(root, scans, seq, int(n), args.set)
        return

    from machine import machine_info

    from dfrmot_jax.io.kitti import sequence_lengths
    from dfrmot_jax.lidar import SimSettings, scan_path, simulate_cached
    from dfrmot_jax.paths import default_data_root

    root = Path(args.data) if args.data else default_data_root()
    lengths = sequence_lengths(root)
    seq = args.seq or max(lengths, key=lambda s: (lengths[s], s))
    n = lengths[seq]
    settings = SimSettings(fov=180.0, az_step=args.az_step)
    t = time.perf_counter()
    folder = simulate_cached(args.scans, root, [seq], [n], settings, seed=0)
    simulate_s = time.perf_counter() - t
    sizes = [scan_path(folder, seq, f).stat().st_size for f in range(n)]
    load0 = os.getloadavg()
    env = {**os.environ, "PYTHONPATH": args.child_path}
    sets = [f"--set={item}" for item in args.set]
    proc = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--child", str(root), str(folder), seq,
                           str(n), *sets], env=env, cwd="/", capture_output=True, text=True)
    if proc.returncode:
        sys.exit(f"child failed:\n{proc.stderr}")
    got = json.loads(proc.stdout.strip().splitlines()[-1])
    load1 = os.getloadavg()
    out = {"benchmark": "lidar_memory", "sequence": seq, "frames": n, "az_step": args.az_step, "fov": 180.0,
           "beams": settings.beams, "points_per_scan": round(sum(sizes) / 16 / n),
           "scan_gb": round(sum(sizes) / 1e9, 2), "simulate_s": round(simulate_s, 1), "lift_settings": args.set, **got,
           "commit": args.commit or git_commit(Path(args.child_path)),
           "load_before": [round(v, 2) for v in load0], "load_after": [round(v, 2) for v in load1]}
    if args.estimate:
        out.update(old_path_estimate(root, folder, seq, lift_settings(args.set)))
    out.update(machine_info())
    print(f"lifting {seq} ({n} frames, {out['points_per_scan']} points per scan): peak RSS {got['peak_rss_mb']} MB "
          f"({got['import_rss_mb']} MB after the imports), {got['lift_s']} s")
    print(json.dumps(out))


if __name__ == "__main__":
    main()
