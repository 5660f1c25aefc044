"""Command-line test tools: run ``dfrmot`` in-process and read its one error line; kill a
``dfrmot`` subprocess at a chosen moment (resume tests); bound a call that could block forever
(:func:`deadline`)."""

from __future__ import annotations

import os
import signal
import time
from contextlib import contextmanager
from typing import Callable, Sequence

from ..cli import main


def run_cli(capsys, argv: Sequence) -> tuple[int, str, list[str]]:
    """``dfrmot argv`` in-process -> (status, stdout, stderr lines); argparse exits become their
    status. No traceback may reach either stream."""
    try:
        status = main([str(a) for a in argv])
    except SystemExit as e:
        status = e.code
    out = capsys.readouterr()
    for text in (out.out, out.err):
        assert "Traceback" not in text, text
    return status, out.out, out.err.splitlines()


def error_line(err: Sequence[str], command: str, alone: bool = False) -> str:
    """The one ``dfrmot COMMAND: error: ...`` line among the stderr lines ``err`` (with ``alone``:
    the only line), without numpy scalar reprs."""
    if alone:
        assert len(err) == 1, err
    errors = [s for s in err if ": error: " in s]
    assert len(errors) == 1 and errors[0].startswith(f"dfrmot {command}: error: "), err
    assert "np." not in errors[0], errors[0]
    return errors[0]


def kill_when(proc, ready: Callable[[], bool], timeout: float = 240.0, poll: float = 0.002) -> bool:
    """SIGKILL the subprocess ``proc`` as soon as ``ready()`` holds; returns whether it was killed
    while running (False: it ended, or ``timeout`` seconds passed, first)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and proc.poll() is None:
        if ready():
            os.kill(proc.pid, signal.SIGKILL)
            return True
        time.sleep(poll)
    return False


class Overdue(BaseException):
    """Raised by :func:`deadline` (a BaseException, so that no ``except Exception`` of the code under
    test, the command line's error handler included, turns it into a result)."""


@contextmanager
def deadline(seconds: float):
    """Raise :class:`Overdue` in the main thread if the block is still running after ``seconds``
    (SIGALRM: it interrupts a blocking ``open`` or ``read``, e.g. of a FIFO without a writer), so a
    test of something that could hang fails instead. Main thread, POSIX only."""
    def alarm(signum, frame):
        raise Overdue(f"still running after {seconds} s")

    old = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
