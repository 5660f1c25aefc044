"""AB3DMOT's greedy matching (61f3bd7 ``matching.greedy_matching``) in JAX: every pair of the cost
matrix ``-A`` [n, m] visited by ``np.argsort`` of its row-major flattening, a pair taken when both
its detection and its track are still free.

The visiting order of equal costs (the many zero IoUs) is NumPy 1.23's: its default ``quicksort``
for floats is an introsort on an index array (median of three moved to ``pr - 1``, both scans
stopping at keys equal to the pivot, the larger part pushed, parts of at most 16 items insertion
sorted, heapsort past a depth of ``2 floor(log2 n)``, checked for popped parts only). When no two
valid costs are equal every sort gives that order, and a plain sort is used; otherwise the
introsort is run, one partition per loop step, each partition vectorised (a Hoare partition swaps
the k-th key not below the pivot from the left with the k-th key not above it from the right, for
as long as the two have not crossed). Insertion sorts of parts are stable sorts of the part,
done together at the end. The heapsort fallback (adversarial inputs only) is not reproduced: a
sort that reaches it is counted (``fallback``).

The pairs taken by sequential greedy are found in rounds: a pair that comes first among the
remaining pairs of both its row and its column is taken by the sequential loop too.
"""

from __future__ import annotations

import jax.numpy as jnp
from jax import lax

__all__ = ["introsort_order", "greedy"]

_SMALL = 16            # parts of at most this many items are insertion sorted
_STACK = 64


def _partition(v, idx, pl, pr):
    """One NumPy partition of idx[pl..pr] (more than 16 items) by ``v[idx]``: (idx, pivot place)."""
    size = idx.shape[0]
    q = jnp.arange(size)

    def swap_if(idx, a, b, cond):
        ia, ib = idx[a], idx[b]
        return idx.at[a].set(jnp.where(cond, ib, ia)).at[b].set(jnp.where(cond, ia, ib))

    pm = pl + ((pr - pl) >> 1)
    idx = swap_if(idx, pm, pl, v[idx[pm]] < v[idx[pl]])
    idx = swap_if(idx, pr, pm, v[idx[pr]] < v[idx[pm]])
    idx = swap_if(idx, pm, pl, v[idx[pm]] < v[idx[pl]])
    vp = v[idx[pm]]
    idx = swap_if(idx, pm, pr - 1, True)
    vals = v[idx]
    is_l = (q >= pl + 1) & (q <= pr - 1) & ~(vals < vp)          # left scan stops here
    is_r = (q >= pl) & (q <= pr - 2) & ~(vp < vals)              # right scan stops here
    rank_l = jnp.cumsum(is_l)
    r_after = jnp.sum(is_r) - jnp.cumsum(is_r)                   # right stops beyond q
    rank_r = r_after + is_r
    swaps = jnp.sum(is_l & (r_after >= rank_l))
    dump = size + 1
    pos_l = jnp.full(size + 2, size).at[jnp.where(is_l, rank_l, dump)].set(q)
    pos_r = jnp.full(size + 2, -1).at[jnp.where(is_r, rank_r, dump)].set(q)
    swap_l, swap_r = is_l & (rank_l <= swaps), is_r & (rank_r <= swaps)
    partner = jnp.where(swap_l, pos_r[jnp.minimum(rank_l, size + 1)],
                        jnp.where(swap_r, pos_l[jnp.minimum(rank_r, size + 1)], q))
    idx = idx[partner]
    pi = jnp.where(swaps >= 1, jnp.minimum(pos_l[swaps + 1], pos_r[swaps]), pos_l[1])
    return swap_if(idx, pi, pr - 1, True), pi


