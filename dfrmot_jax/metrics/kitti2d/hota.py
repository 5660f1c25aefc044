"""HOTA (Luiten et al. 2020) exactly as TrackEval's ``metrics/hota.py``, batched over configs.

Per sequence, TrackEval (1) accumulates a soft co-occurrence ``potential_matches_count[g, t]`` of
``sim / (rowsum + colsum - sim)`` over all frames, turns it into a global alignment score
``A[g, t] = pm / (n_g + n_t - pm)``, (2) solves ``linear_sum_assignment(-A[g, t] * sim)`` per
frame, and (3) for each of the 19 alphas ``0.05, 0.10, ..., 0.95`` counts matches with
``sim >= alpha - eps`` (TP), FN, FP, summed IoU (LocA) and per id-pair match counts (AssA, AssRe,
AssPr). Here steps (1)-(3) run on the flat pair list of all frames of all configs; the frame sums
reproduce numpy's summation order so that ``A`` and hence every assignment is bit-identical.

Arrays: ``L`` configs, ``S`` sequences, ``NA = 19`` alphas.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np
import pandas as pd

from dfrmot_jax.metrics.common.assignment import match_block, workspace
from dfrmot_jax.metrics.common.kernel_cache import cached_njit
from dfrmot_jax.metrics.common.pairs import (assign_frames, crowded_segments, numpy_col_sums, numpy_row_sums,
                                             pairwise_sum, segment_rows)
from dfrmot_jax.metrics.common.sorting import argsort
from dfrmot_jax.metrics.kitti2d.boxes import EPS
from dfrmot_jax.metrics.kitti2d.kitti import MAX_ID_TABLE, EvalBatch

ALPHAS = np.arange(0.05, 0.99, 0.05)  # TrackEval's array_labels, [19]
NA = len(ALPHAS)
FLOAT_ARRAY_FIELDS = ("HOTA", "DetA", "AssA", "DetRe", "DetPr", "AssRe", "AssPr", "LocA", "OWTA")
INTEGER_ARRAY_FIELDS = ("HOTA_TP", "HOTA_FN", "HOTA_FP")
FLOAT_FIELDS = ("HOTA(0)", "LocA(0)", "HOTALocA(0)")
FIELDS = FLOAT_ARRAY_FIELDS + INTEGER_ARRAY_FIELDS + FLOAT_FIELDS
MAX_TABLE = MAX_ID_TABLE       # (the compiled pass's limit: kitti.MAX_ID_TABLE)


def _final_fields(res: dict) -> dict:
    """TrackEval's ``HOTA._compute_final_fields`` on arrays [..., NA]."""
    tp, fn, fp = res["HOTA_TP"], res["HOTA_FN"], res["HOTA_FP"]
    res["DetRe"] = tp / np.maximum(1, tp + fn)
    res["DetPr"] = tp / np.maximum(1, tp + fp)
    res["DetA"] = tp / np.maximum(1, tp + fn + fp)
    res["HOTA"] = np.sqrt(res["DetA"] * res["AssA"])
    res["OWTA"] = np.sqrt(res["DetRe"] * res["AssA"])
    res["HOTA(0)"] = res["HOTA"][..., 0]
    res["LocA(0)"] = res["LocA"][..., 0]
    res["HOTALocA(0)"] = res["HOTA(0)"] * res["LocA(0)"]
    return res


def _rev_cum(hist: np.ndarray) -> np.ndarray:
    """hist [..., NA+1] counts by number of alphas passed -> [..., NA] totals passing each alpha."""
    rc = np.cumsum(hist[..., ::-1], axis=-1)[..., ::-1]
    return rc[..., 1:]


