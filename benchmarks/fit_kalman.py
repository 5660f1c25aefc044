"""Kalman noise fitted by maximum likelihood to the KITTI car ground truth, against the best grid setting.

    python benchmarks/fit_kalman.py [--grid DIR] [--class car]

Fits kf_q, kf_r of the 2D corners and kf_q3, kf_r3 of the 3D corners (``dfrmot_jax.trackers.dfr.kalman_noise``)
to every ``label_02`` sequence, once per covariance initialisation (``kalman_init`` diffuse / steady),
then tracks the class's split (RRC + PointRCNN) with filter "kalman" and scores it (TrackEval-identical
HOTA): the fitted noise on the dfr2023 preset and on the best grid config's other settings, the 2D
fit shared by the 3D corners, and the best in-sample config of ``sweeps/kitti_kalman.toml`` (read
from ``--grid DIR``, a sweep directory of that file; the sweep, 161 configs, runs into it when it is
not finished there). Fitting and scoring use the same sequences: every number is in-sample.

The last line of the output is one JSON object. Without KITTI data it prints a JSON line with "skipped".
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from machine import machine_info

HERE = Path(__file__).resolve().parent
GRID = HERE.parent / "sweeps" / "kitti_kalman.toml"
NOISE = ("kf_q", "kf_r", "kf_q3", "kf_r3")


def best_grid_config(grid_dir: Path):
    """(Params, Options, HOTA) of the best Kalman config of the kitti_kalman sweep (run when unfinished)."""
    from dfrmot_jax.trackers.dfr.config import Options, Params
    from dfrmot_jax.sweep import load_results, run_sweep

    try:
        df = load_results(grid_dir)
    except FileNotFoundError:
        df = run_sweep(str(GRID), grid_dir, progress=False)
    if df["sweep"].iloc[0] != "kitti_kalman":
        raise SystemExit(f"{grid_dir} holds the sweep {df['sweep'].iloc[0]!r}, not kitti_kalman")
    comb = df[(df["sequence"] == "COMBINED") & (df["filter"] == "kalman")]
    best = comb.loc[comb["HOTA"].idxmax()]
    params = Params(**{k: np.asarray(best[k]).item() for k in Params._fields if k in best})
    options = Options(**{k: np.asarray(best[k]).item() for k in Options._fields if k in best})
    return params, options, float(best["HOTA"]), int(best["config"])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--grid", default="/tmp/dfrmot_kitti_kalman", help="sweep directory of sweeps/kitti_kalman.toml "
                    "(default /tmp/dfrmot_kitti_kalman; the sweep runs there unless finished)")
    ap.add_argument("--class", dest="cls", default="car", choices=["car"], help="the class (the grid is car's)")
    args = ap.parse_args(argv)

    machine = machine_info()          # one XLA device per core, before any JAX operation
    import dfrmot_jax as dm
    from dfrmot_jax.metrics import evaluate_arrays, metrics_table, prepare_gt
    from dfrmot_jax.paths import data_available, default_data_root
    from dfrmot_jax.trackers.dfr.kalman_noise import fit_kalman_noise

    root = default_data_root()
    if not data_available(root):
        print(f"KITTI data not found at {root} (set DFRMOT_DATA)")
        print(json.dumps({"benchmark": "fit_kalman", "skipped": "no KITTI data", **machine}))
        return 0

    t0 = time.perf_counter()
    grid_params, grid_options, grid_hota, grid_config = best_grid_config(Path(args.grid))
    grid_seconds = time.perf_counter() - t0
    base, _ = dm.preset("dfr2023", args.cls)
    fits, lanes = {}, {}
    t1 = time.perf_counter()
    for init in ("diffuse", "steady"):
        on_base = fit_kalman_noise(root, args.cls, kalman_init=init, kf_p0=base.kf_p0)
        fits[f"{init}, kf_p0 {base.kf_p0:g}" if init == "diffuse" else init] = on_base
        lanes[(init, f"dfr2023 + fitted ({init})")] = base._replace(**on_base["params"])
        shared = {"kf_q": on_base["params"]["kf_q"], "kf_r": on_base["params"]["kf_r"]}
        lanes[(init, f"dfr2023 + fitted 2D noise for 3D too ({init})")] = base._replace(**shared)
        on_grid = on_base
        if init == "diffuse" and grid_params.kf_p0 != base.kf_p0:       # the steady start has no kf_p0
            on_grid = fits[f"{init}, kf_p0 {grid_params.kf_p0:g}"] = fit_kalman_noise(
                root, args.cls, kalman_init=init, kf_p0=grid_params.kf_p0)
        lanes[(init, f"grid config {grid_config} + fitted ({init})")] = grid_params._replace(**on_grid["params"])
    fit_seconds = time.perf_counter() - t1
    lanes[(grid_options.kalman_init, f"grid config {grid_config} (best in-sample)")] = grid_params

    split = dm.load_split(root, "rrc", "pointrcnn", args.cls)
    gt = prepare_gt(root, args.cls, split.names)
    hota = {}
    for init in ("diffuse", "steady"):
        names = [name for (i, name) in lanes if i == init]
        options = grid_options._replace(filter="kalman", kalman_init=init)
        res = dm.track(split, dm.stack_params([lanes[(init, n)] for n in names]), options)
        assert not res.overflow.any()
        boxes = res.boxes if res.boxes.ndim == 4 else np.broadcast_to(res.boxes, (len(names),) + res.boxes.shape)
        for name, out in zip(names, evaluate_arrays(gt, res.ids, boxes, split.offsets)):
            hota[name] = float(metrics_table(out).loc["COMBINED", "HOTA"])

    n_labels = len(list((Path(root) / "label_02").glob("*.txt")))
    print(f"KITTI {args.cls}: noise fitted on the ground truth of all {n_labels} label_02 sequences, tracked and "
          f"scored on the {len(split.names)} with the class (RRC + PointRCNN): in-sample")
    for name, fit in fits.items():
        print(f"fit ({name}):  2D kf_q {fit['2d']['kf_q']:.6g}  kf_r {fit['2d']['kf_r']:.6g}   "
              f"3D kf_q3 {fit['3d']['kf_q']:.6g}  kf_r3 {fit['3d']['kf_r']:.6g}   "
              f"(mean log-likelihood 2D {fit['2d']['loglik']:.4f}, 3D {fit['3d']['loglik']:.4f})")
    print(f"best grid config {grid_config}: " + ", ".join(f"{k} {getattr(grid_params, k):g}"
                                                        for k in ("kf_q", "kf_r", "kf_p0", "a_l"))
          + f", kalman_init {grid_options.kalman_init}: HOTA {grid_hota:.2f} (sweep)")
    for name, h in sorted(hota.items(), key=lambda kv: -kv[1]):
        print(f"  {h:6.2f}  {name}")
    result = {"benchmark": "fit_kalman", "class": args.cls, "fit_sequences": n_labels, "sequences": len(split.names),
              "in_sample": True,
              "fits": {name: {"2d": {k: fit["2d"][k] for k in ("kf_q", "kf_r", "loglik", "n_innovations")},
                              "3d": {k: fit["3d"][k] for k in ("kf_q", "kf_r", "loglik", "n_innovations")}}
                       for name, fit in fits.items()},
              "grid_best": {"config": grid_config, "hota_sweep": round(grid_hota, 4),
                            **{k: getattr(grid_params, k) for k in ("kf_q", "kf_r", "kf_p0", "a_l")},
                            "kalman_init": grid_options.kalman_init},
              "hota": {k: round(v, 4) for k, v in hota.items()},
              "seconds": {"grid": round(grid_seconds, 1), "fits": round(fit_seconds, 1),
                          "total": round(time.perf_counter() - t0, 1)}, **machine}
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
