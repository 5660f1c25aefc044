"""AB3DMOT's evaluation passes, all thresholds of one output at once (the rules:
:mod:`dfrmot_jax.metrics.samota.evaluate`).

The reference runs ~42 passes, each a full per-frame assignment and count. Most of a pass is fixed
by the candidate pairs, which do not change between passes; only which tracks are kept changes
(a track's averaged score against the pass's threshold). So the passes are computed together, as
``[P, ...]`` arrays over passes ``P``:

* **Kept tracks** ``kept [P, T]``: the track scores of every averaging round are known before any
  pass (the averaging never looks at matches), so ``kept[j] = ~(score_j < thr_j)``.
* **Matches.** A candidate pair alone in its connected component is matched exactly when its
  track is kept; components of two or more pairs are solved per pass (scipy's
  ``linear_sum_assignment``, cached per component and kept-column subset).
* **Counts** in track space: TP and the non-ignored TP are ``kept @ (pairs per track)`` plus the
  components'; a kept row is "ignored" when unmatched, never matched before (the reference's
  sticky ``valid`` flag) and neighbour / small / in DontCare: a row with a lone pair is matched
  whenever kept, so only rows without pairs (``kept @ count per track``) and component rows
  (explicit) can be; ``FP = kept rows - TP - ignored``.
* **IDS / FRAG** (the reference's trajectory loop, :func:`ids_frag`): an id switch at frame ``f``
  needs frames ``f - 1`` and ``f`` matched to different tracks, a fragmentation the same of
  ``f - 1`` / ``f`` / ``f + 1`` and an earlier match since the last ignored frame. Whether a
  frame *can* be matched, and to which track if its only pair is lone, is fixed; so only the few
  frames where a trajectory's candidate changes can count, and "an earlier match since the last
  ignored frame" is the earliest kept candidate of the stretch: all of it ``[P, Q]`` gathers.
* **MOTP's sum** is the reference's sequential float sum over the matched pairs in (frame, object,
  row) order, per pass: a row-wise ``cumsum`` of ``[P, E]`` with zeros off the matches (adding 0.0
  changes no float), bit-identical to summing the matched values alone.

Shapes: T tracks, E candidate pairs, N ground-truth objects, P passes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from .sums import DEFAULT_SUM, group_sums, other_sum, parse_sum, repeat_sums
from dfrmot_jax.metrics.common.pairs import segment_starts

__all__ = ["N_SAMPLE_POINTS", "ALL_TRACKS", "PASS_FIELDS", "score_rounds", "track_means", "thresholds", "TrajLayout",
           "traj_layout", "ids_frag", "run_passes", "run_passes_many"]

N_SAMPLE_POINTS = 41
ALL_TRACKS = -10000.0          # the reference's threshold of the pass that keeps every track
_NO = np.iinfo(np.int64).max


def score_rounds(mean: np.ndarray, n: np.ndarray, rounds: int, sum_mode: str = DEFAULT_SUM) -> np.ndarray:
    """The reference's track scores after 0..rounds averaging rounds -> [rounds + 1, T].

    mean [T]: round 0 (each track's mean row score); n [T] rows per track. A round replaces each
    score by the ``sum`` of ``n`` copies of it divided by ``n`` (its per-pass re-averaging of already
    averaged scores; the sum as ``sum_mode``'s interpreters compute it, :mod:`.sums`); a score that a
    round leaves unchanged stays (the reference stops at that fixed point), so only the others are
    recomputed. Tracks with ``n == 0`` keep their score."""
    out = np.empty((rounds + 1, len(mean)))
    out[0] = mean
    live = np.flatnonzero(n > 0)
    for r in range(1, rounds + 1):
        out[r] = out[r - 1]
        if live.size:
            cur = out[r - 1, live]
            with np.errstate(invalid="ignore", divide="ignore"):
                new = repeat_sums(cur, n[live], sum_mode) / n[live]
            out[r, live] = new
            live = live[~(new == cur)]
    return out


def track_means(preps: list, sum_mode: str = DEFAULT_SUM) -> list[np.ndarray]:
    """Each prepared output's track scores before any pass: ``sum(row scores) / len`` per track, the
    rows in file order, the sum as ``sum_mode``'s interpreters compute it; one call for all outputs
    -> a [n_tracks] array per output."""
    n = np.array([p.trk.n_tracks for p in preps], dtype=np.int64)
    starts = segment_starts(n)
    score = np.concatenate([p.trk.score for p in preps]) if preps else np.zeros(0)
    track = np.concatenate([p.trk.track + starts[i] for i, p in enumerate(preps)]) if preps else np.zeros(0, np.int64)
    length = np.concatenate([p.track_len for p in preps]) if preps else np.zeros(0, np.int64)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = group_sums(score, track, int(starts[-1]), sum_mode) / length
    return [mean[starts[i]:starts[i + 1]] for i in range(len(preps))]


def thresholds(scores: np.ndarray, num_gt: int) -> tuple[list, list]:
    """The reference's ``getThresholds``: (thresholds, recall points) from pass 0's matched scores."""
    s = np.sort(np.asarray(scores, dtype=np.float64))[::-1]
    n = len(s)
    if n == 0:
        return [], []
    i = np.arange(n)
    left = (i + 1) / float(num_gt)
    right = np.where(i < n - 1, (i + 2) / float(num_gt), left)
    thr, rec = [], []
    cur, pos, step = 0, 0, 1 / (N_SAMPLE_POINTS - 1.0)
    while pos < n:
        take = ~((right[pos:] - cur) < (cur - left[pos:])) | (i[pos:] == n - 1)
        j = pos + int(np.argmax(take))
        thr.append(float(s[j]))
        rec.append(cur)
        cur += step
        pos = j + 1
    return thr[1:], rec[1:]


@dataclass(eq=False)
class TrajLayout:
    """The frames of the object trajectories where IDS / FRAG can count (:func:`ids_frag`).

    Objects are taken in trajectory order (by trajectory, then frame): position ``p`` is object
    ``order[p]``. ``cand`` [N] per position: the track of its one lone pair, -1 without pairs
    (never matched), -2 when matched through a component (any track, per pass). ``q_ids`` [Qi],
    ``q_frag`` [Qf], ``q_end`` [Qe]: positions where an id switch / a fragmentation / a last-frame
    fragmentation can count. Stretches between resets (a trajectory's first frame, an ignored
    frame) for the fragmentation's "an earlier match": ``pair_unit`` [U] the unit (a track, or
    ``T + component object``) of each (stretch, unit) pair, ``pair_first`` [U] its earliest
    position, grouped by stretch from ``pair_start`` [S']; ``frag_stretch`` [Qf] each candidate's
    stretch among them.
    """
    order: np.ndarray
    cand: np.ndarray
    q_ids: np.ndarray
    q_frag: np.ndarray
    q_end: np.ndarray
    pair_unit: np.ndarray
    pair_first: np.ndarray
    pair_start: np.ndarray
    frag_stretch: np.ndarray


def traj_layout(order: np.ndarray, traj: np.ndarray, ignored: np.ndarray, cand_obj: np.ndarray, n_units: int,
                comp_index: np.ndarray) -> TrajLayout:
    """The :class:`TrajLayout` of objects ``order`` ([N] trajectory order) with trajectory ``traj``
    [N], ``ignored`` [N] and ``cand_obj`` [N] (per object, see ``TrajLayout.cand``); ``n_units`` =
    T (units of component objects are ``T + comp_index[object]``)."""
    c = cand_obj[order]
    tr = traj[order]
    ign = ignored[order]
    n = len(order)
    first = np.ones(n, dtype=bool)
    first[1:] = tr[1:] != tr[:-1]
    last = np.ones(n, dtype=bool)
    last[:-1] = tr[1:] != tr[:-1]
    prev_c = np.roll(c, 1)
    next_c = np.roll(c, -1)
    same = (c >= 0) & (prev_c == c)                  # lone pairs of one track: always equal (both -1 or both t)
    body = ~first & ~ign & (c != -1) & ~same
    prev_counts = np.roll(first | ~ign, 1)           # the previous frame sets ``last`` (first, or not ignored)
    q_ids = np.flatnonzero(body & prev_counts & (prev_c != -1))
    q_frag = np.flatnonzero(body & ~last & (next_c != -1))
    q_end = np.flatnonzero(body & last)
    # stretches: a new one at a first frame or an ignored frame (which itself never counts as a match)
    reset = first | ign
    stretch = np.cumsum(reset) - 1
    counted = np.flatnonzero((first | ~ign) & (c != -1))
    unit = np.where(c[counted] >= 0, c[counted], n_units + comp_index[order[counted]])
    need = np.zeros(int(stretch[-1]) + 1 if n else 0, dtype=bool)
    need[stretch[q_frag]] = True
    keep = need[stretch[counted]]
    counted, unit = counted[keep], unit[keep]
    key_s = stretch[counted]
    o = np.lexsort((counted, unit, key_s))
    ks, ku, kp = key_s[o], unit[o], counted[o]
    new = np.ones(len(o), dtype=bool)
    new[1:] = (ks[1:] != ks[:-1]) | (ku[1:] != ku[:-1])
    ps, pu, pf = ks[new], ku[new], kp[new]
    used, pos = np.unique(ps, return_index=True)
    return TrajLayout(order=order, cand=c, q_ids=q_ids, q_frag=q_frag, q_end=q_end, pair_unit=pu, pair_first=pf,
                      pair_start=np.append(pos, len(ps)).astype(np.int64),
                      frag_stretch=np.searchsorted(used, stretch[q_frag]))


def _g(lay: TrajLayout, pos: np.ndarray, kept: np.ndarray, comp_g: np.ndarray, comp_index: np.ndarray) -> np.ndarray:
    """Matched track per pass at trajectory positions ``pos`` -> [P, len(pos)] (-1: unmatched)."""
    c = lay.cand[pos]
    lone = kept[:, np.maximum(c, 0)] if kept.shape[1] else np.zeros((kept.shape[0], len(c)), dtype=bool)
    g = np.where((c >= 0) & lone, c, -1)
    comp = np.flatnonzero(c == -2)
    if comp.size:
        g[:, comp] = comp_g[:, comp_index[lay.order[pos[comp]]]]
    return g


def ids_frag(lay: TrajLayout, kept: np.ndarray, comp_g: np.ndarray, comp_index: np.ndarray) -> tuple:
    """The reference's id switches and fragmentations of every pass -> ([P] IDS, [P] FRAG).

    kept [P, T] bool; comp_g [P, Nc] matched track of each component object (-1 none); comp_index
    [N] object -> column of comp_g. The reference's loop (per trajectory g[0..n-1] with ignore flags;
    ``last`` = g[0]; at f >= 1 an ignored frame sets last = -1 and counts nothing; else an id switch
    when last != g[f] != -1, last != -1 and g[f-1] != -1; a fragmentation when f < n-1,
    g[f-1] != g[f] != -1, last != -1 and g[f+1] != -1; then last = g[f] if matched; after the loop
    one more fragmentation when n > 1, frame n-1 is not ignored, g[n-1] != -1 and g[n-2] != g[n-1])
    reads as: ``last != -1`` at f iff a frame of f's stretch before f is matched (see the module
    docstring); ``last`` equals g[f-1] when that is matched and counts."""
    P = kept.shape[0]
    qi = lay.q_ids
    gi, gp = _g(lay, qi, kept, comp_g, comp_index), _g(lay, qi - 1, kept, comp_g, comp_index)
    ids = ((gi != -1) & (gp != -1) & (gi != gp)).sum(axis=1)
    qe = lay.q_end
    ge, gep = _g(lay, qe, kept, comp_g, comp_index), _g(lay, qe - 1, kept, comp_g, comp_index)
    frag = ((ge != -1) & (gep != ge)).sum(axis=1)
    qf = lay.q_frag
    if qf.size:
        g0, gm, gn = (_g(lay, qf + d, kept, comp_g, comp_index) for d in (0, -1, 1))
        units = np.concatenate([kept, comp_g != -1], axis=1)[:, lay.pair_unit]       # [P, U]
        earliest = np.minimum.reduceat(np.where(units, lay.pair_first, _NO), lay.pair_start[:-1], axis=1)
        before = earliest[:, lay.frag_stretch] < qf
        frag = frag + ((g0 != -1) & (gn != -1) & (gm != g0) & before).sum(axis=1)
    return ids.astype(np.int64).reshape(P), frag.astype(np.int64).reshape(P)


class _Structure:
    """What every pass of one output shares (from :class:`~dfrmot_jax.metrics.samota.Ab3dPrepared`)."""

    def __init__(self, prep):
        gt, trk = prep.gt, prep.trk
        T = trk.n_tracks
        self.prep = prep
        self.edge_track = trk.track[prep.e_t]
        triv = prep.trivial
        ign_obj = gt.ignored[prep.e_g]
        self.tp_t = np.bincount(self.edge_track[triv], minlength=T)
        self.tpn_t = np.bincount(self.edge_track[triv & ~ign_obj], minlength=T)
        has_pair = np.zeros(len(trk.frame), dtype=bool)
        has_pair[prep.e_t] = True
        self.free_ign_t = np.bincount(trk.track[prep.trk_static_ignore & ~has_pair], minlength=T)
        self.rows_t = prep.track_len
        self.vals = 1.0 - prep.e_c
        self.triv = triv
        self.n_gt = int((~gt.ignored).sum())
        # components: their rows and objects
        N = len(gt.frame)
        comp_obj = np.concatenate([c[0] for c in prep.comps]) if prep.comps else np.zeros(0, np.int64)
        self.comp_rows = np.concatenate([c[1] for c in prep.comps]) if prep.comps else np.zeros(0, np.int64)
        self.comp_index = np.full(N, -1, dtype=np.int64)
        self.comp_index[comp_obj] = np.arange(len(comp_obj))
        self.n_comp_obj = len(comp_obj)
        self.comp_row_index = np.full(len(trk.frame), -1, dtype=np.int64)
        self.comp_row_index[self.comp_rows] = np.arange(len(self.comp_rows))
        self.cache: dict = {}
        cand = np.full(N, -1, dtype=np.int64)
        cand[prep.e_g[triv]] = self.edge_track[triv]
        cand[comp_obj] = -2
        self.layout = traj_layout(gt.traj_order, gt.traj, gt.ignored, cand, T, self.comp_index)

    def _components(self, kept: np.ndarray) -> list:
        """Per pass, the matched pairs of the components (edge indices) -> list of P arrays."""
        p = self.prep
        out = []
        for j in range(kept.shape[0]):
            hits = []
            for c, (_, rows, idx, cost) in enumerate(p.comps):
                k = kept[j, p.trk.track[rows]]
                key = (c, k.tobytes())
                hit = self.cache.get(key)
                if hit is None:
                    cols = np.flatnonzero(k)
                    if cols.size:
                        r, cc = linear_sum_assignment(cost[:, cols])
                        e = idx[r, cols[cc]]
                        hit = e[e >= 0]
                    else:
                        hit = np.zeros(0, np.int64)
                    self.cache[key] = hit
                hits.append(hit)
            out.append(np.concatenate(hits) if hits else np.zeros(0, np.int64))
        return out

    def counts(self, kept: np.ndarray, valid: np.ndarray) -> tuple[dict, np.ndarray]:
        """Counts of passes ``kept`` [P, T] (in order), component rows matched before them ``valid``
        [Rc] -> ({field: [P]}, valid after them)."""
        p = self.prep
        P = kept.shape[0]
        comp_on = self._components(kept)
        ign_obj = p.gt.ignored
        tp = kept @ self.tp_t + np.array([len(e) for e in comp_on], dtype=np.int64)
        tpn = kept @ self.tpn_t + np.array([int((~ign_obj[p.e_g[e]]).sum()) for e in comp_on], dtype=np.int64)
        ignored = kept @ self.free_ign_t
        comp_g = np.full((P, self.n_comp_obj), -1, dtype=np.int64)
        on = np.zeros((P, len(self.vals)), dtype=bool)
        on[:, self.triv] = kept[:, self.edge_track[self.triv]]
        if len(self.comp_rows):
            rc = self.comp_rows
            static = p.trk_static_ignore[rc]
            k_rows = kept[:, p.trk.track[rc]]
            for j, e in enumerate(comp_on):
                on[j, e] = True
                comp_g[j, self.comp_index[p.e_g[e]]] = self.edge_track[e]
                valid = valid.copy()
                valid[self.comp_row_index[p.e_t[e]]] = True
                ignored[j] += int((k_rows[j] & static & ~valid).sum())
        if len(self.vals):
            w = np.where(on, self.vals, 0.0)
            total = np.add.accumulate(w, axis=1, out=w)[:, -1].copy()
        else:
            total = np.zeros(P)
        ids, frag = ids_frag(self.layout, kept, comp_g, self.comp_index)
        matched_scores = [on[j] for j in range(P)]
        return dict(TP=tp, FN=self.n_gt - tpn, FP=kept @ self.rows_t - tp - ignored, IDS=ids, FRAG=frag,
                    TP_ignored=tp - tpn, total=total, on=matched_scores), valid


def _figures(c: dict, j: int, n_gt: int, recall: float) -> dict:
    """One pass's figures from its counts, in the reference's Python float arithmetic."""
    tp, fn, fp, ids, frag = (int(c[k][j]) for k in ("TP", "FN", "FP", "IDS", "FRAG"))
    if n_gt == 0:
        mota = smota = -math.inf
    else:
        mota = 1 - (fn + fp + ids) / float(n_gt)
        smota = min(1, max(0, 1 - (fn + fp + ids - (1 - recall) * n_gt) / float(recall * n_gt)))
    motp = float(c["total"][j]) / float(tp) if tp else 0
    if (fp + tp) == 0 or (tp + fn) == 0:
        rec = prec = 0.0
    else:
        rec, prec = tp / float(tp + fn), tp / float(fp + tp)
    return dict(MOTA=mota, MOTP=motp, sMOTA=smota, IDS=ids, FRAG=frag, FP=fp, FN=fn, TP=tp, recall=rec,
                precision=prec)


#: the columns of a result's per-pass table (``res["passes"]``, :func:`run_passes_many`): the recall
#: point ``r`` and the score threshold of each pass, the recall reached, the pass's counts and
#: figures, ``TP_ignored`` (matches to ignored ground truth: neighbouring class, truncated or
#: occluded objects, in TP and so in the recall that places the points, but not in sMOTA's
#: denominator) and ``drifted`` (tracks whose first mean is at or above the threshold but whose
#: re-averaged score is below it: dropped by the sequential sum's drift; 0 with the compensated one
#: wherever its re-average is a fixed point)
PASS_FIELDS = ("recall_point", "threshold", "recall", "precision", "TP", "FP", "FN", "IDS", "FRAG", "MOTA", "MOTP",
               "sMOTA", "TP_ignored", "drifted")


def run_passes(prep, sum_mode: str = DEFAULT_SUM, other: bool = False) -> dict:
    """The reference's full evaluation of one prepared output (:mod:`dfrmot_jax.metrics.samota.evaluate`)."""
    return run_passes_many([prep], sum_mode, other)[0]


