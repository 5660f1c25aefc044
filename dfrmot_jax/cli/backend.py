"""The ``--backend`` / ``--address`` / ``--worker-cpus`` / ``--workers`` options of ``sweep`` and ``tune``."""

from __future__ import annotations

from ..sweep.backend import make_backend


def add_backend_arguments(p) -> None:
    p.add_argument("--workers", type=int, help="local backend: metric processes beside the tracker (default: 2 for "
                                               "large sweeps, 0: in-process)")
    p.add_argument("--backend", choices=("local", "ray"), default="local",
                   help="where chunks run: this process (default) or a Ray cluster (pip install \"dfrmot_jax[ray]\")")
    p.add_argument("--address", metavar="ADDR",
                   help="Ray cluster address (HOST:PORT of 'ray start --head', 'auto', ray://HOST:10001); "
                        "default: a local Ray instance")
    p.add_argument("--worker-cpus", type=int, metavar="N",
                   help="Ray: one worker per N CPUs of a node (default: one worker per node, all its CPUs)")


def backend_from(args):
    """The backend object the options name (bad combinations: ``SweepConfigError``, exit 2)."""
    if args.workers is not None and args.workers < 0:
        raise ValueError(f"--workers {args.workers}: expected a whole number >= 0")
    if args.backend == "ray" and args.workers is not None:
        raise ValueError("--workers is for the local backend (Ray workers score their own chunks)")
    return make_backend(args.backend, workers=args.workers, address=args.address, worker_cpus=args.worker_cpus)
