"""Benchmark: AB3DMOT's pair affinity alone (dfrmot_jax.trackers.ab3dmot.affinity / polygon), every metric, on
KITTI's pair lists: pairs/s and ns per pair, amortised over a batch.

The pairs: KITTI PointRCNN car (``--sequences``, default all 21), every (detection of frame t,
detection of frame t - 1) of a sequence, the previous frame's boxes standing for the predicted
tracks (the tracker's own pairs: a detection against every live track, most of them apart).
Per box once (footprints, circles: as ``batch.pooled_affinity`` does per frame, each box of the split
once), then per pair in one compiled call over ``--chunk`` pairs at a time:

- ``iou_*`` / ``giou_*``: the circle test for every pair; the clip of the detection's footprint by the
  track's for the pairs that may overlap (packed: ``frac_clipped`` of the pairs); GIoU's hull of
  both footprints for every pair; then the value (``affinity.combine``);
- ``dist_2d``, ``dist_3d``, ``m_dis`` (the innovation of a newborn track at the track box).

Also the parts alone for giou_3d (``part_*``, after the per-box quantities: the circle test, the hull,
the clip of every pair). Times are the
best of ``--repeat`` warm calls (wall, this process; the machine is shared: the load average goes
with them). The AB3DMOT reference for the same pairs: its own ``iou(box_a, box_b, metric)`` per pair
(xinshuoweng/AB3DMOT 61f3bd7, ``dist_metrics``), when ``--ab3dmot-python PY --ab3dmot-root DIR``
are given (DIR holds its ``AB3DMOT_libs``), on ``--ab3dmot-pairs`` of the pairs. The LAST line of each
metric is one JSON object.

    python benchmarks/bench_ab3dmot_affinity.py [--sequences 0000,0001] [--chunk 65536] \
        [--ab3dmot-python /tmp/ab3dmot_ref/venv/bin/python --ab3dmot-root /tmp/ab3dmot_ref]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from machine import cpu_model  # noqa: E402

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

from dfrmot_jax import ab3dmot as J  # noqa: E402
from dfrmot_jax.trackers.ab3dmot import kalman  # noqa: E402
from dfrmot_jax.trackers.ab3dmot.affinity import circle, circles_apart, combine, compact, distance, footprint, \
    footprint_hull, footprint_intersection  # noqa: E402
from dfrmot_jax.trackers.ab3dmot.exact import runtime_zero  # noqa: E402
from dfrmot_jax.paths import default_data_root  # noqa: E402

_REF = r"""
import sys, json, time, types, numpy as np
sys.path.insert(0, sys.argv[1])
class Stub(types.ModuleType):                     # its helper toolbox: not on the geometry's path
    def __getattr__(self, name):
        if name.startswith("__"):
            raise AttributeError(name)
        return lambda *a, **k: None
for n in ("xinshuo_miscellaneous", "xinshuo_io"):
    sys.modules[n] = Stub(n)
from AB3DMOT_libs.dist_metrics import iou, dist3d, dist_ground
from AB3DMOT_libs.box import Box3D
d = np.load(sys.argv[2]); det, trk = d["det"], d["trk"]
out = {}
for metric in sys.argv[3].split(","):
    a = [Box3D.array2bbox(b) for b in det]                  # states [x, y, z, theta, l, w, h], as its own
    b = [Box3D.array2bbox(t) for t in trk]
    fn = {"dist_3d": dist3d, "dist_2d": dist_ground}.get(metric)
    for x, y in list(zip(a, b))[:3]:                         # (numba's compilation, not timed)
        fn(x, y) if fn else iou(x, y, metric)
    w = time.perf_counter()
    for x, y in zip(a, b):
        fn(x, y) if fn else iou(x, y, metric)
    out[metric] = time.perf_counter() - w
