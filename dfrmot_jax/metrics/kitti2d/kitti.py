"""KITTI 2D-box preprocessing, reproducing TrackEval's ``Kitti2DBox`` exactly, batched over configs.

What TrackEval does (``trackeval/datasets/kitti_2d_box.py`` and ``_base_dataset.py``, v1.3.0):

* **Reading.** Every row is read; rows typed ``DontCare`` (case-insensitive) in the ground truth
  become crowd-ignore regions (whatever their id). Other rows with a negative track id are dropped
  (GT and tracker) before their class or frame is looked at. The ``valid_filter`` in ``_load_simple_text_file`` is a no-op (its ``continue``
  only continues the inner loop), so rows of every class are kept and mapped to class ids through
  ``{car: 1, van: 2, truck: 3, pedestrian: 4, person: 5, cyclist: 6, tram: 7, misc: 8,
  dontcare: 9, car_2: 1}``; any other type name (e.g. ``Person_sitting``) is an error. Truncation
  and occlusion are cast with ``astype(int)``. A frame ``>=`` the sequence length is an error.
  Result files are read by those rules (:mod:`dfrmot_jax.io.result_rows`: any row order, ``x2 < x1``,
  frames and ids truncated toward zero, 10+ columns); the ground truth by the strict KITTI reader.
* **Classes.** Evaluating ``car``: GT of class car (id 1) is evaluated, vans (2) are distractors.
  Evaluating ``pedestrian``: GT pedestrian (4) evaluated, ``Person`` (5; KITTI's sitting persons)
  distractors. GT with occlusion > 2 or truncation > 0 are distractors too. Other GT classes are
  ignored entirely. Only tracker rows of the evaluated class id are used (``Car`` and ``car_2``
  both count as car).
* **Preprocessing, per frame.** IoU between the class+distractor GT and the tracker boxes;
  ``linear_sum_assignment`` maximising IoU where IoU >= 0.5 - eps (else 0); tracker boxes matched
  (score > eps) to a distractor GT are removed. Of the unmatched tracker boxes, those with height
  ``y2 - y1 <= 25 + eps`` px or with intersection-over-own-area ``> 0.5 + eps`` with any DontCare
  region are removed. Distractor GT are then dropped.
* **Similarity** (``similarity=``, :mod:`dfrmot_jax.metrics.kitti2d.similarity`): TrackEval's image-box
  IoU (``'2d'``, the default), or, with the rest unchanged, the 3D IoU of the rotated boxes (``'3d'``) or their
  bird's-eye-view IoU (``'bev'``) (:mod:`dfrmot_jax.metrics.common.box3d`), which then feeds HOTA, CLEAR
  and Identity in place of the 2D IoU (their thresholds unchanged: CLEAR and Identity match at
  similarity >= 0.5, HOTA over alpha = 0.05..0.95). The preprocessing stays 2D, as KITTI's: the
  distractor matching (image IoU >= 0.5), the 25 px height and the DontCare overlap use the image
  boxes whatever the similarity. A row without a 3D box (the 2D-only placeholder
  ``-1 -1 -1 -1000 -1000 -1000``, or all NaN in arrays; :mod:`dfrmot_jax.metrics.common.fields3d`) has 3D /
  BEV similarity 0 to every object: in 3D it is never matched (a false positive unless removed by
  the 2D preprocessing), and a ground-truth object without one is never matched either (a miss).
* **Ids.** GT and tracker ids are relabelled per sequence to ``0..n-1`` in sorted order (this
  does not change any metric value here; we use one global index per (config, sequence, id)).
  Duplicate ids within a frame after preprocessing are an error.

Arrays here: ``F`` = total frames of the evaluated sequences (concatenated in order), ``L`` =
configs ("lanes"), a *lane-frame* ``lf = lane * F + frame``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import NamedTuple, Sequence

import numpy as np
import pandas as pd

from dfrmot_jax.io import kitti as kio  # the shared reader (KittiFormatError, read_tracking_labels)
from dfrmot_jax.metrics.common.fields3d import box_rows
from dfrmot_jax.metrics.common.kernel_cache import cached_njit
from dfrmot_jax.metrics.common.pairs import enumerate_pairs, segment_starts
from dfrmot_jax.metrics.common.sequences import CLASS_NAME_TO_ID, DISTRACTORS, distinct_types, seq_name
from dfrmot_jax.metrics.common.sorting import argsort
from dfrmot_jax.metrics.kitti2d.box_table import box_table, metric_pairs
from dfrmot_jax.metrics.kitti2d.boxes import columns
from dfrmot_jax.metrics.kitti2d.kept import kept_boxes
from dfrmot_jax.metrics.kitti2d.similarity import pair_similarity_3d, parse_similarity

__all__ = [
    "PreparedGT",
    "TrackerDets",
    "EvalBatch",
    "prepare_gt",
    "class_ids",
    "preprocess",
    "DuplicateIdError",
]

MAX_OCCLUSION = 2
MAX_TRUNCATION = 0


#: the most entries of one (config, sequence)'s (tracker id x GT id) table in the compiled metric passes
#: (int64: 128 MB); a larger one is scored by the NumPy paths
MAX_ID_TABLE = 1 << 24


class DuplicateIdError(ValueError):
    """A tracker id occurs twice in one frame after preprocessing (TrackEval refuses this too)."""


def _kitti_io():
    return kio


def class_ids(types: np.ndarray, path, kio, rows: np.ndarray | None = None) -> np.ndarray:
    """[R] object type names -> [R] int64 class ids (lower-cased lookup, as TrackEval).

    ``rows`` [R]: file row of each entry (for the error's line number); default 0..R-1.
    """
    return coded_class_ids(*distinct_types(types), path, kio, rows)


def coded_class_ids(code: np.ndarray, names: np.ndarray, path, kio, rows: np.ndarray | None = None) -> np.ndarray:
    """:func:`class_ids` of type names given as ``code`` [R] into ``names`` [U] (names no entry uses
    are skipped: ``names`` may be those of a whole file, ``code`` of some of its rows)."""
    used = np.bincount(code, minlength=len(names)) > 0
    ids = np.zeros(len(names), dtype=np.int64)
    for k in np.argsort(names, kind="stable"):       # names in sorted order: the first unknown one is named
        if not used[k]:
            continue
        name = names[k]
        cid = CLASS_NAME_TO_ID.get(name.lower())
        if cid is None:
            r = int(np.flatnonzero(code == k)[0])
            r = r if rows is None else int(rows[r])
            raise kio.KittiFormatError(path, kio.line_of_row(path, r) or r + 1, "type",
                                       f"unknown class {name!r} (TrackEval accepts "
                                       f"{', '.join(sorted(CLASS_NAME_TO_ID))}; case-insensitive)")
        ids[k] = cid
    return ids[code]


@dataclass(eq=False)
class PreparedGT:
    """Ground truth of one split (class + sequences), prepared once and reused for every tracker.

    Frames are global: sequence ``s`` owns frames ``offsets[s]:offsets[s+1]`` (F in total).

    * ``cls`` 'car' | 'pedestrian'; ``sequences`` tuple of S names; ``lengths`` [S] and
      ``offsets`` [S+1] int64; ``seq_of_frame`` [F].
    * Class rows (evaluated class + distractors, in file order within a frame), N rows:
      ``row_box`` [N, 4] float64, ``row_eval`` [N] bool (kept for evaluation),
      ``row_eval_index`` [N] int64 (index among eval rows, -1 for distractors), ``row_start`` [F+1].
    * Eval rows, NE rows: ``eval_gid`` [NE] (global GT id; sequence s owns ids
      ``gid_start[s]:gid_start[s+1]``), ``eval_start`` [F+1], ``eval_count`` [F].
    * ``gid_count`` [NG] float64 detections per GT id; ``gid_label`` [NG] int64 its track id in the
      label file; ``gid_seq`` [NG]; ``n_gt_ids`` [S];
      ``n_gt_dets`` [S].
    * DontCare regions: ``dc_box`` [D, 4], ``dc_start`` [F+1].
    * 3D boxes of the class rows: ``row_box3d`` [N, 7] ``h w l x y z rot_y`` (label_02's columns),
      ``row_has3d`` [N] bool (False where the fields are no box: the placeholder or worse).
    """
    cls: str
    cls_id: int
    sequences: tuple
    lengths: np.ndarray
    offsets: np.ndarray
    seq_of_frame: np.ndarray
    row_box: np.ndarray
    row_eval: np.ndarray
    row_eval_index: np.ndarray
    row_start: np.ndarray
    eval_gid: np.ndarray
    eval_start: np.ndarray
    eval_count: np.ndarray
    gid_count: np.ndarray
    gid_label: np.ndarray
    gid_seq: np.ndarray
    gid_start: np.ndarray
    n_gt_ids: np.ndarray
    n_gt_dets: np.ndarray
    dc_box: np.ndarray
    dc_start: np.ndarray
    row_box3d: np.ndarray
    row_has3d: np.ndarray
    root: str = ""
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def row_cols(self) -> tuple:
        """``row_box`` as four contiguous [N] columns (cached)."""
        c = self._cache.get("row_cols")
        if c is None:
            c = self._cache["row_cols"] = columns(self.row_box)
        return c

    @property
    def n_frames(self) -> int:
        return int(self.offsets[-1])

    @property
    def lengths_dict(self) -> dict:
        return {s: int(n) for s, n in zip(self.sequences, self.lengths)}

    def __repr__(self) -> str:
        return (f"PreparedGT(cls={self.cls!r}, sequences={len(self.sequences)}, frames={self.n_frames}, "
                f"gt_dets={int(self.n_gt_dets.sum())}, gt_ids={int(self.n_gt_ids.sum())})")


def prepare_gt(root, cls: str = "car", sequences: Sequence | None = None) -> PreparedGT:
    """Read and prepare the KITTI ground truth of ``root/label_02`` for class ``cls``.

    ``sequences``: names (``'0000'``) or ints; default every ``label_02/*.txt``. Sequence lengths
    are ``max GT frame + 1`` (what :func:`dfrmot_jax.io.kitti.sequence_lengths` gives and what
    TrackEval's seqmap must say). Returns a :class:`PreparedGT`.
    """
    kio = _kitti_io()
    cls = cls.lower()
    if cls not in DISTRACTORS:
        raise ValueError(f"class {cls!r} is not evaluatable (TrackEval's KITTI 2D box: 'car' or 'pedestrian')")
    cls_id = CLASS_NAME_TO_ID[cls]
    classes = (cls_id,) + DISTRACTORS[cls]
    label_dir = Path(root) / "label_02"
    if sequences is None:
        names = sorted(p.stem for p in label_dir.glob("*.txt"))
        if not names:
            raise FileNotFoundError(f"no ground truth files in {label_dir}")
    else:
        names = [seq_name(s) for s in sequences]

    paths = [label_dir / f"{name}.txt" for name in names]
    joined = kio.joined_tracking_labels(paths)
    if joined is not None:
        rows = _sequences_gt(joined[0], joined[1], paths, kio, cls_id, classes)
    else:                   # one file after the other: a file's problem is raised at its turn
        labels = kio.iter_tracking_labels(paths)
        rows = _joined_rows([_sequences_gt(lab, np.array([0, len(lab.frame)]), [p], kio, cls_id, classes)
                             for p, lab in zip(paths, labels)])
    return _prepared(cls, cls_id, names, rows, root)


class _GTRows(NamedTuple):
    """The ground truth of a class in some sequences, frames and GT ids global (:func:`prepare_gt`)."""
    lengths: np.ndarray      # [S] frames of each sequence: its max label frame + 1
    box: np.ndarray          # [n, 4] class rows (evaluated class + distractors), by frame
    box3d: np.ndarray        # [n, 7] ``h w l x y z rot_y``
    eval: np.ndarray         # [n] bool: kept for evaluation
    frame: np.ndarray        # [n] global frame
    gid: np.ndarray          # [n] global GT id of an eval row (-1 for distractors)
    n_ids: np.ndarray        # [S] eval GT ids of each sequence
    n_dets: np.ndarray       # [S] eval rows of each sequence
    gid_count: np.ndarray    # [NG] float64 detections per GT id
    gid_label: np.ndarray    # [NG] int64 the label file's track id of each GT id
    dc_box: np.ndarray       # [d, 4] DontCare regions, by frame
    dc_frame: np.ndarray     # [d] their global frames


def _sequences_gt(lab, starts: np.ndarray, paths: Sequence, kio, cls_id: int, classes: tuple) -> _GTRows:
    """The class rows, eval ids and DontCare regions of one or more sequences' labels (TrackEval's
    rules, module docstring), all at once: ``lab`` holds the rows of sequence s (read from
    ``paths[s]``) at ``starts[s]:starts[s + 1]``. Each sequence's frames follow the
    last one's, its GT ids too (per sequence, sorted by track id). A problem (a type TrackEval does
    not know, a GT id twice in one frame) is raised for the first sequence that has it, named by
    its file, as when the sequences are taken one by one."""
    S = len(starts) - 1
    n = np.diff(starts)
    seq = np.repeat(np.arange(S), n)
    lengths = np.zeros(S, dtype=np.int64)
    if len(lab.frame):
        lengths[n > 0] = np.maximum.reduceat(lab.frame, starts[:-1][n > 0]) + 1
    frame = lab.frame + np.repeat(segment_starts(lengths)[:-1], n)
    code, uniq = distinct_types(lab.type)
    is_dc = (np.char.lower(uniq) == "dontcare")[code]
    cid = np.zeros(len(code), dtype=np.int64)
    nd = ~is_dc & (lab.track_id >= 0)  # TrackEval skips negative ids before mapping class names
    known = np.array([u.lower() in CLASS_NAME_TO_ID for u in uniq], dtype=bool)
    if S > 1 and not known[code[nd]].all():
        return _one_by_one(lab, starts, paths, kio, cls_id, classes)
    cid[nd] = coded_class_ids(code[nd], uniq, paths[0], kio, np.flatnonzero(nd))
    use = nd & np.logical_or.reduce([cid == c for c in classes])
    occ = lab.occluded.astype(np.int64)
    trunc = lab.truncated.astype(np.int64)
    is_eval = (occ <= MAX_OCCLUSION) & (trunc <= MAX_TRUNCATION) & (cid == cls_id)
    sel = np.flatnonzero(use)
    order = sel[np.argsort(frame[sel], kind="stable")]
    box3d = np.concatenate([lab.dims[order], lab.loc[order], lab.rot_y[order, None]], axis=1)
    # relabel eval ids contiguously per sequence (sorted unique, as TrackEval), sequence after sequence
    ev = order[is_eval[order]]
    s_ev, t_ev = seq[ev], lab.track_id[ev]
    by_id = np.lexsort((t_ev, s_ev))
    first = np.ones(len(ev), dtype=bool)
    first[1:] = (s_ev[by_id][1:] != s_ev[by_id][:-1]) | (t_ev[by_id][1:] != t_ev[by_id][:-1])
    inv = np.empty(len(ev), dtype=np.int64)
    inv[by_id] = np.cumsum(first) - 1
    gid = np.full(len(order), -1, dtype=np.int64)
    gid[is_eval[order]] = inv
    # duplicate GT ids within a frame (TrackEval raises)
    f_ev = frame[ev]
    by_frame = np.lexsort((inv, f_ev))
    if np.any((f_ev[by_frame][1:] == f_ev[by_frame][:-1]) & (inv[by_frame][1:] == inv[by_frame][:-1])):
        if S > 1:
            return _one_by_one(lab, starts, paths, kio, cls_id, classes)
        raise ValueError(f"{paths[0]}: ground truth has the same id twice in one frame")
    dsel = np.flatnonzero(is_dc)
    dsel = dsel[np.argsort(frame[dsel], kind="stable")]
    return _GTRows(lengths, lab.box[order], box3d, is_eval[order], frame[order], gid,
                   np.bincount(s_ev[by_id][first], minlength=S), np.bincount(s_ev, minlength=S),
                   np.bincount(inv).astype(np.float64), t_ev[by_id][first].astype(np.int64), lab.box[dsel], frame[dsel])


def _one_by_one(lab, starts: np.ndarray, paths: Sequence, kio, cls_id: int, classes: tuple) -> _GTRows:
    """:func:`_sequences_gt` of each sequence alone, in order, joined (the first problem is raised)."""
    return _joined_rows([_sequences_gt(type(lab)(*(f[a:b] for f in lab)), np.array([0, b - a]), [p], kio, cls_id,
                                       classes) for p, a, b in zip(paths, starts[:-1], starts[1:])])


def _joined_rows(parts: list[_GTRows]) -> _GTRows:
    """Sequences' :class:`_GTRows` one after the other: frames and GT ids moved past the earlier ones'."""
    if not parts:
        e = np.zeros(0, np.int64)
        return _GTRows(e, np.zeros((0, 4)), np.zeros((0, 7)), np.zeros(0, bool), e, e, e, e, np.zeros(0), e,
                       np.zeros((0, 4)), e)
    frame_off = segment_starts(np.concatenate([p.lengths for p in parts]))
    id_off = segment_starts(np.concatenate([p.n_ids for p in parts]))
    cat = {f: np.concatenate([getattr(p, f) for p in parts]) for f in _GTRows._fields}
    cat["frame"] = np.concatenate([p.frame + o for p, o in zip(parts, frame_off)])
    cat["dc_frame"] = np.concatenate([p.dc_frame + o for p, o in zip(parts, frame_off)])
    cat["gid"] = np.concatenate([np.where(p.gid >= 0, p.gid + o, -1) for p, o in zip(parts, id_off)])
    return _GTRows(**cat)


def _prepared(cls: str, cls_id: int, names: list, g: _GTRows, root) -> PreparedGT:
    """The sequences' ground truth as one :class:`PreparedGT`."""
    F = int(g.lengths.sum())
    offsets = segment_starts(g.lengths)
    row_start = segment_starts(np.bincount(g.frame, minlength=F))
    eval_idx = np.full(len(g.eval), -1, dtype=np.int64)
    eval_idx[g.eval] = np.arange(int(g.eval.sum()))
    eval_count = np.bincount(g.frame[g.eval], minlength=F).astype(np.int64)
    row_box3d = np.ascontiguousarray(g.box3d.reshape(-1, 7), dtype=np.float64)
    n_gt_ids = g.n_ids.astype(np.int64)
    return PreparedGT(
        cls=cls, cls_id=cls_id, sequences=tuple(names), lengths=g.lengths.astype(np.int64), offsets=offsets,
        seq_of_frame=np.repeat(np.arange(len(names)), g.lengths),
        row_box=np.ascontiguousarray(g.box.reshape(-1, 4), dtype=np.float64), row_eval=g.eval,
        row_eval_index=eval_idx, row_start=row_start,
        eval_gid=g.gid[g.eval], eval_start=segment_starts(eval_count), eval_count=eval_count,
        gid_count=g.gid_count, gid_label=g.gid_label, gid_seq=np.repeat(np.arange(len(names)), n_gt_ids),
        gid_start=segment_starts(n_gt_ids), n_gt_ids=n_gt_ids, n_gt_dets=g.n_dets.astype(np.int64),
        dc_box=np.ascontiguousarray(g.dc_box.reshape(-1, 4), dtype=np.float64),
        dc_start=segment_starts(np.bincount(g.dc_frame, minlength=F)),
        row_box3d=row_box3d, row_has3d=box_rows(row_box3d), root=str(root),   # (no box in the 3D fields: no 3D box)
    )


class TrackerDets(NamedTuple):
    """Tracker boxes of ``n_lanes`` configs, sorted by (lane, frame), slot/file order within a frame.

    lane, frame (global GT frame), track_id: [M] int64; box: [M, 4] float64 ``x1, y1, x2, y2`` (float32
    from float32 arrays: :func:`preprocess` widens a batch's boxes to float64, exactly);
    source: [M] int64 row in the source file (files) or slot index (arrays), for error messages;
    paths: per lane, per sequence the source file (or None). box3d: [M, 7] float64 ``h w l x y z
    rot_y`` and has3d: [M] bool (False: no 3D box), or both None when the 3D fields were not read.
    configs: [n_lanes, S] (or [n_lanes, 1]: every sequence) int64, the caller's config of each lane's
    rows, for error messages (lanes of a slice, virtual lanes of several configs); None: the lane.
    """
    n_lanes: int
    lane: np.ndarray
    frame: np.ndarray
    track_id: np.ndarray
    box: np.ndarray
    source: np.ndarray
    paths: tuple = ()
    box3d: np.ndarray | None = None
    has3d: np.ndarray | None = None
    configs: np.ndarray | None = None

    def config(self, lane: int, s: int) -> int:
        """The caller's config of ``lane``'s rows of sequence ``s``."""
        if self.configs is None:
            return lane
        return int(self.configs[lane, s if self.configs.shape[1] > 1 else 0])


@dataclass(eq=False)
class EvalBatch:
    """Preprocessed data of ``n_lanes`` configs, ready for the metrics (TrackEval's ``data`` dict).

    Kept tracker dets (KD rows, sorted by lane-frame): ``det_lf`` [KD], ``det_gid`` [KD] global
    tracker-id index; ``det_start`` [L*F+1]; ``det_count`` [L*F].
    Tracker ids (NT): ``tid_lane``, ``tid_seq`` [NT], ``tid_count`` [NT] float64.
    Metric pairs (eval GT x kept dets of each lane-frame, row-major, sorted by lane-frame), P:
    ``p_lf``, ``p_e`` (eval GT row), ``p_k`` (kept det) [P] int64, ``sim`` [P] float64 (IoU);
    ``pair_start`` [L*F+1]. Per (lane, seq): ``n_tr_dets``, ``n_tr_ids`` [L, S].
    """
    gt: PreparedGT
    n_lanes: int
    det_lf: np.ndarray
    det_gid: np.ndarray
    det_start: np.ndarray
    det_count: np.ndarray
    tid_lane: np.ndarray
    tid_seq: np.ndarray
    tid_count: np.ndarray
    p_lf: np.ndarray
    p_e: np.ndarray
    p_k: np.ndarray
    sim: np.ndarray
    pair_start: np.ndarray
    n_tr_dets: np.ndarray
    n_tr_ids: np.ndarray

    @cached_property
    def lf_eval_count(self) -> np.ndarray:
        """[L*F] eval GT rows per lane-frame."""
        return np.tile(self.gt.eval_count, self.n_lanes)

    @cached_property
    def p_gid(self) -> np.ndarray:
        """[P] int64 each pair's global GT id."""
        return np.ascontiguousarray(self.gt.eval_gid[self.p_e], dtype=np.int64)

    @cached_property
    def p_tid(self) -> np.ndarray:
        """[P] int64 each pair's global tracker id index (``det_gid``)."""
        return np.ascontiguousarray(self.det_gid[self.p_k], dtype=np.int64)

    @cached_property
    def ls_lf_start(self) -> np.ndarray:
        """[L*S + 1] the first lane-frame of each (lane, sequence) ``ls = lane * S + s``, and ``L * F``."""
        L, F = self.n_lanes, self.gt.n_frames
        return np.append((np.arange(L, dtype=np.int64)[:, None] * F + self.gt.offsets[None, :-1]).reshape(-1), L * F)

    @cached_property
    def ls_tid_start(self) -> np.ndarray:
        """[L*S + 1] the first tracker id index of each (lane, sequence) (ids are numbered by it)."""
        S = len(self.gt.sequences)
        return segment_starts(np.bincount(self.tid_lane * S + self.tid_seq, minlength=self.n_lanes * S))

    @property
    def id_table_size(self) -> int:
        """The largest (tracker id x GT id) table of one (lane, sequence): entries a compiled pass
        indexes (:data:`MAX_ID_TABLE`)."""
        S = len(self.gt.sequences)
        n_tid = np.diff(self.ls_tid_start).reshape(self.n_lanes, S)
        return int((n_tid * np.diff(self.gt.gid_start)[None, :]).max(initial=0))

    @cached_property
    def ls_seq(self) -> np.ndarray:
        """[L*S] the sequence of each (lane, sequence)."""
        return np.tile(np.arange(len(self.gt.sequences), dtype=np.int64), self.n_lanes)

    @cached_property
    def early_sequences(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(no_tr, no_gt, early) [L, S] bool: the (lane, sequence)s TrackEval returns early for, each
        metric with its own fields: no tracker detections, or some but no ground-truth detections."""
        no_tr = self.n_tr_dets == 0
        no_gt = (self.gt.n_gt_dets[None, :] == 0) & ~no_tr
        return no_tr, no_gt, no_tr | no_gt


def _duplicate_error(gt: PreparedGT, dets: TrackerDets, idx: int) -> Exception:
    lane = int(dets.lane[idx])
    g = int(dets.frame[idx])
    s = int(gt.seq_of_frame[g])
    t = g - int(gt.offsets[s])
    tid = int(dets.track_id[idx])
    msg = (f"tracker predicts id {tid} more than once in frame {t} of sequence {gt.sequences[s]} "
           f"(after preprocessing; TrackEval refuses this)")
    if dets.paths and dets.paths[lane] and dets.paths[lane][s]:
        kio = _kitti_io()
        path = dets.paths[lane][s]
        row = int(dets.source[idx])
        return kio.KittiFormatError(path, kio.line_of_row(path, row) or row + 1, "track_id", msg)
    return DuplicateIdError(f"config {dets.config(lane, s)}: {msg}")


def preprocess(gt: PreparedGT, dets: TrackerDets, similarity: str = "2d") -> EvalBatch:
    """TrackEval's ``get_preprocessed_seq_data`` for every lane and frame at once.

    similarity: ``'2d'`` (image IoU), ``'3d'`` or ``'bev'`` (module docstring: the metric pairs'
    ``sim``; the preprocessing itself stays 2D); 3D and BEV need ``dets.box3d``.
    Returns an :class:`EvalBatch`. Raises :class:`DuplicateIdError` (or ``KittiFormatError`` for
    file input) when an id repeats within a frame after preprocessing.
    """
    similarity = parse_similarity(similarity)
    if similarity != "2d" and dets.box3d is None:
        raise ValueError(f"similarity {similarity!r} needs the tracker's 3D boxes (read with need_3d=True, or "
                         f"box3d= for arrays)")
    L = int(dets.n_lanes)
    F = gt.n_frames
    S = len(gt.sequences)
    lf = dets.lane * F + dets.frame
    g_of_lf = np.tile(np.arange(F, dtype=np.int64), L)
    # IoU of each distinct (frame, box) with the frame's class rows and its DontCare overlap, once
    box = np.asarray(dets.box, dtype=np.float64)
    tab = box_table(gt.row_start, gt.row_cols, gt.dc_start, gt.dc_box, dets.frame, box)
    kidx = np.flatnonzero(kept_boxes(gt, dets, tab, box, lf, g_of_lf))
    k_lf, grp, det_gid, tid_grp, tid_count = _tracker_ids(gt, dets, kidx, lf)
    nk = np.bincount(k_lf, minlength=L * F).astype(np.int64)

    # --- metric pairs: eval GT x kept dets of each lane-frame, row-major; IoU looked up in the table
    ev_rows = np.flatnonzero(gt.row_eval)             # class row of each eval row
    if similarity == "2d":
        p_lf, p_e, p_k, sim, pair_start = metric_pairs(tab, gt.row_start, gt.eval_start, gt.eval_count, ev_rows,
                                                       g_of_lf, nk, kidx)
    else:
        ng_e = gt.eval_count[g_of_lf]
        p_lf, p_e, p_k, pair_start = enumerate_pairs(ng_e, gt.eval_start[g_of_lf], nk, segment_starts(nk)[:-1])
        sim = pair_similarity_3d(gt.row_box3d, gt.row_has3d, ev_rows[p_e], dets.box3d, dets.has3d, kidx[p_k],
                                 similarity)
    n_tr_dets = np.bincount(grp, minlength=L * S).reshape(L, S).astype(np.int64)
    n_tr_ids = np.bincount(tid_grp, minlength=L * S).reshape(L, S).astype(np.int64)
    return EvalBatch(gt=gt, n_lanes=L, det_lf=k_lf, det_gid=det_gid, det_start=segment_starts(nk), det_count=nk,
                     tid_lane=tid_grp // S, tid_seq=tid_grp % S, tid_count=tid_count,
                     p_lf=p_lf, p_e=p_e, p_k=p_k, sim=sim, pair_start=pair_start,
                     n_tr_dets=n_tr_dets, n_tr_ids=n_tr_ids)


def _tracker_ids(gt: PreparedGT, dets: TrackerDets, kidx: np.ndarray, lf: np.ndarray) -> tuple:
    """The kept boxes ``kidx``' tracker ids, one global index per (lane, sequence, id) in sorted order ->
    (lane-frame [KD], lane x sequence [KD], id index [KD], lane x sequence of each id [NT], boxes
    per id [NT] float64). Raises (:func:`_duplicate_error`) when an id repeats within a frame."""
    S = len(gt.sequences)
    k_lane = dets.lane[kidx]
    k_frame = dets.frame[kidx]
    k_tid = dets.track_id[kidx]
    k_lf = lf[kidx]
    k_seq = gt.seq_of_frame[k_frame]
    grp = k_lane * S + k_seq
    if len(kidx) and np.all(grp[1:] >= grp[:-1]):     # (rows by lane-frame: each (lane, seq) one run, compiled)
        det_gid, tid_grp, tid_count, dup = _ids_by_run(grp, np.ascontiguousarray(k_tid, np.int64), k_lf)
        if not dup:
            return k_lf, grp, det_gid, tid_grp, tid_count
    return (k_lf, grp) + _ids_numpy(gt, dets, kidx, k_lf, grp, k_tid)


def _ids_numpy(gt: PreparedGT, dets: TrackerDets, kidx: np.ndarray, k_lf: np.ndarray, grp: np.ndarray,
               k_tid: np.ndarray) -> tuple:
    """:func:`_tracker_ids`' numbering by hashing or sorting (any row order; what names a repeated id):
    (id index [KD], (lane, sequence) of each id [NT], rows per id [NT] float64)."""
    L, F, S = int(dets.n_lanes), gt.n_frames, len(gt.sequences)
    top = int(k_tid.max(initial=0)) + 1               # ids >= 0: one int64 key per (lane, seq, id) if it fits
    if (L * S + 1) * top < 2**62:
        det_gid, uniq = pd.factorize(grp * top + k_tid, sort=True)   # ranks of (grp, id), hashed
        tid_grp = uniq // top
    else:
        order = np.lexsort((k_tid, grp))
        gs, ts = grp[order], k_tid[order]
        new = np.ones(len(order), dtype=bool)
        new[1:] = (gs[1:] != gs[:-1]) | (ts[1:] != ts[:-1])
        det_gid = np.empty(len(order), dtype=np.int64)
        det_gid[order] = np.cumsum(new) - 1
        tid_grp = gs[new]
    NT = len(tid_grp)
    tid_count = np.bincount(det_gid, minlength=NT).astype(np.float64)
    # duplicates within a frame
    if len(kidx) and (L * F * NT >= 2**62 or pd.Series(k_lf * NT + det_gid).duplicated().any()):
        o2 = np.lexsort((det_gid, k_lf))
        dup = (k_lf[o2][1:] == k_lf[o2][:-1]) & (det_gid[o2][1:] == det_gid[o2][:-1])
        if dup.any():
            raise _duplicate_error(gt, dets, int(kidx[o2[1:][dup][0]]))
    return det_gid, tid_grp, tid_count


@cached_njit(nogil=True, calls=("dfrmot_jax.metrics.common.sorting",))
def _ids_by_run(grp, tid, lf):
    """:func:`_tracker_ids`' numbering in one compiled pass where each (lane, sequence) ``grp`` is one
    run of rows: each run's distinct ids in sorted order, numbered on from the last run's; and
    whether an id repeats within a lane-frame ``lf`` (the caller then names it by the general path).
    Returns (id index [KD], (lane, sequence) of each id [NT], rows per id [NT] float64, repeated)."""
    n = len(grp)
    det_gid = np.empty(n, np.int64)
    tid_grp = np.empty(n, np.int64)
    rank = np.full(4 * n + 1024, -1, np.int64)          # ids of a run within this span: ranked by a table
    nt = 0
    a = 0
    while a < n:
        e = a
        lo, hi = tid[a], tid[a]
        while e < n and grp[e] == grp[a]:
            lo, hi = min(lo, tid[e]), max(hi, tid[e])
            e += 1
        if hi - lo < len(rank):
            for i in range(a, e):
                rank[tid[i] - lo] = 0
            k = 0
            for v in range(hi - lo + 1):
                if rank[v] == 0:
                    rank[v] = k
                    k += 1
            for i in range(a, e):
                det_gid[i] = nt + rank[tid[i] - lo]
            rank[:hi - lo + 1] = -1
        else:                                      # ranked by sorting
            order = argsort(tid[a:e])
            k = 0
            for r in range(e - a):
                i = a + order[r]
                if r and tid[i] != tid[a + order[r - 1]]:
                    k += 1
                det_gid[i] = nt + k
            k += 1
        tid_grp[nt:nt + k] = grp[a]
        nt += k
        a = e
    count = np.zeros(nt)
    for i in range(n):
        count[det_gid[i]] += 1.0
    repeated = False
    a = 0
    while a < n and not repeated:
        e = a
        while e < n and lf[e] == lf[a]:
            e += 1
        for i in range(a, e):
            for j in range(i + 1, e):
                repeated = repeated or det_gid[i] == det_gid[j]
        a = e
    return det_gid, tid_grp[:nt].copy(), count, repeated
