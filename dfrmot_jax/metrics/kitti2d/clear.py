"""CLEAR MOT metrics exactly as TrackEval's ``metrics/clear.py``, batched over configs.

Per frame TrackEval solves ``linear_sum_assignment(-(1000 * continues + sim))`` with entries of
``sim < 0.5 - eps`` zeroed, where ``continues[g, t]`` says tracker ``t`` was matched to GT ``g`` in
the previous frame *that had both GT and tracker boxes* (frames with either empty are skipped and
do not reset it). IDSW counts changes of a GT's matched tracker id (over any gap), Frag counts
re-starts of tracking between consecutive such frames, MT/PT/ML use the tracked ratio
(> 0.8 / >= 0.2).

Only frames where a GT or tracker box has two candidates (IoU >= 0.5) need the solver (the
``continues`` bonus can only matter there), scipy's assignment (:mod:`dfrmot_jax.metrics.common.assignment`).
Every (config, sequence) is one compiled pass over its frames in time order (:func:`clear_sequences`);
the vectorised NumPy path (the other frames' matches at once, then the solver's frames in time
order) is kept as the reference it is tested against. Arrays: ``L`` configs, ``S`` sequences.
"""

from __future__ import annotations

import numba
import numpy as np

from dfrmot_jax.metrics.common.assignment import match_block, solve_block, workspace, workspace_for
from dfrmot_jax.metrics.common.kernel_cache import cached_njit
from dfrmot_jax.metrics.common.pairs import crowded_segments, segment_pairs, segment_rows
from dfrmot_jax.metrics.kitti2d.boxes import EPS
from dfrmot_jax.metrics.kitti2d.kitti import EvalBatch

THRESHOLD = 0.5
MAIN_INTEGER_FIELDS = ("CLR_TP", "CLR_FN", "CLR_FP", "IDSW", "MT", "PT", "ML", "Frag")
INTEGER_FIELDS = MAIN_INTEGER_FIELDS + ("CLR_Frames",)
MAIN_FLOAT_FIELDS = ("MOTA", "MOTP", "MODA", "CLR_Re", "CLR_Pr", "MTR", "PTR", "MLR", "sMOTA")
FLOAT_FIELDS = MAIN_FLOAT_FIELDS + ("CLR_F1", "FP_per_frame", "MOTAL", "MOTP_sum")
FIELDS = FLOAT_FIELDS + INTEGER_FIELDS
SUMMED_FIELDS = INTEGER_FIELDS + ("MOTP_sum",)


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


def _solve_sequential(hard: np.ndarray, b: EvalBatch, sim: np.ndarray, p_gid: np.ndarray, p_tid: np.ndarray,
                      matched: np.ndarray) -> None:
    """Solve the listed lane-frames with TrackEval's continuation bonus (in place), in one compiled
    pass in time order (:func:`_solve_in_order`).

    ``matched`` holds the final matches of every other lane-frame on entry. The bonus of a frame
    needs the matches of the previous frame with both GT and tracker boxes (same lane and
    sequence): final on entry, or solved earlier in the pass.
    """
    hard = np.sort(np.asarray(hard, dtype=np.int64))
    ps = b.pair_start
    matched[segment_pairs(hard, ps)] = False
    nr, nc = b.lf_eval_count[hard], b.det_count[hard]
    status = _solve_in_order(hard, ps.astype(np.int64), nr.astype(np.int64), nc.astype(np.int64),
                             np.ascontiguousarray(sim, dtype=np.float64), p_gid.astype(np.int64), p_tid.astype(np.int64),
                             matched, _prev_active(b), THRESHOLD - EPS, EPS)
    if status != 0:
        raise RuntimeError(f"CLEAR's assignment failed (status {status})")