print(json.dumps(out))
"""


def kitti_pairs(root: Path, sequences) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(boxes [M, 7], det [P], trk [P]) and the pairs' frame [P]: every (detection of frame t, detection
    of frame t - 1) pair as indices into the boxes of the split (each box once)."""
    split = J.read_split(root, "car", sequences)
    f = split.frames
    boxes, valid, reset = np.asarray(f.boxes), np.asarray(f.valid, bool), np.asarray(f.reset, bool)
    n = boxes.shape[1]
    flat = boxes.reshape(-1, 7)
    det, trk = [], []
    for t in range(1, len(reset)):
        if reset[t]:
            continue
        a, b = np.flatnonzero(valid[t]) + t * n, np.flatnonzero(valid[t - 1]) + (t - 1) * n
        if len(a) and len(b):
            det.append(np.repeat(a, len(b)))
            trk.append(np.tile(b, len(a)))
    det, trk = np.concatenate(det), np.concatenate(trk)
    used, inv = np.unique(np.concatenate([det, trk]), return_inverse=True)
    return flat[used], inv[:len(det)], inv[len(det):]


def programs(metric: str):
    """The compiled per-pair affinity of ``metric`` over a chunk: fn(boxes [M, 7], det [P], trk [P],
    zero, clip_capacity): per box once (footprints, circles, innovations), then per pair."""
    def iou_fn(boxes, di, ti, zero, clip_capacity):
        fp, cc = footprint(boxes, zero), circle(boxes, zero)                 # (every box once)
        dfp, tfp = tuple(v[di] for v in fp), tuple(v[ti] for v in fp)
        apart = circles_apart(tuple(v[di] for v in cc), tuple(v[ti] for v in cc), zero)
        sel, rank = compact(~apart, clip_capacity)
        sel = jnp.minimum(sel, di.shape[0] - 1)
        area, _ = footprint_intersection(tuple(v[sel] for v in dfp), tuple(v[sel] for v in tfp), zero)
        inter = jnp.where(~apart & (rank < clip_capacity), area[jnp.clip(rank, 0, clip_capacity - 1)], 0.0)
        hull = footprint_hull(dfp, tfp, zero)[0] if metric.startswith("giou") else None
        return combine(boxes[di], boxes[ti], metric, inter, hull, zero).astype(jnp.float32)

    def dist_fn(boxes, di, ti, zero, clip_capacity):
        inn = kalman.innovation(kalman.birth(boxes))[ti] if metric == "m_dis" else None
        return distance(boxes[di], boxes[ti], metric, zero, inn).astype(jnp.float32)

    fn = iou_fn if "iou" in metric else dist_fn
    return jax.jit(fn, static_argnums=4)


def parts():
    """giou_3d's parts alone, per pair after the boxes' footprints and circles (not timed here):
    the circle test, the hull of every pair, the clip of every pair."""
    def circles(cc, di, ti, zero):
        return circles_apart(tuple(v[di] for v in cc), tuple(v[ti] for v in cc), zero)

    def hull(fp, di, ti, zero):
        return footprint_hull(tuple(v[di] for v in fp), tuple(v[ti] for v in fp), zero)[0]

    def clip(fp, di, ti, zero):
        return footprint_intersection(tuple(v[di] for v in fp), tuple(v[ti] for v in fp), zero)[0]
    return {"part_circles": (jax.jit(circles), "circle"), "part_hull": (jax.jit(hull), "footprint"),
            "part_clip": (jax.jit(clip), "footprint")}


