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

import dfrmot_jax

dfrmot_jax.setup_host_devices()   # before any JAX operation (machine_info reports the devices)

from dfrmot_jax import distort as D
from dfrmot_jax.frames import Frames
from dfrmot_jax.distort import cast_params, draws
from dfrmot_jax.distort.hook import apply_draws
from dfrmot_jax.distort.bursts import burst_length


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


class KeyDraws:
    """``distort.apply_draws``'s source of randomness from ``jax.random`` keys of ``impl``."""

    def __init__(self, impl: str):
        self.impl = impl

    def streams(self, seed, t):
        kt = jax.random.fold_in(_keys(seed, self.impl), t)
        return lambda stream: jax.random.fold_in(kt, stream)

    def uniform(self, key, shape):
        return jax.random.uniform(key, shape, jnp.float32)

    def normal(self, key, shape):
        return jax.random.normal(key, shape, jnp.float32)

    def occluded(self, gid, t, dp, spec):
        return _occluded_keys(gid, t, dp, spec, self.impl)


def distort_frame_keys(frame, gid2, gid3, t, dp, spec, impl="threefry2x32"):
    """``distort.distort_frame``'s very steps, with ``jax.random`` draws."""
    return apply_draws(frame, gid2, gid3, t, dp, spec, KeyDraws(impl))


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