def hota_sequences(b: EvalBatch) -> dict[str, np.ndarray]:
    """HOTA fields per (config, sequence): arrays [L, S, NA] and [L, S] (``FIELDS``).

    Steps (1)-(3) run in one compiled pass per (config, sequence) (:func:`_hota_kernel`), exactly
    the operations of :func:`hota_sequences_numpy` in their order: the same bits. Where one sequence's
    (tracker id, GT id) table would pass :data:`MAX_TABLE` entries, the NumPy path answers."""
    gt = b.gt
    L, S = b.n_lanes, len(gt.sequences)
    if not len(b.sim) or b.id_table_size > MAX_TABLE:
        return hota_sequences_numpy(b)
    hist, loc_hist, ass = _hota_kernel(
        b.ls_lf_start, b.ls_seq, np.ascontiguousarray(b.pair_start, np.int64),
        np.ascontiguousarray(b.lf_eval_count, np.int64), np.ascontiguousarray(b.det_count, np.int64),
        np.ascontiguousarray(b.sim, np.float64), b.p_gid, b.p_tid,
        np.ascontiguousarray(gt.gid_count, np.float64), np.ascontiguousarray(b.tid_count, np.float64), b.ls_tid_start,
        np.ascontiguousarray(gt.gid_start, np.int64), ALPHAS - EPS, EPS)
    res = _fields(b, hist.reshape(L, S, NA + 1), loc_hist.reshape(L, S, NA + 1), ass)
    return _early_sequences(b, res)


def hota_sequences_numpy(b: EvalBatch) -> dict[str, np.ndarray]:
    """:func:`hota_sequences` vectorised in NumPy over the flat pair list: the reference the compiled
    pass is tested against."""
    row_lf, row_first = segment_rows(b.lf_eval_count, b.det_count, b.pair_start)
    combos = _alignment(b, row_lf, row_first)
    matched = _assign(b, combos.score, row_lf, row_first)
    res = _alpha_fields(b, combos, matched)
    return _early_sequences(b, res)


class _Combos(NamedTuple):
    """The (tracker id, GT id) combos that ever overlap and the global alignment score of step (1)."""
    pos: np.ndarray      # [Q] the pairs with sim > 0
    inv: np.ndarray      # [Q] the combo of each, 0..C-1 in sorted order of (tracker id, GT id)
    n: int               # C combos
    c_tid: np.ndarray    # [C] the combo's tracker id
    gc: np.ndarray       # [C] detections of its GT id
    tc: np.ndarray       # [C] detections of its tracker id
    score: np.ndarray    # [P] alignment score x sim of each pair (0 where sim = 0)


def _alignment(b: EvalBatch, row_lf: np.ndarray, row_first: np.ndarray) -> _Combos:
    """Step (1): ``sim / (rowsum + colsum - sim)`` accumulated per (tracker id, GT id) combo into
    the global alignment score ``A``, times each pair's similarity."""
    gt = b.gt
    NG = len(gt.gid_count)
    P = len(b.sim)
    sim = b.sim
    ng_e = b.lf_eval_count
    nk = b.det_count

    # sim_iou = sim / (colsum + rowsum - sim), sums exactly as numpy, the rest in one compiled pass
    row_len = nk[row_lf]
    rowsum = numpy_row_sums(sim, row_first, row_len)
    colsum = numpy_col_sums(sim, b.p_k, len(b.det_lf), b.det_lf, ng_e, nk, b.pair_start)
    sim_iou = _sim_iou(np.ascontiguousarray(sim, dtype=np.float64), row_first.astype(np.int64),
                       row_len.astype(np.int64), rowsum, colsum, b.p_k.astype(np.int64), EPS)

    # potential matches per (tracker id, gt id) combo, accumulated in time order like TrackEval
    pos = np.flatnonzero(sim > 0)
    p_gid = gt.eval_gid[b.p_e[pos]]
    p_tid = b.det_gid[b.p_k[pos]]
    inv, uniq = pd.factorize(p_tid * max(NG, 1) + p_gid, sort=True)  # = np.unique(..., return_inverse), hashed
    pm = np.bincount(inv, weights=sim_iou[pos], minlength=len(uniq))
    c_gid = uniq % max(NG, 1)
    c_tid = uniq // max(NG, 1)
    gc = gt.gid_count[c_gid]
    tc = b.tid_count[c_tid]
    gas = pm / (gc + tc - pm)
    score = np.zeros(P)
    score[pos] = gas[inv] * sim[pos]
    return _Combos(pos, inv, len(uniq), c_tid, gc, tc, score)


def _assign(b: EvalBatch, score: np.ndarray, row_lf: np.ndarray, row_first: np.ndarray) -> np.ndarray:
    """Step (2): the per-frame assignment maximising ``score`` -> [P] bool, the matched pairs."""
    positive = score > 0
    matched = positive.copy()
    hard = crowded_segments(positive, row_lf, row_first, b.p_k, b.det_lf)
    assign_frames(hard, b.pair_start, b.lf_eval_count, b.det_count, score, matched, 0.0)
    return matched


