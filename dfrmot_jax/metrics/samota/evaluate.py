"""AB3DMOT's KITTI 3D MOT metrics (sAMOTA, AMOTA, AMOTP and its best-threshold CLEAR figures), exactly.

The reference is ``scripts/KITTI/evaluate.py`` of xinshuoweng/AB3DMOT (the KITTI devkit's
``trackingEvaluation`` with 3D IoU and recall-averaged metrics), reimplemented independently,
vectorised, with every preprocessing step (reading, filtering, IoU, DontCare overlap, graph
components) done once and shared by its ~42 evaluation passes. Inputs are read by
:mod:`dfrmot_jax.metrics.samota.prep` (its docstring: which rows load, what is ignored, the
3D-field and seqmap rules). Per pass, for a score threshold ``thr``:

1. **Track scores.** Every row's score becomes the mean score of its track (per sequence); tracks
   whose mean is ``< thr`` are dropped whole.
2. **Matching, per frame.** Cost ``c = 1 - IoU`` between ground-truth objects (ignored ones
   included) and kept tracker rows, IoU the image-box IoU (``2d``) or the 3D IoU of the rotated
   boxes (``3d``, :mod:`dfrmot_jax.metrics.common.box3d`); pairs with ``c <= 1 - T`` (T the IoU
   threshold, in floats) are candidates, others cost 1e9. The reference's Munkres on that matrix
   maximises the number of candidate pairs, then minimises their cost; here the same optimum per
   connected component of the candidate graph (one pair: matched outright; larger:
   ``scipy.optimize.linear_sum_assignment``, cached per component and kept-column subset).
3. **Ignoring.** An unmatched kept tracker row is ignored when it is of the neighbouring class,
   its image box is at most 25 px high (``|y1 - y2|``), or more than half of its image box lies
   in a DontCare region (2D, also in 3D mode); "unmatched" is the reference's sticky ``valid``
   flag: a row matched in *any earlier pass* is never ignored again (the tracker objects are
   shared by the passes and the flag is not reset). A ground-truth object with occlusion > 2,
   truncation > 0 or of the neighbouring class is ignored (matched or not).
4. **Counts.** ``TP`` = matches (ignored objects' included, as the reference prints it), ``FN`` =
   unmatched non-ignored objects, ``FP`` = kept rows - matches - ignored rows, ``n_gt`` = non-ignored
   objects; ``IDS`` / ``FRAG`` from each object trajectory's per-frame matched track (the
   reference's trajectory pass: a frame of an ignored object resets the last id; its exact rules
   in :func:`~dfrmot_jax.metrics.samota.passes.ids_frag`); ``MOTA = 1 - (FN + FP + IDS) / n_gt``,
   ``MOTP`` = sum of matched IoUs (``1 - c``) / TP,
   ``sMOTA = min(1, max(0, 1 - (FN + FP + IDS - (1 - r) n_gt) / (r n_gt)))``.

The evaluation: pass 0 keeps every track (``thr = -10000``, ``r = 1``); its matched rows' scores,
sorted descending, give up to 40 thresholds at recall ``0.025 k`` (``getThresholds``: a score is
taken when the running recall point is nearer its own recall than the next one's; the first, at
recall 0, is dropped); one pass per threshold (in that order: descending scores), each with
``r`` its recall point; ``sAMOTA``, ``AMOTA``, ``AMOTP`` = sums of sMOTA, MOTA, MOTP over these
passes / 40 (missing recall points count 0); the best threshold is the first with the largest
MOTA > 0 (else -10000), and a last pass at it gives the printed ``MOTA MOTP IDS FRAG FP FN TP``.

Quirks of the reference that are reproduced (and tested on its figures):

* the sticky ``valid`` flag above: the best-threshold pass can count more FP than pass 0 at the
  same threshold (published 2D val: 251 vs 250);
* the score averaging is repeated each pass on the already averaged scores: the mean of ``n``
  copies of a float is computed again (a sequential float sum / n, Python's ``sum`` before 3.12),
  which may move it by an ulp and so drop a track at the threshold that is its own score. Every
  fixture line depends on it (averaging once changes all ten); under Python >= 3.12, whose
  ``sum`` of floats is compensated, the reference itself would print other figures;
* ``num_gt`` for the recall points is pass 0's ``TP + FN``, with ignored TPs in TP;
* ``MOTP`` counts ignored TPs' overlaps; sums are accumulated in the reference's order
  (frames, then objects; passes in order), as float64 like Python's floats;
* the per-frame sanity checks and MT/PT/ML are not reproduced (not printed in the figures used).

Ties: on an exactly tied optimum the reference's Munkres and scipy may choose different pairs;
on the fixtures (two outputs x 2D/3D x two splits) the figures agree to the last printed digit.
The reference crashes on a result box identical to its ground-truth box (Qhull error in its
polygon clipping); here the IoU is 1.

Results are dicts of fractions (percent = x 100): ``sAMOTA AMOTA AMOTP MOTA MOTP`` float,
``IDS FRAG FP FN TP`` int, ``recall precision best_threshold`` float, ``n_recall_points`` int,
``all_tracks`` (pass 0: ``MOTA MOTP IDS FRAG FP FN TP recall``), ``n_rows`` (tracker rows of the
class read) and ``n_objects`` (ground-truth objects not ignored: MOTA's denominator).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from dfrmot_jax.choices import parse_iou
from .passes import run_passes
from .sums import DEFAULT_SUM
from .prep import MIN_HEIGHT, Ab3dGT, Ab3dTracker, cached_ab3dmot_gt, read_ab3dmot_results, read_seqmap
from dfrmot_jax.metrics.common.box3d import iou_3d
from dfrmot_jax.metrics.common.pairs import enumerate_pairs, segment_starts
from dfrmot_jax.metrics.common.sequences import cached_class_sequences
from dfrmot_jax.paths import default_data_root

__all__ = ["AB3DMOT_FIELDS", "parse_iou", "Ab3dPrepared", "prepare_passes", "static_ignore", "iou_2d_pairs", "ab3dmot_metrics",
           "evaluate_ab3dmot", "evaluate_ab3dmot_files"]

#: the figures of one evaluation (fractions except counts), in the order the CLI writes them
AB3DMOT_FIELDS = ("sAMOTA", "AMOTA", "AMOTP", "MOTA", "MOTP", "IDS", "FRAG", "FP", "FN", "TP")
_MAX_COST = 1e9


def iou_2d_pairs(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The reference's ``boxoverlap(a, b)`` (union criterion) for pairs of [P, 4] image boxes."""
    w = np.minimum(a[:, 2], b[:, 2]) - np.maximum(a[:, 0], b[:, 0])
    h = np.minimum(a[:, 3], b[:, 3]) - np.maximum(a[:, 1], b[:, 1])
    hit = (w > 0) & (h > 0)
    inter = w * h
    union = (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1]) + (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1]) - inter
    out = np.zeros(len(a))
    np.divide(inter, union, out=out, where=hit & (union != 0))
    return out


