"""A stable argsort of integer keys for compiled callers, cheap to compile.

numba compiles ``np.argsort``, ``np.sort`` and ``np.unique`` from its generic quicksort (a dozen
closures typed, optimised and code-generated per dtype, per kind of sort and again in every kernel
they are linked into): the two sorts the metrics' kernels used (HOTA's and Identity's argsort,
the tracker ids' ``np.unique`` and ``np.searchsorted``) were about 5 s of CPU of a first run's
compilation. :func:`argsort` is a bottom-up merge sort in plain loops: a fraction of that to
compile, O(n log n), and stable (equal keys keep their order; numba's quicksort is not). No
caller's result depends on the order of equal keys: HOTA's keys are distinct, Identity sums each
component's integer counts exactly, the tracker ids are ranked by value.
"""

from __future__ import annotations

import numpy as np

from dfrmot_jax.metrics.common.kernel_cache import cached_njit

__all__ = ["argsort"]


@cached_njit(nogil=True)
def argsort(keys):
    """The indices [n] int64 that sort ``keys`` [n] (integers) ascending, equal keys in index order:
    ``np.argsort(keys, kind="stable")``."""
    n = len(keys)
    order = np.empty(n, np.int64)
    tmp = np.empty(n, np.int64)
    for i in range(n):
        order[i] = i
    width = 1
    while width < n:
        for lo in range(0, n, 2 * width):
            mid, hi = min(lo + width, n), min(lo + 2 * width, n)
            i, j = lo, mid
            for k in range(lo, hi):
                if j >= hi or (i < mid and keys[order[i]] <= keys[order[j]]):
                    tmp[k] = order[i]
                    i += 1
                else:
                    tmp[k] = order[j]
                    j += 1
        order, tmp = tmp, order
        width *= 2
    return order