@cached_njit(nogil=True, calls=("dfrmot_jax.metrics.common.assignment",))
def _solve_in_order(hard, pair_start, n_rows, n_cols, sim, p_gid, p_tid, matched, prev_of, thr, eps):
    """The hard lane-frames (sorted: time order within each lane) one after the other: each frame's
    matrix is TrackEval's ``1000 * continues + sim``, zero where ``sim < thr`` (= 0.5 - eps), where
    ``continues`` says the GT's match in the previous active frame (``prev_of``; final in ``matched``
    by then) is this tracker id; solved as scipy does (:func:`~dfrmot_jax.metrics.common.assignment.
    solve_block`, ``-score`` minimised), the pairs above ``0 + eps`` set in ``matched``."""
    ws = workspace_for(n_rows, n_cols)
    vals = np.empty(len(ws[0]))                  # (the workspace's cost array: the largest block)
    rows = np.empty(len(ws[1]), np.int64)
    cols = np.empty(len(ws[1]), np.int64)
    for h in range(len(hard)):
        lf = hard[h]
        a, r, c = pair_start[lf], n_rows[h], n_cols[h]
        for k in range(r * c):
            s = sim[a + k]
            vals[k] = s if s >= thr else 0.0
        prev = prev_of[lf]
        if prev >= 0:
            pa, pe = pair_start[prev], pair_start[prev + 1]
            for k in range(r * c):
                if vals[k] > 0:
                    g = p_gid[a + k]
                    for q in range(pa, pe):
                        if matched[q] and p_gid[q] == g:
                            if p_tid[q] == p_tid[a + k]:
                                vals[k] += 1000    # TrackEval: 1000 * continues + sim
                            break
        status = solve_block(vals, np.int64(0), r, c, np.bool_(True), np.bool_(False), rows, cols, np.int64(0),
                             ws)                        # (typed arguments: assignment's docstring)
        if status != 0:
            return status
        for k in range(min(r, c)):
            i, j = rows[k], cols[k]
            if vals[i * c + j] > 0 + eps:
                matched[a + i * c + j] = True
    return 0


def clear_sequences(b: EvalBatch) -> dict[str, np.ndarray]:
    """CLEAR fields per (config, sequence): arrays [L, S] (``FIELDS``; counts as int64), from one
    compiled pass per (config, sequence) in time order (:func:`_clear_kernel`): bit for bit
    :func:`clear_sequences_numpy`."""
    gt = b.gt
    L, S = b.n_lanes, len(gt.sequences)
    if not len(b.sim):
        return clear_sequences_numpy(b)
    tp, motp, idsw, mt, pt, frag = _clear_kernel(
        b.ls_lf_start, b.ls_seq, np.ascontiguousarray(b.pair_start, np.int64),
        np.ascontiguousarray(b.lf_eval_count, np.int64), np.ascontiguousarray(b.det_count, np.int64),
        np.ascontiguousarray(b.sim, np.float64), b.p_gid, b.p_tid, np.ascontiguousarray(gt.gid_start, np.int64),
        np.ascontiguousarray(gt.gid_count, np.float64), THRESHOLD - EPS, EPS)
    mt, pt = mt.reshape(L, S), pt.reshape(L, S) - mt.reshape(L, S)
    tp = tp.reshape(L, S)
    res = {
        "CLR_TP": tp,
        "CLR_FN": np.broadcast_to(gt.n_gt_dets[None, :], (L, S)).astype(np.int64) - tp,
        "CLR_FP": (b.n_tr_dets - tp).astype(np.int64),
        "IDSW": idsw.reshape(L, S),
        "MT": mt, "PT": pt, "ML": (gt.n_gt_ids[None, :] - mt - pt).astype(np.int64), "Frag": frag.reshape(L, S),
        "CLR_Frames": np.broadcast_to(gt.lengths[None, :], (L, S)).astype(np.int64),
        "MOTP_sum": motp.reshape(L, S),
    }
    return _early_sequences(b, _final_fields(res))


