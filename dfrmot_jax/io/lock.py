"""One writer per output folder: :func:`folder_lock`, held by ``dfrmot sweep``, ``tune`` and ``track``
(and ``run_sweep`` / ``tune`` with an ``out``) while they write a folder.

The lock is ``FOLDER/.dfrmot.lock``, an OS lock (``flock``) taken with the ``filelock`` library: the
kernel releases it when its process ends, however it ends (kill -9 included), so a lock never
outlives its process on a local file system. While held, the file records its holder (pid, host,
command, start time, one JSON line); a second run on the folder fails at once with
:class:`FolderInUseError` naming the folder and that process. On a normal exit (an error included)
the file is removed, still locked (filelock >= 3.30 checks after locking that the file it locked is
still there, so a contender that opened it just before cannot hold a removed file's lock; before
3.30 a contender also truncated the holder's record), and so is a folder the lock created that
nothing else was written to. A file left by a process that ended without removing it (killed,
crashed) is taken over by the next run with a ``RuntimeWarning`` naming that process. A
``.dfrmot.lock`` that is no regular file (a FIFO, a folder, ...) is refused with a ``ValueError``
naming it, before anything opens it (a FIFO would block the run).
"""

from __future__ import annotations

import json
import os
import socket
import stat
import sys
import time
import warnings
from contextlib import contextmanager, suppress
from pathlib import Path

from filelock import FileLock, Timeout

__all__ = ["LOCK_NAME", "FolderInUseError", "folder_lock", "lock_holder"]

#: the lock file of an output folder (ignored by the checks that a folder is empty)
LOCK_NAME = ".dfrmot.lock"


class FolderInUseError(ValueError):
    """The output folder is being written by another process (bad input: exit 2)."""


def lock_holder(folder) -> dict | None:
    """The record of the process holding (or last holding, if it did not clear it) the lock of
    ``folder``: {pid, host, command, started}; None if there is none or it does not parse."""
    path = Path(folder) / LOCK_NAME
    try:
        if not path.is_file():                  # (a FIFO would block the read)
            return None
        doc = json.loads(path.read_text(encoding="utf-8") or "null")
    except (OSError, ValueError):
        return None
    return doc if isinstance(doc, dict) and isinstance(doc.get("pid"), int) else None


def _who(rec: dict | None) -> str:
    if rec is None:
        return "another process (just starting)"
    host = "" if rec.get("host") == socket.gethostname() else f" on {rec.get('host')}"
    return f"process {rec['pid']}{host} ({rec.get('command', '?')}, since {rec.get('started', '?')})"


def _write(path: Path, rec: dict) -> None:
    """Replace the record in the lock file in place (the file, and so the lock, stays the same)."""
    with open(path, "r+", encoding="utf-8") as f:
        f.truncate(0)
        f.write(json.dumps(rec) + "\n")


@contextmanager
def folder_lock(folder, what: str = "dfrmot"):
    """Hold the lock of output folder ``folder`` (created if missing) for the ``with`` block.

    Raises :class:`FolderInUseError` at once when another process holds it (naming the folder and
    that process), ``ValueError`` when ``folder`` is a file or its lock file no regular file (a
    FIFO: nothing opens it). ``what``: how the record names this run when no command line is at
    hand (``sys.argv`` is used when there is one)."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise ValueError(f"{folder} is a file, not a directory (the output folder)")
    created = not folder.exists()
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / LOCK_NAME
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        mode = None
    if mode is not None and not stat.S_ISREG(mode):
        kind = ("a FIFO (named pipe)" if stat.S_ISFIFO(mode) else "a directory" if stat.S_ISDIR(mode)
                else "not a regular file")
        raise ValueError(f"{path} is {kind}, not the lock file of the output folder: remove it, or write elsewhere")
    lock = FileLock(str(path), timeout=0)
    try:
        lock.acquire()
    except Timeout:
        raise FolderInUseError(f"{folder} is in use by {_who(lock_holder(folder))}: wait for it to finish, or write "
                               f"elsewhere") from None
    try:
        stale = lock_holder(folder)
        if stale is not None and stale["pid"] != os.getpid():
            warnings.warn(f"{folder}: took over the lock of {_who(stale)}, which ended without releasing it "
                          f"(killed or crashed): its partial output is checked as usual", RuntimeWarning,
                          stacklevel=3)
        command = " ".join([Path(sys.argv[0]).name] + sys.argv[1:]) if sys.argv and sys.argv[0] else what
        _write(path, {"pid": os.getpid(), "host": socket.gethostname(), "command": command,
                      "started": time.strftime("%Y-%m-%d %H:%M:%S")})
        yield folder
    finally:
        with suppress(OSError):
            path.unlink()
            if created and not any(folder.iterdir()):
                folder.rmdir()
        lock.release()
