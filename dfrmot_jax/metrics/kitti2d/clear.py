"""CLEAR MOT metrics exactly as TrackEval's ``metrics/clear.py``, batched over configs.

Per frame TrackEval solves ``linear_sum_assignment(-(1000 * continues + sim))`` with entries of
``sim < 0.5 - eps`` zeroed, where ``continues[g, t]`` says tracker ``t`` was matched to GT ``g`` in
the previous frame *that had both GT and tracker boxes* (frames with either empty are skipped and
do not reset it). IDSW counts changes of a GT's matched tracker id (over any gap), Frag counts
re-starts of tracking between consecutive such frames, MT/PT/ML use the tracked ratio
(> 0.8 / >= 0.2).

Only frames where a GT or tracker box has two candidates (IoU >= 0.5) need the solver (the
``continues`` bonus can only matter there); they are solved after all other frames' matches are
known, in rounds of frames whose previous frame is final (vectorised), then the rest in time order. Arrays: ``L`` configs, ``S`` sequences.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment

from dfrmot_jax.metrics.common.pairs import crowded_segments, segment_pairs, segment_rows, segment_starts, solve_blocks
from dfrmot_jax.metrics.kitti2d.boxes import EPS
from dfrmot_jax.metrics.kitti2d.kitti import EvalBatch

THRESHOLD = 0.5
MAIN_INTEGER_FIELDS = ("CLR_TP", "CLR_FN", "CLR_FP", "IDSW", "MT", "PT", "ML", "Frag")
INTEGER_FIELDS = MAIN_INTEGER_FIELDS + ("CLR_Frames",)
MAIN_FLOAT_FIELDS = ("MOTA", "MOTP", "MODA", "CLR_Re", "CLR_Pr", "MTR", "PTR", "MLR", "sMOTA")
FLOAT_FIELDS = MAIN_FLOAT_FIELDS + ("CLR_F1", "FP_per_frame", "MOTAL", "MOTP_sum")
FIELDS = FLOAT_FIELDS + INTEGER_FIELDS
SUMMED_FIELDS = INTEGER_FIELDS + ("MOTP_sum",)
#: frames solved together per round while a round has at least this many (then one by one)
ROUND_MIN = 16


def _final_fields(res: dict) -> dict:
    """TrackEval's ``CLEAR._compute_final_fields`` on arrays of any shape."""
    tp, fn, fp, idsw = (np.asarray(res[k], dtype=np.float64) for k in ("CLR_TP", "CLR_FN", "CLR_FP", "IDSW"))
    num_gt_ids = np.asarray(res["MT"] + res["ML"] + res["PT"], dtype=np.float64)
    res["MTR"] = res["MT"] / np.maximum(1.0, num_gt_ids)
    res["MLR"] = res["ML"] / np.maximum(1.0, num_gt_ids)
    res["PTR"] = res["PT"] / np.maximum(1.0, num_gt_ids)
    res["CLR_Re"] = tp / np.maximum(1.0, tp + fn)
    res["CLR_Pr"] = tp / np.maximum(1.0, tp + fp)
    res["MODA"] = (tp - fp) / np.maximum(1.0, tp + fn)
    res["MOTA"] = (tp - fp - idsw) / np.maximum(1.0, tp + fn)
    res["MOTP"] = res["MOTP_sum"] / np.maximum(1.0, tp)
    res["sMOTA"] = (res["MOTP_sum"] - fp - idsw) / np.maximum(1.0, tp + fn)
    res["CLR_F1"] = tp / np.maximum(1.0, tp + 0.5 * fn + 0.5 * fp)
    res["FP_per_frame"] = fp / np.maximum(1.0, np.asarray(res["CLR_Frames"], dtype=np.float64))
    safe_log_idsw = np.where(idsw > 0, np.log10(np.maximum(idsw, 1)), idsw)
    res["MOTAL"] = (tp - fp - safe_log_idsw) / np.maximum(1.0, tp + fn)
    return res


