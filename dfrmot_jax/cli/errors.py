"""The ``dfrmot`` command line's one error handler (:func:`guarded`) and exit statuses; see
:mod:`dfrmot_jax.cli` for what each status means. It also shows each Python warning raised while a
command runs as one line, ``dfrmot CMD: warning: MESSAGE`` (``--debug``: Python's own format, with
the source line). :func:`run_later` is every command's handler: its parser is built without its
module (``CMD_parser``), which is imported when the command runs.

Bad input is a ``ValueError`` (``KittiFormatError`` and ``SweepConfigError`` are ValueErrors) or an
``OSError`` naming a file; this module imports neither class (nor anything of the package), so that
the parser costs no import of the commands' dependencies."""

from __future__ import annotations

import argparse
import functools
import importlib
import re
import sys
import warnings
from contextlib import contextmanager
from typing import Callable

EXIT_OK, EXIT_INTERNAL, EXIT_INPUT, EXIT_OVERFLOW, EXIT_INTERRUPTED = 0, 1, 2, 3, 130


class CommandParser(argparse.ArgumentParser):
    """argparse with a one-line error: ``dfrmot CMD: error: MESSAGE (see 'dfrmot CMD --help')``, exit 2."""

    def error(self, message):
        self.exit(EXIT_INPUT, f"{self.prog}: error: {_one_line(message)} (see '{self.prog} --help')\n")


# numpy scalar reprs (numpy >= 2) inside messages: np.str_('Bus') -> 'Bus', np.float64(2.5) -> 2.5
_NP_REPR = re.compile(r"\bnp\.(?:str_|bytes_|bool_?|u?int\d*|float\d*|complex\d*|longdouble|intp|uintp)\(([^()]*)\)")


def _one_line(text) -> str:
    text = _NP_REPR.sub(r"\1", str(text))
    return "; ".join(line.strip() for line in text.splitlines() if line.strip())


def _input_error(e: BaseException) -> str | None:
    """The message of a known bad-input error, None for anything else."""
    if isinstance(e, ValueError):                 # KittiFormatError and SweepConfigError among them
        return str(e) or type(e).__name__
    if isinstance(e, OSError) and (e.filename is not None or isinstance(e, (FileNotFoundError, PermissionError))):
        if e.filename is None:
            return str(e)
        what = e.strerror or str(e)
        where = f"{e.filename} -> {e.filename2}" if e.filename2 is not None else str(e.filename)
        return f"{where}: {what}"
    return None


@contextmanager
def warning_lines(cmd: str):
    """Inside, a warning that Python's filters let through is printed as one line on stderr,
    ``{cmd}: warning: MESSAGE``, instead of ``FILE:LINE: Category: MESSAGE`` and the source line."""
    def show(message, category, filename, lineno, file=None, line=None):
        print(f"{cmd}: warning: {_one_line(message)}", file=sys.stderr if file is None else file)

    with warnings.catch_warnings():
        warnings.showwarning = show
        yield


def guarded(run: Callable[[argparse.Namespace], int]) -> Callable[[argparse.Namespace], int]:
    """``run(args)`` of a subcommand module behind the one error handler (the parser's ``func``):
    returns ``run``'s status, or the status of the error it raised (module docstring)."""
    name = run.__module__.rpartition(".")[2]

    @functools.wraps(run)
    def func(args) -> int:
        cmd = f"dfrmot {getattr(args, 'command', None) or name}"
        debug = getattr(args, "debug", False)
        try:
            if debug:
                return run(args)
            with warning_lines(cmd):
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


def run_later(module: str) -> Callable[[argparse.Namespace], int]:
    """The parser's ``func`` of a command whose parser is built without its module: imports
    ``module`` (e.g. ``"dfrmot_jax.cli.track"``) when the command runs and calls its ``run(args)``
    behind :func:`guarded` (the module's ``run`` as it is then: a test may replace it), the import
    behind it too (a warning the import raises, such as the metrics' kernel cache's, is one line)."""
    def imported(args) -> int:
        return importlib.import_module(module).run(args)

    imported.__module__ = module      # guarded names the command by it

    def run(args) -> int:
        return guarded(imported)(args)     # the import too: its warnings one line each, its errors handled

    run.module = module
    return run
