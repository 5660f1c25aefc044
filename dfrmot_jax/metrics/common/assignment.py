"""The rectangular linear sum assignment, compiled, with scipy's answer on tied optima.

``scipy.optimize.linear_sum_assignment`` (what TrackEval calls every frame) is the shortest
augmenting path algorithm of Crouse (2016, "On implementing 2D rectangular assignment algorithms",
IEEE TAES 52(4), pp. 1679-1696, pages 1685-1686), as its documentation cites. Which optimum it
returns among tied ones is decided by the algorithm's order of work, so reproducing the choice means
reproducing that order, written here from the paper and scipy's documented behaviour:

* a matrix with more rows than columns is solved transposed (rows <= columns), and the pairs are
  returned sorted by row;
* ``maximize`` solves the negated costs;
* rows are added one at a time, ``0 .. n_rows - 1``; for each, Dijkstra over reduced costs
  ``min_val + c[i, j] - u[i] - v[j]`` grows a shortest path tree from the row until it reaches an
  unassigned column; the columns not yet in the tree are scanned in the order of a list that starts
  reversed (``n_cols - 1 .. 0``, so that a constant matrix gives the identity) and loses a column by
  moving its last entry into the column's place; among columns of equal lowest cost, the first
  scanned wins unless a later one is unassigned (a sink), which then wins;
* the duals are updated from the tree (``u[cur] += min_val``; ``u[i] += min_val - d[col4row[i]]``
  for the tree's other rows, ``v[j] -= min_val - d[j]`` for its columns) and the path is augmented.

Every operation is the same float64 operation in the same order as in that description, so the
choices are the same bit for bit; ``tests/metrics/common/test_assignment.py`` checks it against scipy on many random,
tie-heavy (small integers, repeated rows and columns, constant) and rectangular matrices.
:func:`solve_many` solves a whole list of blocks in one compiled call: no Python per block.

Compiled callers pass :func:`solve_block` and :func:`workspace` typed arguments, never literal
constants (``np.int64(0)``, ``np.bool_(True)``; a count that starts at a constant and grows in a loop
starts at ``np.int64(...)``): numba compiles a kernel anew for every literal value it is called
with (and for the literal type a loop's first typing pass sees), which tripled these kernels' share
of the first run's compilation (``tests/metrics/common/test_kernel_cache.py`` checks each compiles once).
``+inf`` entries are forbidden pairs, as in scipy; NaN or ``-inf`` or an infeasible block raise.
"""

from __future__ import annotations

import numpy as np

from dfrmot_jax.metrics.common.kernel_cache import cached_njit

__all__ = ["linear_sum_assignment", "solve_many", "solve_block", "match_block", "workspace", "workspace_for",
           "TIE_MARGIN"]

_INVALID, _INFEASIBLE = -1, -2


@cached_njit(nogil=True)
def _augmenting_path(nc, cost, u, v, path, row4col, short, i, SR, SC, remaining):
    """Grow the shortest path tree from row ``i`` to an unassigned column (the sink): returns
    (sink or -1 where no finite path exists, min_val). Work arrays are reused across calls."""
    min_val = 0.0
    num_remaining = nc
    for it in range(nc):
        remaining[it] = nc - it - 1
    SR[:] = False
    SC[:] = False
    short[:] = np.inf
    sink = -1
    while sink == -1:
        index = -1
        lowest = np.inf
        SR[i] = True
        base = i * nc
        for it in range(num_remaining):
            j = remaining[it]
            r = min_val + cost[base + j] - u[i] - v[j]
            if r < short[j]:
                path[j] = i
                short[j] = r
            if short[j] < lowest or (short[j] == lowest and row4col[j] == -1):
                lowest = short[j]
                index = it
        min_val = lowest
        if min_val == np.inf:
            return -1, min_val
        j = remaining[index]
        if row4col[j] == -1:
            sink = j
        else:
            i = row4col[j]
        SC[j] = True
        num_remaining -= 1
        remaining[index] = remaining[num_remaining]
    return sink, min_val


@cached_njit(nogil=True)
def _solve(nr, nc, cost, col4row, row4col, u, v, short, path, SR, SC, remaining):
    """Assign each of ``nr`` rows (nr <= nc) of the row-major ``cost`` [nr * nc] (no NaN, no -inf):
    fills col4row [nr]; returns 0, or _INFEASIBLE."""
    u[:nr] = 0.0
    v[:nc] = 0.0
    path[:nc] = -1
    col4row[:nr] = -1
    row4col[:nc] = -1
    for cur in range(nr):
        sink, min_val = _augmenting_path(nc, cost, u, v, path[:nc], row4col[:nc], short[:nc], cur, SR[:nr], SC[:nc],
                                         remaining[:nc])
        if sink < 0:
            return _INFEASIBLE
        u[cur] += min_val
        for i in range(nr):
            if SR[i] and i != cur:
                u[i] += min_val - short[col4row[i]]
        for j in range(nc):
            if SC[j]:
                v[j] -= min_val - short[j]
        j = sink
        while True:
            i = path[j]
            row4col[j] = i
            j_old = col4row[i]
            col4row[i] = j
            j = j_old
            if i == cur:
                break
    return 0


