"""ByteTrack's ``matching.linear_assignment``: ``lap.lapjv(cost, extend_cost=True, cost_limit=thresh)``
(lap 0.5.13, ``_lapjv_cpp/lapjv.cpp``) decided exactly as lap decides it, ties included, inside a
``lax.scan`` step.

lap extends the ``n x m`` matrix to ``(n + m)`` square (``cost_limit / 2`` on the dummy entries, 0 on
the dummy-dummy block) and runs the dense Jonker-Volgenant solver: column reduction, reduction
transfer, augmenting row reduction (twice), then an augmenting path from every row still free (a
Dijkstra-like search whose SCAN / TODO lists live in one permuted column array). Its decisions
depend on the order of rows and columns and on exact float64 comparisons (``<`` against ``<=``,
the first or the last of equal values), so :func:`lapjv_square` follows the C code unit of work by
unit of work: one ``lax.while_loop`` whose program counter names the part of the C code a step
runs (one free row of the row reduction, one column of a search's find or scan, one step back along
the augmenting path); the vector parts (column minima, a row's two smallest reduced costs, the
final ``v`` update of a search) are vector operations.

The shortcut (:func:`fast_path`): when every real row and column has at most one entry below the
limit and no entry lies within ``1e-9`` of it, the extended problem's optimum is unique (each such
pair saves ``limit - cost > 0`` against leaving both to dummies, any entry above the limit costs
more than the two dummies) and lapjv, an exact solver whose float64 sums here are of a few terms
bounded by 2 (rounding errors far below 1e-9), returns it. :func:`unique_small` widens it: the
optimum is the union of the best matchings of the connected components of the entries below the
limit; where each component is small (at most ``C`` of them with more than one entry, each within
``A`` rows and ``A`` columns) every partial matching of each is enumerated in closed form, and
where each component's best is the only one within ``1e-9`` that union is lapjv's answer. Every
other case (ties, large components: a few per cent of the KITTI associations) runs the emulation
(:func:`solve`), one lane at a time.

Where lapjv's choices differ from ``scipy.optimize.linear_sum_assignment`` (checked with lap
0.5.13 and scipy 1.10.1; tests: ``test_bytetrack_lapjv.py``): tied totals. ``[[0.3, 0.3], [0.3,
0.3]]`` at limit 0.8: lap gives row 0 column 1 and row 1 column 0, scipy row 0 column 0. Both keep
``[[0.5, 0.5]]`` at 0.75 on column 0 and ``[[0.5], [0.5]]`` on row 0. A cost exactly at the limit
(``[[0.8]]`` at 0.8: matching it or leaving both to dummies totals 0.8 either way) is matched by
lap, so "matched iff cost < thresh" is not lap's rule; the shortcut leaves such cases to the
emulation.
"""

from __future__ import annotations

import itertools

import numpy as np
import jax.numpy as jnp
from jax import lax

__all__ = ["LARGE", "lapjv_square", "extended", "assign", "fast_path", "shortcut", "unique_small", "solve"]

LARGE = 1000000.0          # lap's LARGE (lapjv.h)
_BIG = 1 << 30
_EPS = 1e-9

# program counter of the solver's loop
ARR, AUG_START, FIND_K, SCAN_HEAD, SCAN_K, AUG_STEP, DONE = range(7)


def _first_argmin(r):
    return jnp.argmin(r).astype(jnp.int32)


