"""How a batch's lanes are grouped into compiled calls and how their outputs are gathered: the rules
every family's batch entry point uses (NumPy only, host side).

- :func:`calls_by_key`: lanes sharing a key (work made once per call: DFR-FastMOT's objects of one
  score setting) in calls of at most ``per`` lanes;
- :func:`calls_of_groups`: groups of lanes kept whole (lanes that track alike, tracked once: AB3DMOT's
  tracking lanes) packed into calls of at most ``per`` groups and ``4 per`` lanes;
- :func:`widen`: a lane's output re-run with more track slots, gathered beside the others.
"""

from __future__ import annotations

from typing import Iterator

import numpy as np

__all__ = ["calls_by_key", "calls_of_groups", "widen"]


def calls_by_key(todo: np.ndarray, per: int, keys: np.ndarray | None) -> Iterator[tuple[np.ndarray, int | None]]:
    """(lanes, key) of each compiled call: ``todo``'s lanes, at most ``per`` per call; with ``keys``
    [B], the lanes of one call share their key (keys in order of first appearance; key None: no
    key)."""
    if keys is None:
        for start in range(0, todo.size, per):
            yield todo[start:start + per], None
        return
    k = keys[todo]
    for key in k[np.sort(np.unique(k, return_index=True)[1])]:
        group = todo[k == key]
        for start in range(0, group.size, per):
            yield group[start:start + per], int(key)


def calls_of_groups(of: np.ndarray, per: int) -> list[np.ndarray]:
    """The lanes of each compiled call: the lanes of one group (``of`` [B], each lane's group
    0..G-1) in one call, each call holding at most ``per`` groups and ``4 per`` lanes (its output's
    memory), groups in order."""
    calls, cur, groups = [], [], 0
    for key in range(int(of.max(initial=-1)) + 1):
        group = np.flatnonzero(of == key)
        if cur and (groups + 1 > per or len(cur) + len(group) > 4 * per):
            calls.append(np.array(cur, np.int64))
            cur, groups = [], 0
        cur += group.tolist()
        groups += 1
    if cur:
        calls.append(np.array(cur, np.int64))
    return calls


def widen(a: np.ndarray, k: int, fill=0) -> np.ndarray:
    """Axis 2 of a [B, T, K', ...] array grown to ``k`` slots, padded with ``fill`` (a lane re-run
    with a larger capacity); ``a`` itself when it has ``k`` or more."""
    if a.shape[2] >= k:
        return a
    pad = [(0, 0)] * a.ndim
    pad[2] = (0, k - a.shape[2])
    return np.pad(a, pad, constant_values=fill)
