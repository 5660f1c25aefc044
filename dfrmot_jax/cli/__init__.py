"""The ``dfrmot`` command line: one parser, one error handler, one module per subcommand.

Each subcommand module (``track``, ``demo``, ``eval``, ``sweep``, ``tune``, ``report``, ``lidar``) has
``add_parser(sub)``, which registers the subcommand with ``func=guarded(run)``, and ``run(args)``,
which returns the exit status or raises. :func:`~dfrmot_jax.cli.errors.guarded` is the only place that turns exceptions
into messages and exit statuses:

==========  ========================================================================================
exit 0      done
exit 1      any other exception (a bug, or an ``OSError`` that names no file such as a full disk): one
            line ``dfrmot CMD: internal error: TYPE: MESSAGE (rerun with --debug for the traceback)``
exit 2      bad input: bad arguments (argparse), data (:class:`~dfrmot_jax.io.kitti.KittiFormatError`),
            values (``ValueError``), sweep files (``SweepConfigError``), missing or unreadable files
            (``FileNotFoundError``, ``PermissionError``, an ``OSError`` naming a file): one line
            ``dfrmot CMD: error: MESSAGE`` (argparse adds ``(see 'dfrmot CMD --help')``)
exit 3      tracking finished but some lane overflowed its track memory (``track``, ``sweep``, ``tune``)
exit 130    interrupted (Ctrl-C)
==========  ========================================================================================

``dfrmot --debug CMD ...`` (or ``dfrmot CMD --debug ...``) lets every exception through with its
traceback. Without it no traceback reaches the user, and each Python warning a command raises (a
lock taken over from a killed run, ...) is one line ``dfrmot CMD: warning: MESSAGE``.
"""

from __future__ import annotations

import argparse

from ..version import __version__
from . import demo, eval, lidar, report, sweep, track, tune
from .errors import (EXIT_INPUT, EXIT_INTERNAL, EXIT_INTERRUPTED, EXIT_OK, EXIT_OVERFLOW, CommandParser,
                     guarded)

__all__ = ["main", "build_parser", "guarded", "EXIT_OK", "EXIT_INTERNAL", "EXIT_INPUT", "EXIT_OVERFLOW",
           "EXIT_INTERRUPTED"]


#: The subcommand modules, in the order ``dfrmot --help`` lists them.
COMMANDS = (track, demo, eval, sweep, tune, report, lidar)

DESCRIPTION = ("DFR-FastMOT camera+LiDAR tracking as batched JAX: track KITTI splits, score them "
               "exactly like TrackEval, run and report parameter sweeps.")
EPILOG = ("exit status: 0 ok, 1 unexpected error (rerun with --debug for the traceback), 2 bad input, "
          "3 a lane overflowed its track memory, 130 interrupted. 'dfrmot COMMAND --help' describes a command.")


def build_parser() -> argparse.ArgumentParser:
    """The ``dfrmot`` parser: global ``--version`` / ``--debug`` and one subparser per command."""
    p = CommandParser(prog="dfrmot", description=DESCRIPTION, epilog=EPILOG)
    p.add_argument("--version", action="version", version=f"dfrmot {__version__}")
    p.add_argument("--debug", action="store_true", help="let errors through with their Python traceback")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for module in COMMANDS:
        sp = module.add_parser(sub)
        # also accepted after the command; SUPPRESS keeps a global --debug from being reset
        sp.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help=argparse.SUPPRESS)
    return p


def main(argv=None) -> int:
    """Run ``dfrmot`` with ``argv`` (default ``sys.argv[1:]``); returns the exit status.

    Argument errors, ``--help`` and ``--version`` raise ``SystemExit`` (argparse); everything else
    returns a status (see the module docstring)."""
    args = build_parser().parse_args(argv)
    return args.func(args)