# Whole on purpose (over 80 lines): lap's lapjv_internal, one branch per unit of work of the C code.
def lapjv_square(c, n):
    """``lapjv_internal`` on the top-left ``n x n`` block of ``c`` [S, S] (float64; entries outside
    are never read). Returns ``x`` [S] int32: row -> column (rows >= n: -1)."""
    s = c.shape[0]
    idx = jnp.arange(s, dtype=jnp.int32)
    valid = idx < n
    inf = jnp.inf
    # --- column reduction: each column's minimum and the first row reaching it
    cm = jnp.where(valid[:, None] & valid[None, :], c, inf)
    colmin = jnp.min(cm, axis=0)
    below = valid & (colmin < LARGE)
    v = jnp.where(below, colmin, jnp.where(valid, LARGE, 0.0))
    y0 = jnp.where(below, jnp.argmin(cm, axis=0).astype(jnp.int32), jnp.where(valid, 0, s))
    owns = (y0[None, :] == idx[:, None]) & valid[None, :]            # [row, col]
    x = jnp.max(jnp.where(owns, idx[None, :], -1), axis=1).astype(jnp.int32)  # the last column
    unique = jnp.sum(owns, axis=1) == 1
    keep = jnp.any(owns & (x[:, None] == idx[None, :]), axis=0)
    y = jnp.where(keep, y0, -1).astype(jnp.int32)
    x = jnp.where(valid, x, -1)
    is_free = valid & (x < 0)
    free = jnp.argsort(jnp.where(is_free, idx, _BIG), stable=True).astype(jnp.int32)
    nfree = jnp.sum(is_free).astype(jnp.int32)
    # --- reduction transfer, row by row (each row's minimum sees the columns lowered before it)
    is_tr = valid & (x >= 0) & unique
    trows = jnp.argsort(jnp.where(is_tr, idx, _BIG), stable=True).astype(jnp.int32)
    ntr = jnp.sum(is_tr).astype(jnp.int32)

    def transfer(carry):
        t, v = carry
        i = trows[t]
        j = x[i]
        r = jnp.where(valid & (idx != j), c[i] - v, inf)
        best = jnp.minimum(jnp.min(r), LARGE)
        return t + 1, v.at[j].add(-best)

    _, v = lax.while_loop(lambda cr: cr[0] < ntr, transfer, (jnp.int32(0), v))

    i32 = jnp.int32
    z = i32(0)
    state = dict(
        x=x, y=y, v=v, free=free, cur=z, nfree=nfree, newfree=z, rr=z, npass=z,
        fi=z, f=z, d=jnp.zeros(s), pred=jnp.zeros(s, i32), cols=idx, lo=z, hi=z, nready=z,
        k=z, mind=jnp.float64(0.0), i_s=z, h_s=jnp.float64(0.0), lo0=z, hi0=z, ja=z,
        pc=jnp.where(nfree > 0, i32(ARR), i32(DONE)))

    def start_find(st):
        # _find_dense begins: the ready columns are cols[:lo]
        lo = st["lo"]
        return {**st, "nready": lo, "hi": lo + 1, "mind": st["d"][st["cols"][lo]], "k": lo + 1,
                "pc": i32(FIND_K)}

    def arr(st):
        x, y, v, free = st["x"], st["y"], st["v"], st["free"]
        rr = st["rr"] + 1
        i = free[st["cur"]]
        cur = st["cur"] + 1
        r = jnp.where(valid, c[i] - v, inf)
        j1 = _first_argmin(r)
        u1 = r[j1]
        r2 = jnp.where(idx == j1, inf, r)
        m2 = jnp.min(r2)
        has2 = m2 < LARGE
        j2 = jnp.where(has2, _first_argmin(r2), -1)
        u2 = jnp.where(has2, m2, LARGE)
        i0 = y[j1]
        v1_new = v[j1] - (u2 - u1)
        lowers = v1_new < v[j1]
        regular = rr < cur * n
        v = jnp.where(regular & lowers, v.at[j1].set(v1_new), v)
        switch = regular & ~lowers & (i0 >= 0) & (j2 >= 0)
        j1 = jnp.where(switch, j2, j1)
        i0 = jnp.where(switch, y[jnp.maximum(j2, 0)], i0)
        back = regular & lowers & (i0 >= 0)             # the displaced row is looked at next
        push = (i0 >= 0) & ~back                        # ... or kept for the next pass
        cur = jnp.where(back, cur - 1, cur)
        pos = jnp.where(back, cur, st["newfree"])
        free = jnp.where(back | push, free.at[pos].set(i0), free)
        newfree = st["newfree"] + push.astype(i32)
        x = x.at[i].set(j1)
        y = y.at[j1].set(i)
        st = {**st, "x": x, "y": y, "v": v, "free": free, "cur": cur, "newfree": newfree, "rr": rr}
        end = cur >= st["nfree"]
        npass = st["npass"] + end.astype(i32)
        again = end & (newfree > 0) & (npass < 2)
        to_aug = end & (newfree > 0) & ~again
        pc = jnp.where(end, jnp.where(again, i32(ARR), jnp.where(to_aug, i32(AUG_START), i32(DONE))),
                       i32(ARR))
        nfree = jnp.where(end, newfree, st["nfree"])
        return {**st, "npass": npass, "pc": pc, "nfree": nfree,
                "cur": jnp.where(end, 0, cur), "newfree": jnp.where(end, 0, newfree),
                "rr": jnp.where(end, 0, rr), "fi": z}

    def aug_start(st):
        fi = st["fi"]
        fin = fi >= st["nfree"]
        f = st["free"][jnp.minimum(fi, s - 1)]
        d = jnp.where(valid, c[f] - st["v"], inf)
        new = {**st, "f": f, "d": d, "pred": jnp.full(s, f, i32), "cols": idx, "lo": z, "hi": z}
        new = start_find(new)
        return jax_select(fin, {**st, "pc": i32(DONE)}, new)

    def path_done(st, final):
        # v of the ready columns; then the augmenting path from `final` back to the free row
        cols, d = st["cols"], st["d"]
        mind = d[cols[st["lo"]]]
        ready = jnp.any((cols[:, None] == idx[None, :]) & (idx[:, None] < st["nready"]), axis=0)
        v = jnp.where(ready, st["v"] + (d - mind), st["v"])
        return {**st, "v": v, "ja": final, "pc": i32(AUG_STEP)}

    def find_k(st):
        k = st["k"]
        over = k >= n
        # one column of _find_dense
        cols, d, lo, hi, mind = st["cols"], st["d"], st["lo"], st["hi"], st["mind"]
        kk = jnp.minimum(k, s - 1)
        j = cols[kk]
        dj = d[j]
        take = ~over & (dj <= mind)
        lower = take & (dj < mind)
        hi1 = jnp.where(lower, lo, hi)
        mind1 = jnp.where(lower, dj, mind)
        hh = jnp.minimum(hi1, s - 1)
        swapped = cols.at[kk].set(cols[hh]).at[hh].set(j)
        cols1 = jnp.where(take, swapped, cols)
        hi2 = jnp.where(take, hi1 + 1, hi1)
        stepped = {**st, "cols": cols1, "hi": hi2, "mind": mind1, "k": k + 1}
        # the list is complete: a free column among the minima (the last of them) ends the search
        pos = jnp.arange(s, dtype=i32)
        in_list = (pos >= lo) & (pos < hi)
        ycols = y_of(st["y"], cols)
        cand = jnp.max(jnp.where(in_list & (ycols < 0), pos, -1))
        final = jnp.where(cand >= 0, cols[jnp.maximum(cand, 0)], -1)
        checked = jax_select(final >= 0, path_done(st, final),
                             {**st, "lo0": lo, "hi0": hi, "pc": i32(SCAN_HEAD)})
        return jax_select(over, checked, stepped)

    def scan_head(st):
        lo, hi = st["lo"], st["hi"]
        empty = lo == hi
        j = st["cols"][jnp.minimum(lo, s - 1)]
        i = st["y"][j]
        mind = st["d"][j]
        h = (c[jnp.maximum(i, 0), j] - st["v"][j]) - mind
        head = {**st, "lo": lo + 1, "i_s": i, "mind": mind, "h_s": h, "k": hi, "pc": i32(SCAN_K)}
        return jax_select(empty, start_find(st), head)

    def scan_k(st):
        k = st["k"]
        over = k >= n
        kk = jnp.minimum(k, s - 1)
        cols, d = st["cols"], st["d"]
        j = cols[kk]
        i = st["i_s"]
        r = (c[i, j] - st["v"][j]) - st["h_s"]
        better = ~over & (r < d[j])
        d1 = jnp.where(better, d.at[j].set(r), d)
        pred1 = jnp.where(better, st["pred"].at[j].set(i), st["pred"])
        hit = better & (r == st["mind"])
        found = hit & (st["y"][j] < 0)
        move = hit & ~found
        hi = st["hi"]
        hh = jnp.minimum(hi, s - 1)
        cols1 = jnp.where(move, cols.at[kk].set(cols[hh]).at[hh].set(j), cols)
        hi1 = jnp.where(move, hi + 1, hi)
        nxt = {**st, "d": d1, "pred": pred1, "cols": cols1, "hi": hi1, "k": k + 1}
        # found: lap returns without storing lo, hi (the scan call's own values stay)
        fin = path_done({**nxt, "lo": st["lo0"], "hi": st["hi0"]}, j)
        nxt = {**nxt, "pc": jnp.where(k + 1 >= n, i32(SCAN_HEAD), i32(SCAN_K))}
        return jax_select(found, fin, jax_select(over, {**st, "pc": i32(SCAN_HEAD)}, nxt))

    def aug_step(st):
        j = st["ja"]
        i = st["pred"][j]
        x, y = st["x"], st["y"]
        old = x[i]
        y = y.at[j].set(i)
        x = x.at[i].set(j)
        back = i == st["f"]
        return {**st, "x": x, "y": y, "ja": old, "fi": st["fi"] + back.astype(i32),
                "pc": jnp.where(back, i32(AUG_START), i32(AUG_STEP))}

    def done(st):
        return st

    branches = [arr, aug_start, find_k, scan_head, scan_k, aug_step, done]
    keys = list(state)

    def body(tup):
        st = dict(zip(keys, tup))
        out = lax.switch(st["pc"], [lambda t, b=b: _tup(b(dict(zip(keys, t))), keys) for b in branches],
                         tup)
        return out

    res = lax.while_loop(lambda t: t[keys.index("pc")] != DONE, body, _tup(state, keys))
    x = dict(zip(keys, res))["x"]
    return jnp.where(valid, x, -1)