#: a certified optimum beats every other assignment by more than this x max(1, |entry|)
TIE_MARGIN = 1e-9


@cached_njit(nogil=True)
def _rows_certified(nr, nc, cost, col4row, taken):
    """A block of ``maximize`` (``cost`` = -S, S >= 0) whose optimum is each row's largest entry,
    proven unique: in every row with a positive entry the largest exceeds the row's others, and 0,
    by more than TIE_MARGIN x max(1, largest), and no two rows take one column. The row maxima (0
    for the columns) are then a feasible dual with the matching's value and every other matching
    loses more than the margin, so the optimum is unique and the algorithm, exact up to rounding
    far below the margin, returns it too whatever its tie-breaking. Then fills col4row [nr] with
    each row's column, -1 for a row with no positive entry (scipy's answer there pairs an S = 0,
    which a caller keeping the pairs with S > 0 drops), and returns True."""
    taken[:nc] = False
    for i in range(nr):
        best, second, arg, n_best = 0.0, 0.0, -1, 0
        for j in range(nc):
            x = -cost[i * nc + j]
            if x > best:
                second = best
                best, arg, n_best = x, j, 1
            elif x == best and x > 0:
                n_best += 1
            elif x > second:
                second = x
        if arg < 0:
            col4row[i] = -1
            continue
        if n_best != 1 or not (best - second > TIE_MARGIN * max(1.0, best)) or taken[arg]:
            return False
        taken[arg] = True
        col4row[i] = arg
    return True


@cached_njit(nogil=True)
def workspace(side, size):
    """Work arrays for :func:`solve_block` on blocks of at most ``side`` rows or columns and ``size``
    entries (one tuple, reused across blocks)."""
    side, size = max(side, 1), max(size, 1)
    return (np.empty(size), np.empty(side, np.int64), np.empty(side, np.int64), np.empty(side), np.empty(side),
            np.empty(side), np.empty(side, np.int64), np.empty(side, np.bool_), np.empty(side, np.bool_),
            np.empty(side, np.int64))


@cached_njit(nogil=True)
def workspace_for(n_rows, n_cols):
    """:func:`workspace` for every block of shapes ``n_rows`` x ``n_cols`` [G]."""
    size, side = np.int64(1), np.int64(1)        # (typed, not literal: module docstring)
    for b in range(len(n_rows)):
        size = max(size, n_rows[b] * n_cols[b])
        side = max(side, n_rows[b], n_cols[b])
    return workspace(side, size)


@cached_njit(nogil=True)
def solve_block(values, a, nr0, nc0, maximize, positive_only, out_rows, out_cols, o, ws):
    """One block, in compiled code: ``values[a:a + nr0 * nc0]`` row-major [nr0, nc0]; its min(nr0, nc0)
    pairs written at ``out_rows[o:]``, ``out_cols[o:]`` in scipy's order (sorted by row; with
    ``positive_only`` a pair may be -1, -1: see :func:`solve_many`). ws: :func:`workspace`. Returns 0,
    or _INVALID / _INFEASIBLE. For compiled callers that solve blocks one after the other."""
    cost, col4row, row4col, u, v, short, path, SR, SC, remaining = ws
    if nr0 == 0 or nc0 == 0:
        return 0
    transpose = nc0 < nr0
    nr, nc = (nc0, nr0) if transpose else (nr0, nc0)
    for i in range(nr):
        for j in range(nc):
            x = values[a + j * nc0 + i] if transpose else values[a + i * nc0 + j]
            cost[i * nc + j] = -x if maximize else x
    for k in range(nr * nc):         # scipy refuses these (before any certificate may answer)
        c = cost[k]
        if c != c or c == -np.inf:
            return _INVALID
    if positive_only and _rows_certified(nr, nc, cost, col4row, SC):
        status = 0
        if transpose:
            row4col[:nc] = -1
            for i in range(nr):
                if col4row[i] >= 0:
                    row4col[col4row[i]] = i
    else:
        status = _solve(nr, nc, cost, col4row, row4col, u, v, short, path, SR, SC, remaining)
    if status != 0:
        return status
    if transpose:        # pairs sorted by the original row (the transposed columns, in order)
        k = 0
        for r in range(nc):
            if row4col[r] >= 0:
                out_rows[o + k] = r
                out_cols[o + k] = row4col[r]
                k += 1
        for k in range(k, nr):       # (positive_only: rows left without a pair)
            out_rows[o + k] = -1
            out_cols[o + k] = -1
    else:
        for k in range(nr):
            c = col4row[k]
            out_rows[o + k] = k if c >= 0 else -1
            out_cols[o + k] = c
    return 0


