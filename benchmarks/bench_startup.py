"""Benchmark: the start-up a user waits for, each command in a fresh interpreter.

Each command runs ``--runs`` times (default 3) in a new process (``python -m dfrmot_jax.cli ...``,
the interpreter this script runs under; no pyenv shim); the wall time of each run is measured from
the parent and the median printed. ``--path DIR`` puts ``DIR`` first on the children's
``PYTHONPATH`` and runs them in it (``python -c`` / ``-m`` look in their working directory first;
default: this checkout), so an older commit extracted with
``git archive COMMIT dfrmot_jax | tar -x -C DIR`` gives a before / after on the same machine, back to
back. ``--importtime`` also runs each command once under ``python -X importtime`` and lists the
heavy dependencies it imports (NumPy, JAX, pandas, pyarrow, SciPy's parts, ...: cumulative seconds
where each was first imported).

Commands: ``import dfrmot_jax``, ``dfrmot --help``, ``dfrmot CMD --help`` for each command of
``--help-of`` (default: every command), ``dfrmot eval DIR``
(``--eval DIR``: a result folder of ``dfrmot track``, e.g. ``dfrmot track --preset dfr2023 --out DIR``)
and ``dfrmot report DIR`` (``--report DIR``: a sweep folder), each only where its folder is given.

The LAST line is one JSON object: the median and every run's seconds per command, the children's
package path, machine info and the load average before and after.

    python benchmarks/bench_startup.py [--path DIR] [--eval DIR] [--report DIR] [--runs 3] [--importtime]
                                     [--help-of track,eval,...]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from importlib import metadata
from pathlib import Path

from dfrmot_jax.cli.commands import HELP

sys.path.insert(0, str(Path(__file__).resolve().parent))

REPO = Path(__file__).resolve().parent.parent


def commands(eval_dir: str | None, report_dir: str | None, helps=tuple(HELP)) -> dict[str, list[str]]:
    """name -> the child's arguments after the interpreter (``helps``: the commands whose ``--help`` runs)."""
    cli = ["-m", "dfrmot_jax.cli"]
    out = {"import dfrmot_jax": ["-c", "import dfrmot_jax"], "dfrmot --help": cli + ["--help"]}
    out |= {f"dfrmot {name} --help": cli + [name, "--help"] for name in helps}
    if eval_dir:
        out["dfrmot eval"] = cli + ["eval", str(Path(eval_dir).resolve())]
    if report_dir:
        out["dfrmot report"] = cli + ["report", str(Path(report_dir).resolve())]
    return out


def timed(args: list[str], env: dict, cwd: str) -> float:
    """Wall seconds of one child run (its output discarded; a failure stops the benchmark)."""
    t0 = time.perf_counter()
    subprocess.run([sys.executable, *args], env=env, cwd=cwd, check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


HEAVY = ("numpy", "jax", "optax", "pandas", "pyarrow", "scipy", "scipy.optimize", "scipy.sparse", "scipy.stats",
         "matplotlib", "optuna", "tqdm", "filelock")


def heavy_imports(args: list[str], env: dict, cwd: str) -> dict[str, float]:
    """Seconds (cumulative, ``-X importtime``) of each of :data:`HEAVY` the command imports, at
    whatever depth it was first imported."""
    r = subprocess.run([sys.executable, "-X", "importtime", *args], env=env, cwd=cwd, capture_output=True, text=True,
                       check=True)
    out = {}
    for line in r.stderr.splitlines():
        if not line.startswith("import time:") or "cumulative" in line:
            continue
        _, cum, name = line.removeprefix("import time:").split("|")
        if name.strip() in HEAVY:
            out[name.strip()] = round(int(cum) / 1e6, 3)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--path", default=str(REPO), help="the package's folder for the children (default: this checkout)")
    ap.add_argument("--eval", help="a result folder for 'dfrmot eval'")
    ap.add_argument("--report", help="a sweep folder for 'dfrmot report'")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--help-of", default=",".join(HELP), metavar="CMDS",
                    help="comma-separated commands whose --help runs (default: every command)")
    ap.add_argument("--importtime", action="store_true", help="also list the heavy dependencies each command imports")
    args = ap.parse_args()

    env = {**os.environ, "PYTHONPATH": os.pathsep.join([args.path, os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)}
    load_before = os.getloadavg()
    result = {}
    helps = [h for h in args.help_of.split(",") if h]
    for name, cmd in commands(args.eval, args.report, helps).items():
        runs = [timed(cmd, env, args.path) for _ in range(args.runs)]
        result[name] = {"median_s": round(statistics.median(runs), 3), "runs_s": [round(t, 3) for t in runs]}
        line = f"{name:22s} median {statistics.median(runs):6.2f} s  (runs {', '.join(f'{t:.2f}' for t in runs)})"
        print(line, flush=True)
        if args.importtime:
            heavy = heavy_imports(cmd, env, args.path)
            result[name]["imports_s"] = heavy
            print("    imports: " + (", ".join(f"{m} {t:.2f} s" for m, t in heavy.items()) or "none of them"), flush=True)

    from machine import cpu_model

    print(json.dumps({"commands": result, "path": args.path, "runs": args.runs, "cpu_model": cpu_model(),
                      "cpus": os.cpu_count(), "python": sys.version.split()[0], "jax": metadata.version("jax"),
                      "load_avg_before": [round(x, 2) for x in load_before],
                      "load_avg_after": [round(x, 2) for x in os.getloadavg()]}))


if __name__ == "__main__":
    main()