def _tup(st, keys):
    return tuple(jnp.asarray(st[k]) for k in keys)


def y_of(y, cols):
    return y[cols]


def jax_select(pred, a: dict, b: dict) -> dict:
    """Elementwise ``a if pred else b`` of two states with the same keys."""
    return {k: jnp.where(pred, a[k], b[k]) for k in a}


def extended(cost, rmask, rkey, cmask, limit):
    """lap's extended matrix [S, S] (S = K + D) of the rows ``rmask`` in the order of ``rkey`` and
    the columns ``cmask`` in index order; returns (ext, n + m, row slot of each position, column
    index of each position, n, m)."""
    k, dd = cost.shape
    s = k + dd
    n = jnp.sum(rmask).astype(jnp.int32)
    m = jnp.sum(cmask).astype(jnp.int32)
    rperm = jnp.argsort(jnp.where(rmask, rkey, _BIG), stable=True).astype(jnp.int32)
    cperm = jnp.argsort(jnp.where(cmask, jnp.arange(dd), _BIG), stable=True).astype(jnp.int32)
    real = cost[rperm][:, cperm]
    real = jnp.pad(real, ((0, s - k), (0, s - dd)))
    p = jnp.arange(s)[:, None]
    q = jnp.arange(s)[None, :]
    half = limit / 2.0
    dim = n + m
    ext = jnp.where((p < n) & (q < m), real,
                    jnp.where((p < dim) & (q < dim), jnp.where((p < n) | (q < m), half, 0.0), jnp.inf))
    return ext, dim, rperm, cperm, n, m