def _prev_active(b: EvalBatch) -> np.ndarray:
    """[L*F] the previous lane-frame with both GT and tracker boxes in the same lane and sequence (-1 none)."""
    gt = b.gt
    F = gt.n_frames
    active = np.flatnonzero(b.lf_eval_count * b.det_count)
    prev_of = np.full(len(b.det_count), -1, dtype=np.int64)
    same = (active[1:] // F == active[:-1] // F) & (
        gt.seq_of_frame[active[1:] % F] == gt.seq_of_frame[active[:-1] % F])
    prev_of[active[1:][same]] = active[:-1][same]
    return prev_of


def _solve_round(ready: np.ndarray, b: EvalBatch, sim: np.ndarray, p_gid: np.ndarray, p_tid: np.ndarray,
                 matched: np.ndarray, prev_of: np.ndarray) -> None:
    """Solve lane-frames whose previous active frame's matches are final in ``matched``, all at once.

    Each frame's matrix is TrackEval's ``1000 * continues + sim`` (zero where ``sim < 0.5 - eps``),
    solved by :func:`~dfrmot_jax.metrics.common.pairs.solve_blocks` (scipy on each full matrix).
    """
    NG = max(len(b.gt.gid_count), 1)
    ps = b.pair_start
    idx = segment_pairs(ready, ps)
    frame = np.repeat(ready, ps[ready + 1] - ps[ready])
    s = sim[idx]
    vals = np.where(s >= THRESHOLD - EPS, s, 0.0)  # TrackEval: score[sim < thr - eps] = 0
    prevs = prev_of[ready]
    prevs = prevs[prevs >= 0]
    q = np.flatnonzero((vals > 0) & (prev_of[frame] >= 0))
    if prevs.size and q.size:
        pp = segment_pairs(prevs, ps)
        mp = pp[matched[pp]]
        if mp.size:
            mkey = b.p_lf[mp] * NG + p_gid[mp]
            order = np.argsort(mkey)
            mkey, mtid = mkey[order], p_tid[mp][order]
            qkey = prev_of[frame[q]] * NG + p_gid[idx[q]]
            pos = np.minimum(np.searchsorted(mkey, qkey), len(mkey) - 1)
            cont = (mkey[pos] == qkey) & (mtid[pos] == p_tid[idx[q]])
            vals[q[cont]] += 1000  # TrackEval: 1000 * continues + sim (where sim >= thr - eps)
    take = solve_blocks(b.lf_eval_count[ready], b.det_count[ready], vals) & (vals > 0 + EPS)
    matched[idx[take]] = True


def _solve_sequential(hard: np.ndarray, b: EvalBatch, sim: np.ndarray, p_gid: np.ndarray, p_tid: np.ndarray,
                      matched: np.ndarray) -> None:
    """Solve the listed lane-frames with TrackEval's continuation bonus (in place).

    ``matched`` holds the final matches of every other lane-frame on entry. The bonus of a frame
    needs the matches of the previous frame with both GT and tracker boxes (same lane and
    sequence). Frames whose previous frame is final are solved together, in rounds
    (:func:`_solve_round`), while a round has at least ``ROUND_MIN`` frames; the rest (the tails of
    long runs of such frames) one by one in time order (:func:`_solve_in_order`).
    """
    prev_of = _prev_active(b)
    pending = np.zeros(len(b.det_count), dtype=bool)
    pending[hard] = True
    matched[segment_pairs(hard, b.pair_start)] = False
    while hard.size:
        prev = prev_of[hard]
        ready = hard[(prev < 0) | ~pending[np.maximum(prev, 0)]]
        if len(ready) < ROUND_MIN:
            break
        _solve_round(ready, b, sim, p_gid, p_tid, matched, prev_of)
        pending[ready] = False
        hard = hard[pending[hard]]
    if hard.size:
        _solve_in_order(hard, b, sim, p_gid, p_tid, matched, prev_of)


