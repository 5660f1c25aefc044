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

from dfrmot_jax.metrics.common.pairs import (assign_frames, crowded_segments, numpy_col_sums, numpy_row_sums,
                                             segment_rows)
from dfrmot_jax.metrics.kitti2d.boxes import EPS
from dfrmot_jax.metrics.kitti2d.kitti import EvalBatch

ALPHAS = np.arange(0.05, 0.99, 0.05)  # TrackEval's array_labels, [19]
NA = len(ALPHAS)
FLOAT_ARRAY_FIELDS = ("HOTA", "DetA", "AssA", "DetRe", "DetPr", "AssRe", "AssPr", "LocA", "OWTA")
INTEGER_ARRAY_FIELDS = ("HOTA_TP", "HOTA_FN", "HOTA_FP")
FLOAT_FIELDS = ("HOTA(0)", "LocA(0)", "HOTALocA(0)")
FIELDS = FLOAT_ARRAY_FIELDS + INTEGER_ARRAY_FIELDS + FLOAT_FIELDS


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
    """HOTA fields per (config, sequence): arrays [L, S, NA] and [L, S] (``FIELDS``)."""
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
    tp = _rev_cum(hist).astype(np.float64)
    loc_hist = np.bincount(ls_h * (NA + 1) + na, weights=sim_h, minlength=L * S * (NA + 1)).reshape(L, S, NA + 1)
    loc_sum = _rev_cum(loc_hist)

    combo_of_pair = np.full(P, -1, dtype=np.int64)
    combo_of_pair[co.pos] = co.inv
    ch = combo_of_pair[h]
    C = co.n
    mc = _rev_cum(np.bincount(ch * (NA + 1) + na, minlength=C * (NA + 1)).reshape(C, NA + 1)).astype(np.float64)
    ls_c = b.tid_lane[co.c_tid] * S + b.tid_seq[co.c_tid]
    ass = _association_sums(mc, co.gc.astype(np.int64), co.tc.astype(np.int64), ls_c.astype(np.int64), L * S)

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


@numba.njit(cache=True, nogil=True)
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


@numba.njit(cache=True, nogil=True)
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