def fast_path(cost, rmask, cmask, limit):
    """(ok, pairs [K, D]): ``ok`` where the shortcut's conditions hold (module docstring)."""
    both = rmask[:, None] & cmask[None, :]
    cand = both & (cost < limit)
    amb = both & (jnp.abs(cost - limit) <= _EPS)
    ok = ~jnp.any(amb) & jnp.all(jnp.sum(cand, axis=1) <= 1) & jnp.all(jnp.sum(cand, axis=0) <= 1)
    return ok, cand


def shortcut(cost, rmask, cmask, limit):
    """(ok, the column of every row slot [K] int32) where the shortcut's conditions hold."""
    ok, cand = fast_path(cost, rmask, cmask, limit)
    return ok, jnp.max(jnp.where(cand, jnp.arange(cost.shape[1])[None, :], -1), axis=1).astype(jnp.int32)


#: a block's side (every partial matching of an ``A x A`` block is enumerated) and the most blocks
A = 4
C = 4
_HOPS = 3        # label propagation rounds: a component of A rows and A columns is settled in A - 1


def _matchings(a: int) -> np.ndarray:
    """[P, A, A] bool: every partial matching of an ``a x a`` block (the empty one first)."""
    out = [np.zeros((a, a), bool)]
    for k in range(1, a + 1):
        for rows in itertools.combinations(range(a), k):
            for cols in itertools.permutations(range(a), k):
                m = np.zeros((a, a), bool)
                m[list(rows), list(cols)] = True
                out.append(m)
    return np.array(out)


