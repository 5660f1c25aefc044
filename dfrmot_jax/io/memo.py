"""Values built from files, kept until one of the files changes: the one memo behind the readers'
caches (prepared ground truth, packed splits, lifted detections). Each entry is stored with a stamp
of its files (:func:`dfrmot_jax.io.kitti.file_stamps`: size and mtime); a lookup whose stamp differs
rebuilds it. A memo holds at most ``size`` entries and forgets all of them when full (the entries
are few and large: a split, a sequence list's ground truth)."""

from __future__ import annotations

from typing import Any, Callable, Hashable


class FileMemo:
    """``memo.get(key, stamp, build)``: the value stored under ``key`` if its ``stamp`` is the same,
    else ``build()`` (stored). ``clear()`` forgets everything (a cold start)."""

    def __init__(self, size: int = 16):
        self.size = size
        self.items: dict[Hashable, tuple[Any, Any]] = {}

    def get(self, key: Hashable, stamp: Any, build: Callable[[], Any]) -> Any:
        hit = self.items.get(key)
        if hit is not None and hit[0] == stamp:
            return hit[1]
        value = build()
        if len(self.items) >= self.size:
            self.items.clear()
        self.items[key] = (stamp, value)
        return value

    def clear(self) -> None:
        self.items.clear()

    def __len__(self) -> int:
        return len(self.items)
