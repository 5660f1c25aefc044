"""``scipy.optimize.linear_sum_assignment`` in JAX: the same pairs, tie choices included, on padded
matrices, as a fixed-size loop that runs inside ``lax.scan`` and ``vmap``.

scipy implements Crouse's shortest augmenting path algorithm (2016, IEEE TAES 52(4), pp. 1685-1686);
which optimum it returns among tied ones follows from its order of work, reproduced here step for
step (as ``metrics.common.assignment`` does in numba, one row at a time):

* a matrix with more rows than columns is solved transposed; pairs come back sorted by row;
* rows ``0 .. nr - 1`` are added one at a time; for each, Dijkstra over the reduced costs
  ``((min_val + c[i, j]) - u[i]) - v[j]`` grows a shortest path tree until it reaches an
  unassigned column; the columns not in the tree are scanned in the order of a list that starts
  reversed (``nc - 1 .. 0``) and loses a column by moving its last entry into the column's place;
  among the columns of lowest cost the first scanned wins, unless one of them is unassigned: then
  the last unassigned one scanned wins;
* the duals are updated (``u[cur] += min_val``; ``u[i] += min_val - short[col4row[i]]`` for the
  tree's other rows; ``v[j] -= min_val - short[j]`` for its columns) and the path is augmented.

The scan of one Dijkstra step is vectorised over the columns: the list order is kept as each
column's position in it. All arithmetic is float64 sums, as scipy's.
"""

from __future__ import annotations

import jax.numpy as jnp
from jax import lax

__all__ = ["solve", "assign"]


def _dijkstra(cost, u, v, row4col, path, cur, nc):
    """Grow the tree from row ``cur``: (sink, min_val, short [L], path [L], SR [L], SC [L])."""
    size = cost.shape[0]
    col = jnp.arange(size)
    in_cols = col < nc
    pos = jnp.where(in_cols, nc - 1 - col, size)                 # each column's place in the list
    init = (cur, jnp.zeros((), jnp.float64), -1, nc, pos, jnp.full(size, jnp.inf), path,
            jnp.zeros(size, bool), jnp.zeros(size, bool))

    def step(s):
        i, min_val, _, num, pos, short, path, sr, sc = s
        sr = sr.at[i].set(True)
        rem = in_cols & ~sc
        r = ((min_val + cost[i]) - u[i]) - v
        better = rem & (r < short)
        path = jnp.where(better, i, path)
        short = jnp.where(better, r, short)
        lowest = jnp.min(jnp.where(rem, short, jnp.inf))
        tied = rem & (short == lowest)
        free = tied & (row4col == -1)
        j = jnp.where(jnp.any(free), jnp.argmax(jnp.where(free, pos, -1)), jnp.argmin(jnp.where(tied, pos, size + 1)))
        sink = jnp.where(row4col[j] == -1, j, -1)
        i = jnp.where(sink < 0, row4col[j], i)
        last = jnp.argmax(rem & (pos == num - 1))
        pos = pos.at[last].set(pos[j])
        return i, lowest, sink, num - 1, pos, short, path, sr, sc.at[j].set(True)

    out = lax.while_loop(lambda s: (s[2] < 0) & (s[3] > 0), step, init)
    _, min_val, sink, _, _, short, path, sr, sc = out
    return sink, min_val, short, path, sr, sc


def solve(cost, nr, nc):
    """Assign rows ``0 .. nr - 1`` of ``cost`` [L, L] (float64; only ``[:nr, :nc]`` read as the
    matrix, ``nr <= nc``): (col4row [L], row4col [L]), -1 where unassigned."""
    size = cost.shape[0]
    idx = jnp.arange(size)

    def row(s):
        cur, u, v, col4row, row4col, path = s
        sink, min_val, short, path, sr, sc = _dijkstra(cost, u, v, row4col, path, cur, nc)
        others = sr & (idx != cur)
        u = jnp.where(others, u + (min_val - short[jnp.clip(col4row, 0, size - 1)]), u)
        u = u.at[cur].add(min_val)
        v = jnp.where(sc, v - (min_val - short), v)

        def augment(a):
            j, _, col4row, row4col = a
            i = path[j]
            row4col = row4col.at[j].set(i)
            nxt = col4row[i]
            return nxt, i == cur, col4row.at[i].set(j), row4col

        _, _, col4row, row4col = lax.while_loop(lambda a: ~a[1], augment, (sink, sink < 0, col4row, row4col))
        return cur + 1, u, v, col4row, row4col, path

    zero = jnp.zeros(size, jnp.float64)
    none = jnp.full(size, -1)
    out = lax.while_loop(lambda s: s[0] < nr, row, (jnp.zeros((), nr.dtype), zero, zero, none, none, none))
    return out[3], out[4]


def assign(affinity, n, m):
    """The track of each detection [N] (-1: none) in ``linear_sum_assignment(-affinity)`` of the
    valid block ``affinity[:n, :m]`` (float32 [N, K]); ``n`` detections, ``m`` tracks. Pairs in
    scipy's order are by ascending detection."""
    n_det, n_trk = affinity.shape
    size = max(n_det, n_trk)
    c = jnp.zeros((size, size), jnp.float64).at[:n_det, :n_trk].set(-affinity.astype(jnp.float64))
    flip = n > m
    col4row, row4col = solve(jnp.where(flip, c.T, c), jnp.minimum(n, m), jnp.maximum(n, m))
    det_track = jnp.where(flip, row4col, col4row)[:n_det]
    return jnp.where(jnp.arange(n_det) < n, det_track, -1)
