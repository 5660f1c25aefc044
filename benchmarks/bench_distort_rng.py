"""The distortion's random draws inside a scanned step: the counter-based hash of
``dfrmot_jax.distort.draws`` against ``jax.random`` keys (``fold_in`` per seed, frame and stream).

Both variants run the same per-frame distortion (bursts, drops, jitter, score noise; the groups of
``distort_frame`` except clutter, whose draws are two more streams of the same kind) on the same
frames, inside ``lax.scan`` over T frames, vmapped over B lanes, jitted, under ``jax.enable_x64``
as the tracker's step. Only the source of the uniforms / normals differs:

* ``hash``: ``distort.distort_frame`` itself (``stream_hash`` per (seed, t, stream), element i
  ``mix(h ^ mix(2 i + 1))``; bursts: one hash chain per (object, start frame)).
* ``threefry``: ``jax.random`` with the default threefry2x32 keys: ``key(seed)``, ``fold_in(t)``,
  ``fold_in(stream)`` then ``uniform`` / ``normal`` of the shape; bursts: ``fold_in(g)``,
  ``fold_in(s)`` per (object slot, start frame) pair and ``uniform(key, (2,))``.
* ``rbg``: the same with ``impl="rbg"`` keys.

    python benchmarks/bench_distort_rng.py [--frames 400] [--lanes 16] [--repeats 3]

Prints per variant and group set: compile seconds, run seconds (best of the repeats) and
microseconds per lane-frame; the last line is one JSON object.
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import jax
import jax.numpy as jnp
import numpy as np
from machine import machine_info

from dfrmot_jax import distort as D
from dfrmot_jax.data import Frames
from dfrmot_jax.distort import cast_params, draws, noise
from dfrmot_jax.distort.bursts import burst_length
from dfrmot_jax.geometry import truncate_2d_box, truncate_3d_box


def synth_frames(T: int, M2: int = 14, M3: int = 19, n_obj: int = 8, seed: int = 0):
    """KITTI-car-sized slots (the full split has 14 2D and 19 3D slots): boxes, scores, ids."""
    rng = np.random.default_rng(seed)
    box2 = np.trunc(rng.uniform(0, 1000, (T, M2, 4))).astype(np.float32)
    box2[..., 2:] = box2[..., :2] + np.trunc(rng.uniform(20, 200, (T, M2, 2)))
    box3 = np.trunc(rng.uniform(0, 1000, (T, M3, 4))).astype(np.float32)
    box3[..., 2:] = box3[..., :2] + np.trunc(rng.uniform(20, 200, (T, M3, 2)))
    valid2 = rng.random((T, M2)) < 0.5
    valid3 = rng.random((T, M3)) < 0.5
    lo3 = rng.uniform(0, 50, (T, M3, 3)).astype(np.float32)
    frames = Frames(reset=np.zeros(T, bool), box2=box2, score2=rng.random((T, M2)).astype(np.float32), valid2=valid2,
                    box3=box3, score3=rng.uniform(-1, 15, (T, M3)).astype(np.float32), valid3=valid3,
                    lo3=lo3, hi3=lo3 + np.float32(2.0))
    gid2 = np.where(valid2, rng.integers(-1, n_obj, (T, M2)), -1).astype(np.int32)
    gid3 = np.where(valid3, rng.integers(-1, n_obj, (T, M3)), -1).astype(np.int32)
    return frames, gid2, gid3


# ---- the jax.random variant of distort_frame (same steps, other draws) --------------------------


def _keys(seed, impl):
    return jax.random.key(jnp.asarray(seed, jnp.uint32), impl=impl)


def _occluded_keys(gid, t, dp, spec, impl):
    """As ``bursts.occluded``, with one jax.random key per (slot object, start frame)."""
    lag = jnp.arange(spec.burst_max, dtype=jnp.int32)
    s = jnp.asarray(t, jnp.int32) - lag
    root = jax.random.fold_in(_keys(dp.seed, impl), draws.BURST_TAG)
    g = jnp.maximum(gid, 0)
    kb = jax.vmap(lambda gg: jax.vmap(lambda ss: jax.random.fold_in(jax.random.fold_in(root, gg), ss))(s))(g)
    u = jax.vmap(jax.vmap(lambda k: jax.random.uniform(k, (2,), jnp.float32)))(kb)       # [M, L, 2]
    start = u[..., 0] < dp.burst_rate
    length = burst_length(u[..., 1], dp.burst_len, spec).astype(jnp.int32)
    return jnp.any(start & (length > lag[None, :]), axis=1) & (gid >= 0)


def distort_frame_keys(frame, gid2, gid3, t, dp, spec, impl="threefry2x32"):
    dp = cast_params(dp)
    t = jnp.asarray(t, jnp.int32)
    m2 = frame.valid2.shape[0]
    kt = jax.random.fold_in(_keys(dp.seed, impl), t)
    key = lambda stream: jax.random.fold_in(kt, stream)
    uniform = lambda k, shape: jax.random.uniform(k, shape, jnp.float32)
    normal = lambda k, shape: jax.random.normal(k, shape, jnp.float32)
    valid2, valid3 = frame.valid2, frame.valid3
    box2, box3, lo3, hi3, score2, score3 = frame.box2, frame.box3, frame.lo3, frame.hi3, frame.score2, frame.score3
    on = set(spec.enabled)
    if "burst" in on:
        occ = _occluded_keys(jnp.concatenate([gid2, gid3]), t, dp, spec, impl)
        valid2 = valid2 & ~occ[:m2]
        valid3 = valid3 & ~occ[m2:]
    if "drop" in on:
        valid2 = valid2 & ~(uniform(key(draws.DROP2), valid2.shape) < dp.drop_2d)
        valid3 = valid3 & ~(uniform(key(draws.DROP3), valid3.shape) < dp.drop_3d)
    if "jitter" in on:
        box2 = noise.jitter_box(box2, frame.valid2, dp.jitter_2d, normal(key(draws.JIT2), box2.shape),
                                truncate_2d_box if spec.truncate else None)
        box3 = noise.jitter_box(box3, frame.valid3, dp.jitter_box3, normal(key(draws.JITB3), box3.shape),
                                truncate_3d_box if spec.truncate else None)
        lo3, hi3 = noise.shift_3d(lo3, hi3, frame.valid3, dp.jitter_3d, normal(key(draws.JIT3), lo3.shape))
    if "score" in on:
        score2 = noise.score_noise(score2, frame.valid2, dp.score_noise_2d, normal(key(draws.SCORE2), score2.shape))
        score3 = noise.score_noise(score3, frame.valid3, dp.score_noise_3d, normal(key(draws.SCORE3), score3.shape))
    return Frames(frame.reset, box2, score2, valid2, box3, score3, valid3, lo3, hi3)


# ---- timing -------------------------------------------------------------------------------------


def make_run(fn, spec):
    """jit(vmap over lanes of scan over frames); the carry sums every output so nothing is dropped."""

    def lane(dp, frames, gid2, gid3):
        def step(acc, xs):
            fr, g2, g3, t = xs
            out = fn(fr, g2, g3, t, dp, spec)
            return acc + sum(jnp.sum(jnp.asarray(x, jnp.float32)) for x in out[1:]), None

        T = frames.reset.shape[0]
        acc, _ = jax.lax.scan(step, jnp.float32(0), (frames, gid2, gid3, jnp.arange(T, dtype=jnp.int32)))
        return acc

    return jax.jit(jax.vmap(lane, in_axes=(0, None, None, None)))


def time_variant(fn, spec, dps, frames, gid2, gid3, repeats):
    with jax.enable_x64(True):
        run = make_run(fn, spec)
        args = (cast_params(dps), Frames(*(jnp.asarray(x) for x in frames)), jnp.asarray(gid2), jnp.asarray(gid3))
        t0 = time.perf_counter()
        run.lower(*args).compile()
        compile_s = time.perf_counter() - t0
        run(*args).block_until_ready()
        best = float("inf")
        for _ in range(repeats):
            t0 = time.perf_counter()
            run(*args).block_until_ready()
            best = min(best, time.perf_counter() - t0)
    return compile_s, best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=400)
    ap.add_argument("--lanes", type=int, default=16)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    frames, gid2, gid3 = synth_frames(args.frames)
    mix = dict(drop_2d=0.2, drop_3d=0.2, burst_rate=0.02, burst_len=10.0, jitter_2d=2.0, jitter_box3=2.0,
               jitter_3d=0.1, score_noise_2d=0.1, score_noise_3d=1.0)
    dps = D.stack_distort([D.DistortParams(**mix, seed=s) for s in range(args.lanes)])
    variants = {
        "hash": D.distort_frame,
        "threefry": functools.partial(distort_frame_keys, impl="threefry2x32"),
        "rbg": functools.partial(distort_frame_keys, impl="rbg"),
    }
    groups = {"drop+burst": ("burst", "drop"), "drop+burst+jitter+score": ("burst", "drop", "jitter", "score")}
    rows = []
    for gname, enabled in groups.items():
        spec = D.DistortSpec(enabled=enabled)
        for vname, fn in variants.items():
            c, r = time_variant(fn, spec, dps, frames, gid2, gid3, args.repeats)
            us = 1e6 * r / (args.frames * args.lanes)
            rows.append({"groups": gname, "rng": vname, "compile_s": round(c, 2), "run_s": round(r, 3),
                         "us_per_lane_frame": round(us, 2)})
            print(f"{gname:26s} {vname:9s} compile {c:6.2f} s   run {r:7.3f} s   {us:7.2f} us / lane-frame", flush=True)
    print(json.dumps({"frames": args.frames, "lanes": args.lanes, "rows": rows, **machine_info()}))


if __name__ == "__main__":
    main()
