"""Numba's on-disk cache for a kernel that calls kernels of other modules, keyed on their source too.

Numba keys a cached function on its own source file (its size and time) and its bytecode, not on the
functions it calls: a cached kernel that calls another module's kernel would keep the old callee
after that module changed (a key short of what its value depends on). Such a kernel is compiled
with ``cache=False`` and reached through a cached entry point, made in the kernel's own module by a
factory like::

    def _entry(digest):
        @numba.njit(cache=True, nogil=True)
        def kernel(*args):
            digest                    # (a closure: in numba's cache key)
            return _kernel(*args)
        return kernel

    kernel = _entry(source_digest("dfrmot_jax.metrics.common.assignment", ...))

Numba's key includes a function's closure, so any change in the callees' modules compiles the entry
anew, while an unchanged install loads it from disk (a closure over the kernel itself would not do:
a pickled dispatcher carries a random id). ``tests/test_metrics_units.py`` checks both.
"""

from __future__ import annotations

import hashlib
import sys
from pathlib import Path

__all__ = ["source_digest"]


def source_digest(*modules: str) -> str:
    """The SHA-1 of the source files of the named (imported) modules, in order: the part of a cached
    entry point's key that names the kernels it calls."""
    h = hashlib.sha1()
    for name in modules:
        h.update(name.encode() + b"\0" + Path(sys.modules[name].__file__).read_bytes())
    return h.hexdigest()
