"""``dfrmot compare``'s paired bootstrap: two outputs (dfr2023 and tuned_both, written as result files)
on KITTI car's 20 sequences; the time to score them (per-sequence fields, once) and then the resamples
(10,000 by default), against the goal of issue 31 (<= 2 s after scoring); then a report's "not
distinguishable from the best" over 1,024 configs (the two outputs' per-sequence fields tiled to the
grid's shape, 1,024 x 20 sequences, 1,000 resamples as ``report.intervals`` draws; goal <= 5 s). The
scoring of one output is the ratios' reference in the same run. The last line is one JSON object.

    python benchmarks/bench_compare.py [--resamples 10000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import dfrmot_jax as dm
from dfrmot_jax.trackers.dfr.config import preset
from dfrmot_jax.metrics.common.sequences import cached_class_sequences
import numpy as np

from dfrmot_jax.metrics.kitti2d.bootstrap import (counts_of, paired_bootstrap, resample_indices, resampled_figure,
                                                  seq_fields)
from dfrmot_jax.report.intervals import REPORT_RESAMPLES
from dfrmot_jax.metrics.kitti2d.evaluate import cached_gt
from dfrmot_jax.metrics.kitti2d.tracker_files import read_tracker_files
from dfrmot_jax.paths import default_data_root
from dfrmot_jax.trackers.dfr.results import write_lane
from machine import machine_info


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--resamples", type=int, default=10_000)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    root = default_data_root()
    if not (root / "label_02").is_dir():
        print(f"KITTI data not found at {root}; set DFRMOT_DATA", file=sys.stderr)
        return 1
    seqs = cached_class_sequences(root, "car")
    split = dm.load_split(root, "rrc", "pointrcnn", "car", seqs)
    gt = cached_gt(root, "car", seqs)
    tmp = Path(tempfile.mkdtemp())
    folders = []
    for name in ("dfr2023", "tuned_both"):
        params, options = preset(name)
        res = dm.track(split, params, options)
        write_lane(tmp / name, split, res.frames, res.options, res.ids[0], res.lane_boxes(0))
        folders.append(tmp / name)
    machine = {**machine_info(), "load_avg_1min": round(os.getloadavg()[0], 2)}
    score_s, boot_s = [], []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        fields = [seq_fields(gt, read_tracker_files(d, gt)) for d in folders]
        score_s.append((time.perf_counter() - t0) / 2)
        t0 = time.perf_counter()
        paired_bootstrap(fields[0], fields[1], args.resamples, seed=0)
        boot_s.append(time.perf_counter() - t0)
    grid = {f: np.concatenate([np.stack([a, b])] * 512) for f, a, b in
            ((f, fields[0][f], fields[1][f]) for f in fields[0])}                     # [1024, S(, 19)]
    counts = counts_of(resample_indices(len(seqs), REPORT_RESAMPLES, 0), len(seqs))
    report_s = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        resampled_figure(grid, counts, "HOTA")
        report_s.append(time.perf_counter() - t0)
    out = {"sequences": len(seqs), "resamples": args.resamples, "score_one_output_s": round(min(score_s), 3),
           "bootstrap_s": round(min(boot_s), 3), "bootstrap_vs_scoring_one_output": round(min(boot_s) / min(score_s), 2),
           "goal_bootstrap_s": 2.0, "report_configs": 1024, "report_resamples": REPORT_RESAMPLES,
           "report_not_distinguishable_s": round(min(report_s), 3), "goal_report_s": 5.0, **machine}
    print(f"# {machine}")
    print(f"scoring one output (files read, per-sequence fields): {out['score_one_output_s']:.3f} s; "
          f"{args.resamples:,} paired resamples: {out['bootstrap_s']:.3f} s (goal <= 2 s); 1,024 configs x "
          f"{REPORT_RESAMPLES:,} resamples (a report's HOTA intervals): {out['report_not_distinguishable_s']:.3f} s "
          f"(goal <= 5 s)")
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
