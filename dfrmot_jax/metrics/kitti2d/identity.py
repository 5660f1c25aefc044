"""Identity metrics (IDF1, IDR, IDP; Ristani et al. 2016) exactly as TrackEval's ``metrics/identity.py``.

TrackEval counts, per sequence, the frames in which GT id ``g`` and tracker id ``t`` overlap with
``IoU >= 0.5`` (no eps here), then solves a ``(G+T) x (G+T)`` assignment whose optimal cost is
``n_gt_dets + n_tr_dets - 2 * IDTP`` with ``IDTP`` the maximum total co-occurrence of a one-to-one
id matching. All costs are integers, so the optimum (and IDTP, IDFN, IDFP) is unique and any exact
solver gives TrackEval's numbers: here the id graph is split into connected components; a
component with one edge is its own optimum, larger ones are solved by scipy's assignment
(:mod:`dfrmot_jax.metrics.common.assignment`, maximising): per (config, sequence) in one compiled pass,
or, in the vectorised NumPy path kept as its reference, the whole batch's in one compiled call.
Arrays: ``L`` configs, ``S`` sequences.
"""

from __future__ import annotations

import numba
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from dfrmot_jax.metrics.common.assignment import solve_block, solve_many, workspace
from dfrmot_jax.metrics.common.kernel_cache import cached_njit
from dfrmot_jax.metrics.common.pairs import segment_starts
from dfrmot_jax.metrics.common.sorting import argsort
from dfrmot_jax.metrics.kitti2d.kitti import MAX_ID_TABLE, EvalBatch

THRESHOLD = 0.5
INTEGER_FIELDS = ("IDTP", "IDFN", "IDFP")
FLOAT_FIELDS = ("IDF1", "IDR", "IDP")
FIELDS = FLOAT_FIELDS + INTEGER_FIELDS
MAX_TABLE = MAX_ID_TABLE       # (the compiled pass's limit: kitti.MAX_ID_TABLE)


def _final_fields(res: dict) -> dict:
    """TrackEval's ``Identity._compute_final_fields``."""
    idtp, idfn, idfp = (np.asarray(res[k], dtype=np.float64) for k in INTEGER_FIELDS)
    res["IDR"] = idtp / np.maximum(1.0, idtp + idfn)
    res["IDP"] = idtp / np.maximum(1.0, idtp + idfp)
    res["IDF1"] = idtp / np.maximum(1.0, idtp + 0.5 * idfp + 0.5 * idfn)
    return res