def best_time(fn, repeat: int) -> float:
    jax.block_until_ready(fn())
    best = np.inf
    for _ in range(repeat):
        w = time.perf_counter()
        jax.block_until_ready(fn())
        best = min(best, time.perf_counter() - w)
    return best


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default=str(default_data_root()))
    ap.add_argument("--sequences", default=",".join(J.ALL_SEQUENCES))
    ap.add_argument("--metrics", default=",".join(J.METRICS))
    ap.add_argument("--chunk", type=int, default=1 << 16)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--ab3dmot-python", default=os.environ.get("AB3DMOT_PYTHON"))
    ap.add_argument("--ab3dmot-root", default=os.environ.get("AB3DMOT_ROOT"))
    ap.add_argument("--ab3dmot-pairs", type=int, default=20000)
    args = ap.parse_args(argv)
    jax.config.update("jax_enable_x64", True)
    boxes, det, trk = kitti_pairs(Path(args.data), args.sequences.split(","))
    p = len(det)
    c = min(args.chunk, p)
    n_chunks = -(-p // c)
    pad = n_chunks * c - p
    det_c = np.concatenate([det, np.repeat(det[:1], pad, 0)]).reshape(n_chunks, c)
    trk_c = np.concatenate([trk, np.repeat(trk[:1], pad, 0)]).reshape(n_chunks, c)
    zero = runtime_zero(jnp.asarray(1))
    base = {"pairs": p, "boxes": len(boxes), "chunk": c, "cpu_model": cpu_model(), "cpus": os.cpu_count()}
    own = {}
    if args.ab3dmot_python and args.ab3dmot_root:
        k = min(args.ab3dmot_pairs, p)
        with tempfile.TemporaryDirectory() as tmp:
            np.savez(Path(tmp) / "pairs.npz", det=boxes[det[:k]], trk=boxes[trk[:k]])
            r = subprocess.run([args.ab3dmot_python, "-c", _REF, args.ab3dmot_root, str(Path(tmp) / "pairs.npz"),
                                ",".join(m for m in args.metrics.split(",") if m != "m_dis")],
                               capture_output=True, text=True, check=True)
        own = {m: s / k * 1e9 for m, s in json.loads(r.stdout.strip().splitlines()[-1]).items()}
        base["ab3dmot_pairs"] = k
    bj = jnp.asarray(boxes)
    dj = [jnp.asarray(v) for v in det_c]
    tj = [jnp.asarray(v) for v in trk_c]
    cc = jax.jit(lambda b: circle(b, zero))(bj)
    apart = np.asarray(jax.jit(lambda d, t: circles_apart(tuple(v[d] for v in cc), tuple(v[t] for v in cc), zero))(
        jnp.asarray(det), jnp.asarray(trk)))
    cap = max(8, int(-(-max(np.sum(~apart[i * c:(i + 1) * c]) for i in range(n_chunks)) // 8) * 8))
    for metric in args.metrics.split(","):
        fn = programs(metric)
        load0 = os.getloadavg()
        w = time.perf_counter()
        jax.block_until_ready(fn(bj, dj[0], tj[0], zero, cap))
        compile_s = time.perf_counter() - w
        s = best_time(lambda: [fn(bj, a, b, zero, cap) for a, b in zip(dj, tj)], args.repeat)
        rec = dict(base, metric=metric, seconds=round(s, 4), pairs_per_s=round(p / s),
                   ns_per_pair=round(s / p * 1e9, 1),
                   compile_s=round(compile_s, 2), frac_clipped=round(float(np.mean(~apart)), 4) if "iou" in metric
                   else None, load=[round(v, 2) for v in load0])
        if metric in own:
            rec.update(ab3dmot_ns_per_pair=round(own[metric], 1), vs_ab3dmot=round(own[metric] / rec["ns_per_pair"], 1))
        print(json.dumps(rec), flush=True)
    if "giou_3d" in args.metrics.split(","):
        per_box = {"circle": cc, "footprint": jax.jit(lambda b: footprint(b, zero))(bj)}
        for name, (fn, what) in parts().items():
            load0 = os.getloadavg()
            s = best_time(lambda: [fn(per_box[what], a, b, zero) for a, b in zip(dj, tj)], args.repeat)
            print(json.dumps(dict(base, metric=name, seconds=round(s, 4), ns_per_pair=round(s / p * 1e9, 1),
                                  load=[round(v, 2) for v in load0])), flush=True)


if __name__ == "__main__":
    main()