_MATCH = _matchings(A)
_MATCH_F = _MATCH.reshape(len(_MATCH), A * A).astype(np.float64)
_OUT = -1e6     # the weight of a block entry not below the limit


def unique_small(cost, rmask, cmask, limit):
    """The optimum where it is unique and its parts small: (ok, column of every row slot [K] int32).

    The extended problem's total is a constant minus the sum of ``limit - cost`` over the matched
    real pairs, so lapjv (exact, its float64 sums of a few terms bounded by 2) returns the matching
    of the real entries below the limit of the largest such sum whenever it is the only one within
    ``1e-9`` (and no entry lies within ``1e-9`` of the limit). That matching is the union of the
    best matchings of the connected components of the graph of the entries below the limit, and it
    is the only one within ``1e-9`` iff each component's is: components of one edge are matched as
    they are; the others (at most ``C``, each of at most ``A`` rows and ``A`` columns) are blocks
    whose partial matchings are all enumerated. Any other case: ``ok`` False."""
    k, dd = cost.shape
    f = cost.dtype
    both = rmask[:, None] & cmask[None, :]
    cand = both & (cost < limit)
    amb = jnp.any(both & (jnp.abs(cost - limit) <= _EPS))
    dr = jnp.sum(cand, axis=1)
    dc = jnp.sum(cand, axis=0)
    single = cand & (dr == 1)[:, None] & (dc == 1)[None, :]
    ra = (dr >= 2) | jnp.any(cand & (dc >= 2)[None, :], axis=1)              # rows of components > 1 edge
    ca = (dc >= 2) | jnp.any(cand & (dr >= 2)[:, None], axis=0)
    # components: the smallest row index of each, propagated along the entries below the limit
    ki = jnp.arange(k)
    big = jnp.int32(_BIG)
    rl = jnp.where(ra, ki, big)
    for _ in range(_HOPS):
        cl = jnp.min(jnp.where(cand, rl[:, None], big), axis=0)
        rl = jnp.minimum(rl, jnp.min(jnp.where(cand, cl[None, :], big), axis=1))
    cl = jnp.min(jnp.where(cand, rl[:, None], big), axis=0)
    settled = jnp.all(rl == jnp.minimum(rl, jnp.min(jnp.where(cand, cl[None, :], big), axis=1)))
    lead = ra & (rl == ki)                                                     # a component's first row
    lrank = jnp.cumsum(lead) - 1
    rslot = jnp.sum(jnp.where((rl[:, None] == ki[None, :]) & lead[None, :], lrank[None, :], 0), axis=1)
    cslot = jnp.sum(jnp.where((cl[:, None] == ki[None, :]) & lead[None, :], lrank[None, :], 0), axis=1)
    same_r = ra[:, None] & ra[None, :] & (rl[:, None] == rl[None, :])
    rpos = jnp.sum(same_r & (ki[None, :] < ki[:, None]), axis=1)               # place inside its component
    di = jnp.arange(dd)
    same_c = ca[:, None] & ca[None, :] & (cl[:, None] == cl[None, :])
    cpos = jnp.sum(same_c & (di[None, :] < di[:, None]), axis=1)
    fits = (settled & (jnp.sum(lead) <= C) & jnp.all(~ra | (rpos < A)) & jnp.all(~ca | (cpos < A)))
    ci = jnp.arange(C)[:, None, None]
    ai = jnp.arange(A)[None, :, None]
    rsel = (ra[None, None, :] & (rslot[None, None, :] == ci) & (rpos[None, None, :] == ai)).astype(f)  # [C, A, K]
    csel = (ca[None, None, :] & (cslot[None, None, :] == ci) & (cpos[None, None, :] == ai)).astype(f)  # [C, A, D]
    # the blocks' weights and entries below the limit (one-hot products: exact)
    both_w = jnp.stack([jnp.where(cand, limit - cost, 0.0), cand.astype(f)])                 # [2, K, D]
    blk = jnp.einsum("cak,skd,cbd->scab", rsel, both_w, csel, precision="highest")         # [2, C, A, A]
    wa = jnp.where(blk[1] > 0.5, blk[0], _OUT).reshape(C, A * A)
    # every partial matching's total; one with an entry not below the limit totals < -1e5
    tot = jnp.dot(wa, jnp.asarray(_MATCH_F.T), precision="highest")                        # [C, P]
    top = jnp.max(tot, axis=1, keepdims=True)
    near = tot >= top - _EPS
    ok = ~amb & fits & jnp.all(jnp.sum(near, axis=1) == 1)
    mb = jnp.dot(near.astype(f), jnp.asarray(_MATCH_F)).reshape(C, A, A) > 0.5
    cidx = jnp.sum(csel * di.astype(f), axis=2)                                               # [C, A]
    bcol = jnp.max(jnp.where(mb, cidx[:, None, :], -1.0), axis=2)                             # [C, A]
    amatch = jnp.max(jnp.where(rsel > 0.5, bcol[:, :, None], -1.0), axis=(0, 1))              # [K]
    smatch = jnp.max(jnp.where(single, di[None, :], -1), axis=1)
    return ok, jnp.where(ra, amatch.astype(jnp.int32), smatch).astype(jnp.int32)


