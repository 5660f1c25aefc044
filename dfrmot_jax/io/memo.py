"""Values built from files, kept until one of the files changes: the one memo behind the readers'
caches (prepared ground truth, packed splits, lifted detections).

A memo's key names the call (its arguments) and its stamp names the files the value was built from:
each file's :class:`FileStamp` (mtime and ctime in ns, size, inode; None for a missing file), so a
file edited in place, replaced by a rename, grown, cut or deleted is seen. What a stamp cannot see
is a file rewritten to the same size within one tick of the filesystem clock after the stamp was
taken; so, as git does for its index ("racily clean" entries), a value whose newest file was
modified within :data:`RACY_NS` of its stamp is used for nothing but the call that built it: the next
lookup builds it again. A memo holds at most ``size`` entries and forgets all of them when full (the
entries are few and large: a split, a sequence list's ground truth)."""

from __future__ import annotations

import os
import time
from typing import Any, Callable, Hashable, NamedTuple

__all__ = ["FileMemo", "FileStamp", "file_stamps", "RACY_NS"]

#: a value built less than this after its newest file's modification is not reused (see the module)
RACY_NS = 1_000_000_000


class FileStamp(NamedTuple):
    """What a memo compares of one file: modification and status-change times (ns), size, inode."""
    mtime_ns: int
    ctime_ns: int
    size: int
    inode: int


def file_stamps(paths) -> tuple:
    """The :class:`FileStamp` of each file, None where there is none (or it cannot be stat-ed)."""
    out = []
    for path in paths:
        try:
            st = os.stat(path)
            out.append(FileStamp(st.st_mtime_ns, st.st_ctime_ns, st.st_size, st.st_ino))
        except OSError:
            out.append(None)
    return tuple(out)


def newest_mtime(stamp: Any) -> int:
    """The newest modification time (ns) of the :class:`FileStamp` s anywhere in ``stamp`` (nested
    tuples of them, None for missing files), -1 without any."""
    if isinstance(stamp, FileStamp):
        return stamp.mtime_ns
    if isinstance(stamp, (tuple, list)):
        return max((newest_mtime(s) for s in stamp), default=-1)
    return -1


class FileMemo:
    """``memo.get(key, stamp, build)``: the value stored under ``key`` if its ``stamp`` (taken before
    ``build`` reads the files; nested tuples of :class:`FileStamp`) is the same and was not racy, else
    ``build()`` (stored). ``clear()`` forgets everything (a cold start)."""

    def __init__(self, size: int = 16):
        self.size = size
        self.items: dict[Hashable, tuple[Any, Any, bool]] = {}     # key -> (stamp, value, racy)

    def get(self, key: Hashable, stamp: Any, build: Callable[[], Any]) -> Any:
        hit = self.items.get(key)
        if hit is not None and hit[0] == stamp and not hit[2]:
            return hit[1]
        now = time.time_ns()
        value = build()
        if len(self.items) >= self.size:
            self.items.clear()
        self.items[key] = (stamp, value, newest_mtime(stamp) >= now - RACY_NS)
        return value

    def clear(self) -> None:
        self.items.clear()

    def __len__(self) -> int:
        return len(self.items)
