"""Freed memory given back to the system during a sweep: :func:`fixed_mmap_threshold`.

glibc's ``malloc`` serves a block of at least its *mmap threshold* with a mapping of its own, which
``free`` unmaps at once; smaller blocks come from its heaps, whose freed space mostly stays with the
process. The threshold is dynamic by default: each time a mapped block is freed, it rises to that
block's size, up to 32 MiB. A sweep allocates and frees NumPy arrays of every size, chunk after
chunk, in three threads (the driver, the scoring's start, AB3DMOT's figures), each with its heap; so
after the first large array is freed, the arrays of up to 32 MiB fill those heaps, and their freed
space is held. Measured on the 1,024-config grid sweep (2-core Intel Xeon, glibc 2.36): peak RSS
2,134 MB with the dynamic threshold, 1,815 MB with it fixed at 4 MiB and 1,854 MB at 1 MiB, in
51.5 s, 52.4 s and 55.6 s (a smaller threshold maps and faults in more blocks).

Why by hand: no library sets ``mallopt``; Python's ``ctypes`` calls it (M_MMAP_THRESHOLD, -3 in
glibc's ``malloc.h``). Elsewhere (musl, macOS, Windows) it does nothing.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os

#: the mmap threshold a sweep fixes (bytes)
MMAP_THRESHOLD = 4 << 20

#: glibc's ``M_MMAP_THRESHOLD`` parameter of ``mallopt``
M_MMAP_THRESHOLD = -3

_done: list[bool] = []


def fixed_mmap_threshold(nbytes: int = MMAP_THRESHOLD) -> bool:
    """Fix glibc's mmap threshold at ``nbytes`` for this process (once; the dynamic threshold is off
    from then on), unless ``$MALLOC_MMAP_THRESHOLD_`` (glibc's own setting) is set. Returns whether
    the threshold is now fixed here (False without glibc or with the variable set)."""
    if _done:
        return _done[0]
    ok = False
    if "MALLOC_MMAP_THRESHOLD_" not in os.environ:
        name = ctypes.util.find_library("c")
        try:
            libc = ctypes.CDLL(name) if name else None
            mallopt = getattr(libc, "mallopt", None) if libc is not None and hasattr(libc, "gnu_get_libc_version") else None
        except OSError:
            mallopt = None
        if mallopt is not None:
            mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
            ok = bool(mallopt(M_MMAP_THRESHOLD, int(nbytes)))
    _done.append(ok)
    return ok