def solve(cost, rmask, rkey, cmask, limit):
    """The full emulation's answer: the matched column of every row slot [K] int32 (-1: none)."""
    k, dd = cost.shape
    ext, dim, rperm, cperm, n, m = extended(cost, rmask, rkey, cmask, limit)
    x = lapjv_square(ext, dim)
    s = ext.shape[0]
    pos = jnp.arange(s)
    xr = x[:k]
    real_col = (pos[:k] < n) & (xr >= 0) & (xr < m)
    col_of_pos = jnp.where(real_col, cperm[jnp.clip(xr, 0, dd - 1)], -1)       # by row position
    slot_hit = (rperm[:, None] == jnp.arange(k)[None, :]) & (pos[:k, None] < n)  # [position, slot]
    return jnp.max(jnp.where(slot_hit, col_of_pos[:, None], -1), axis=0).astype(jnp.int32)


def assign(cost, rmask, rkey, cmask, limit):
    """``linear_assignment(cost[rows][:, cols], limit)`` for the rows ``rmask`` (in ``rkey`` order) and
    the columns ``cmask`` (in index order) of ``cost`` [K, D]. Returns the matched column of every
    row slot [K] int32 (-1: none) and whether the full solver ran."""
    ok, quick = unique_small(cost, rmask, cmask, limit)
    # a real branch where the predicate is one lane's (B = 1); under vmap both run, selected
    return lax.cond(ok, lambda: quick, lambda: solve(cost, rmask, rkey, cmask, limit)), ~ok