def introsort_order(v, count, run):
    """The order ``np.argsort(v[:count], kind='quicksort')`` of NumPy 1.23 gives (v [P] float32
    without NaN; the rest of the [P] result is the positions beyond ``count``), run only where
    ``run``: (order [P] int32, heapsort reached)."""
    size = v.shape[0]
    q = jnp.arange(size)
    key = jnp.where(v == 0, 0.0, v)                                  # -0.0 and 0.0 are equal keys
    depth0 = 2 * (31 - lax.clz(jnp.maximum(count, 1).astype(jnp.int32)))
    init = (q, q, jnp.zeros((_STACK, 3), jnp.int32), 0, 0, count - 1, depth0, True, ~run | (count <= _SMALL), False)

    def body(s):
        idx, seg, stack, sp, pl, pr, depth, fresh, _, heap = s
        heap_now = fresh & (depth < 0)
        split = (pr - pl > _SMALL - 1) & ~heap_now
        idx_p, pi = _partition(key, idx, jnp.maximum(pl, 0), pr)
        left_small = pi - pl < pr - pi
        push = jnp.where(left_small, jnp.stack([pi + 1, pr, depth - 1]), jnp.stack([pl, pi - 1, depth - 1]))
        # a part done (insertion sorted at the end): label its items; then pop the next part
        seg_l = jnp.where((q >= pl) & (q <= pr), pl, seg)
        top = stack[jnp.maximum(sp - 1, 0)]
        idx = jnp.where(split, idx_p, idx)
        seg = jnp.where(split, seg, seg_l)
        stack = jnp.where(split, stack.at[sp].set(push), stack)
        pl_n = jnp.where(split, jnp.where(left_small, pl, pi + 1), top[0])
        pr_n = jnp.where(split, jnp.where(left_small, pi - 1, pr), top[1])
        depth_n = jnp.where(split, depth - 1, top[2])
        done = ~split & (sp == 0)
        sp = jnp.where(split, sp + 1, sp - 1)
        return idx, seg, stack, sp, pl_n, pr_n, depth_n, ~split, done, heap | heap_now

    idx, seg, *_, heap = lax.while_loop(lambda s: ~s[8], body, init)
    seg = jnp.where(q < count, seg, size)
    small = count <= _SMALL
    seg = jnp.where(small & (q < count), 0, seg)
    idx = jnp.where(small | ~run, q, idx)
    order = jnp.lexsort((q, key[idx], seg))                          # each part stable sorted
    return idx[order].astype(jnp.int32), heap & run & ~small


def greedy(affinity, n, m):
    """(det_track [N] int32, key [N] int32, fallback bool) of AB3DMOT's greedy matching on
    ``-affinity[:n, :m]`` (float32 [N, K]): the track each detection is paired with (-1: none)
    and its pair's place in the visiting order (the order of assignment)."""
    n_det, n_trk = affinity.shape
    size = n_det * n_trk
    p = jnp.arange(size)
    mm = jnp.maximum(m, 1)
    count = n * m
    i, j = p // mm, p % mm
    inside = p < count
    v = jnp.where(inside, -affinity[jnp.minimum(i, n_det - 1), jnp.minimum(j, n_trk - 1)], jnp.inf)
    key = jnp.where(v == 0, 0.0, v)
    s = jnp.sort(key)
    ties = jnp.any((s[1:] == s[:-1]) & (p[1:] < count))
    plain = jnp.argsort(key, stable=True).astype(jnp.int32)
    intro, fallback = introsort_order(v, count, ties)
    order = jnp.where(ties, intro, plain)
    rank_flat = jnp.zeros(size, jnp.int32).at[order].set(p.astype(jnp.int32))
    pairs = (jnp.arange(n_det)[:, None] < n) & (jnp.arange(n_trk)[None] < m)
    flat_index = jnp.arange(n_det)[:, None] * mm + jnp.arange(n_trk)[None]
    big = jnp.int32(size + 1)
    rank = jnp.where(pairs, rank_flat[jnp.minimum(flat_index, size - 1)], big)

    def round_(s):
        det_free, trk_free, det_track, det_key = s
        avail = det_free[:, None] & trk_free[None] & pairs
        r = jnp.where(avail, rank, big)
        row_min, col_min = jnp.min(r, 1), jnp.min(r, 0)
        take = avail & (r == row_min[:, None]) & (r == col_min[None])
        took_d, took_t = jnp.any(take, 1), jnp.any(take, 0)
        det_track = jnp.where(took_d, jnp.argmax(take, 1), det_track)
        det_key = jnp.where(took_d, row_min, det_key)
        return det_free & ~took_d, trk_free & ~took_t, det_track, det_key

    def more(s):
        return jnp.any(s[0][:, None] & s[1][None] & pairs)

    init = (jnp.ones(n_det, bool), jnp.ones(n_trk, bool), jnp.full(n_det, -1), jnp.full(n_det, big))
    _, _, det_track, det_key = lax.while_loop(more, round_, init)
    return det_track.astype(jnp.int32), det_key.astype(jnp.int32), fallback