def run_passes_many(preps: list, sum_mode: str = DEFAULT_SUM, other: bool = False) -> list[dict]:
    """:func:`run_passes` of several prepared outputs, each mode's track means in one call.

    sum_mode: how the evaluator's ``sum`` adds the track scores (:mod:`.sums`); other: also the
    figures with the other sum, under ``"other"`` (a result dict of its own, without ``other``).
    Each result names its ``sum``; ``passes``: its per-pass table ({:data:`PASS_FIELDS` field: list})."""
    sum_mode = parse_sum(sum_mode)
    modes = (sum_mode, other_sum(sum_mode)) if other else (sum_mode,)
    structs = [_Structure(prep) for prep in preps]
    out = [None] * len(preps)
    for mode in modes:
        res = _run_mode(preps, structs, mode)
        for i, r in enumerate(res):
            if mode == sum_mode:
                out[i] = r
            else:
                out[i]["other"] = r
    return out


def _run_mode(preps: list, structs: list, sum_mode: str) -> list[dict]:
    """Every pass of each output with one sum (``structs``: their :class:`_Structure`, shared by the modes)."""
    means = track_means(preps, sum_mode)
    first_passes = []
    for prep, st, mean in zip(preps, structs, means):
        valid = np.zeros(len(st.comp_rows), dtype=bool)
        c0, valid = st.counts(~(mean < ALL_TRACKS)[None], valid)
        first = _figures(c0, 0, st.n_gt, 1.0)
        num_gt = first["TP"] + first["FN"]
        matched = mean[st.edge_track[c0["on"][0]]]
        thr, rec = thresholds(matched, num_gt) if num_gt else ([], [])
        first_passes.append((st, valid, first, thr, rec))
    n_rounds = max(len(f[3]) for f in first_passes) + 1 if preps else 0
    starts = segment_starts(np.array([len(m) for m in means], dtype=np.int64))
    all_rounds = score_rounds(np.concatenate(means) if preps else np.zeros(0),
                              np.concatenate([p.track_len for p in preps]) if preps else np.zeros(0, np.int64),
                              n_rounds, sum_mode)
    out = []
    for i, (prep, (st, valid, first, thr, rec)) in enumerate(zip(preps, first_passes)):
        rounds = all_rounds[:, starts[i]:starts[i + 1]]
        s_smota = s_mota = s_motp = 0
        best_mota, best_thr = 0, ALL_TRACKS
        passes = {k: [] for k in PASS_FIELDS}
        if thr:
            t_arr = np.asarray(thr)[:, None]
            scored = rounds[1:len(thr) + 1]
            kept = ~(scored < t_arr)
            drifted = ((~(rounds[0] < t_arr)) & ~kept).sum(axis=1)
            c, valid = st.counts(kept, valid)
            for j, (t, r) in enumerate(zip(thr, rec)):
                f = _figures(c, j, st.n_gt, r)
                s_smota += f["sMOTA"]
                s_mota += f["MOTA"]
                s_motp += f["MOTP"]
                if f["MOTA"] > best_mota:
                    best_thr, best_mota = t, f["MOTA"]
                row = dict(f, recall_point=r, threshold=t, TP_ignored=int(c["TP_ignored"][j]),
                           drifted=int(drifted[j]))
                for k in PASS_FIELDS:
                    passes[k].append(row[k])
        cb, _ = st.counts(~(rounds[len(thr) + 1] < best_thr)[None], valid)
        best = _figures(cb, 0, st.n_gt, 1.0)
        keys = ("MOTA", "MOTP", "IDS", "FRAG", "FP", "FN", "TP")
        res = {"sAMOTA": s_smota / (N_SAMPLE_POINTS - 1), "AMOTA": s_mota / (N_SAMPLE_POINTS - 1),
               "AMOTP": s_motp / (N_SAMPLE_POINTS - 1)}
        res.update({k: best[k] for k in keys})
        res.update(recall=best["recall"], precision=best["precision"], best_threshold=float(best_thr),
                   n_recall_points=len(thr), all_tracks={k: first[k] for k in keys + ("recall",)},
                   n_rows=len(prep.trk.frame), n_objects=st.n_gt, sum=sum_mode, passes=passes)
        out.append(res)
    return out
