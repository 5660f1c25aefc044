"""Identity metrics (IDF1, IDR, IDP; Ristani et al. 2016) exactly as TrackEval's ``metrics/identity.py``.

TrackEval counts, per sequence, the frames in which GT id ``g`` and tracker id ``t`` overlap with
``IoU >= 0.5`` (no eps here), then solves a ``(G+T) x (G+T)`` assignment whose optimal cost is
``n_gt_dets + n_tr_dets - 2 * IDTP`` with ``IDTP`` the maximum total co-occurrence of a one-to-one
id matching. All costs are integers, so the optimum (and IDTP, IDFN, IDFP) is unique and any exact
solver gives TrackEval's numbers: here the id graph is split into connected components; a
component with one edge is its own optimum, larger ones are solved in one compiled call
(:func:`dfrmot_jax.metrics.common.assignment.solve_many`, maximising). Arrays: ``L`` configs, ``S`` sequences.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from dfrmot_jax.metrics.common.assignment import solve_many
from dfrmot_jax.metrics.common.pairs import segment_starts
from dfrmot_jax.metrics.kitti2d.kitti import EvalBatch

THRESHOLD = 0.5
INTEGER_FIELDS = ("IDTP", "IDFN", "IDFP")
FLOAT_FIELDS = ("IDF1", "IDR", "IDP")
FIELDS = FLOAT_FIELDS + INTEGER_FIELDS


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
    """Identity fields per (config, sequence): arrays [L, S] (``FIELDS``; counts as int64)."""
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
    idtp = np.rint(np.bincount(ls, weights=val, minlength=L * S)).astype(np.int64).reshape(L, S)
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


def identity_combine(res: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """TrackEval's ``Identity.combine_sequences``: sums of the counts over axis 1, then ratios. -> [L]."""
    out = {f: res[f].sum(axis=1) for f in INTEGER_FIELDS}
    return _final_fields(out)
