"""Atomic file writes, the one writer every output of the package goes through: the bytes go to a
temp file beside the target (``.<name>.<pid>.tmp``), which is then renamed over it, so a reader (or a
resumed run) sees the old file or the new one, never half of one. On any error the temp file is
removed; an ``OSError`` that names no file (a full disk) or names only the temp file (a folder
that cannot be written) is raised again naming the target, the file the caller asked for."""

from __future__ import annotations

import hashlib
import os
import re
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import Callable

#: Temp files of the atomic writes: ``.<name>.<pid>.tmp`` (group 1: the writer's pid).
TMP_NAME = re.compile(r"^\..+\.(\d+)\.tmp$")


@contextmanager
def naming(path: Path, tmp: Path | None = None):
    """An ``OSError`` inside that names no file (a full disk), or names ``tmp`` (the temp file of an
    atomic write, also as the source of its rename), is raised again naming ``path``
    (``OSError(errno, ...)`` keeps its subclass: ``PermissionError``, ...)."""
    try:
        yield
    except OSError as e:
        if e.filename is not None and (tmp is None or str(e.filename) != str(tmp)):
            raise
        raise OSError(e.errno, e.strerror or str(e), str(path)) from e


def sha256(path) -> str:
    """The hex sha256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def atomic_write(path, write: Callable[[Path], None], *, parents: bool = False, digest: bool = False) -> str | None:
    """``write(tmp)`` to a temp file beside ``path``, then rename it to ``path``. ``parents``: create
    the missing parent directories first; ``digest``: return the sha256 of the bytes written."""
    path = Path(path)
    if parents:
        path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    out = None
    try:
        with naming(path, tmp):
            write(tmp)
            if digest:
                out = sha256(tmp)
            os.replace(tmp, path)
    finally:
        with suppress(OSError):
            tmp.unlink(missing_ok=True)
    return out


def write_text_atomic(path, text: str, *, parents: bool = True, digest: bool = False) -> str | None:
    """Replace ``path`` with UTF-8 ``text`` (``\\n`` line ends) atomically."""
    def write(tmp: Path) -> None:
        with open(tmp, "w", encoding="utf-8", newline="\n") as f:
            f.write(text)

    return atomic_write(path, write, parents=parents, digest=digest)


def write_parquet_atomic(path, df, *, parents: bool = False, digest: bool = False) -> str | None:
    """Replace ``path`` with the Parquet file of the ``pandas.DataFrame`` ``df`` (no index) atomically."""
    return atomic_write(path, lambda tmp: df.to_parquet(tmp, index=False), parents=parents, digest=digest)
