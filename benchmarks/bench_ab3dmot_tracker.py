"""Benchmark: AB3DMOT's tracker in JAX (dfrmot_jax.trackers.ab3dmot) against the NumPy oracle
(dfrmot_jax.testing.ab3dmot_oracle), KITTI PointRCNN car, the car preset (giou_3d, Hungarian).

- the oracle: ``--oracle-sequences`` (default all 21, 8008 frames), frames/s;
- JAX, one lane (B = 1) over ``--sequences`` (default all 21, 8008 frames): compile + first run, then
  the warm run, frames/s; its lines checked against the reference run (``car_default``);
- AB3DMOT's own code (xinshuoweng/AB3DMOT at 61f3bd7, not part of this project), when
  ``--ab3dmot-python PY --ab3dmot-driver FILE`` (or the env vars ``AB3DMOT_PYTHON``,
  ``AB3DMOT_DRIVER``) are given: a subprocess runs the driver over ``--ab3dmot-sequences`` (default
  ``--sequences``); its frames/s are those of its ``track()`` calls alone; without them the run says
  so and the ratios are against the NumPy oracle only;
- JAX, ``--distinct`` lanes (default 64) that all track differently (16 thresholds -0.6 .. 0.15 x
  max_age 1..4, min_hits 3: no two lanes share a tracking lane) over ``--distinct-sequences``
  (default ``--sequences``): config-frames/s, warm;
- JAX, ``--batch`` lanes (default 64: thresholds -0.4 .. 0.1 x min_hits 1..4 x max_age 1..4, the
  car preset's program) over ``--batch-sequences`` (default 0000-0003, 978 frames): config-frames/s,
  warm (the second call, with the capacities the first one grew to).

Times are wall seconds and this process's CPU seconds; the machine is shared, so the load average
goes with them. The LAST line is one JSON object.

Measured 2026-11-29 (2 vCPU AMD EPYC, quiet; benchmarks/RESULTS.md, "AB3DMOT's programs: one copy of the
pair geometry, in blocks"): AB3DMOT's own code 135.9 frames/s (59 s of track() for 8008 frames, 117 s CPU);
JAX B = 1 4009 frames/s (36168 lines exact), B = 64 24550 config-frames/s: 29.5x and 181x (goals 100x and
1000x). Earlier: pair lists in halves, then one block loop per stage (compile 12 -> 3 s, runs 15-35 % faster).
Dropped: shift-register hull chains (2.7x slower), unrolled chains (compile > 10 min). The time is per pair
(the GIoU hull of every pair, the clip of overlapping ones), so lanes do not amortise it.

    python benchmarks/bench_ab3dmot_tracker.py [--data ROOT] [--buckets 3] [--batch 64] \
        [--ab3dmot-python /work/venvs/ab3dmot-tracker/bin/python --ab3dmot-driver /work/ab3dmot_ref/time_tracker.py]
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np


sys.path.insert(0, str(Path(__file__).resolve().parent))

from machine import cpu_model  # noqa: E402

from dfrmot_jax.trackers import ab3dmot as J  # noqa: E402
from dfrmot_jax.trackers.ab3dmot import batch as ab_batch  # noqa: E402
from dfrmot_jax.io.kitti import sequence_lengths  # noqa: E402
from dfrmot_jax.paths import default_data_root  # noqa: E402
from dfrmot_jax.testing import ab3dmot_oracle as ab  # noqa: E402
from dfrmot_jax.testing.ab3dmot_compare import Comparison, compare_folder  # noqa: E402


def timed(fn):
    w, c = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w, time.process_time() - c


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default=str(default_data_root()))
    ap.add_argument("--sequences", default=",".join(J.ALL_SEQUENCES))
    ap.add_argument("--oracle-sequences", default=",".join(J.ALL_SEQUENCES))
    ap.add_argument("--batch-sequences", default="0000,0001,0002,0003")
    ap.add_argument("--batch", type=int, default=64)
    ap.add_argument("--distinct", type=int, default=64,
                    help="a batch of this many configs that all track differently (16 thresholds x 4 max_age; 0: none)")
    ap.add_argument("--distinct-sequences", default=None, help="its sequences (default --sequences)")
    ap.add_argument("--buckets", type=int, default=3)
    ap.add_argument("--tracks", type=int, default=48)
    ap.add_argument("--skip-oracle", action="store_true")
    ap.add_argument("--ab3dmot-python", default=os.environ.get("AB3DMOT_PYTHON"),
                    help="the Python of an environment with AB3DMOT's dependencies (env AB3DMOT_PYTHON)")
    ap.add_argument("--ab3dmot-driver", default=os.environ.get("AB3DMOT_DRIVER"),
                    help="a script timing AB3DMOT's own tracker, its last line JSON with frames and track_s "
                         "(env AB3DMOT_DRIVER)")
    ap.add_argument("--ab3dmot-sequences", default=None, help="AB3DMOT's own run (default: --sequences)")
    args = ap.parse_args(argv)
    args.distinct_sequences = args.distinct_sequences or args.sequences
    root = Path(args.data)
    res = {"load_start": os.getloadavg()}
    params, options = J.ab3dmot_car(capacity=args.tracks, pairs=32, buckets=args.buckets)

    if args.ab3dmot_python and args.ab3dmot_driver:
        seqs = args.ab3dmot_sequences or args.sequences
        proc = subprocess.run([args.ab3dmot_python, args.ab3dmot_driver, "--data", str(root), "--sequences", seqs,
                               "--category", "Car"], capture_output=True, text=True, check=True)
        own = json.loads(proc.stdout.strip().splitlines()[-1])
        res.update(ab3dmot_frames=own["frames"], ab3dmot_track_s=own["track_s"], ab3dmot_cpu_s=own.get("cpu_s"),
                   ab3dmot_fps=own["frames"] / own["track_s"], ab3dmot_load=own.get("load"))
        print(f"AB3DMOT's own code: {own['frames']} frames, track() {own['track_s']:.1f} s: "
              f"{res['ab3dmot_fps']:.1f} frames/s", flush=True)
    else:
        res.update(ab3dmot_fps=None)
        print("AB3DMOT's own code not timed (no --ab3dmot-python / --ab3dmot-driver): ratios against the oracle "
              "only", flush=True)

    if not args.skip_oracle:
        seqs = args.oracle_sequences.split(",")
        lines, wall, cpu = timed(lambda: ab.track_sequences(root, ab.PRESETS["car_default"], seqs))
        frames = sum(sequence_lengths(root, seqs).values())
        res.update(oracle_frames=frames, oracle_wall_s=wall, oracle_cpu_s=cpu, oracle_fps=frames / wall,
                   oracle_fps_cpu=frames / cpu)
        print(f"oracle: {frames} frames in {wall:.1f} s ({cpu:.1f} s CPU): {frames / wall:.1f} frames/s", flush=True)

    split = J.read_split(root, "car", args.sequences.split(","))
    t = len(split.frames.reset)
    out, wall, cpu = timed(lambda: J.run(params, split.frames, options))
    res.update(b1_frames=t, b1_first_s=wall)
    out, wall, cpu = timed(lambda: J.run(params, split.frames, out.options))
    res.update(b1_warm_s=wall, b1_cpu_s=cpu, b1_fps=t / wall, b1_fps_cpu=t / cpu)
    lines = J.result_lines(split, out)
    total = Comparison(diffs=[])
    for c in compare_folder(lines, root / "reference" / "ab3dmot_tracker" / "head61f3bd7_car_default").values():
        total += c
    res.update(b1_lines_exact=total.exact, b1_lines_differing=total.differing + total.close)
    print(f"JAX B=1: {t} frames, first call {res['b1_first_s']:.1f} s, warm {wall:.2f} s ({cpu:.2f} s CPU): "
          f"{t / wall:.0f} frames/s; lines exact {total.exact}, differing {total.differing + total.close}", flush=True)

    grid = list(itertools.product((-0.4, -0.3, -0.2, 0.1), (1, 2, 3, 4), (1, 2, 3, 4)))[:args.batch]
    batch = J.stack_params([J.Params(th, mh, ma) for th, mh, ma in grid])
    split = J.read_split(root, "car", args.batch_sequences.split(","))
    t = len(split.frames.reset)
    out, wall, cpu = timed(lambda: J.run(batch, split.frames, options))
    res.update(batch=len(grid), batch_frames=t, batch_first_s=wall, batch_peak=int(out.peak.max()),
               batch_tracks=out.options.capacity)
    grown = out.options
    out, wall, cpu = timed(lambda: J.run(batch, split.frames, grown))
    res.update(batch_warm_s=wall, batch_cpu_s=cpu, batch_config_fps=len(grid) * t / wall,
               batch_config_fps_cpu=len(grid) * t / cpu)
    print(f"JAX B={len(grid)}: {t} frames, first call {res['batch_first_s']:.1f} s, warm {wall:.2f} s "
          f"({cpu:.2f} s CPU): {len(grid) * t / wall:.0f} config-frames/s; peak {res['batch_peak']} tracks, "
          f"ran with {grown.capacity}", flush=True)
    if args.distinct:
        # 64 configs that all track differently: 16 thresholds x 4 max_age (no lane shares tracking)
        th = np.round(np.linspace(-0.6, 0.15, 16), 4)
        grid_d = [(float(a), 3, ma) for a in th for ma in (1, 2, 3, 4)][:args.distinct]
        dist = J.stack_params([J.Params(a, mh, ma) for a, mh, ma in grid_d])
        split = J.read_split(root, "car", args.distinct_sequences.split(","))
        t = len(split.frames.reset)
        out, wall, cpu = timed(lambda: J.run(dist, split.frames, options))
        res.update(distinct=len(grid_d), distinct_frames=t, distinct_first_s=wall,
                   distinct_tracking_lanes=len(ab_batch.tracking_lanes(ab_batch.broadcast_lanes(dist))[0].threshold))
        grown = out.options
        out, wall, cpu = timed(lambda: J.run(dist, split.frames, grown))
        res.update(distinct_warm_s=wall, distinct_cpu_s=cpu, distinct_config_fps=len(grid_d) * t / wall,
                   distinct_config_fps_cpu=len(grid_d) * t / cpu)
        print(f"JAX B={len(grid_d)} distinct lanes: {t} frames, first call {res['distinct_first_s']:.1f} s, warm "
              f"{wall:.2f} s ({cpu:.2f} s CPU): {len(grid_d) * t / wall:.0f} config-frames/s", flush=True)
    for name, base in (("ab3dmot", res.get("ab3dmot_fps")), ("oracle", res.get("oracle_fps"))):
        if base:
            res[f"b1_vs_{name}"] = res["b1_fps"] / base
            res[f"batch_vs_{name}"] = res["batch_config_fps"] / base
            if "distinct_config_fps" in res:
                res[f"distinct_vs_{name}"] = res["distinct_config_fps"] / base
            print(f"against {name}: B=1 {res[f'b1_vs_{name}']:.0f}x, B={len(grid)} {res[f'batch_vs_{name}']:.0f}x",
                  flush=True)
    res.update(load_end=os.getloadavg(), cpu_model=cpu_model(), cpus=os.cpu_count(), buckets=args.buckets,
               capacity=args.tracks)
    print(json.dumps(res))


if __name__ == "__main__":
    main()