def _ioa(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The reference's ``boxoverlap(a, b, 'a')``: intersection over the area of ``a`` ([P, 4] pairs)."""
    w = np.minimum(a[:, 2], b[:, 2]) - np.maximum(a[:, 0], b[:, 0])
    h = np.minimum(a[:, 3], b[:, 3]) - np.maximum(a[:, 1], b[:, 1])
    area = (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])
    out = np.zeros(len(a))
    np.divide(w * h, area, out=out, where=(w > 0) & (h > 0) & (area != 0))
    return out


@dataclass(eq=False)
class Ab3dPrepared:
    """Everything the passes share, for one (ground truth, tracker output, IoU kind and threshold).

    Candidate pairs (E, by frame then object then row): ``e_g`` [E] object, ``e_t`` [E] tracker
    row, ``e_c`` [E] cost ``1 - IoU``. ``trivial`` [E] bool: the pair is its component alone.
    Components of two or more pairs (C): ``comp_edges`` [E_nt] edge indices grouped by component,
    ``comp_start`` [C+1]; ``comps``: per component (objects, rows, edge-index matrix [n_obj, n_row]
    with -1 off the candidates, cost matrix with 1e9 off them). ``trk_static_ignore`` [M] bool
    (neighbour class, <= 25 px, or in DontCare). ``track_len`` [n_tracks] rows per track (the
    tracks' scores are averaged by the passes, with the chosen sum: :func:`~.passes.track_means`).
    """
    gt: Ab3dGT
    trk: Ab3dTracker
    kind: str
    threshold: float
    e_g: np.ndarray
    e_t: np.ndarray
    e_c: np.ndarray
    trivial: np.ndarray
    comp_edges: np.ndarray
    comp_start: np.ndarray
    comps: list
    trk_static_ignore: np.ndarray
    track_len: np.ndarray