def _solve_in_order(hard: np.ndarray, b: EvalBatch, sim: np.ndarray, p_gid: np.ndarray, p_tid: np.ndarray,
                    matched: np.ndarray, prev_of: np.ndarray) -> None:
    """The listed lane-frames (pairs cleared in ``matched``) one by one in time order: the bonus
    looked up vectorised when the previous frame is final, else taken from the loop."""
    gt = b.gt
    NG = max(len(gt.gid_count), 1)
    ng_e = b.lf_eval_count
    nk = b.det_count
    ps = b.pair_start
    is_hard = np.zeros(len(nk), dtype=bool)
    is_hard[hard] = True

    # rows of the hard frames, their GT ids and (for non-hard previous frames) the previous match
    nr = ng_e[hard]
    nc = nk[hard]
    row_lf = np.repeat(hard, nr)
    row_first = ps[row_lf] + (np.arange(nr.sum()) - np.repeat(segment_starts(nr)[:-1], nr)) * nk[row_lf]
    row_gid = p_gid[row_first]
    row_prev = prev_of[row_lf]
    prev_tid_row = np.full(len(row_lf), -1, dtype=np.int64)
    q = np.flatnonzero((row_prev >= 0) & ~is_hard[np.maximum(row_prev, 0)])
    if q.size:
        mp = np.flatnonzero(matched)
        mkey = b.p_lf[mp] * NG + p_gid[mp]
        order = np.argsort(mkey, kind="stable")
        mkey, mtid = mkey[order], p_tid[mp][order]
        qkey = row_prev[q] * NG + row_gid[q]
        pos = np.searchsorted(mkey, qkey)
        pos_c = np.minimum(pos, max(len(mkey) - 1, 0))
        found = (pos < len(mkey)) & (mkey[pos_c] == qkey) if len(mkey) else np.zeros(len(q), dtype=bool)
        prev_tid_row[q[found]] = mtid[pos_c[found]]

    score0 = np.where(sim >= THRESHOLD - EPS, sim, 0.0)  # TrackEval: score[sim < thr - eps] = 0
    row_start = segment_starts(nr)
    solved: dict[int, dict[int, int]] = {}
    hp = prev_of[hard]
    needed = set(hp[(hp >= 0) & is_hard[np.maximum(hp, 0)]].tolist())
    out = []
    for lf, a, e, r, c, prev, ro in zip(hard.tolist(), ps[hard].tolist(), ps[hard + 1].tolist(), nr.tolist(),
                                        nc.tolist(), prev_of[hard].tolist(), row_start[:-1].tolist()):
        m = score0[a:e].reshape(r, c)
        if prev >= 0:
            if is_hard[prev]:
                lut = solved[prev]
                ptr = np.array([lut.get(g, -1) for g in row_gid[ro:ro + r].tolist()], dtype=np.int64)
            else:
                ptr = prev_tid_row[ro:ro + r]
            bonus = (p_tid[a:a + c][None, :] == ptr[:, None]) & (m > 0)
            if bonus.any():
                m = m.copy()
                m[bonus] += 1000  # TrackEval: 1000 * continues + sim (where sim >= thr - eps)
        rows, cols = linear_sum_assignment(-m)
        ok = m[rows, cols] > 0 + EPS
        flat = a + rows[ok] * c + cols[ok]
        out.append(flat)
        if lf in needed:
            solved[lf] = dict(zip(p_gid[flat].tolist(), p_tid[flat].tolist()))
    if out:
        matched[np.concatenate(out)] = True


def clear_sequences(b: EvalBatch) -> dict[str, np.ndarray]:
    """CLEAR fields per (config, sequence): arrays [L, S] (``FIELDS``; counts as int64)."""
    p_gid = b.gt.eval_gid[b.p_e]
    p_tid = b.det_gid[b.p_k]
    matched = _matched_pairs(b, p_gid, p_tid)
    res = _counts(b, matched, p_gid, p_tid)
    return _early_sequences(b, res)


