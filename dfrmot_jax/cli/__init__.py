"""The ``dfrmot`` command line: one parser, one error handler, one module per subcommand.

Each subcommand module (``track``, ``demo``, ``eval``, ``sweep``, ``tune``, ``report``) has
``add_parser(sub)``, which registers the subcommand with ``func=guarded(run)``, and ``run(args)``,
which returns the exit status or raises. :func:`guarded` is the only place that turns exceptions
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
traceback. Without it no traceback reaches the user.
"""

from __future__ import annotations

import argparse
import functools
import re
import sys
from typing import Callable

from . import demo, eval, report, sweep, track, tune

__all__ = ["main", "build_parser", "guarded", "EXIT_OK", "EXIT_INTERNAL", "EXIT_INPUT", "EXIT_OVERFLOW",
           "EXIT_INTERRUPTED"]

EXIT_OK, EXIT_INTERNAL, EXIT_INPUT, EXIT_OVERFLOW, EXIT_INTERRUPTED = 0, 1, 2, 3, 130

#: The subcommand modules, in the order ``dfrmot --help`` lists them.
COMMANDS = (track, demo, eval, sweep, tune, report)

DESCRIPTION = ("DFR-FastMOT camera+LiDAR tracking as batched JAX: track KITTI splits, score them "
               "exactly like TrackEval, run and report parameter sweeps.")
EPILOG = ("exit status: 0 ok, 1 unexpected error (rerun with --debug for the traceback), 2 bad input, "
          "3 a lane overflowed its track memory, 130 interrupted. 'dfrmot COMMAND --help' describes a command.")


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error: ``dfrmot CMD: error: MESSAGE (see 'dfrmot CMD --help')``, exit 2."""

    def error(self, message):
        self.exit(EXIT_INPUT, f"{self.prog}: error: {_one_line(message)} (see '{self.prog} --help')\n")


def build_parser() -> argparse.ArgumentParser:
    """The ``dfrmot`` parser: global ``--version`` / ``--debug`` and one subparser per command."""
    from .. import __version__

    p = _Parser(prog="dfrmot", description=DESCRIPTION, epilog=EPILOG)
    p.add_argument("--version", action="version", version=f"dfrmot {__version__}")
    p.add_argument("--debug", action="store_true", help="let errors through with their Python traceback")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for module in COMMANDS:
        sp = module.add_parser(sub)
        # also accepted after the command; SUPPRESS keeps a global --debug from being reset
        sp.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help=argparse.SUPPRESS)
    return p


# numpy scalar reprs (numpy >= 2) inside messages: np.str_('Bus') -> 'Bus', np.float64(2.5) -> 2.5
_NP_REPR = re.compile(r"\bnp\.(?:str_|bytes_|bool_?|u?int\d*|float\d*|complex\d*|longdouble|intp|uintp)\(([^()]*)\)")


def _one_line(text) -> str:
    text = _NP_REPR.sub(r"\1", str(text))
    return "; ".join(line.strip() for line in text.splitlines() if line.strip())


def _input_error(e: BaseException) -> str | None:
    """The message of a known bad-input error, None for anything else."""
    from ..io.kitti import KittiFormatError
    from ..sweep import SweepConfigError

    if isinstance(e, (KittiFormatError, SweepConfigError, ValueError)):
        return str(e) or type(e).__name__
    if isinstance(e, OSError) and (e.filename is not None or isinstance(e, (FileNotFoundError, PermissionError))):
        if e.filename is None:
            return str(e)
        what = e.strerror or str(e)
        where = f"{e.filename} -> {e.filename2}" if e.filename2 is not None else str(e.filename)
        return f"{where}: {what}"
    return None


def guarded(run: Callable[[argparse.Namespace], int]) -> Callable[[argparse.Namespace], int]:
    """``run(args)`` of a subcommand module behind the one error handler (the parser's ``func``):
    returns ``run``'s status, or the status of the error it raised (module docstring)."""
    name = run.__module__.rpartition(".")[2]

    @functools.wraps(run)
    def func(args) -> int:
        cmd = f"dfrmot {getattr(args, 'command', None) or name}"
        debug = getattr(args, "debug", False)
        try:
            return run(args)
        except KeyboardInterrupt:
            if debug:
                raise
            print(f"{cmd}: interrupted", file=sys.stderr)
            return EXIT_INTERRUPTED
        except Exception as e:
            if debug:
                raise
            message = _input_error(e)
            if message is not None:
                print(f"{cmd}: error: {_one_line(message)}", file=sys.stderr)
                return EXIT_INPUT
            detail = _one_line(e)
            print(f"{cmd}: internal error: {type(e).__name__}{': ' + detail if detail else ''} "
                  f"(rerun with --debug for the traceback)", file=sys.stderr)
            return EXIT_INTERNAL

    return func


def main(argv=None) -> int:
    """Run ``dfrmot`` with ``argv`` (default ``sys.argv[1:]``); returns the exit status.

    Argument errors, ``--help`` and ``--version`` raise ``SystemExit`` (argparse); everything else
    returns a status (see the module docstring)."""
    args = build_parser().parse_args(argv)
    return args.func(args)