def max_matching_value(g: np.ndarray, t: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Maximum-weight bipartite matching value per connected component, summed per edge group.

    g, t: [E] int64 node ids of the two sides (any range), w: [E] positive weights (integers as
    float64). Returns [E] float64: for the first edge of each component its optimal value, 0
    elsewhere (so ``np.bincount(group_of_edge, weights=result)`` totals it).
    """
    E = len(w)
    out = np.zeros(E)
    if E == 0:
        return out
    ug, ig = np.unique(g, return_inverse=True)
    ut, it = np.unique(t, return_inverse=True)
    ig, it = ig.reshape(-1), it.reshape(-1)
    dg = np.bincount(ig)
    dt = np.bincount(it)
    single = (dg[ig] == 1) & (dt[it] == 1)
    out[single] = w[single]
    rest = np.flatnonzero(~single)
    if rest.size == 0:
        return out
    nG, nT = len(ug), len(ut)
    adj = coo_matrix((np.ones(rest.size), (ig[rest], nG + it[rest])), shape=(nG + nT, nG + nT))
    _, comp = connected_components(adj, directed=False)
    ec = comp[ig[rest]]
    order = np.lexsort((it[rest], ig[rest], ec))
    rest, ec = rest[order], ec[order]
    # component-local row / column indices
    _, lr = np.unique(ec * nG + ig[rest], return_inverse=True)
    _, lc = np.unique(ec * nT + it[rest], return_inverse=True)
    lr, lc = lr.reshape(-1), lc.reshape(-1)
    bounds = segment_starts(np.bincount(ec)[np.unique(ec)])
    r0 = lr[bounds[:-1]]
    c_min = np.minimum.reduceat(lc, bounds[:-1])
    r_max = np.maximum.reduceat(lr, bounds[:-1])
    c_max = np.maximum.reduceat(lc, bounds[:-1])
    lr_local = lr - np.repeat(r0, np.diff(bounds))
    lc_local = lc - np.repeat(c_min, np.diff(bounds))
    # every component's dense matrix, row-major one after the other, solved in one compiled call
    nr = (r_max - r0 + 1).astype(np.int64)
    nc = (c_max - c_min + 1).astype(np.int64)
    m_start = segment_starts(nr * nc)
    comp_of = np.repeat(np.arange(len(nr)), np.diff(bounds))
    vals = np.zeros(int(m_start[-1]))
    vals[m_start[comp_of] + lr_local * nc[comp_of] + lc_local] = w[rest]
    r, c, ps = solve_many(vals, nr, nc, maximize=True)
    per = np.diff(ps)
    # (integer weights: the components' sums are exact in any order)
    taken = vals[m_start[:-1].repeat(per) + r * nc.repeat(per) + c]
    value = np.bincount(np.repeat(np.arange(len(nr)), per), weights=taken, minlength=len(nr))
    out[rest[bounds[:-1]]] = value
    return out


def identity_sequences(b: EvalBatch) -> dict[str, np.ndarray]:
    """Identity fields per (config, sequence): arrays [L, S] (``FIELDS``; counts as int64), from one
    compiled pass per (config, sequence) (:func:`_identity_kernel`); :func:`identity_sequences_numpy`
    is the reference it is tested against. Where one sequence's (tracker id x GT id) table would pass
    :data:`MAX_TABLE` entries, the NumPy path answers."""
    gt = b.gt
    L, S = b.n_lanes, len(gt.sequences)
    if not len(b.sim) or b.id_table_size > MAX_TABLE:
        return identity_sequences_numpy(b)
    idtp = _identity_kernel(b.ls_lf_start, b.ls_seq, np.ascontiguousarray(b.pair_start, np.int64),
                            np.ascontiguousarray(b.sim, np.float64), b.p_gid, b.p_tid, b.ls_tid_start,
                            np.ascontiguousarray(gt.gid_start, np.int64), THRESHOLD)
    return _fields(b, np.rint(idtp).astype(np.int64).reshape(L, S))


def identity_sequences_numpy(b: EvalBatch) -> dict[str, np.ndarray]:
    """:func:`identity_sequences` vectorised in NumPy (the id graph's components over the batch, the
    larger ones solved in one compiled call)."""
    gt = b.gt
    L, S = b.n_lanes, len(gt.sequences)
    NG = max(len(gt.gid_count), 1)
    hit = np.flatnonzero(np.greater_equal(b.sim, THRESHOLD))
    gid = b.p_gid[hit]
    tid = b.p_tid[hit]
    uniq, cnt = np.unique(tid * NG + gid, return_counts=True)
    c_gid, c_tid = uniq % NG, uniq // NG
    lane = b.tid_lane[c_tid]
    val = max_matching_value(lane * NG + c_gid, c_tid, cnt.astype(np.float64))
    ls = lane * S + b.tid_seq[c_tid]
    return _fields(b, np.rint(np.bincount(ls, weights=val, minlength=L * S)).astype(np.int64).reshape(L, S))


def _fields(b: EvalBatch, idtp: np.ndarray) -> dict[str, np.ndarray]:
    """Every field from IDTP [L, S] (int64), with TrackEval's early returns."""
    gt = b.gt
    L, S = b.n_lanes, len(gt.sequences)
    n_gt = np.broadcast_to(gt.n_gt_dets[None, :], (L, S)).astype(np.int64)
    n_tr = b.n_tr_dets.astype(np.int64)
    res = {"IDTP": idtp, "IDFN": n_gt - idtp, "IDFP": n_tr - idtp}
    res = _final_fields(res)
    no_tr, no_gt, early = b.early_sequences
    if early.any():
        for f in FIELDS:
            res[f] = np.array(res[f], copy=True)
            res[f][early] = 0
        res["IDFN"][no_tr] = n_gt[no_tr]
        res["IDFP"][no_gt] = n_tr[no_gt]
    return res


@cached_njit(nogil=True, calls=("dfrmot_jax.metrics.common.assignment", "dfrmot_jax.metrics.common.sorting"))
def _identity_kernel(ls_lf_start, ls_seq, pair_start, sim, p_gid, p_tid, tid_start, gid_start, thr):
    """IDTP of every (config, sequence) ``ls`` (lane-frames ``ls_lf_start[ls]:ls_lf_start[ls + 1]``): the
    frames in which each (tracker id, GT id) pair overlaps with ``sim >= thr`` counted, then the
    maximum total count of a one-to-one id matching: per connected component of the id graph, its one
    edge's count or scipy's assignment (:func:`~dfrmot_jax.metrics.common.assignment.solve_block`,
    maximising) of its dense (GT id x tracker id) count matrix. Counts are integers: the optimum's
    value is unique and exact. Returns [L*S] float64."""
    n_ls = len(ls_lf_start) - 1
    out = np.zeros(n_ls)
    n_table, n_pairs, n_ids = 1, 1, 1
    for ls in range(n_ls):
        sq = ls_seq[ls]
        nt, ng = tid_start[ls + 1] - tid_start[ls], gid_start[sq + 1] - gid_start[sq]
        n_table = max(n_table, nt * ng)
        n_ids = max(n_ids, nt + ng)
        n_pairs = max(n_pairs, pair_start[ls_lf_start[ls + 1]] - pair_start[ls_lf_start[ls]])
    table = np.full(n_table, -1, np.int64)
    c_key, c_n = np.empty(n_pairs, np.int64), np.empty(n_pairs)
    parent = np.arange(n_ids)
    comp_of = np.empty(n_pairs, np.int64)
    local = np.full(n_ids, -1, np.int64)
    for ls in range(n_ls):
        sq = ls_seq[ls]
        t0, g0, ng = tid_start[ls], gid_start[sq], gid_start[sq + 1] - gid_start[sq]
        nt = tid_start[ls + 1] - t0
        C = np.int64(0)                          # (typed: assignment's docstring)
        for q in range(pair_start[ls_lf_start[ls]], pair_start[ls_lf_start[ls + 1]]):
            if sim[q] >= thr:
                key = (p_tid[q] - t0) * ng + (p_gid[q] - g0)
                c = table[key]
                if c < 0:
                    c, C = C, C + 1
                    table[key], c_key[c], c_n[c] = c, key, 0.0
                c_n[c] += 1.0
        # the id graph's components: GT id g is node g, tracker id t node ng + t
        for v in range(ng + nt):
            parent[v] = v
        for c in range(C):
            a, z = _root(parent, c_key[c] % ng), _root(parent, ng + c_key[c] // ng)
            if a != z:
                parent[max(a, z)] = min(a, z)
        for c in range(C):
            comp_of[c] = _root(parent, c_key[c] % ng)
        out[ls] = _matching_value(C, c_key, c_n, comp_of, ng, local)
        for c in range(C):
            table[c_key[c]] = -1
    return out


@numba.njit(cache=False, nogil=True)     # (compiled into _identity_kernel, the cached one)
def _root(parent, v):
    """The root of ``v`` in a union-find forest (paths halved)."""
    while parent[v] != v:
        parent[v] = parent[parent[v]]
        v = parent[v]
    return v


@numba.njit(cache=False, nogil=True)     # (compiled into _identity_kernel, the cached one)
def _matching_value(C, c_key, c_n, comp_of, ng, local):
    """The maximum matching value of the ``C`` edges (``c_key`` = tracker id * ``ng`` + GT id, weights
    ``c_n``), component by component (``comp_of``): one edge its weight, else scipy's assignment of the
    component's dense count matrix. ``local`` [ng + nt] is scratch (-1 on entry and on return)."""
    total = 0.0
    order = argsort(comp_of[:C])
    a = 0
    while a < C:
        e = a
        while e < C and comp_of[order[e]] == comp_of[order[a]]:
            e += 1
        if e - a == 1:
            total += c_n[order[a]]
        else:
            nr = nc = np.int64(0)                # (typed: assignment's docstring)
            for k in range(a, e):
                g, t = c_key[order[k]] % ng, ng + c_key[order[k]] // ng
                if local[g] < 0:
                    local[g], nr = nr, nr + 1
                if local[t] < 0:
                    local[t], nc = nc, nc + 1
            vals = np.zeros(nr * nc)
            for k in range(a, e):
                c = order[k]
                vals[local[c_key[c] % ng] * nc + local[ng + c_key[c] // ng]] = c_n[c]
            rows, cols = np.empty(min(nr, nc), np.int64), np.empty(min(nr, nc), np.int64)
            solve_block(vals, np.int64(0), nr, nc, np.bool_(True), np.bool_(False), rows, cols, np.int64(0),
                        workspace(max(nr, nc), nr * nc))
            for k in range(min(nr, nc)):
                total += vals[rows[k] * nc + cols[k]]
            for k in range(a, e):
                local[c_key[order[k]] % ng] = -1
                local[ng + c_key[order[k]] // ng] = -1
        a = e
    return total


def identity_combine(res: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """TrackEval's ``Identity.combine_sequences``: sums of the counts over axis 1, then ratios. -> [L]."""
    out = {f: res[f].sum(axis=1) for f in INTEGER_FIELDS}
    return _final_fields(out)