def _candidate_pairs(gt: Ab3dGT, trk: Ab3dTracker, kind: str, threshold: float):
    F = gt.n_frames
    nt = np.bincount(trk.frame, minlength=F)
    t_start = segment_starts(nt)
    seg, row, col, _ = enumerate_pairs(np.diff(gt.start), gt.start[:-1], nt, t_start[:-1])
    if kind == "2d":
        iou = iou_2d_pairs(gt.box[row], trk.box[col])
    else:
        iou = np.zeros(len(row))
        live = np.flatnonzero(trk.has3d[col])
        if live.size:
            iou[live] = iou_3d(gt.box3d[row[live]], trk.box3d[col[live]])
    cost = 1.0 - iou
    ok = cost <= 1.0 - threshold
    return row[ok], col[ok], cost[ok]


def static_ignore(gt: Ab3dGT, frame: np.ndarray, box: np.ndarray, neighbour: np.ndarray) -> np.ndarray:
    """The static part of the tracker-ignore rule for rows (any order; global ``frame`` [M], image ``box``
    [M, 4], ``neighbour`` [M] bool): of the neighbouring class, at most 25 px high (``|y1 - y2|``),
    or more than half inside a DontCare region -> [M] bool."""
    static = neighbour | (np.abs(box[:, 1] - box[:, 3]) <= MIN_HEIGHT)
    by_frame = np.argsort(frame, kind="stable")            # rows in any order
    nt = np.bincount(frame, minlength=gt.n_frames)
    t_start = segment_starts(nt)
    _, drow, dcol, _ = enumerate_pairs(nt, t_start[:-1], np.diff(gt.dc_start), gt.dc_start[:-1])
    if len(drow):
        drow = by_frame[drow]
        inside = _ioa(box[drow], gt.dc_box[dcol]) > 0.5
        static[drow[inside]] = True
    return static


def prepare_passes(gt: Ab3dGT, trk: Ab3dTracker, kind: str = "3d", threshold: float = 0.25,
                   pairs: tuple | None = None, static: np.ndarray | None = None) -> Ab3dPrepared:
    """The shared preprocessing of :func:`ab3dmot_metrics` (see :class:`Ab3dPrepared`).

    Computed for many outputs at once by :mod:`dfrmot_jax.metrics.samota.arrays`, and then given:
    pairs, the candidate pairs ``(e_g, e_t, e_c)`` (by frame, object, row); static, the rows'
    :func:`static_ignore`."""
    kind, threshold = parse_iou((kind, threshold))
    N, M = len(gt.frame), len(trk.frame)
    e_g, e_t, e_c = _candidate_pairs(gt, trk, kind, threshold) if pairs is None else pairs
    if static is None:
        static = static_ignore(gt, trk.frame, trk.box, trk.neighbour)
    # components of the candidate graph
    E = len(e_g)
    trivial = np.ones(E, dtype=bool)
    comps, comp_edges, comp_start = [], np.zeros(0, np.int64), np.zeros(1, np.int64)
    if E:
        deg_g = np.bincount(e_g, minlength=N)
        deg_t = np.bincount(e_t, minlength=M)
        trivial = (deg_g[e_g] == 1) & (deg_t[e_t] == 1)
        hard = np.flatnonzero(~trivial)
        if hard.size:
            graph = coo_matrix((np.ones(hard.size), (e_g[hard], N + e_t[hard])), shape=(N + M, N + M))
            _, label = connected_components(graph, directed=False)
            lab = label[e_g[hard]]
            order = np.argsort(lab, kind="stable")         # edges stay in (frame, object, row) order
            comp_edges = hard[order]
            _, counts = np.unique(lab[order], return_counts=True)
            comp_start = segment_starts(counts)
            for c in range(len(counts)):
                ed = comp_edges[comp_start[c]:comp_start[c + 1]]
                objs, gi = np.unique(e_g[ed], return_inverse=True)
                rows, ti = np.unique(e_t[ed], return_inverse=True)
                idx = np.full((len(objs), len(rows)), -1, dtype=np.int64)
                idx[gi, ti] = ed
                cost = np.full((len(objs), len(rows)), _MAX_COST)
                cost[gi, ti] = e_c[ed]
                comps.append((objs, rows, idx, cost))
    track_len = np.bincount(trk.track, minlength=trk.n_tracks)
    return Ab3dPrepared(gt=gt, trk=trk, kind=kind, threshold=threshold, e_g=e_g, e_t=e_t, e_c=e_c, trivial=trivial,
                        comp_edges=comp_edges, comp_start=comp_start, comps=comps, trk_static_ignore=static,
                        track_len=track_len)


