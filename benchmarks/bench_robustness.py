"""End-to-end time of the robustness study (``sweeps/robustness.toml``): short vs long memory
(epsilon 1, 2, 3 vs 30, 60) x fixed-gain / Kalman filter, under independent detection drops
(0 ... 0.6) and occlusion bursts (1 ... 30 frames), 10 seeds per level, on the whole KITTI car
training split (RRC + PointRCNN): 10 settings x 131 distortion lanes = 1,310 tracker lanes, every
lane of an option group vmapped in the same batch, tracked, scored (TrackEval-identical HOTA /
CLEAR / Identity) and written as Parquet chunks, from a cold start (data, ground truth, ground-truth
identities of the detections, compilation included); then the report with the long-minus-short
memory contrast.

    python benchmarks/bench_robustness.py [--sweep FILE] [--out DIR] [--workers N] [--quiet-load 1.0]

The last line of the output is one JSON object: configs (parameter / option settings), levels
(per kind, level 0 included), seeds, lanes, seconds, cpu_seconds, cores_used, load averages,
machine, and the answer (per kind: up to which level long memory significantly helps, HOTA / AssA
/ IDSW gaps). Without KITTI data it prints a JSON line with "skipped".
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import time
from pathlib import Path

from machine import cold_output_dir, cpu_time, machine_info

HERE = Path(__file__).resolve().parent
DEFAULT_SWEEP = HERE.parent / "sweeps" / "robustness.toml"


def _wait_quiet(threshold: float, max_wait: float) -> float:
    """Wait (up to max_wait s) until the 1-min load average is below threshold; returns it."""
    t0 = time.monotonic()
    while os.getloadavg()[0] >= threshold and time.monotonic() - t0 < max_wait:
        time.sleep(10)
    return os.getloadavg()[0]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sweep", default=str(DEFAULT_SWEEP), help="sweep file (default: sweeps/robustness.toml)")
    ap.add_argument("--out", help="keep the results here (default: a temporary directory, removed)")
    ap.add_argument("--workers", type=int, default=None, help="metric processes (default: the sweep's choice)")
    ap.add_argument("--chunk", type=int, default=None, help="configs per chunk (default: the file's)")
    ap.add_argument("--quiet-load", type=float, default=None,
                    help="first wait (up to --max-wait s) until the 1-min load average is below this")
    ap.add_argument("--max-wait", type=float, default=900.0)
    ap.add_argument("--progress", action="store_true", help="show the progress bar")
    args = ap.parse_args(argv)

    from dfrmot_jax.paths import data_available, default_data_root
    from dfrmot_jax.sweep import (expand, load_spec, n_settings, robustness_contrast, robustness_summary, run_sweep,
                                  sweep_report)

    machine = machine_info()
    spec = load_spec(args.sweep)
    table = expand(spec)
    d = spec.distortion
    if d is None:
        raise SystemExit(f"{args.sweep}: not a distortion sweep (no [distortion] table)")
    shape = {"configs": n_settings(table),
             "levels": min(len(lv) for _, lv in d.kinds), "levels_per_kind": {k: len(lv) for k, lv in d.kinds},
             "kinds": [k for k, _ in d.kinds], "seeds": len(d.seeds), "lanes": len(table)}
    if spec.data_root is None and not data_available(default_data_root()):
        print(f"KITTI data not found at {default_data_root()} (set DFRMOT_DATA)")
        print(json.dumps({"benchmark": "robustness", **shape, "seconds": None, "skipped": "no KITTI data",
                          **machine}))
        return 0

    if args.quiet_load is not None:
        _wait_quiet(args.quiet_load, args.max_wait)
    out = cold_output_dir(args.out, "dfrmot_bench_robustness_")


    load0 = os.getloadavg()
    try:
        t0, c0 = time.perf_counter(), cpu_time()
        df = run_sweep(spec, out, progress=args.progress, workers=args.workers, chunk=args.chunk)
        seconds = time.perf_counter() - t0
        cpu_seconds = cpu_time() - c0      # this process and its metric workers (forkserver children too)
        load1 = os.getloadavg()
        t1 = time.perf_counter()
        rep = sweep_report(df, objective=spec.objective, top=spec.top, contrast=spec.contrast)
        report_seconds = time.perf_counter() - t1
    finally:
        if not args.out:
            shutil.rmtree(out, ignore_errors=True)
    print(rep.text)
    comb = df[df["sequence"] == "COMBINED"]
    answer = {}
    if spec.contrast is not None:
        c = spec.contrast
        summ = robustness_summary(robustness_contrast(df, c.axis, c.high, c.low, ("HOTA", "AssA", "IDSW")))
        for r in summ.to_dict("records"):
            answer.setdefault(r["kind"], {})[r["metric"]] = {
                k: (None if v != v else round(float(v), 3))
                for k, v in r.items() if k in ("gap_at_0", "helps_up_to", "stops_at", "crossing", "gap_before",
                                               "max_gap", "max_gap_level")}
    result = {
        "benchmark": "robustness", "sweep": spec.name, **shape, "seconds": round(seconds, 2),
        "lanes_per_s": round(len(comb) / seconds, 2),
        "lane_frames_per_s": round(len(comb) * int(comb["frames"].iloc[0]) / seconds),
        "frames": int(comb["frames"].iloc[0]), "sequences": int(rep.summary["sequences"]),
        "report_seconds": round(report_seconds, 2), "cpu_seconds": round(cpu_seconds, 1),
        # what the sweep got of the machine: other processes running at the same time lower it
        "cores_used": round(cpu_seconds / seconds, 2),
        "load_avg_start": [round(v, 2) for v in load0], "load_avg_end": [round(v, 2) for v in load1],
        "overflow_configs": int((comb["overflow"] > 0).sum()),
        "contrast": None if spec.contrast is None else f"{spec.contrast.axis} {list(spec.contrast.high)} - "
                                                       f"{list(spec.contrast.low)}",
        "answer": answer, **machine,
    }
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
