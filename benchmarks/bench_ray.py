"""The Ray backend's overhead: the 1,024-config sweep (``sweeps/kitti_dfr_grid.toml``, KITTI car,
RRC + PointRCNN) run by the local backend, by a one-node local Ray instance (one worker with every
core) and by a two-node Ray cluster on this same machine (``ray.cluster_utils.Cluster``: two nodes of
half the cores, one worker each). Same cores every time, so the ratios measure overhead, not scaling.
Each mode runs cold in its own process (data loading, ground truth, Ray workers' start and
compilations included; the cluster's own start is reported apart).

    python benchmarks/bench_ray.py [--sweep FILE] [--modes local,ray1,ray2]

Also measured: bytes shipped per chunk (the task's arguments; the chunk table back, pickled) and once
per worker (the packed split and prepared ground truth), and the driver's own time per chunk
(receiving and writing a chunk), which bounds how many machines one driver can keep busy: see
``benchmarks/RESULTS.md`` ("Ray backend"). The last line is one JSON object with ``seconds`` per mode,
``overhead`` (Ray / local), the shipping figures, machine and load.
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from machine import machine_info

HERE = Path(__file__).resolve().parent
DEFAULT_SWEEP = HERE.parent / "sweeps" / "kitti_dfr_grid.toml"
MODES = ("local", "ray1", "ray2")


def run_mode(mode: str, sweep: str, out: Path) -> dict:
    """One cold run of the sweep (in this process) with ``mode``'s backend."""
    import dfrmot_jax
    from dfrmot_jax.sweep import run_sweep, runner

    cpus = os.cpu_count() or 1
    info: dict = {"mode": mode}
    writes: list[float] = []
    real_write = runner.write_chunk

    def timed_write(o, chunk, df):          # the driver's time per chunk
        t = time.perf_counter()
        real_write(o, chunk, df)
        writes.append(time.perf_counter() - t)

    runner.write_chunk = timed_write
    kw: dict = {}
    cluster = None
    if mode != "local":
        import ray

        os.environ.setdefault("RAY_AUTH_MODE", "disabled")
        t = time.perf_counter()
        if mode == "ray1":
            ray.init(address="local", num_cpus=cpus, include_dashboard=False, logging_level="WARNING")
        else:
            from ray.cluster_utils import Cluster

            half = max(1, cpus // 2)
            cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": half})
            cluster.add_node(num_cpus=cpus - half if cpus > 1 else 1)
            cluster.wait_for_nodes()
            ray.init(address=cluster.address, logging_level="WARNING")
        info["cluster_start_seconds"] = round(time.perf_counter() - t, 2)
        kw = {"backend": "ray"}
    else:
        dfrmot_jax.setup_host_devices()
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    df = run_sweep(sweep, out, progress=False, **kw)
    info["seconds"] = round(time.perf_counter() - t0, 2)
    info["load_avg_1min"] = [round(load0, 2), round(os.getloadavg()[0], 2)]
    comb = df[df["sequence"] == "COMBINED"]
    info["configs"] = int(len(comb))
    info["best_hota"] = float(comb["HOTA"].max())
    info["driver_seconds_per_chunk"] = round(sum(writes) / max(1, len(writes)), 4)
    info["chunks"] = len(writes)
    if mode != "local":
        from dfrmot_jax.sweep.plan import resolve_data
        from dfrmot_jax.sweep.chunks import load_data

        split, gt = load_data(resolve_data(sweep))
        tables = [p for p in (out / "chunks").glob("*.parquet")]
        import pandas as pd

        sizes = [len(pickle.dumps(pd.read_parquet(p), protocol=5)) for p in tables]
        info["bytes_back_per_chunk"] = int(sum(sizes) / len(sizes))
        from dfrmot_jax.sweep.plan import plan
        from dfrmot_jax.sweep.table import expand

        chunk = plan(expand(sweep), [resolve_data(sweep)], 64)[0]
        info["bytes_out_per_chunk"] = len(pickle.dumps(("run-key-" + "0" * 24, chunk), protocol=5))
        info["bytes_once_per_worker"] = len(pickle.dumps((split, gt), protocol=5))
        from dfrmot_jax.sweep.ray_backend import release

        release()
        ray.shutdown()
        if cluster is not None:
            cluster.shutdown()
    return info


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sweep", default=str(DEFAULT_SWEEP))
    ap.add_argument("--modes", default=",".join(MODES))
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        out = Path(tempfile.mkdtemp(prefix="dfrmot_bench_ray_"))
        try:
            print(json.dumps(run_mode(args.child, args.sweep, out / "sweep")))
        finally:
            shutil.rmtree(out, ignore_errors=True)
        return 0

    from dfrmot_jax.paths import data_available, default_data_root

    machine = machine_info()
    if not data_available(default_data_root()):
        print(f"KITTI data not found at {default_data_root()} (set DFRMOT_DATA)")
        print(json.dumps({"benchmark": "ray", "skipped": "no KITTI data", **machine}))
        return 0
    results = {}
    for mode in args.modes.split(","):
        proc = subprocess.run([sys.executable, __file__, "--sweep", args.sweep, "--child", mode],
                              capture_output=True, text=True, env={**os.environ, "RAY_AUTH_MODE": "disabled"})
        if proc.returncode != 0:
            print(proc.stdout, proc.stderr, file=sys.stderr)
            raise SystemExit(f"mode {mode} failed")
        results[mode] = json.loads(proc.stdout.strip().splitlines()[-1])
        print(f"{mode}: {json.dumps(results[mode])}", flush=True)
    local = results.get("local", {}).get("seconds")
    summary = {
        "benchmark": "ray", "configs": next(iter(results.values()))["configs"],
        "seconds": {m: r["seconds"] for m, r in results.items()},
        "overhead": {m: round(r["seconds"] / local, 3) for m, r in results.items() if local and m != "local"},
        "same_best_hota": len({r["best_hota"] for r in results.values()}) == 1,
        "modes": results, **machine,
    }
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
