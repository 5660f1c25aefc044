"""End-to-end time of the 1,024-config sweep (``sweeps/kitti_dfr_grid.toml``): the whole KITTI car
training split (RRC + PointRCNN), every config tracked and scored (TrackEval-identical HOTA, CLEAR,
Identity) and written as Parquet chunks, from a cold start (data loading, ground truth, compilation
included), then the report with k-fold cross-validation.

    python benchmarks/bench_sweep.py [--sweep FILE] [--folds 5] [--out DIR] [--workers N] [--ab3dmot 3d:0.25]

``--ab3dmot IOU``: the same sweep with AB3DMOT's figures too (``[metrics] ab3dmot = IOU``); with
``--both`` the sweep runs twice back to back, without and then with them, and the JSON line adds
``plain_seconds`` and ``ab3dmot_added_s`` (what sAMOTA costs the sweep, measured in one run).

The last line of the output is one JSON object: configs, seconds, configs_per_s,
config_frames_per_s, frames, sequences, baseline / best_in_sample / best_cross_validated (HOTA),
the best configs, the tracker's own compacted B = 64 rate measured after the sweep in the same run and
the sweep's ratio to it (``sweep_vs_tracker``, with its goal), peak RSS, machine and versions. Without KITTI data it prints a JSON line with "skipped".
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import time
from dataclasses import replace
from pathlib import Path

from machine import cold_output_dir, cpu_time, machine_info, peak_rss_mb

HERE = Path(__file__).resolve().parent
DEFAULT_SWEEP = HERE.parent / "sweeps" / "kitti_dfr_grid.toml"


def tracker_reference(b: int = 64, lanes_per_call: int = 16) -> float:
    """The tracker's own config-frames/s on the compacted KITTI car split at B = ``b`` (settings around
    dfr2023, as ``bench_tracker.py``'s ``compact_b64``), after its compilation: the reference the
    sweep's rate is a ratio to, measured in the same run."""
    import numpy as np

    from bench_tracker import lane_calls, run_calls, settings
    from dfrmot_jax.trackers.dfr.config import keep_thresholds, preset
    from dfrmot_jax.data import compact_split, load_sequences, pack
    from dfrmot_jax.trackers.dfr.frames import prepare_frames
    from dfrmot_jax.trackers.dfr.track import default_capacity
    from dfrmot_jax.paths import default_data_root

    names = [f"{i:04d}" for i in range(21)]
    split = pack(load_sequences(default_data_root(), "rrc", "pointrcnn", "car", names))
    _, options = preset("dfr2023")
    big = settings(b)
    frames = prepare_frames(compact_split(split, *(float(np.min(x)) for x in keep_thresholds(big))), options)
    cap = default_capacity(prepare_frames(split, options), big, options)
    _, seconds, _ = run_calls(lane_calls(big, b, lanes_per_call), frames, options, cap)
    return b * split.n_frames / seconds


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sweep", default=str(DEFAULT_SWEEP), help="sweep file (default: sweeps/kitti_dfr_grid.toml)")
    ap.add_argument("--folds", type=int, default=5, help="cross-validation folds of the report (default 5)")
    ap.add_argument("--objective", default="HOTA")
    ap.add_argument("--out", help="keep the results here (default: a temporary directory, removed)")
    ap.add_argument("--workers", type=int, default=None, help="metric processes (default: the sweep's choice)")
    ap.add_argument("--progress", action="store_true", help="show the progress bar")
    ap.add_argument("--ab3dmot", default=None, help="also AB3DMOT's figures at this IoU (e.g. 3d:0.25)")
    ap.add_argument("--both", action="store_true", help="with --ab3dmot: run without it first, then with it")
    args = ap.parse_args(argv)

    from dfrmot_jax.paths import data_available, default_data_root
    from dfrmot_jax.sweep import expand, load_spec, run_sweep, sweep_report

    machine = machine_info()
    spec = load_spec(args.sweep)
    if spec.data_root is None and not data_available(default_data_root()):
        print(f"KITTI data not found at {default_data_root()} (set DFRMOT_DATA)")
        print(json.dumps({"configs": len(expand(spec)), "seconds": None, "skipped": "no KITTI data", **machine}))
        return 0

    plain_seconds = None
    if args.ab3dmot and args.both:
        plain_out = cold_output_dir(None, "dfrmot_bench_sweep_plain_")
        try:
            t0 = time.perf_counter()
            run_sweep(spec, plain_out, progress=args.progress, workers=args.workers)
            plain_seconds = time.perf_counter() - t0
        finally:
            shutil.rmtree(plain_out, ignore_errors=True)
    if args.ab3dmot:
        spec = replace(spec, ab3dmot=args.ab3dmot)
    out = cold_output_dir(args.out, "dfrmot_bench_sweep_")

    load0 = os.getloadavg()[0]
    try:
        t0, c0 = time.perf_counter(), cpu_time()
        df = run_sweep(spec, out, progress=args.progress, workers=args.workers)
        seconds = time.perf_counter() - t0
        cpu_seconds = cpu_time() - c0      # this process and its metric workers (forkserver children too)
        load1 = os.getloadavg()[0]
        t1 = time.perf_counter()
        rep = sweep_report(df, objective=args.objective, folds=args.folds)
        report_seconds = time.perf_counter() - t1
    finally:
        if not args.out:
            shutil.rmtree(out, ignore_errors=True)
    print(rep.text)
    comb = df[df["sequence"] == "COMBINED"]
    frames = int(comb["frames"].iloc[0])
    n = int(len(comb))
    s = rep.summary
    result = {
        "benchmark": "sweep", "sweep": spec.name, "configs": n, "seconds": round(seconds, 2),
        "configs_per_s": round(n / seconds, 2), "config_frames_per_s": round(n * frames / seconds),
        "frames": frames, "sequences": int(s["sequences"]), "report_seconds": round(report_seconds, 2),
        "cpu_seconds": round(cpu_seconds, 1),
        # what the sweep got of the machine: other processes running at the same time lower it
        "cores_used": round(cpu_seconds / seconds, 2), "load_avg_1min": [round(load0, 2), round(load1, 2)],
        "objective": s["objective"], "baseline": s["baseline"], "best_in_sample": s["best_in_sample"],
        "best_cross_validated": s.get("best_cross_validated"), "folds": s.get("folds"),
        "best_config": s["best_config"], "overflow_configs": int((comb["overflow"] > 0).sum()),
        "ab3dmot": args.ab3dmot, "peak_rss_mb": round(peak_rss_mb(), 1), **machine,
    }
    # issue 32's goals, ratios in this run: the sweep's config-frames/s >= 0.8x the tracker's own
    # compacted B = 64 rate (0.6x with AB3DMOT's figures); peak memory <= 2 GB (this process's)
    ref = tracker_reference()
    result.update(tracker_compact_b64_config_frames_per_s=round(ref), sweep_vs_tracker=round(result["config_frames_per_s"] / ref, 3),
                  goal_sweep_vs_tracker=0.6 if args.ab3dmot else 0.8, goal_peak_rss_mb=2000)
    if args.ab3dmot:
        best = comb.loc[comb["sAMOTA"].idxmax()]
        result.update(best_samota=float(best["sAMOTA"]), best_samota_config=int(best["config"]))
    if plain_seconds is not None:
        result.update(plain_seconds=round(plain_seconds, 2), ab3dmot_added_s=round(seconds - plain_seconds, 2))
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