def _alpha_fields(b: EvalBatch, co: _Combos, matched: np.ndarray) -> dict[str, np.ndarray]:
    """Step (3): the matches' statistics per alpha -> every field, [L, S, NA] and [L, S]."""
    gt = b.gt
    L, F, S = b.n_lanes, gt.n_frames, len(gt.sequences)
    P = len(b.sim)
    sim = b.sim
    h = np.flatnonzero(matched)
    sim_h = sim[h]
    na = np.searchsorted(ALPHAS - EPS, sim_h, side="right")  # alphas passed: sim >= alpha - eps
    lf_h = b.p_lf[h]
    ls_h = (lf_h // F) * S + gt.seq_of_frame[lf_h % F]
    hist = np.bincount(ls_h * (NA + 1) + na, minlength=L * S * (NA + 1)).reshape(L, S, NA + 1)
    loc_hist = np.bincount(ls_h * (NA + 1) + na, weights=sim_h, minlength=L * S * (NA + 1)).reshape(L, S, NA + 1)

    combo_of_pair = np.full(P, -1, dtype=np.int64)
    combo_of_pair[co.pos] = co.inv
    ch = combo_of_pair[h]
    C = co.n
    mc = _rev_cum(np.bincount(ch * (NA + 1) + na, minlength=C * (NA + 1)).reshape(C, NA + 1)).astype(np.float64)
    ls_c = b.tid_lane[co.c_tid] * S + b.tid_seq[co.c_tid]
    ass = _association_sums(mc, co.gc.astype(np.int64), co.tc.astype(np.int64), ls_c.astype(np.int64), L * S)
    return _fields(b, hist, loc_hist, ass)


def _fields(b: EvalBatch, hist: np.ndarray, loc_hist: np.ndarray, ass: np.ndarray) -> dict[str, np.ndarray]:
    """Every field from the matches' histograms by alphas passed, ``hist`` [L, S, NA + 1] and the summed
    similarity ``loc_hist`` [L, S, NA + 1], and the association sums ``ass`` [3, L * S * NA]."""
    gt = b.gt
    L, S = b.n_lanes, len(gt.sequences)
    tp = _rev_cum(hist).astype(np.float64)
    loc_sum = _rev_cum(loc_hist)
    n_gt = np.broadcast_to(gt.n_gt_dets[None, :, None], (L, S, 1)).astype(np.float64)
    n_tr = b.n_tr_dets[:, :, None].astype(np.float64)
    res = {
        "HOTA_TP": tp,
        "HOTA_FN": n_gt - tp,
        "HOTA_FP": n_tr - tp,
    }
    den = np.maximum(1, tp)
    res["AssA"] = ass[0].reshape(L, S, NA) / den
    res["AssRe"] = ass[1].reshape(L, S, NA) / den
    res["AssPr"] = ass[2].reshape(L, S, NA) / den
    res["LocA"] = np.maximum(1e-10, loc_sum) / np.maximum(1e-10, tp)
    return _final_fields(res)


@cached_njit(nogil=True, calls=("dfrmot_jax.metrics.common.assignment", "dfrmot_jax.metrics.common.pairs",
                                "dfrmot_jax.metrics.common.sorting"))
def _hota_kernel(lf_start, seq_of_ls, pair_start, ng, nk, sim, p_gid, p_tid, gid_count, tid_count, tid_start,
                 gid_start, thresholds, eps):
    """Steps (1)-(3) of every (config, sequence) ``ls`` (lane-frames ``lf_start[ls]:lf_start[ls + 1]``,
    sequence ``seq_of_ls[ls]``): (1) the alignment score of each (tracker id, GT id) combo
    (:func:`_align`); (2) each frame's matching; (3) each match's alphas passed
    (``thresholds`` [NA] = alphas - eps, ``sim >= threshold``) counted and its similarity summed per
    bucket in pair order, per (config, sequence) and per combo, and the association sums over the
    combos in (tracker id, GT id) order (:func:`_match`). Pairs: ``sim``, ``p_gid``, ``p_tid`` [P] (their GT id and
    tracker id), row-major per lane-frame at ``pair_start``, ``ng`` x ``nk`` per lane-frame;
    ``gid_count`` [NG], ``tid_count`` [NT] detections per id; ``tid_start`` [L*S + 1], ``gid_start``
    [S + 1] each (config, sequence)'s ids. Returns (hist [L*S, NA + 1] matches by alphas passed,
    loc_hist the same summed similarity, ass [3, L*S*NA] the AssA / AssRe / AssPr sums)."""
    n_ls = len(lf_start) - 1
    NA = len(thresholds)
    hist = np.zeros((n_ls, NA + 1), np.int64)
    loc_hist = np.zeros((n_ls, NA + 1))
    ass = np.zeros((3, n_ls * NA))
    one = np.int64(1)                                       # (typed, not literal: assignment's docstring)
    n_table, n_pairs, side, block = one, one, one, one
    for ls in range(n_ls):
        sq = seq_of_ls[ls]
        n_table = max(n_table, (tid_start[ls + 1] - tid_start[ls]) * (gid_start[sq + 1] - gid_start[sq]))
        n_pairs = max(n_pairs, pair_start[lf_start[ls + 1]] - pair_start[lf_start[ls]])
    for lf in range(lf_start[n_ls]):
        side = max(side, ng[lf], nk[lf])
        block = max(block, ng[lf] * nk[lf])
    table = np.full(n_table, -1, np.int64)                  # (tracker id, GT id) -> combo, per sequence
    c_key, c_hist = np.empty(n_pairs, np.int64), np.empty((n_pairs, NA + 1), np.int64)
    c_pm, c_gc, c_tc = np.empty(n_pairs), np.empty(n_pairs), np.empty(n_pairs)
    pos_q, pos_c = np.empty(n_pairs, np.int64), np.empty(n_pairs, np.int64)   # positive pairs, their combos
    out_rows, out_cols = np.empty(side, np.int64), np.empty(side, np.int64)
    score = np.empty(block)
    ws = workspace(side, block)
    for ls in range(n_ls):
        sq = seq_of_ls[ls]
        t0, g0, n_g = tid_start[ls], gid_start[sq], gid_start[sq + 1] - gid_start[sq]
        lf0, lf1 = lf_start[ls], lf_start[ls + 1]
        C, n_pos = _align(lf0, lf1, pair_start, ng, nk, sim, p_gid, p_tid, gid_count, tid_count, t0, g0, n_g, eps,
                          table, c_key, c_pm, c_gc, c_tc, c_hist, pos_q, pos_c, side)
        _match(lf0, lf1, pair_start, ng, nk, sim, pos_q[:n_pos], pos_c[:n_pos], c_pm, c_hist, thresholds, hist[ls],
               loc_hist[ls], score, out_rows, out_cols, ws)
        for c in argsort(c_key[:C]):                                  # the association sums
            m = 0.0
            gc, tc = c_gc[c], c_tc[c]
            for k in range(NA, 0, -1):
                m += c_hist[c, k]
                o = ls * NA + k - 1
                ass[0, o] += m * (m / max(1.0, (gc + tc) - m))
                ass[1, o] += m * (m / max(1.0, gc))
                ass[2, o] += m * (m / max(1.0, tc))
        for c in range(C):
            table[c_key[c]] = -1
    return hist, loc_hist, ass


@numba.njit(cache=False, nogil=True)     # (compiled into _hota_kernel, the cached one)
def _align(lf0, lf1, pair_start, ng, nk, sim, p_gid, p_tid, gid_count, tid_count, t0, g0, n_g, eps, table, c_key,
           c_pm, c_gc, c_tc, c_hist, pos_q, pos_c, side):
    """Step (1) of one (config, sequence), lane-frames ``lf0:lf1``: each frame's ``sim / (rowsum + colsum
    - sim)`` (0 where the denominator is not above ``0 + eps``), its sums as numpy's
    (:func:`~dfrmot_jax.metrics.common.pairs.pairwise_sum` along a row, in row order down a column of
    two or more), accumulated per (tracker id, GT id) combo in pair order; then each combo's alignment
    score ``pm / (gc + tc - pm)`` in ``c_pm``. Combos are numbered as first seen (``table`` [local
    tracker id * n_g + local GT id]; ``c_key`` each one's entry); the positive pairs (``sim > 0``) and
    their combos are listed in pair order in ``pos_q``, ``pos_c``. Returns (combos, positive pairs)."""
    rowsum, colsum = np.empty(side), np.empty(side)
    C = n_pos = 0
    for lf in range(lf0, lf1):
        a, nr, nc = pair_start[lf], ng[lf], nk[lf]
        if nr == 0 or nc == 0:
            continue
        for i in range(nr):
            rowsum[i] = pairwise_sum(sim, a + i * nc, nc)
        if nc == 1:
            colsum[0] = pairwise_sum(sim, a, nr)
        else:
            colsum[:nc] = 0.0
            for i in range(nr):
                for j in range(nc):
                    colsum[j] += sim[a + i * nc + j]
        for i in range(nr):
            for j in range(nc):
                q = a + i * nc + j
                x = sim[q]
                if x > 0:
                    denom = (colsum[j] + rowsum[i]) - x
                    key = (p_tid[q] - t0) * n_g + (p_gid[q] - g0)
                    c = table[key]
                    if c < 0:
                        c, C = C, C + 1
                        table[key], c_key[c], c_pm[c] = c, key, 0.0
                        c_gc[c], c_tc[c] = gid_count[p_gid[q]], tid_count[p_tid[q]]
                        c_hist[c, :] = 0
                    c_pm[c] += x / denom if denom > 0 + eps else 0.0
                    pos_q[n_pos], pos_c[n_pos] = q, c
                    n_pos += 1
    for c in range(C):
        c_pm[c] = c_pm[c] / ((c_gc[c] + c_tc[c]) - c_pm[c])
    return C, n_pos


@numba.njit(cache=False, nogil=True)     # (compiled into _hota_kernel, the cached one)
def _match(lf0, lf1, pair_start, ng, nk, sim, pos_q, pos_c, gas, c_hist, thresholds, hist, loc_hist, score, rows,
           cols, ws):
    """Steps (2) and (3) of one (config, sequence), lane-frames ``lf0:lf1``, from its positive pairs
    ``pos_q`` (pair order) and their combos ``pos_c`` (:func:`_align`; every other score is 0): each
    frame's scores ``gas * sim``; its matches: its positive scores where no row or column holds two,
    else those of scipy's assignment of the frame's score matrix
    (:func:`~dfrmot_jax.metrics.common.assignment.match_block`), pairs of score > 0, in row order; each
    match's alphas passed counted in ``hist`` [NA + 1] and its combo's ``c_hist``, its similarity
    summed in ``loc_hist`` (pair order)."""
    NA = len(thresholds)
    n_row, n_col = np.zeros(len(rows), np.int64), np.zeros(len(rows), np.int64)
    match_c = np.empty(len(rows), np.int64)
    p = 0
    for lf in range(lf0, lf1):
        a, nr, nc = pair_start[lf], ng[lf], nk[lf]
        p0 = p
        while p < len(pos_q) and pos_q[p] < a + nr * nc:
            p += 1
        if p == p0:
            continue
        crowded = False
        for k in range(p0, p):
            if gas[pos_c[k]] * sim[pos_q[k]] > 0:
                i, j = (pos_q[k] - a) // nc, (pos_q[k] - a) % nc
                n_row[i] += 1
                n_col[j] += 1
                crowded = crowded or n_row[i] > 1 or n_col[j] > 1
        n_match = 0
        if crowded:
            score[:nr * nc] = 0.0
            for k in range(p0, p):
                score[pos_q[k] - a] = gas[pos_c[k]] * sim[pos_q[k]]
            n_match = match_block(score, nr, nc, 0.0, rows, cols, ws)
            for k in range(p0, p):             # (each match's combo)
                for m in range(n_match):
                    if pos_q[k] == a + rows[m] * nc + cols[m]:
                        match_c[m] = pos_c[k]
        else:
            for k in range(p0, p):
                if gas[pos_c[k]] * sim[pos_q[k]] > 0:
                    rows[n_match], cols[n_match] = (pos_q[k] - a) // nc, (pos_q[k] - a) % nc
                    match_c[n_match] = pos_c[k]
                    n_match += 1
        for k in range(p0, p):
            n_row[(pos_q[k] - a) // nc] = 0
            n_col[(pos_q[k] - a) % nc] = 0
        for m in range(n_match):
            x = sim[a + rows[m] * nc + cols[m]]
            na = 0
            while na < NA and thresholds[na] <= x:
                na += 1
            hist[na] += 1
            loc_hist[na] += x
            c_hist[match_c[m], na] += 1


@cached_njit(nogil=True)
def _sim_iou(sim, row_first, row_len, rowsum, colsum, p_k, eps):
    """[P] ``sim / (colsum + rowsum - sim)`` of each pair (0 where the denominator is not above
    ``0 + eps``): rows of pairs ``row_first[r] .. + row_len[r]``, ``rowsum`` [R] per row, ``colsum``
    per tracker column (``p_k`` [P] each pair's); TrackEval's operations in its order."""
    out = np.zeros(len(sim))
    for r in range(len(row_first)):
        rs = rowsum[r]
        for q in range(row_first[r], row_first[r] + row_len[r]):
            denom = (colsum[p_k[q]] + rs) - sim[q]
            if denom > 0 + eps:
                out[q] = sim[q] / denom
    return out


@cached_njit(nogil=True)
def _association_sums(mc, gc, tc, ls_c, n_ls):
    """[3, n_ls * NA]: per (lane, sequence) and alpha, the sums over combos (in combo order) of
    ``mc * AssA``, ``mc * AssRe``, ``mc * AssPr`` with TrackEval's per-combo ratios
    ``mc / max(1, gc + tc - mc)``, ``mc / max(1, gc)``, ``mc / max(1, tc)``; mc [C, NA] match counts,
    gc / tc [C] detections of the combo's GT / tracker id, ls_c [C] its (lane, sequence)."""
    C, na = mc.shape
    out = np.zeros((3, n_ls * na))
    for c in range(C):
        base = ls_c[c] * na
        for a in range(na):
            m = mc[c, a]
            out[0, base + a] += m * (m / max(1.0, (gc[c] + tc[c]) - m))
            out[1, base + a] += m * (m / max(1.0, float(gc[c])))
            out[2, base + a] += m * (m / max(1.0, float(tc[c])))
    return out


def _early_sequences(b: EvalBatch, res: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The fields of the sequences TrackEval returns early for (no tracker dets, or no GT dets)."""
    gt = b.gt
    L, S = b.n_lanes, len(gt.sequences)
    n_gt = np.broadcast_to(gt.n_gt_dets[None, :, None], (L, S, 1)).astype(np.float64)
    n_tr = b.n_tr_dets[:, :, None].astype(np.float64)
    no_tr, no_gt, early = b.early_sequences
    if early.any():
        for f in FLOAT_ARRAY_FIELDS + INTEGER_ARRAY_FIELDS:
            res[f][early] = 0.0
        res["HOTA_FN"][no_tr] = n_gt[no_tr]
        res["HOTA_FP"][no_gt] = n_tr[no_gt]
        res["LocA"][early] = 1.0
        res["HOTA(0)"][early] = 0.0
        res["LocA(0)"][early] = 1.0
        res["HOTALocA(0)"][early] = 0.0
    return res


def hota_combine(res: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """TrackEval's ``HOTA.combine_sequences`` over the sequence axis of :func:`hota_sequences` output.

    res: fields [L, S, NA] / [L, S]; sequences are the second axis. Returns fields [L, NA] / [L].
    """
    out = {}
    for f in INTEGER_ARRAY_FIELDS:
        out[f] = _seq_sum(res[f])
    tp = out["HOTA_TP"]
    for f in ("AssRe", "AssPr", "AssA"):
        out[f] = _seq_sum(res[f] * res["HOTA_TP"]) / np.maximum(1.0, tp)
    loca_weighted_sum = _seq_sum(res["LocA"] * res["HOTA_TP"])
    out["LocA"] = np.maximum(1e-10, loca_weighted_sum) / np.maximum(1e-10, tp)
    return _final_fields(out)


def _seq_sum(x: np.ndarray) -> np.ndarray:
    """Sum over axis 1 (sequences) one after the other, like Python's ``sum`` in TrackEval."""
    out = np.zeros(x.shape[:1] + x.shape[2:])
    for s in range(x.shape[1]):
        out = out + x[:, s]
    return out
