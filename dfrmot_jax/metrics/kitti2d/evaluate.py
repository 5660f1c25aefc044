"""Entry points: evaluate KITTI result files or padded tracker arrays, TrackEval-identical.

Results are ``{seq or 'COMBINED': {field: value}}`` dicts with TrackEval's field names:

* HOTA: ``HOTA DetA AssA DetRe DetPr AssRe AssPr LocA OWTA HOTA_TP HOTA_FN HOTA_FP`` as [19] float64
  arrays over alpha = 0.05..0.95, and floats ``HOTA(0) LocA(0) HOTALocA(0)``;
* CLEAR: floats ``MOTA MOTP MODA CLR_Re CLR_Pr MTR PTR MLR sMOTA CLR_F1 FP_per_frame MOTAL
  MOTP_sum``, ints ``CLR_TP CLR_FN CLR_FP IDSW MT PT ML Frag CLR_Frames``;
* Identity: floats ``IDF1 IDR IDP``, ints ``IDTP IDFN IDFP``;
* Count: ints ``Dets GT_Dets IDs GT_IDs``.

Values are fractions (as TrackEval stores them); :func:`dfrmot_jax.metrics.metrics_table` gives
the x100 summary view. ``COMBINED`` is TrackEval's ``COMBINED_SEQ`` (sums of counts; HOTA's
association scores weighted by HOTA_TP, LocA likewise; every ratio recomputed from the sums).

Several classes (:func:`evaluate_files_classes`, :func:`evaluate_classes`): each class is
evaluated on its own (on the sequences whose ground truth has it, unless sequences are given), and
the class average (:func:`class_average`) is TrackEval's ``combine_classes_class_averaged`` (the
KITTI / BoxMOT "class average"): the fields in :data:`CLASS_SUMMED_FIELDS` (counts: CLR_TP CLR_FN
CLR_FP IDSW MT PT ML Frag CLR_Frames IDTP IDFN IDFP Dets GT_Dets IDs GT_IDs and the per-alpha
HOTA_TP HOTA_FN HOTA_FP) are summed over the classes, every other field (the ratios: HOTA DetA
AssA DetRe DetPr AssRe AssPr LocA OWTA per alpha, HOTA(0) LocA(0) HOTALocA(0), MOTA MOTP MODA
CLR_Re CLR_Pr MTR PTR MLR sMOTA CLR_F1 FP_per_frame MOTAL, IDF1 IDR IDP, and MOTP_sum as TrackEval
does) is the plain mean over the classes; nothing is recomputed from the sums.

Similarity: every entry point takes ``similarity='2d'`` (TrackEval's image IoU, the default),
``'3d'`` (3D IoU of the rotated boxes) or ``'bev'`` (bird's-eye-view IoU): the same definitions and
the same KITTI preprocessing, only the similarity the metrics match on changes (see
:mod:`dfrmot_jax.metrics.kitti2d.kitti`: distractors and DontCare stay 2D, as KITTI's; a row without a 3D
box is unmatched in 3D). Files are then read with their 3D fields (located errors); arrays need
``box3d``. The result fields keep their names (``HOTA``, ``DetA``, ...): the caller labels them
(e.g. ``HOTA_3d``).

Sweeps (:mod:`dfrmot_jax.sweep`) score padded tracker output with
:class:`dfrmot_jax.metrics.kitti2d.lane_scorer.LaneScorer` (each distinct output of each sequence scored
once, in sub-batches of lanes, optionally in a :func:`worker_pool`), keep TrackEval's summary view
per row (:func:`summary_columns`), re-combine any subset of sequences
from the per-alpha fields :data:`RAW_FIELDS` (:func:`combine_sequences`) and average classes
column-wise (:func:`dfrmot_jax.metrics.columns.class_average_columns`, with AB3DMOT's columns).
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import sys
import threading
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from dfrmot_jax.choices import EVAL_CLASSES, parse_classes
from dfrmot_jax.io.memo import FileMemo, file_stamps
from dfrmot_jax.io.result_rows import iter_result_rows
from dfrmot_jax.metrics.common.sequences import cached_class_sequences, seq_name
from dfrmot_jax.metrics.common.sequences import clear_cache as clear_sequence_cache
from dfrmot_jax.metrics.kitti2d import clear, hota, identity, table
from dfrmot_jax.metrics.kitti2d.kitti import (
    EvalBatch,
    PreparedGT,
    TrackerDets,
    prepare_gt,
    preprocess,
)
from dfrmot_jax.metrics.kitti2d.similarity import parse_similarity
from dfrmot_jax.metrics.kitti2d.table import classes_table
from dfrmot_jax.metrics.kitti2d.tracker_files import read_tracker_files, result_paths
from dfrmot_jax.paths import default_data_root

COUNT_FIELDS = ("Dets", "GT_Dets", "IDs", "GT_IDs")
INTEGER_FIELDS = frozenset(clear.INTEGER_FIELDS + identity.INTEGER_FIELDS + COUNT_FIELDS)
ARRAY_FIELDS = frozenset(hota.FLOAT_ARRAY_FIELDS + hota.INTEGER_ARRAY_FIELDS)
ALL_FIELDS = hota.FIELDS + clear.FIELDS + identity.FIELDS + COUNT_FIELDS
# the class average (TrackEval's combine_classes_class_averaged): these are summed, the rest averaged
CLASS_SUMMED_FIELDS = hota.INTEGER_ARRAY_FIELDS + clear.INTEGER_FIELDS + identity.INTEGER_FIELDS + COUNT_FIELDS
CLASS_AVERAGED_FIELDS = tuple(f for f in ALL_FIELDS if f not in CLASS_SUMMED_FIELDS)
#: per-alpha HOTA fields that, with CLEAR's summed fields, Identity's and the counts, re-combine any
#: subset of sequences exactly as TrackEval combines sequences (:func:`combine_sequences`).
RAW_FIELDS = ("HOTA_TP", "HOTA_FN", "HOTA_FP", "AssA", "AssRe", "AssPr", "LocA")
AVERAGE = "average"

_GT_CACHE = FileMemo()


def cached_gt(root, cls: str = "car", sequences: Sequence | None = None) -> PreparedGT:
    """:func:`prepare_gt` memoised. Key: (root, class, sequences); stamp: the sequences' label files
    (:class:`~dfrmot_jax.io.memo.FileMemo`): all that the prepared ground truth is read from."""
    if isinstance(root, PreparedGT):
        return root
    label_dir = Path(root) / "label_02"
    names = gt_sequences(root, sequences)
    stamp = file_stamps(label_dir / f"{n}.txt" for n in names)
    key = (str(Path(root).resolve()), cls.lower(), names)
    return _GT_CACHE.get(key, stamp, lambda: prepare_gt(root, cls, names))


def gt_sequences(root, sequences: Sequence | None = None) -> tuple:
    """The sequence names :func:`cached_gt` prepares: ``sequences`` (names or ints), by default every
    ``root/label_02/*.txt`` sorted; a :class:`PreparedGT`'s own."""
    if isinstance(root, PreparedGT):
        return root.sequences
    if sequences is None:
        return tuple(sorted(p.stem for p in (Path(root) / "label_02").glob("*.txt")))
    return tuple(seq_name(s) for s in sequences)


def clear_caches() -> None:
    """Forget the memoised ground truth and class sequences (``cached_gt``, ``cached_class_sequences``):
    the next call reads the files again, as a cold start does."""
    _GT_CACHE.clear()
    clear_sequence_cache()


def class_average(per_class: Mapping[str, Mapping[str, object]]) -> dict[str, object]:
    """The class average of one result dict per class, ``{cls: {field: value}}`` (e.g. each class's
    ``COMBINED``), exactly as TrackEval's ``combine_classes_class_averaged`` (all classes, none skipped
    for being empty): :data:`CLASS_SUMMED_FIELDS` summed (``sum`` in class order), every other field
    (:data:`CLASS_AVERAGED_FIELDS`, per alpha for the HOTA arrays) ``np.mean`` over the classes.
    Returns ``{field: value}`` with the fields present in every input.
    """
    vals = list(per_class.values())
    if not vals:
        raise ValueError("class_average: no class results")
    out: dict[str, object] = {}
    for f in ALL_FIELDS:
        if not all(f in v for v in vals):
            continue
        if f in CLASS_SUMMED_FIELDS:
            total = sum(v[f] for v in vals)  # TrackEval's _combine_sum
            out[f] = np.array(total, dtype=np.float64) if f in ARRAY_FIELDS else int(total)
        else:
            m = np.mean([np.asarray(v[f], dtype=np.float64) for v in vals], axis=0)
            out[f] = m if f in ARRAY_FIELDS else float(m)
    return out


def evaluate_batch(gt: PreparedGT, dets: TrackerDets, similarity: str = "2d") -> dict[str, dict[str, np.ndarray]]:
    """All metrics for the lanes of ``dets``: ``{'seq': {field: [L, S(, 19)]}, 'comb': {field: [L(, 19)]}}``.
    similarity: ``'2d'``, ``'3d'`` or ``'bev'`` (module docstring)."""
    return batch_fields(preprocess(gt, dets, similarity))


def batch_fields(b: EvalBatch) -> dict[str, dict[str, np.ndarray]]:
    """:func:`evaluate_batch` of an already preprocessed batch (:func:`~dfrmot_jax.metrics.kitti2d.kitti.preprocess`)."""
    gt = b.gt
    L, S = b.n_lanes, len(gt.sequences)
    seq = {}
    seq.update(hota.hota_sequences(b))
    seq.update(clear.clear_sequences(b))
    seq.update(identity.identity_sequences(b))
    seq["Dets"] = b.n_tr_dets
    seq["GT_Dets"] = np.broadcast_to(gt.n_gt_dets[None, :], (L, S))
    seq["IDs"] = b.n_tr_ids
    seq["GT_IDs"] = np.broadcast_to(gt.n_gt_ids[None, :], (L, S))
    return {"seq": seq, "comb": combine_sequences(seq)}


def combine_sequences(seq_rows: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """TrackEval's ``combine_sequences`` over axis 1 of per-sequence fields [C, S(, 19)] -> fields [C(, 19)].

    ``seq_rows`` holds ``RAW_FIELDS`` (per alpha), CLEAR's summed fields, Identity's and the counts.
    """
    h = hota.hota_combine({f: seq_rows[f] for f in RAW_FIELDS})
    c = clear.clear_combine({f: seq_rows[f] for f in clear.SUMMED_FIELDS})
    i = identity.identity_combine({f: seq_rows[f] for f in identity.INTEGER_FIELDS})
    out = {**h, **c, **i}
    for f in COUNT_FIELDS:
        if f in seq_rows:
            out[f] = seq_rows[f].sum(axis=1)
    return out


def result_dicts(gt: PreparedGT, out: dict) -> list[dict[str, dict[str, object]]]:
    """``{'seq': {f: [L, S(, 19)]}, 'comb': {f: [L(, 19)]}}`` -> L dicts ``{seq | 'COMBINED': {field: value}}``."""
    seq, comb = out["seq"], out["comb"]
    L = next(iter(comb.values())).shape[0]
    conv = {}
    for f in ALL_FIELDS:
        if f in ARRAY_FIELDS:
            conv[f] = (np.asarray(seq[f], dtype=np.float64), np.asarray(comb[f], dtype=np.float64), "a")
        elif f in INTEGER_FIELDS:
            conv[f] = (np.rint(seq[f]).astype(np.int64).tolist(), np.rint(comb[f]).astype(np.int64).tolist(), "i")
        else:
            conv[f] = (np.asarray(seq[f], dtype=np.float64).tolist(), np.asarray(comb[f], dtype=np.float64).tolist(),
                       "f")
    results = []
    for lane in range(L):
        res = {}
        for s, name in enumerate(gt.sequences):
            d = {}
            for f, (sv, _, kind) in conv.items():
                d[f] = sv[lane, s].copy() if kind == "a" else sv[lane][s]
            res[name] = d
        d = {}
        for f, (_, cv, kind) in conv.items():
            d[f] = cv[lane].copy() if kind == "a" else cv[lane]
        res["COMBINED"] = d
        results.append(res)
    return results


def evaluate_files(results_dir, root=None, cls: str = "car", sequences: Sequence | None = None,
                   missing: str = "empty", similarity: str = "2d") -> dict[str, dict[str, object]]:
    """Evaluate one tracker's KITTI result files ``results_dir/SSSS.txt`` like TrackEval's Kitti2DBox.

    root: KITTI training root (default :func:`dfrmot_jax.paths.default_data_root`) or a
    :class:`PreparedGT` (then ``cls``/``sequences`` come from it); ground truth is prepared once
    per (root, class, sequences) and cached. sequences: default every ``label_02`` sequence.
    missing: a sequence without a result file is an empty output (``'empty'``, default) or an
    error (``'error'``); TrackEval itself refuses to run unless every file exists. A name that is
    no readable file (a directory, a dangling symlink) is always an error. ``dfrmot eval`` is
    stricter by default (it also refuses stale files and results without the class).
    Files are read as TrackEval reads them (:func:`read_tracker_files`: rows in any order,
    ``x2 < x1`` allowed, ...). similarity: ``'2d'`` (default), ``'3d'`` or ``'bev'`` (module
    docstring; 3D and BEV read the rows' 3D fields ``h w l x y z rot_y``, the ground truth's from
    label_02). Returns ``{seq: {field: value}, ..., 'COMBINED': {...}}``.
    Raises ``KittiFormatError`` (file, line, field) for malformed files, frames beyond a sequence,
    unknown class names, an id repeated within a frame or (3D, BEV) 3D fields that are no box.
    """
    similarity = parse_similarity(similarity)
    if root is None:
        root = default_data_root()
    names = gt_sequences(root, sequences)
    rows = iter_result_rows(result_paths(results_dir, names), ahead=True)   # parsed while the GT is prepared
    gt = cached_gt(root, cls, names)
    return evaluate_dets(gt, read_tracker_files(results_dir, gt, missing=missing, need_3d=similarity != "2d",
                                                rows=rows), similarity)


def evaluate_dets(gt: PreparedGT, dets: TrackerDets, similarity: str = "2d") -> dict[str, dict[str, object]]:
    """One lane of tracker output (:func:`read_tracker_files`) scored against ``gt``:
    ``{seq: {field: value}, ..., 'COMBINED': {...}}``."""
    return result_dicts(gt, evaluate_batch(gt, dets, similarity))[0]


def evaluate_files_classes(results_dir, root=None, classes: Sequence[str] | str = EVAL_CLASSES,
                           sequences: Sequence | None = None, missing: str = "empty",
                           similarity: str = "2d") -> dict[str, dict]:
    """Evaluate one tracker's result files for several classes, each like :func:`evaluate_files`.

    One file ``results_dir/SSSS.txt`` holds the rows of every class (type names ``Car``,
    ``Pedestrian``, ... in column 3); each class is scored on its own rows only, exactly as
    TrackEval's Kitti2DBox does with ``CLASSES_TO_EVAL`` = several classes.
    classes: ``('car', 'pedestrian')`` (default), a list or a comma-separated str.
    sequences: default, per class, the sequences whose ground truth has that class
    (:func:`cached_class_sequences`: car 20 of KITTI's 21, pedestrian 15); given, every class is
    scored on exactly these (as TrackEval's seqmap).
    Returns ``{cls: {seq: {field: value}, ..., 'COMBINED': {...}}, ...}`` and, with two or more
    classes, ``'average': {'COMBINED': class_average(each class's COMBINED)}`` (:func:`class_average`).
    similarity: ``'2d'`` (default), ``'3d'`` or ``'bev'``, as :func:`evaluate_files`.
    """
    if root is None:
        root = default_data_root()
    out: dict[str, dict] = {}
    for c in parse_classes(classes):
        seqs = sequences if sequences is not None else cached_class_sequences(root, c)
        if not len(seqs):
            raise ValueError(f"no sequence of {Path(root) / 'label_02'} has ground truth of class {c!r}")
        out[c] = evaluate_files(results_dir, cached_gt(root, c, seqs), missing=missing, similarity=similarity)
    if len(out) > 1:
        out[AVERAGE] = {"COMBINED": class_average({c: r["COMBINED"] for c, r in out.items()})}
    return out


def evaluate_classes(results_dir, root=None, classes: Sequence[str] | str = EVAL_CLASSES,
                     sequences: Sequence | None = None, missing: str = "empty", tracker: str | None = None,
                     similarity: str = "2d"):
    """:func:`evaluate_files_classes` as a tidy pandas DataFrame
    (:func:`dfrmot_jax.metrics.kitti2d.table.classes_table`).

    Columns ``[tracker,] class, seq`` and TrackEval's summary fields (ratios x100, counts int); one
    row per (class, sequence), each class's ``COMBINED``, and with two or more classes a last row
    ``class = 'average', seq = 'COMBINED'`` (ratio columns the mean over the classes, counts summed).
    similarity: ``'2d'`` (default), ``'3d'`` or ``'bev'``; the column names stay (``HOTA``, ...).
    """
    return classes_table(evaluate_files_classes(results_dir, root, classes, sequences, missing, similarity),
                         tracker=tracker)


def lane_slice(dets: TrackerDets, a: int, b: int) -> TrackerDets:
    """Lanes a..b-1 of flattened tracker output (rows are sorted by lane), renumbered from 0 (their
    ``configs`` keep the caller's numbers for error messages)."""
    i, j = np.searchsorted(dets.lane, [a, b], side="left")
    configs = np.arange(dets.n_lanes, dtype=np.int64)[:, None] if dets.configs is None else dets.configs
    return dets._replace(n_lanes=b - a, lane=dets.lane[i:j] - a, frame=dets.frame[i:j], configs=configs[a:b],
                         track_id=dets.track_id[i:j], box=dets.box[i:j], source=dets.source[i:j],
                         paths=dets.paths[a:b] if dets.paths else dets.paths,
                         box3d=None if dets.box3d is None else dets.box3d[i:j],
                         has3d=None if dets.has3d is None else dets.has3d[i:j])


def concat_results(outs: list[dict]) -> dict:
    """Results of consecutive lane ranges (:func:`evaluate_batch`) as one."""
    return {part: {f: np.concatenate([o[part][f] for o in outs], axis=0) for f in outs[0][part]}
            for part in ("seq", "comb")}


def evaluate_lanes(gt: PreparedGT, dets: TrackerDets, lanes_per_batch: int = 16, similarity: str = "2d") -> dict:
    """:func:`evaluate_batch` over sub-batches of ``lanes_per_batch`` lanes (bounded memory), concatenated:
    ``{'seq': {field: [L, S(, 19)]}, 'comb': {field: [L(, 19)]}}``."""
    return concat_results([evaluate_batch(gt, lane_slice(dets, a, min(a + lanes_per_batch, dets.n_lanes)), similarity)
                           for a in range(0, dets.n_lanes, lanes_per_batch)])


_WORKER_GT: PreparedGT | None = None


def _init_worker(gt: PreparedGT) -> None:
    global _WORKER_GT
    _WORKER_GT = gt


def run_in_worker(dets: TrackerDets, similarity: str = "2d") -> dict:
    """:func:`evaluate_batch` of ``dets`` against the ground truth a :func:`worker_pool` worker holds."""
    return evaluate_batch(_WORKER_GT, dets, similarity)


class PoolParts(list):
    """Futures of consecutive lane ranges of one batch (:func:`run_in_worker`), read as one future."""
    def done(self) -> bool:
        return all(f.done() for f in self)

    def result(self) -> dict:
        return concat_results([f.result() for f in self])


def worker_pool(gt: PreparedGT, workers: int, start_method: str | None = None) -> ProcessPoolExecutor:
    """A process pool whose workers hold ``gt`` (sent once): submit ``run_in_worker(dets, similarity)``.
    ``start_method`` default ``'forkserver'`` where available, else ``'spawn'`` (both safe in a
    process running JAX threads).

    The forkserver is told not to preload ``__main__``: the workers need only this package, and
    re-running the caller's script in them would start the sweep again there (a plain script
    without ``if __name__ == "__main__":`` then dies with "start a new process before ... bootstrapping").
    The processes start at once, in a thread: each start waits ~1 s for its worker to import the
    package, which the caller's own work (tracking the first chunk, its compilation) now overlaps.
    """
    method = start_method or ("forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn")
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=_without_main(mp.get_context(method)),
                               initializer=_init_worker, initargs=(gt,))
    threading.Thread(target=_start_processes, args=(pool, workers), name="metric-workers", daemon=True).start()
    return pool


def _start_processes(pool: ProcessPoolExecutor, n: int) -> None:
    """Start the pool's ``n`` processes (a pool starts one per task submitted while none is idle)."""
    for _ in range(n):
        try:
            pool.submit(int)
        except RuntimeError:        # shut down meanwhile
            return


@contextlib.contextmanager
def _main_hidden():
    """While a worker starts, ``__main__`` has no ``__file__`` and a ``None`` ``__spec__``:
    multiprocessing then does not re-import the caller's script (or module) in the worker."""
    main = sys.modules.get("__main__")
    saved = {k: main.__dict__[k] for k in ("__file__", "__spec__") if main is not None and k in main.__dict__}
    try:
        if main is not None:
            main.__dict__.pop("__file__", None)
            if "__spec__" in saved:
                main.__spec__ = None
        yield
    finally:
        if main is not None:
            main.__dict__.update(saved)


class _StartWithoutMain:
    """Mixin of a process class: ``start`` with ``__main__`` hidden (module level: picklable)."""
    def start(self):
        with _main_hidden():
            super().start()


class _SpawnProcess(_StartWithoutMain, mp.context.SpawnProcess):
    pass


class _SpawnContext(mp.context.SpawnContext):
    Process = _SpawnProcess


if hasattr(mp.context, "ForkServerProcess"):
    class _ForkServerProcess(_StartWithoutMain, mp.context.ForkServerProcess):
        pass

    class _ForkServerContext(mp.context.ForkServerContext):
        Process = _ForkServerProcess


def _without_main(ctx):
    """The same kind of multiprocessing context, its processes started with ``__main__`` hidden
    (forkserver and spawn; a fork context copies the parent and imports nothing: unchanged)."""
    method = ctx.get_start_method()
    if method == "forkserver":
        return _ForkServerContext()
    return _SpawnContext() if method == "spawn" else ctx


# ---------------------------------------------------------------------------------------------
# Summary columns and the class average, vectorised over rows (sweep tables)


def summary_columns(seq: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """TrackEval fields (arrays [..., 19] or [...]) -> the summary columns of ``metrics_table``
    (HOTA family: mean over alphas x100; other ratios x100; counts int64), vectorised."""
    out = {}
    for f in table.TABLE_FIELDS:
        if f not in seq:
            continue
        v = np.asarray(seq[f])
        if f in table.COUNT_FIELDS:
            out[f] = np.rint(v.astype(np.float64)).astype(np.int64)
        elif f in hota.FLOAT_ARRAY_FIELDS:
            out[f] = 100.0 * np.mean(v.astype(np.float64), axis=-1)
        else:
            out[f] = 100.0 * v.astype(np.float64)
    for f in ("CLR_Frames",):
        if f in seq:
            out[f] = np.rint(np.asarray(seq[f], np.float64)).astype(np.int64)
    if "MOTP_sum" in seq:
        out["MOTP_sum"] = np.asarray(seq["MOTP_sum"], np.float64)
    return out