def clear_sequences_numpy(b: EvalBatch) -> dict[str, np.ndarray]:
    """:func:`clear_sequences` vectorised in NumPy (the frames needing the solver in one compiled pass):
    the reference the compiled pass is tested against."""
    p_gid = b.gt.eval_gid[b.p_e]
    p_tid = b.det_gid[b.p_k]
    matched = _matched_pairs(b, p_gid, p_tid)
    res = _counts(b, matched, p_gid, p_tid)
    return _early_sequences(b, res)


@cached_njit(nogil=True, calls=("dfrmot_jax.metrics.common.assignment",))
def _clear_kernel(ls_lf_start, ls_seq, pair_start, ng, nk, sim, p_gid, p_tid, gid_start, gid_count, thr, eps):
    """TrackEval's CLEAR over the frames of every (config, sequence) ``ls`` in time order: each frame
    with GT and tracker boxes (active) matched: its pairs of ``sim >= thr`` (= 0.5 - eps) where no row
    or column holds two, else those of scipy's assignment (:func:`~dfrmot_jax.metrics.common.assignment.
    match_block`) of ``1000 * continues + sim`` (zero below ``thr``; ``continues``: the GT id was
    matched to this tracker id in the previous active frame), pairs above ``0 + eps``; each match
    counted (TP; its similarity summed, pair order), an IDSW where its GT id's last match had another
    tracker id, a new run where that last match was not in the previous active frame; per GT id,
    its matches over its detections (MT: > 0.8, PT and MT: >= 0.2) and its runs beyond the first
    (Frag). Returns [L*S] arrays: TP, MOTP_sum, IDSW, MT, MT + PT, Frag."""
    n_ls = len(ls_lf_start) - 1
    tp, idsw = np.zeros(n_ls, np.int64), np.zeros(n_ls, np.int64)
    mt, pt, frag = np.zeros(n_ls, np.int64), np.zeros(n_ls, np.int64), np.zeros(n_ls, np.int64)
    motp = np.zeros(n_ls)
    n_g, side, block = np.int64(1), np.int64(1), np.int64(1)   # (typed: assignment's docstring)
    for s in range(len(gid_start) - 1):
        n_g = max(n_g, gid_start[s + 1] - gid_start[s])
    for lf in range(ls_lf_start[n_ls]):
        side = max(side, ng[lf], nk[lf])
        block = max(block, ng[lf] * nk[lf])
    last_tid, last_rank = np.full(n_g, -1, np.int64), np.full(n_g, -2, np.int64)
    matches, runs = np.zeros(n_g, np.int64), np.zeros(n_g, np.int64)
    vals = np.empty(block)
    rows, cols = np.empty(side, np.int64), np.empty(side, np.int64)
    ws = workspace(side, block)
    for ls in range(n_ls):
        g0 = gid_start[ls_seq[ls]]
        rank = 0
        for lf in range(ls_lf_start[ls], ls_lf_start[ls + 1]):
            a, nr, nc = pair_start[lf], ng[lf], nk[lf]
            if nr == 0 or nc == 0:
                continue
            rank += 1
            n = _frame_matches(a, nr, nc, sim, p_gid, p_tid, g0, last_tid, last_rank, rank, thr, eps, vals, rows,
                               cols, ws)
            for k in range(n):
                q = a + rows[k] * nc + cols[k]
                g, t = p_gid[q] - g0, p_tid[q]
                tp[ls] += 1
                motp[ls] += sim[q]
                if last_tid[g] >= 0 and last_tid[g] != t:
                    idsw[ls] += 1
                if last_rank[g] != rank - 1:
                    runs[g] += 1
                matches[g] += 1
                last_tid[g], last_rank[g] = t, rank
        for g in range(gid_start[ls_seq[ls] + 1] - g0):
            ratio = matches[g] / gid_count[g0 + g]
            mt[ls] += ratio > 0.8
            pt[ls] += ratio >= 0.2
            frag[ls] += max(runs[g] - 1, 0)
            last_tid[g], last_rank[g], matches[g], runs[g] = -1, -2, 0, 0
    return tp, motp, idsw, mt, pt, frag