def clear_matches(b: EvalBatch) -> dict[str, np.ndarray]:
    """CLEAR's matches themselves, for looking at where two outputs differ: M matched pairs sorted by
    (lane, GT id, frame), ``lane``, ``frame`` (global), ``gid`` (global GT id), ``tid`` (global tracker
    id, ``b.det_gid``'s), ``switch`` (the pair's tracker id differs from the GT id's previous match: an
    IDSW), ``restart`` (a match starting a new run after a gap of active frames: a Frag); the same
    decisions as :func:`clear_sequences` (``_matched_pairs``, ``_switches_and_fragments``)."""
    p_gid = b.gt.eval_gid[b.p_e]
    p_tid = b.det_gid[b.p_k]
    m = np.flatnonzero(_matched_pairs(b, p_gid, p_tid))
    F = b.gt.n_frames
    lf, gid, tid = b.p_lf[m], p_gid[m], p_tid[m]
    lane = lf // F
    order = np.lexsort((lf, gid, lane))
    lane, lf, gid, tid = lane[order], lf[order], gid[order], tid[order]
    same = np.zeros(len(order), bool)
    same[1:] = (lane[1:] == lane[:-1]) & (gid[1:] == gid[:-1])
    switch = np.zeros(len(order), bool)
    switch[1:] = same[1:] & (tid[1:] != tid[:-1])
    rank = np.cumsum((b.lf_eval_count * b.det_count) > 0) - 1          # rank among active lane-frames
    restart = np.zeros(len(order), bool)
    restart[1:] = same[1:] & (rank[lf[1:]] != rank[lf[:-1]] + 1)
    return {"lane": lane, "frame": lf % F, "gid": gid, "tid": tid, "switch": switch, "restart": restart}


def _matched_pairs(b: EvalBatch, p_gid: np.ndarray, p_tid: np.ndarray) -> np.ndarray:
    """[P] bool: TrackEval's per-frame matches (``sim >= 0.5 - eps``; the frames where a GT or
    tracker box has two candidates solved with the continuation bonus, :func:`_solve_sequential`)."""
    sim = b.sim
    positive = sim >= THRESHOLD - EPS
    matched = positive.copy()
    hard = crowded_segments(positive, *segment_rows(b.lf_eval_count, b.det_count, b.pair_start), b.p_k, b.det_lf)
    if hard.size:
        _solve_sequential(hard, b, sim, p_gid, p_tid, matched)
    return matched


def _counts(b: EvalBatch, matched: np.ndarray, p_gid: np.ndarray, p_tid: np.ndarray) -> dict[str, np.ndarray]:
    """The matches' counts per (lane, seq) -> every field, [L, S]."""
    gt = b.gt
    L, F, S = b.n_lanes, gt.n_frames, len(gt.sequences)
    NG = len(gt.gid_count)
    sim = b.sim
    m = np.flatnonzero(matched)
    m_lf = b.p_lf[m]
    m_lane = m_lf // F
    m_seq = gt.seq_of_frame[m_lf % F]
    m_ls = m_lane * S + m_seq
    m_gid = p_gid[m]
    m_tid = p_tid[m]
    tp = np.bincount(m_ls, minlength=L * S).reshape(L, S)
    motp_sum = np.bincount(m_ls, weights=sim[m], minlength=L * S).reshape(L, S)
    n_gt = np.broadcast_to(gt.n_gt_dets[None, :], (L, S)).astype(np.int64)
    n_tr = b.n_tr_dets
    key = m_lane * max(NG, 1) + m_gid
    idsw, frag_per_gid = _switches_and_fragments(b, key, m_lf, m_tid, m_ls)

    # MT / PT / ML
    matched_per_gid = np.bincount(key, minlength=L * max(NG, 1)).reshape(L, max(NG, 1))[:, :NG]
    ratio = matched_per_gid / gt.gid_count[None, :]
    seq_idx = np.broadcast_to(gt.gid_seq[None, :], (L, NG)) + (np.arange(L) * S)[:, None]

    def per_seq(v):
        return np.bincount(seq_idx.reshape(-1), weights=v.reshape(-1), minlength=L * S).reshape(L, S)

    mt = per_seq(np.greater(ratio, 0.8)).round().astype(np.int64)
    pt = per_seq(np.greater_equal(ratio, 0.2)).round().astype(np.int64) - mt
    ml = gt.n_gt_ids[None, :] - mt - pt
    frag = per_seq(frag_per_gid).round().astype(np.int64)

    res = {
        "CLR_TP": tp.astype(np.int64),
        "CLR_FN": (n_gt - tp).astype(np.int64),
        "CLR_FP": (n_tr - tp).astype(np.int64),
        "IDSW": idsw.astype(np.int64),
        "MT": mt, "PT": pt, "ML": ml.astype(np.int64), "Frag": frag,
        "CLR_Frames": np.broadcast_to(gt.lengths[None, :], (L, S)).astype(np.int64),
        "MOTP_sum": motp_sum,
    }
    return _final_fields(res)


