"""Python's ``sum`` of floats as each CPython computes it, for AB3DMOT's track-score averages.

AB3DMOT's evaluator averages each track's row scores with ``sum(scores) / float(len(scores))`` and,
at every threshold pass, re-averages the already averaged scores in place (:mod:`.evaluate`). The
figures therefore depend on how the interpreter adds floats:

* ``"sequential"``: CPython <= 3.11 adds left to right from 0 (plain float64 additions). The
  re-average of ``n`` equal copies of a mean drifts by ulps, and a track whose drifted score falls
  below a threshold that is its own first mean is dropped at that pass.
* ``"compensated"``: CPython >= 3.12 (``builtin_sum_impl`` in ``Python/bltinmodule.c``) keeps a
  running compensation ``c`` beside the sum ``s`` (Neumaier's improvement of Kahan's): for each float
  ``x``, ``t = s + x``; ``c += (s - t) + x`` if ``|s| >= |x|`` else ``(x - t) + s``; ``s = t``; at the
  end the result is ``s + c`` when ``c`` is non-zero and finite, else ``s``. It is not
  ``math.fsum`` (which rounds the exact sum once): the two differ on some inputs, and the evaluator
  ran this one. Its re-average of equal copies is a fixed point on every score of the reference
  folders (the drift is gone).

The default is ``"compensated"``: the figures the reference prints on every CPython still maintained,
without the drift. Both are reproduced bit for bit (``tests/metrics/samota/test_samota_sums.py`` checks them against
the running interpreter's ``sum`` and against stored sums of the other interpreters).

All functions add float64 values in array order, many sums at once: a loop over positions whose
body is elementwise over the sums (the longest sum sets the number of steps).
"""

from __future__ import annotations

import numpy as np

from dfrmot_jax.choices import DEFAULT_SUM, SUM_HELP, SUMS
from dfrmot_jax.metrics.common.pairs import segment_starts

__all__ = ["SUMS", "DEFAULT_SUM", "SUM_HELP", "parse_sum", "other_sum", "python_of", "python_sum", "group_sums",
           "repeat_sums"]

_PYTHON = {"compensated": "CPython >= 3.12", "sequential": "CPython <= 3.11"}


def parse_sum(text) -> str:
    """``'compensated'`` / ``'sequential'`` (any case, spaces stripped) -> the name; ValueError otherwise."""
    name = str(text).strip().lower() if isinstance(text, str) else text
    if name not in SUMS:
        raise ValueError(f"AB3DMOT sum {text!r}: expected {' or '.join(SUMS)}")
    return name


def other_sum(name: str) -> str:
    """The other behaviour's name."""
    return SUMS[1 - SUMS.index(parse_sum(name))]


def python_of(name: str) -> str:
    """The interpreters that sum so: ``'CPython >= 3.12'`` / ``'CPython <= 3.11'``."""
    return _PYTHON[parse_sum(name)]


def _add(s: np.ndarray, c: np.ndarray | None, x: np.ndarray) -> np.ndarray:
    """One step of each sum: ``s + x``, updating the compensation ``c`` in place (None: sequential)."""
    t = s + x
    if c is not None:
        with np.errstate(invalid="ignore", over="ignore"):
            c += np.where(np.abs(s) >= np.abs(x), (s - t) + x, (x - t) + s)
    return t


def _finish(s: np.ndarray, c: np.ndarray | None) -> np.ndarray:
    if c is None:
        return s
    use = (c != 0) & np.isfinite(c)
    return np.where(use, s + c, s)


def python_sum(values, mode: str = DEFAULT_SUM) -> float:
    """``sum(values)`` of a sequence of floats as ``mode``'s interpreters compute it (one sum)."""
    v = np.asarray(values, dtype=np.float64).reshape(-1)
    return float(group_sums(v, np.zeros(len(v), dtype=np.int64), 1, mode)[0])


def group_sums(values: np.ndarray, group: np.ndarray, n_groups: int, mode: str = DEFAULT_SUM) -> np.ndarray:
    """``sum`` of ``values`` per group, in array order within a group (from 0, as Python's ``sum``).

    values, group: [R] float64 / int in [0, n_groups); returns [n_groups] (0.0 for an empty group)."""
    comp = parse_sum(mode) == "compensated"
    s = np.zeros(n_groups)
    c = np.zeros(n_groups) if comp else None
    if len(values) == 0:
        return s
    order = np.argsort(group, kind="stable")
    g = group[order]
    v = np.asarray(values, dtype=np.float64)[order]
    counts = np.bincount(g, minlength=n_groups)
    starts = segment_starts(counts)[:-1]
    rank = np.arange(len(g)) - starts[g]
    # step k adds the k-th value of every group that has one
    by_rank = np.argsort(rank, kind="stable")
    pos = 0
    for n in np.bincount(rank).tolist():
        idx = by_rank[pos:pos + n]
        gi = g[idx]
        if c is None:
            s[gi] += v[idx]
        else:
            ci = c[gi]
            s[gi] = _add(s[gi], ci, v[idx])
            c[gi] = ci
        pos += n
    return _finish(s, c)


def repeat_sums(value: np.ndarray, n: np.ndarray, mode: str = DEFAULT_SUM) -> np.ndarray:
    """``sum([value[i]] * n[i])`` for each i ([T] each) -> [T] (0.0 where ``n[i] == 0``)."""
    comp = parse_sum(mode) == "compensated"
    out = np.zeros(len(value))
    if len(value) == 0:
        return out
    order = np.argsort(-np.asarray(n), kind="stable")
    v, ns = np.asarray(value, dtype=np.float64)[order], np.asarray(n)[order]
    s = np.zeros(len(v))
    c = np.zeros(len(v)) if comp else None
    active = len(v)
    for k in range(1, int(ns.max(initial=0)) + 1):
        while active and ns[active - 1] < k:
            active -= 1
        if c is None:
            s[:active] += v[:active]
        else:
            ca = c[:active]                       # a view: updated in place
            s[:active] = _add(s[:active], ca, v[:active])
    out[order] = _finish(s, c)
    return out
