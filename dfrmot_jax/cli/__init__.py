"""The ``dfrmot`` command line: one parser, one error handler, one module per subcommand.

Each subcommand (``track``, ``demo``, ``eval``, ``compare``, ``sweep``, ``tune``, ``report``, ``lidar``)
has a parser module, ``CMD_parser``, whose ``add_parser(sub)`` registers it with
``func=run_later("dfrmot_jax.cli.CMD")``, and a module ``CMD`` whose ``run(args)`` returns the exit
status or raises. :func:`~dfrmot_jax.cli.errors.guarded` (through ``run_later``) is the only place that
turns exceptions into messages and exit statuses:

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

Each command imports what it uses, and only when it runs: the parser lists every command from
:mod:`.commands` (names and help) and builds in full only the subparser of the command named on the
command line, importing that command's parser module, which imports only light modules (``dfrmot
--help`` imports none; ``dfrmot CMD --help`` no JAX, pandas, pyarrow, SciPy, Optuna or Matplotlib:
``config`` for ``track``, ``lidar_settings`` for ``lidar``, :mod:`dfrmot_jax.choices` for the names a
user picks); the command's own module is imported when it runs (``dfrmot eval`` the metrics, not JAX).
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from contextlib import nullcontext

from ..paths import COMPILE_CACHE_VAR, default_compile_cache
from ..version import __version__
from .commands import FAMILIES, HELP, PARSERS
from .errors import (EXIT_INPUT, EXIT_INTERNAL, EXIT_INTERRUPTED, EXIT_OK, EXIT_OVERFLOW, CommandParser,
                     guarded, warning_lines)

__all__ = ["main", "build_parser", "guarded", "EXIT_OK", "EXIT_INTERNAL", "EXIT_INPUT", "EXIT_OVERFLOW",
           "EXIT_INTERRUPTED"]


#: The subcommands, in the order ``dfrmot --help`` lists them.
COMMANDS = tuple(HELP)

DESCRIPTION = (f"Multi-object trackers as batched JAX, tracker families {FAMILIES} (a preset names its family, "
               "e.g. --preset ab3dmot_car or bytetrack_car; a sweep file's [options] family). Track KITTI splits, "
               "score them exactly like TrackEval (and AB3DMOT's sAMOTA), run and report parameter sweeps.")
EPILOG = ("exit status: 0 ok, 1 unexpected error (rerun with --debug for the traceback), 2 bad input, "
          "3 a lane overflowed its track memory, 130 interrupted. 'dfrmot COMMAND --help' describes a command.")


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The ``dfrmot`` parser: global ``--version`` / ``--debug`` and one subparser per command.

    ``command``: build only that command's subparser in full (importing its parser module, the
    per-command lazy import of ARCHITECTURE.md's rules); every other command is listed by its name
    and help alone, and its module not imported (a name of no command, e.g. "": none is built, as
    for ``dfrmot --help``). None (the default): every subparser in full."""
    p = CommandParser(prog="dfrmot", description=DESCRIPTION, epilog=EPILOG)
    p.add_argument("--version", action="version", version=f"dfrmot {__version__}")
    p.add_argument("--debug", action="store_true", help="let errors through with their Python traceback")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMANDS:
        if command is not None and name != command:
            sub.add_parser(name, help=HELP[name], add_help=False)         # listed, never parsed
            continue
        sp = importlib.import_module(f"{__name__}.{PARSERS[name]}").add_parser(sub)
        # also accepted after the command; SUPPRESS keeps a global --debug from being reset
        sp.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help=argparse.SUPPRESS)
    return p


def command_of(argv) -> str | None:
    """The command ``argv`` names: its first argument that is no option (the global options take no
    value); None when there is none."""
    return next((a for a in argv if not a.startswith("-")), None)


def main(argv=None) -> int:
    """Run ``dfrmot`` with ``argv`` (default ``sys.argv[1:]``); returns the exit status.

    Argument errors, ``--help`` and ``--version`` raise ``SystemExit`` (argparse); everything else
    returns a status (see the module docstring). Only the named command's parser module is imported
    (:func:`build_parser`); the command's own module when it runs."""
    argv = sys.argv[1:] if argv is None else list(argv)
    # compiled tracker programs kept between runs (devices.setup_compile_cache; "off": none)
    os.environ.setdefault(COMPILE_CACHE_VAR, str(default_compile_cache()))
    command = command_of(argv) or ""
    # a warning raised while the command's parser module is imported (the metrics' kernel cache) is
    # one line too, as those of the command's run (errors.guarded)
    with nullcontext() if "--debug" in argv else warning_lines(f"dfrmot {command}".rstrip()):
        args = build_parser(command).parse_args(argv)
    return args.func(args)
