"""The backend ``sweep`` and ``tune`` run on, from their ``--backend`` / ``--address`` / ``--worker-cpus``
/ ``--workers`` options (the options themselves: :func:`dfrmot_jax.cli.args.add_backend_arguments`)."""

from __future__ import annotations

from ..sweep.backend import make_backend


def backend_from(args):
    """The backend object the options name (bad combinations: ``SweepConfigError``, exit 2)."""
    if args.workers is not None and args.workers < 0:
        raise ValueError(f"--workers {args.workers}: expected a whole number >= 0")
    if args.backend == "ray" and args.workers is not None:
        raise ValueError("--workers is for the local backend (Ray workers score their own chunks)")
    return make_backend(args.backend, workers=args.workers, address=args.address, worker_cpus=args.worker_cpus)
