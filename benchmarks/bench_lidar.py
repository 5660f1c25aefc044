"""Benchmark: lifting the whole car split from simulated scans (simulation included), then more shrinks.

For each car sequence (20 sequences, 7,863 frames): simulate every frame's scan in memory
(``lidar.simulate``, 64 beams, the camera's view) and lift the RRC detections with the default
settings (``lidar.lift``: voxel grid, crop, projection, shrink 0.2, clusters); sequences run on
``--workers`` processes (default 2, the issue's "2 cores"). Then each further shrink value lifts
again from the first stage (``lift_prepared``; the first stage travels to the workers, pickling
included). Also, indicative: writing and reading back one sequence's scans as ``.bin`` files.

The LAST line is one JSON object: ``first_setting_s`` (simulation + lifting, wall), ``simulate_cpu_s``,
``prepare_cpu_s``, ``lift_cpu_s`` (summed over workers), ``further_shrink_s`` {shrink: wall s},
``frames``, ``lifted``, ``io`` (one sequence written and read), machine info and the load average.

    python benchmarks/bench_lidar.py [--data ROOT] [--workers 2] [--shrinks 0,0.1,0.3]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))


def first_setting(task):
    """One sequence: simulate all frames, lift with the defaults -> (seq, times, prepared, lifted count)."""
    import numpy as np

    from dfrmot_jax.io.kitti import read_calib, read_detections_2d, read_tracking_labels
    from dfrmot_jax.lidar import LiftSettings, SimSettings, lift_prepared, prepare_points, simulate_sequence

    root, seq, n = task
    root = Path(root)
    labels = read_tracking_labels(root / "label_02" / f"{seq}.txt")
    calib = read_calib(root / "calib" / f"{seq}.txt")
    det2 = read_detections_2d(root / "detections" / "rrc" / "car" / f"{seq}.txt")
    t0 = time.process_time()
    scans = dict(simulate_sequence(labels, calib, n, seq, SimSettings(), seed=0))
    t1 = time.process_time()
    points = int(sum(v.shape[0] for v in scans.values()))
    prep = prepare_points(scans, det2.frame, det2.box, det2.score, calib, LiftSettings())
    del scans
    t2 = time.process_time()
    lifted = lift_prepared(prep, LiftSettings())
    t3 = time.process_time()
    return seq, (t1 - t0, t2 - t1, t3 - t2), prep, int(lifted.rows.size), points, int(np.asarray(prep.rows).size)


def again(task):
    from dfrmot_jax.lidar import LiftSettings, lift_prepared

    prep, shrink = task
    return int(lift_prepared(prep, LiftSettings(shrink=shrink)).rows.size)


def io_check(root: Path, seq: str, n: int) -> dict:
    """Write one sequence's simulated scans as .bin and read them back (indicative I/O)."""
    from dfrmot_jax.io.kitti import read_calib, read_tracking_labels
    from dfrmot_jax.lidar import read_scan, scan_path, simulate_to_folder

    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        pts = simulate_to_folder(tmp, read_tracking_labels(root / "label_02" / f"{seq}.txt"),
                                 read_calib(root / "calib" / f"{seq}.txt"), n, seq)
        t_write = time.perf_counter() - t
        t = time.perf_counter()
        for f in range(n):
            read_scan(scan_path(tmp, seq, f))
        t_read = time.perf_counter() - t
    return {"sequence": seq, "frames": n, "mbytes": round(pts * 16 / 1e6, 1), "simulate_write_s": round(t_write, 2),
            "read_s": round(t_read, 2)}


def main() -> None:
    from machine import machine_info

    from dfrmot_jax.data import sequences_with_class
    from dfrmot_jax.io.kitti import sequence_lengths
    from dfrmot_jax.paths import default_data_root

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=None, help="KITTI tracking training root (default: default_data_root())")
    ap.add_argument("--workers", type=int, default=2, help="processes (default 2)")
    ap.add_argument("--shrinks", default="0,0.1,0.3", help="further shrink values (default 0,0.1,0.3)")
    ap.add_argument("--seqs", default=None, help="comma-separated sequences (default: the car split)")
    args = ap.parse_args()
    root = Path(args.data) if args.data else default_data_root()
    seqs = args.seqs.split(",") if args.seqs else sequences_with_class(root, "car")
    lengths = sequence_lengths(root, seqs)
    tasks = sorted(((str(root), s, lengths[s]) for s in seqs), key=lambda t: -t[2])   # longest first
    load0 = os.getloadavg()
    with ProcessPoolExecutor(args.workers) as pool:
        list(pool.map(again, []))                                   # start the workers
        t = time.perf_counter()
        results = list(pool.map(first_setting, tasks))
        first = time.perf_counter() - t
        preps = [r[2] for r in results]
        further = {}
        for shrink in (float(v) for v in args.shrinks.split(",") if v.strip()):
            t = time.perf_counter()
            counts = list(pool.map(again, [(p, shrink) for p in preps]))
            further[shrink] = {"s": round(time.perf_counter() - t, 2), "lifted": int(sum(counts))}
    frames = int(sum(lengths.values()))
    cpu = [round(sum(r[1][k] for r in results), 2) for k in range(3)]
    io = io_check(root, min(seqs, key=lambda s: lengths[s]), min(lengths.values()))
    out = {"benchmark": "lidar", "sequences": len(seqs), "frames": frames, "workers": args.workers,
           "first_setting_s": round(first, 2), "simulate_cpu_s": cpu[0], "prepare_cpu_s": cpu[1], "lift_cpu_s": cpu[2],
           "points_per_scan": round(sum(r[4] for r in results) / frames), "detections": int(sum(r[5] for r in results)),
           "lifted": int(sum(r[3] for r in results)), "further_shrink": further, "io": io,
           "load_before": [round(v, 2) for v in load0], "load_after": [round(v, 2) for v in os.getloadavg()],
           **machine_info()}
    print(f"first setting (simulate + lift, {frames} frames, {args.workers} workers): {first:.1f} s; "
          f"further shrinks: " + ", ".join(f"{k}: {v['s']} s" for k, v in further.items()))
    print(json.dumps(out))


if __name__ == "__main__":
    main()
