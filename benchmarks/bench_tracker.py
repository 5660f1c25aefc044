"""Tracker speed on the whole KITTI training split (21 sequences, 8,008 frames; car; RRC + PointRCNN).

In one run: the NumPy reference (frames/s), then the JAX tracker at B = 1, 8, 64, 256, 1024
settings around the dfr2023 preset (config-frames/s after compile, compile time, peak RSS), then
the same batches on the split compacted to the batch's loosest score thresholds, as sweeps track
(``data.compact_split``; JSON keys ``compact_b*``; ``--no-compact`` skips them), then through the
public call ``dfrmot_jax.track`` on the whole split (JSON keys ``track_b*``: it compacts the split
itself, groups lanes by merge settings and gives the output back in the split's layout).
Batches larger than ``--lanes-per-call`` run in several compiled calls (each call's lanes split over the
host's devices). (Records before the rename name it ``chunk`` / ``--chunk``, still accepted.)
The last line is one JSON object.

Speed goals are ratios to the oracle in the same run (``*_vs_reference``; ``goal_*``), the CPU model
and load beside them; ``--device gpu`` tracks on a GPU (``platform``, ``device_kind`` in the line).

    python benchmarks/bench_tracker.py [--sizes 1,8,64,256,1024] [--lanes-per-call 16] [--preset dfr2023]
                                       [--device auto|cpu|gpu]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

import dfrmot_jax

dfrmot_jax.setup_host_devices()   # one XLA device per core, before any JAX operation

from dfrmot_jax.trackers.dfr import run as tracker
from dfrmot_jax.trackers.dfr.track import default_capacity, track
from dfrmot_jax.devices import chosen_platform, default_lanes_per_call
from dfrmot_jax.data import compact_split, load_sequences, pack
from dfrmot_jax.trackers.dfr.frames import prepare_frames
from dfrmot_jax.trackers.dfr.config import Params, keep_thresholds, preset, stack_params
from dfrmot_jax.paths import default_data_root
from dfrmot_jax.testing.reference import track_sequence
from machine import machine_info, peak_rss_mb


def settings(b: int, seed: int = 0, name: str = "dfr2023") -> Params:
    """B settings around the preset ``name`` (a_l, alpha_c, score_2d, epsilon varied)."""
    rng = np.random.default_rng(seed)
    base, _ = preset(name)
    return stack_params([base._replace(a_l=float(rng.uniform(4, 12)), alpha_c=float(rng.uniform(0.3, 0.7)),
                                       score_2d=float(rng.uniform(0.3, 0.6)), epsilon=int(rng.integers(10, 40)))
                         for _ in range(b)])


def lane_calls(big: Params, b: int, width: int) -> list:
    """The first ``b`` settings of ``big`` as the ``Params`` of calls of at most ``width`` lanes."""
    p = Params(*(np.asarray(v)[:b] for v in big))
    width = min(b, width)
    return [Params(*(np.asarray(v)[i:i + width] for v in p)) for i in range(0, b, width)]


def run_calls(lanes: list, frames, options, cap: int) -> tuple:
    """``trackers.dfr.run.run_batch`` of each call: (seconds of a first call of the first lanes, which
    compiles; seconds of all the calls after it; their outputs)."""
    t0 = time.perf_counter()
    tracker.run_batch(lanes[0], frames, options, cap)
    first_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    res = [tracker.run_batch(lane, frames, options, cap) for lane in lanes]
    return first_s, time.perf_counter() - t0, res


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="1,8,64,256,1024")
    ap.add_argument("--lanes-per-call", "--chunk", dest="lanes_per_call", type=int, default=None,
                    help="lanes per compiled call for large batches (--chunk: its old name; default 16 on the CPU, "
                         "devices.LANES_PER_CALL on a GPU)")
    ap.add_argument("--device", choices=("auto", "cpu", "gpu"), default=None,
                    help="the platform to track on ($DFRMOT_DEVICE; default auto: JAX's default backend)")
    ap.add_argument("--reference-seqs", type=int, default=21, help="sequences the reference runs (frames/s)")
    ap.add_argument("--no-compact", action="store_true", help="skip the compacted-split runs")
    ap.add_argument("--preset", default="dfr2023", help="settings around this preset, with its options "
                    "(e.g. tuned_both: weak detections, filtered output)")
    args = ap.parse_args()
    if args.device:
        os.environ["DFRMOT_DEVICE"] = args.device
    platform = chosen_platform()
    if args.lanes_per_call is None:
        args.lanes_per_call = 16 if platform == "cpu" else default_lanes_per_call(platform)
    root = default_data_root()
    if not (root / "label_02").is_dir():
        print(f"KITTI data not found at {root}; set DFRMOT_DATA", file=sys.stderr)
        return 1
    names = [f"{i:04d}" for i in range(21)]
    seqs = load_sequences(root, "rrc", "pointrcnn", "car", names)
    split = pack(seqs)
    params0, options = preset(args.preset)
    frames = prepare_frames(split, options)
    T = split.n_frames
    sizes = [int(s) for s in args.sizes.split(",")]
    big = settings(max(sizes), name=args.preset)
    cap = default_capacity(frames, big, options)
    machine = {**machine_info(), "load_avg_1min": round(os.getloadavg()[0], 2)}
    print(f"# {T} frames, capacity {cap}, {machine}")

    t0 = time.perf_counter()
    n_ref = 0
    for s in seqs[: args.reference_seqs]:
        track_sequence(s, params0, options)
        n_ref += s.n_frames
    ref_fps = n_ref / (time.perf_counter() - t0)
    print(f"reference (NumPy, 1 core): {ref_fps:,.0f} frames/s over {n_ref} frames")

    out = {"preset": args.preset, "frames": T, "capacity": cap, "lanes_per_call": args.lanes_per_call, "reference_frames_per_s": round(ref_fps, 1)}
    compile_s = {}
    runs = [("", frames)]
    if not args.no_compact:
        packed = compact_split(split, *(float(np.min(s)) for s in keep_thresholds(big)))
        out["compact_slots"] = [int(packed.valid2d.shape[1]), int(packed.valid3d.shape[1])]
        out["slots"] = [int(split.valid2d.shape[1]), int(split.valid3d.shape[1])]
        runs.append(("compact_", prepare_frames(packed, options)))
    for prefix, fr in runs:
        for b in sizes:
            first_s, dt, res = run_calls(lane_calls(big, b, args.lanes_per_call), fr, options, cap)
            if not prefix:
                compile_s[b] = first_s
            overflow = int(sum(int(r.overflow.sum()) for r in res))
            rate = b * T / dt
            print(f"{prefix or 'full '}B={b:5d}: {rate:12,.0f} config-frames/s  ({dt:7.2f} s; overflow {overflow}; "
                  f"peak RSS {peak_rss_mb():,.0f} MB)", flush=True)
            key = f"{prefix}b1_frames_per_s" if b == 1 else f"{prefix}b{b}_config_frames_per_s"
            out[key] = round(rate, 1)
            del res
    # through the public call on the whole split, as a user runs it (track compacts the split to the
    # batch's loosest thresholds, groups lanes by merge settings and moves the output back)
    for b in sizes:
        p = Params(*(np.asarray(v)[:b] for v in big))
        track(split, p, options, lanes_per_call=args.lanes_per_call)    # compiled
        t0 = time.perf_counter()
        res = track(split, p, options, lanes_per_call=args.lanes_per_call)
        dt = time.perf_counter() - t0
        rate = b * T / dt
        print(f"track B={b:5d}: {rate:12,.0f} config-frames/s  ({dt:7.2f} s; overflow {int(res.overflow.sum())}; "
              f"peak RSS {peak_rss_mb():,.0f} MB)", flush=True)
        out["track_b1_frames_per_s" if b == 1 else f"track_b{b}_config_frames_per_s"] = round(rate, 1)
        del res
    # the goals are ratios to the NumPy oracle measured above, in this run (issue 32: compacted B = 64
    # >= 120x, B = 1 >= 15x)
    for key in ("b1_frames_per_s", "compact_b1_frames_per_s", "track_b1_frames_per_s", "b64_config_frames_per_s",
                "compact_b64_config_frames_per_s", "track_b64_config_frames_per_s"):
        if key in out:
            out[key.replace("_config_frames_per_s", "").replace("_frames_per_s", "") + "_vs_reference"] = \
                round(out[key] / ref_fps, 2)
    out["goal_compact_b64_vs_reference"], out["goal_b1_vs_reference"] = 120, 15
    if 1 in sizes:
        for b in sizes:
            if b >= 256:
                out[f"b{b}_vs_b1"] = round(out[f"b{b}_config_frames_per_s"] / out["b1_frames_per_s"], 2)
    # compile time of one program: B = 1's first call minus its steady run time
    out["compile_s"] = round(compile_s[sizes[0]] - (sizes[0] * T / out.get("b1_frames_per_s", 1e18)), 2)
    out["compile_s_by_b"] = {str(k): round(v, 2) for k, v in compile_s.items()}
    out["peak_rss_mb"] = round(peak_rss_mb(), 1)
    out.update(machine)
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