def _switches_and_fragments(b: EvalBatch, key: np.ndarray, m_lf: np.ndarray, m_tid: np.ndarray,
                            m_ls: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """IDSW [L, S] and fragmentations per (lane, GT id) [L, NG] of the matches (``key`` = lane x GT id,
    lane-frame, tracker id, lane x sequence of each)."""
    gt = b.gt
    L, S = b.n_lanes, len(gt.sequences)
    NG = len(gt.gid_count)
    # IDSW: matched tracker id of a GT id changes between consecutive matches (per lane)
    order = np.lexsort((m_lf, key))
    k_s, t_s, ls_s = key[order], m_tid[order], m_ls[order]
    same_gt = k_s[1:] == k_s[:-1]
    idsw_ev = same_gt & (t_s[1:] != t_s[:-1])
    idsw = np.bincount(ls_s[1:][idsw_ev], minlength=L * S).reshape(L, S)

    # Frag: runs of matches over consecutive "active" frames (both GT and tracker boxes present)
    active_lf = (b.lf_eval_count * b.det_count) > 0
    a_idx = np.cumsum(active_lf) - 1  # rank of each active lane-frame
    r_s = a_idx[m_lf[order]]
    cont = same_gt & (r_s[1:] == r_s[:-1] + 1)
    new_run = np.ones(len(order), dtype=bool)
    new_run[1:] = ~cont
    runs = np.bincount(key[order], weights=new_run, minlength=L * max(NG, 1))
    frag_per_gid = np.maximum(runs - 1, 0).reshape(L, max(NG, 1))[:, :NG]
    return idsw, frag_per_gid


def _early_sequences(b: EvalBatch, res: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The fields of the sequences TrackEval returns early for (no tracker dets, or no GT dets)."""
    gt = b.gt
    L, S = b.n_lanes, len(gt.sequences)
    n_gt = np.broadcast_to(gt.n_gt_dets[None, :], (L, S)).astype(np.int64)
    n_tr = b.n_tr_dets
    no_tr, no_gt, early = b.early_sequences
    if early.any():
        for f in FIELDS:
            res[f] = np.array(res[f], copy=True)
            res[f][early] = 0
        res["CLR_FN"][no_tr] = n_gt[no_tr]
        res["ML"][no_tr] = np.broadcast_to(gt.n_gt_ids[None, :], (L, S))[no_tr]
        res["MLR"][early] = 1.0
        res["CLR_FP"][no_gt] = n_tr[no_gt]
    return res


def clear_combine(res: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """TrackEval's ``CLEAR.combine_sequences``: sum ``SUMMED_FIELDS`` over axis 1, recompute the rest.

    res: fields [L, S]; returns fields [L].
    """
    out = {}
    for f in SUMMED_FIELDS:
        acc = np.zeros(res[f].shape[0], dtype=res[f].dtype)
        for s in range(res[f].shape[1]):
            acc = acc + res[f][:, s]
        out[f] = acc
    return _final_fields(out)