def ab3dmot_metrics(prep: Ab3dPrepared, sum_mode: str = DEFAULT_SUM, other: bool = False) -> dict:
    """The reference's full evaluation on prepared inputs (module docstring) -> dict of figures;
    its passes computed together (:mod:`dfrmot_jax.metrics.samota.passes`). sum_mode: the
    evaluator's ``sum`` of track scores (:mod:`~dfrmot_jax.metrics.samota.sums`: ``"compensated"``,
    CPython >= 3.12, the default; ``"sequential"``, CPython <= 3.11); other: also the other sum's
    figures, under ``"other"``."""
    return run_passes(prep, sum_mode, other)


def evaluate_ab3dmot(gt: Ab3dGT, trk: Ab3dTracker, iou="3d:0.25", sum_mode: str = DEFAULT_SUM,
                     other: bool = False) -> dict:
    """Score one tracker output (:func:`~dfrmot_jax.metrics.samota.prep.read_ab3dmot_results`);
    sum_mode, other: :func:`ab3dmot_metrics`'s."""
    kind, thr = parse_iou(iou)
    return ab3dmot_metrics(prepare_passes(gt, trk, kind, thr), sum_mode, other)


def evaluate_ab3dmot_files(results_dir, root=None, cls: str = "car", sequences: Sequence | None = None,
                           iou="3d:0.25", seqmap=None, missing: str = "empty", sum_mode: str = DEFAULT_SUM,
                           other: bool = False) -> dict:
    """AB3DMOT's KITTI evaluation of ``results_dir/SSSS.txt`` (one class) -> dict of figures.

    root: KITTI training root (default :func:`dfrmot_jax.paths.default_data_root`) or an
    :class:`~dfrmot_jax.metrics.samota.prep.Ab3dGT`; sequences: names or ints (default: the
    seqmap's, else every ``label_02`` sequence whose ground truth has the class); seqmap: a KITTI
    seqmap file (e.g. AB3DMOT's ``evaluate_tracking.seqmap.val``); iou: ``'3d:0.25'`` (default),
    ``'2d:0.5'``, ... (:func:`parse_iou`). missing: a sequence without a file is scored as an empty
    file (``'empty'``, the reference's behaviour with an empty file) or an error (``'error'``).
    sum_mode, other: :func:`ab3dmot_metrics`'s.
    """
    kind, thr = parse_iou(iou)
    if isinstance(root, Ab3dGT):
        gt = root
    else:
        if root is None:
            root = default_data_root()
        if sequences is None and seqmap is not None:
            sequences = read_seqmap(seqmap, root)
        if sequences is None:
            sequences = cached_class_sequences(root, cls)
        gt = cached_ab3dmot_gt(root, cls, sequences)
    trk = read_ab3dmot_results(results_dir, gt, need_3d=(kind == "3d"), missing=missing)
    return ab3dmot_metrics(prepare_passes(gt, trk, kind, thr), sum_mode, other)