@cached_njit(nogil=True)
def match_block(vals, nr, nc, above, rows, cols, ws):
    """The pairs of ``linear_sum_assignment(-S)`` with ``S > above`` (>= 0) of one block ``S = vals[:nr * nc]``
    (row-major, >= 0), for compiled callers (a frame's matching in the metrics): where no row or column
    holds two positive entries, those entries (every optimum holds them all: one missing could be added);
    else :func:`solve_block` (maximising, ``positive_only``). Writes (row, column) to ``rows``, ``cols``
    in row order; returns their number. ws: :func:`workspace`."""
    crowded = False
    for i in range(nr):
        n = 0
        for j in range(nc):
            n += vals[i * nc + j] > 0
        crowded = crowded or n > 1
    for j in range(nc):
        n = 0
        for i in range(nr):
            n += vals[i * nc + j] > 0
        crowded = crowded or n > 1
    n = 0
    if not crowded:
        for i in range(nr):
            for j in range(nc):
                if vals[i * nc + j] > above:
                    rows[n], cols[n] = i, j
                    n += 1
        return n
    solve_block(vals, np.int64(0), nr, nc, np.bool_(True), np.bool_(True), rows, cols, np.int64(0), ws)  # (typed)
    for k in range(min(nr, nc)):
        i, j = rows[k], cols[k]
        if i >= 0 and vals[i * nc + j] > above:
            rows[n], cols[n] = i, j
            n += 1
    return n


@cached_njit(nogil=True)
def _solve_blocks(values, starts, n_rows, n_cols, maximize, positive_only, out_rows, out_cols, out_start):
    """Every block b (:func:`solve_block`): ``values[starts[b]:...]`` row-major [n_rows[b], n_cols[b]],
    its pairs at ``out_start[b]``. Returns -1 or the first block that failed, its status in the second value."""
    ws = workspace_for(n_rows, n_cols)
    for b in range(len(n_rows)):
        status = solve_block(values, starts[b], n_rows[b], n_cols[b], maximize, positive_only, out_rows, out_cols,
                             out_start[b], ws)
        if status != 0:
            return b, status
    return -1, 0


def _starts(counts: np.ndarray) -> np.ndarray:
    """[n] counts -> [n + 1] exclusive prefix sums (int64)."""
    out = np.zeros(len(counts) + 1, dtype=np.int64)
    np.cumsum(counts, out=out[1:])
    return out


def solve_many(values: np.ndarray, n_rows: np.ndarray, n_cols: np.ndarray, maximize: bool = False,
               starts: np.ndarray | None = None, positive_only: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``linear_sum_assignment`` of every block, in one compiled call.

    values: [sum(n_rows * n_cols)] float64, the blocks row-major one after the other (or at
    ``starts`` [G]); n_rows, n_cols: [G] int. Returns ``(rows, cols, pair_start)``: rows, cols [P] int64
    of each block's min(nr, nc) pairs in scipy's order (sorted by row), pair_start [G + 1].
    positive_only (with ``maximize`` and values >= 0): only the pairs with a value > 0 are wanted;
    a block whose optimum an optimality certificate proves unique (:func:`_rows_certified`) is then
    answered without the solver, its pairs of no positive entry given as -1, -1."""
    if positive_only and not maximize:
        raise ValueError("positive_only needs maximize=True (values >= 0)")
    n_rows = np.ascontiguousarray(n_rows, dtype=np.int64)
    n_cols = np.ascontiguousarray(n_cols, dtype=np.int64)
    values = np.ascontiguousarray(values, dtype=np.float64)
    if starts is None:
        starts = _starts(n_rows * n_cols)[:-1]
    starts = np.ascontiguousarray(starts, dtype=np.int64)
    if not (len(starts) == len(n_rows) == len(n_cols)):
        raise ValueError(f"{len(n_rows)} block shapes, {len(n_cols)} column counts, {len(starts)} starts")
    if len(n_rows) and ((n_rows < 0).any() or (n_cols < 0).any() or (starts < 0).any()
                        or (starts + n_rows * n_cols > len(values)).any()):
        raise ValueError(f"blocks reach beyond the {len(values)} values (compiled code checks no index)")
    pair_start = _starts(np.minimum(n_rows, n_cols))
    rows = np.empty(int(pair_start[-1]), np.int64)
    cols = np.empty(int(pair_start[-1]), np.int64)
    if len(n_rows):
        bad, status = _solve_blocks(values, starts, n_rows, n_cols, bool(maximize), bool(positive_only), rows, cols,
                                   pair_start[:-1])
        if bad >= 0:
            what = "contains invalid numeric entries" if status == _INVALID else "is infeasible"
            raise ValueError(f"block {bad}: cost matrix {what}")
    return rows, cols, pair_start


def linear_sum_assignment(cost, maximize: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """One matrix [nr, nc]: ``(rows, cols)`` as ``scipy.optimize.linear_sum_assignment`` returns them."""
    cost = np.asarray(cost, dtype=np.float64)
    if cost.ndim != 2:
        raise ValueError(f"expected a matrix (2-D array), got a {cost.ndim}-D array")
    rows, cols, _ = solve_many(cost.reshape(-1), np.array([cost.shape[0]]), np.array([cost.shape[1]]), maximize)
    return rows, cols
