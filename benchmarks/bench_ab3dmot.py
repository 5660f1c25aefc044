"""Benchmark: AB3DMOT's KITTI metrics (dfrmot_jax.metrics.samota) on one result folder, cold.

Times :func:`evaluate_ab3dmot_files` on the published DFR-FastMOT output (20 car sequences), 3D IoU
0.25 by default: cold = every call reads the result files and reads and prepares the ground truth
(its cache cleared), then the 41-threshold evaluation. Best of ``--repeats``; the median too. Also
the same with the ground truth prepared (cached), 2D IoU 0.5, and ``--batch`` configs scored from
padded arrays (:func:`evaluate_ab3dmot_arrays`; the output with 3% of its rows dropped per config;
goal >= 50 configs/s, so that sAMOTA adds <= 20 s to a 1,024-config sweep). The reference evaluator's wall
time on this machine kind is in the fixture README (``reference/ab3dmot_eval/README.md``: 204 s for
this file in 3D on all 21 sequences); the speedup printed is against that figure, so indicative.

``--sweep-batch N`` (default 64): as a sweep scores them, from the tracker's arrays: the first and
the last N configs of ``sweeps/kitti_dfr_grid.toml`` (output "detections" and "filtered") tracked
with ``detail`` on the car split, then scored by the sweep's :class:`Ab3dmotLanes` (digests, the
rows a kitti file carries, the figures; memo empty): ``sweep_configs_per_s`` (goal >= 50), and what
``detail`` costs the tracking (``detail_track_s`` against ``plain_track_s``).

The LAST line is one JSON object: ``cold_s``, ``cold_median_s``, ``warm_s``, ``cold_2d_s``,
``arrays_s``, ``arrays_configs_per_s``, ``reference_s``, ``speedup``, the figures (sAMOTA, AMOTA, MOTA), machine info and the load average.

    python benchmarks/bench_ab3dmot.py [--data ROOT] [--iou 3d:0.25] [--repeats 5]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
import tomllib
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

REFERENCE_S = 204.0   # reference evaluator, published file, 3D, all 21 sequences (fixture README)


def _times(fn, repeats):
    out, res = [], None
    for _ in range(repeats):
        t = time.perf_counter()
        res = fn()
        out.append(time.perf_counter() - t)
    return out, res


def main() -> None:
    from machine import machine_info

    from dfrmot_jax.metrics.samota import prep as ab3dmot_prep
    from dfrmot_jax.metrics.samota.evaluate import evaluate_ab3dmot_files
    from dfrmot_jax.metrics.samota.arrays import evaluate_ab3dmot_arrays
    from dfrmot_jax.paths import default_data_root

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=None, help="KITTI tracking training root (default: default_data_root())")
    ap.add_argument("--iou", default="3d:0.25", help="AB3DMOT IoU, 2d:T or 3d:T (default 3d:0.25)")
    ap.add_argument("--repeats", type=int, default=5, help="runs per timing (best and median reported)")
    ap.add_argument("--batch", type=int, default=16, help="configs for the arrays timing (default 16)")
    ap.add_argument("--sweep-batch", type=int, default=64, help="configs per sweep-path timing (0: skip)")
    args = ap.parse_args()

    root = Path(args.data) if args.data else default_data_root()
    folder = root / "reference" / "dfr_fastmot_rrc_pointrcnn"
    seqs = sorted(p.stem for p in folder.glob("*.txt"))
    load_before = os.getloadavg()

    def cold(iou):
        ab3dmot_prep.clear_cache()
        return evaluate_ab3dmot_files(folder, root, "car", seqs, iou=iou)

    cold_t, res = _times(lambda: cold(args.iou), args.repeats)
    warm_t, _ = _times(lambda: evaluate_ab3dmot_files(folder, root, "car", seqs, iou=args.iou), args.repeats)
    cold2_t, res2 = _times(lambda: cold("2d:0.5"), args.repeats)
    # from arrays: B copies of the output with 3% of the rows dropped at random per config
    gt = ab3dmot_prep.cached_ab3dmot_gt(root, "car", seqs)
    trk = ab3dmot_prep.read_ab3dmot_results(folder, gt)
    slot = np.arange(len(trk.frame)) - np.searchsorted(trk.frame, trk.frame)
    K = int(slot.max()) + 1
    B = args.batch
    ids = np.full((B, gt.n_frames, K), -1, dtype=np.int64)
    ids[:, trk.frame, slot] = trk.track
    ids[np.random.default_rng(0).random(ids.shape) < 0.03] = -1
    boxes = np.zeros((B, gt.n_frames, K, 4))
    boxes[:, trk.frame, slot] = trk.box
    scores = np.zeros((B, gt.n_frames, K))
    scores[:, trk.frame, slot] = trk.score
    box3d = np.full((B, gt.n_frames, K, 7), np.nan)
    box3d[:, trk.frame, slot] = np.where(trk.has3d[:, None], trk.box3d, np.nan)
    arr_t, _ = _times(lambda: evaluate_ab3dmot_arrays(gt, ids, boxes, scores, box3d, iou=args.iou),
                      max(1, args.repeats // 2))
    sweep = _sweep_path(args.sweep_batch, args.iou, root) if args.sweep_batch else {}
    rows = [(f"cold, {args.iou}", cold_t), ("ground truth cached", warm_t), ("cold, 2d:0.5", cold2_t),
            (f"arrays, B={B}, {args.iou}", arr_t)]
    print(f"AB3DMOT KITTI metrics, car, {len(seqs)} sequences of {folder.name}; best / median of {args.repeats}")
    for name, t in rows:
        print(f"  {name:28s} {min(t):7.3f} s  {statistics.median(t):7.3f} s")
    if sweep:
        print(f"  sweep path, {sweep['sweep_configs']} grid configs: scored in {sweep['sweep_score_s']:.3f} s "
              f"({sweep['sweep_configs_per_s']:.1f} configs/s, {sweep['sweep_distinct']} distinct); tracking "
              f"{sweep['detail_track_s']:.2f} s with detail, {sweep['plain_track_s']:.2f} s without")
    print(f"  {args.iou}: sAMOTA {100 * res['sAMOTA']:.4f} AMOTA {100 * res['AMOTA']:.4f} MOTA {100 * res['MOTA']:.4f}; "
          f"2d:0.5: sAMOTA {100 * res2['sAMOTA']:.4f}")
    info = machine_info()
    out = {"bench": "ab3dmot", "iou": args.iou, "sequences": len(seqs), "cold_s": round(min(cold_t), 4),
           "cold_median_s": round(statistics.median(cold_t), 4), "warm_s": round(min(warm_t), 4),
           "cold_2d_s": round(min(cold2_t), 4), "arrays_batch": B, "arrays_s": round(min(arr_t), 4),
           "arrays_configs_per_s": round(B / min(arr_t), 1), "reference_s": REFERENCE_S,
           "speedup": round(REFERENCE_S / min(cold_t), 1),
           "sAMOTA": round(100 * res["sAMOTA"], 4), "AMOTA": round(100 * res["AMOTA"], 4),
           "MOTA": round(100 * res["MOTA"], 4), **sweep, "loadavg_before": [round(x, 2) for x in load_before],
           "loadavg_after": [round(x, 2) for x in os.getloadavg()], **info}
    print(json.dumps(out))


def _sweep_path(n: int, iou: str, root) -> dict:
    """The sweep's AB3DMOT scoring of the grid's first and last ``n`` configs (module docstring)."""
    from dfrmot_jax.trackers.dfr.track import track
    from dfrmot_jax.sweep.chunks import ChunkRunner
    from dfrmot_jax.sweep.runner import prepare_sweep
    from dfrmot_jax.sweep.table import params_of

    spec = tomllib.loads((Path(__file__).resolve().parent.parent / "sweeps" / "kitti_dfr_grid.toml").read_text())
    spec["data"]["root"] = str(root)
    spec.setdefault("metrics", {})["ab3dmot"] = iou
    spec["chunk"] = n
    ps = prepare_sweep(spec)
    runner = ChunkRunner.load(ps.spec, ps.table, ps.datas[0], ps.chunks)
    score_s = detail_s = plain_s = 0.0
    configs = distinct = 0
    for c in (ps.chunks[0], ps.chunks[-1]):
        frames = runner.frames_of(c.options)
        params = params_of(ps.table, c.configs, "car")
        opts = c.options._replace(capacity=c.options.capacity or 40)
        for detail in (False, True):
            track(frames, params, opts, lanes_per_call=32, detail=detail)        # compiled
            t = time.perf_counter()
            res = track(frames, params, opts, lanes_per_call=32, detail=detail)
            if detail:
                detail_s += time.perf_counter() - t
            else:
                plain_s += time.perf_counter() - t
        runner.scoring.ab3dmot.memo.clear()
        t = time.perf_counter()
        runner.scoring.ab3dmot.score(res)
        score_s += time.perf_counter() - t
        configs += len(c.configs)
        distinct += len(runner.scoring.ab3dmot.memo)
    return {"sweep_configs": configs, "sweep_distinct": distinct, "sweep_score_s": round(score_s, 4),
            "sweep_configs_per_s": round(configs / score_s, 1), "detail_track_s": round(detail_s, 3),
            "plain_track_s": round(plain_s, 3)}


if __name__ == "__main__":
    main()