@numba.njit(cache=False, nogil=True)     # (compiled into _clear_kernel, the cached one)
def _frame_matches(a, nr, nc, sim, p_gid, p_tid, g0, last_tid, last_rank, rank, thr, eps, vals, rows, cols, ws):
    """CLEAR's matches of one active frame (pairs ``a .. a + nr * nc``, its rank ``rank`` among its
    sequence's active frames; ``last_tid`` / ``last_rank`` each local GT id's last match): TrackEval's
    matrix ``1000 * continues + sim``, zero below ``thr``, matched by
    :func:`~dfrmot_jax.metrics.common.assignment.match_block` (pairs above ``0 + eps``); (row, column)
    in ``rows``, ``cols`` in row order; returns their number (:func:`_clear_kernel`)."""
    for k in range(nr * nc):
        x = sim[a + k]
        vals[k] = x if x >= thr else 0.0
        if vals[k] > 0:
            g = p_gid[a + k] - g0
            if last_rank[g] == rank - 1 and last_tid[g] == p_tid[a + k]:
                vals[k] += 1000                   # TrackEval: 1000 * continues + sim
    return match_block(vals, nr, nc, eps, rows, cols, ws)


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
    lane-frame, tracker id, lane x sequence of each; the matches in lane-frame order, as the pairs)."""
    gt = b.gt
    L, S = b.n_lanes, len(gt.sequences)
    NG = len(gt.gid_count)
    active_lf = (b.lf_eval_count * b.det_count) > 0
    a_idx = np.cumsum(active_lf) - 1  # rank of each active lane-frame
    idsw, runs = _switch_runs(key.astype(np.int64), m_lf.astype(np.int64), m_tid.astype(np.int64),
                              m_ls.astype(np.int64), a_idx.astype(np.int64), L * max(NG, 1), L * S)
    frag_per_gid = np.maximum(runs - 1, 0).reshape(L, max(NG, 1))[:, :NG]
    return idsw.reshape(L, S), frag_per_gid


@cached_njit(nogil=True)
def _switch_runs(key, m_lf, m_tid, m_ls, rank, n_keys, n_ls):
    """One pass over the matches in time order: IDSW per (lane, sequence) [n_ls] (a GT id's matched
    tracker id differs from its previous match's) and runs per (lane, GT id) [n_keys] float64 (a run
    starts at a GT id's first match and wherever the previous match was not on the previous active
    lane-frame, ``rank`` [L*F] their ranks)."""
    last_tid = np.zeros(n_keys, np.int64)
    last_rank = np.zeros(n_keys, np.int64)
    seen = np.zeros(n_keys, np.bool_)
    idsw = np.zeros(n_ls, np.int64)
    runs = np.zeros(n_keys, np.float64)
    for i in range(key.shape[0]):
        k = key[i]
        r = rank[m_lf[i]]
        if seen[k]:
            if m_tid[i] != last_tid[k]:
                idsw[m_ls[i]] += 1
            if r != last_rank[k] + 1:
                runs[k] += 1.0
        else:
            seen[k] = True
            runs[k] += 1.0
        last_tid[k] = m_tid[i]
        last_rank[k] = r
    return idsw, runs


def _switches_and_fragments_numpy(b: EvalBatch, key: np.ndarray, m_lf: np.ndarray, m_tid: np.ndarray,
                                  m_ls: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_switches_and_fragments` by sorting (the reference the compiled pass is tested against)."""
    gt = b.gt
    L, S = b.n_lanes, len(gt.sequences)
    NG = len(gt.gid_count)
    order = np.lexsort((m_lf, key))
    k_s, t_s, ls_s = key[order], m_tid[order], m_ls[order]
    same_gt = k_s[1:] == k_s[:-1]
    idsw_ev = same_gt & (t_s[1:] != t_s[:-1])
    idsw = np.bincount(ls_s[1:][idsw_ev], minlength=L * S).reshape(L, S)
    active_lf = (b.lf_eval_count * b.det_count) > 0
    a_idx = np.cumsum(active_lf) - 1
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
