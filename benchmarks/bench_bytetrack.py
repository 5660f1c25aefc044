"""Benchmark: ByteTrack's tracker in JAX (dfrmot_jax.trackers.bytetrack) on the whole KITTI car
split (RRC detections, 21 sequences, 8,008 frames, packed into one run with a reset per sequence),
against ByteTrack's own code (ifzhang/ByteTrack at d1bf019, not part of this project) timed in the
same run.

- JAX, one lane (B = 1, ``car_default``): compile + first run, then the warm run, frames/s; its
  lines checked against the reference run ``car_default``;
- JAX, ``--batch`` lanes (default 64 distinct configs: track_thresh 0.3-0.6 x match_thresh 0.6-0.9
  x det_thresh_margin 0-0.2), warm, config-frames/s;
- ByteTrack's own code when ``--bytetrack-python PY --bytetrack-driver FILE`` (or the env vars
  ``BYTETRACK_PYTHON``, ``BYTETRACK_DRIVER``) are given: a subprocess runs the driver over the same
  sequences with ``car_default``'s settings and prints its CPU seconds of tracking (the driver reads
  the files before the clock starts); ratios use CPU seconds on both sides.

Times are wall and CPU seconds; the machine is shared, so the load average goes with them. Every
line is one JSON object; the LAST one is the summary.

    python benchmarks/bench_bytetrack.py [--data ROOT] [--batch 64] [--batch-sequences 21] [--label TEXT] \
        [--bytetrack-python /tmp/bt_env/bin/python --bytetrack-driver /tmp/bt_driver/drive.py]
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

sys.path.insert(0, str(Path(__file__).resolve().parent))

from machine import cpu_model  # noqa: E402

from dfrmot_jax.paths import default_data_root  # noqa: E402
from dfrmot_jax.testing import bytetrack_oracle as O  # noqa: E402
from dfrmot_jax.testing.bytetrack_compare import compare_lines, reference_lines  # noqa: E402
from dfrmot_jax.trackers.bytetrack import batch, results  # noqa: E402
from dfrmot_jax.trackers.bytetrack.config import Options, Params  # noqa: E402

SEQS = [f"{i:04d}" for i in range(21)]


def timed(fn):
    w, c = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w, time.process_time() - c


def load():
    return os.getloadavg()[0]


def grid(b: int) -> Params:
    rows = list(itertools.product([0.3, 0.4, 0.5, 0.6], [0.6, 0.7, 0.8, 0.9], [0.0, 0.05, 0.1, 0.2]))[:b]
    while len(rows) < b:
        rows.append(rows[len(rows) % 64])
    t, m, g = (list(v) for v in zip(*rows))
    import numpy as np
    return Params(np.array(t), np.array(m), np.full(b, 30, np.int32), np.array(g))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default=None)
    ap.add_argument("--batch", type=int, default=64)
    ap.add_argument("--batch-sequences", type=int, default=21,
                    help="the batched run over the first N sequences only (default all 21)")
    ap.add_argument("--label", default="", help="a label written in every line (e.g. before / after)")
    ap.add_argument("--bytetrack-python", default=os.environ.get("BYTETRACK_PYTHON"))
    ap.add_argument("--bytetrack-driver", default=os.environ.get("BYTETRACK_DRIVER"))
    a = ap.parse_args(argv)
    root = Path(a.data) if a.data else default_data_root()
    frs = [O.load_frames(root, "car", q) for q in SEQS]
    lens = [len(f) for f in frs]
    frames = batch.pack_frames(frs)
    t_frames = sum(lens)
    base = {"cpu_model": cpu_model(), "cpus": os.cpu_count(), "frames": t_frames, "label": a.label}

    own = None
    if a.bytetrack_python and a.bytetrack_driver:
        res = subprocess.run([a.bytetrack_python, a.bytetrack_driver, "--root", str(root), "--time"],
                             capture_output=True, text=True, check=True)
        own = json.loads(res.stdout.strip().splitlines()[-1])
        own["fps_cpu"] = own["frames"] / own["cpu_s"]
        print(json.dumps({**base, "what": "bytetrack_own", **own, "load": load()}), flush=True)

    p1 = Params(0.5, 0.8, 30, 0.1)
    opt = Options()
    out, w_cold, c_cold = timed(lambda: batch.run(p1, opt, frames))
    out, w1, c1 = timed(lambda: batch.run(p1, opt, frames))
    per = results.sequence_lines(out, 0, lens)
    matched = total = 0
    for q, lines in zip(SEQS, per):
        c = compare_lines(lines, reference_lines(root, "car_default", q))
        matched += c.matched
        total += c.total
    r1 = {**base, "what": "jax_b1", "compile_and_first_s": w_cold, "compile_and_first_cpu_s": c_cold,
          "compile_s_est": w_cold - w1, "wall_s": w1, "cpu_s": c1,
          "fps": t_frames / w1, "fps_cpu": t_frames / c1, "lines_matched": matched, "lines": total,
          "solver_calls": int(out.solver[0]), "load": load()}
    print(json.dumps(r1), flush=True)

    pb = grid(a.batch)
    nb = sum(lens[:a.batch_sequences])
    if a.batch_sequences < len(SEQS):
        frames = batch.pack_frames(frs[:a.batch_sequences])
    outb, wb_cold, cb_cold = timed(lambda: batch.run(pb, opt, frames))
    outb, wb, cb = timed(lambda: batch.run(pb, opt, frames))
    import hashlib
    distinct = len({hashlib.sha1(outb.written[i].tobytes() + (outb.tid[i] * outb.written[i]).tobytes()).hexdigest()
                    for i in range(a.batch)})
    rb = {**base, "frames": nb, "what": f"jax_b{a.batch}", "compile_and_first_s": wb_cold,
          "compile_and_first_cpu_s": cb_cold, "compile_s_est": wb_cold - wb, "wall_s": wb, "cpu_s": cb,
          "config_fps": a.batch * nb / wb, "config_fps_cpu": a.batch * nb / cb,
          "overflow": int(outb.overflow.sum()), "distinct_lanes": distinct, "load": load()}
    print(json.dumps(rb), flush=True)
    summary = {**base, "what": "summary", "b1_fps": r1["fps"], f"b{a.batch}_config_fps": rb["config_fps"],
               "b1_exact": matched == total, "b1_compile_s_est": r1["compile_s_est"],
               f"b{a.batch}_compile_s_est": rb["compile_s_est"], "load": load()}
    if own:
        summary.update(bytetrack_fps_cpu=own["fps_cpu"], ratio_b1_cpu=r1["fps_cpu"] / own["fps_cpu"],
                       ratio_batch_cpu=rb["config_fps_cpu"] / own["fps_cpu"], goals="30x at B=1, 300x at B=64")
    print(json.dumps(summary), flush=True)


if __name__ == "__main__":
    main()
