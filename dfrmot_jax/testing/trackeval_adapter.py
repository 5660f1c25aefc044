"""Run the reference ``trackeval`` package (KITTI 2D box) in-process, for parity tests and benchmarks.

``trackeval`` is imported lazily, so the rest of :mod:`dfrmot_jax.metrics` never needs it.

TrackEval's :class:`trackeval.datasets.Kitti2DBox` expects this layout::

    GT_FOLDER/evaluate_tracking.seqmap.training     one line per sequence: "SSSS empty 000000 LLLLLL"
    GT_FOLDER/label_02/SSSS.txt                      KITTI tracking labels
    TRACKERS_FOLDER/<tracker>/data/SSSS.txt          KITTI tracking results, one file per sequence

:func:`make_gt_folder` builds the GT part in a scratch directory (label files are symlinked from
the data root, never copied into the repository), :func:`make_tracker_folder` the tracker part,
and :func:`run_trackeval` runs the evaluation and returns the results flattened into the same
``{seq or 'COMBINED': {field: value}}`` dicts that :func:`dfrmot_jax.metrics.evaluate_files`
returns.
"""

from __future__ import annotations

import contextlib
import io
import os
import shutil
from pathlib import Path
from typing import Mapping, Sequence

__all__ = ["write_seqmap", "make_gt_folder", "make_tracker_folder", "run_trackeval", "run_trackeval_classes",
           "flatten_trackeval"]


def write_seqmap(path, lengths: Mapping[str, int]) -> Path:
    """Write a KITTI seqmap (``SSSS empty 000000 LLLLLL`` per line) for ``lengths`` {seq: frames}."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w") as f:
        for seq, n in lengths.items():
            f.write(f"{seq} empty 000000 {int(n):06d}\n")
    return path


def make_gt_folder(folder, root, lengths: Mapping[str, int], split: str = "training") -> Path:
    """Create ``folder`` with ``label_02/SSSS.txt`` (symlinks into ``root/label_02``) and the seqmap.

    ``lengths`` {seq: number of frames} selects the sequences (in that order). Returns ``folder``.
    """
    folder = Path(folder)
    lab = folder / "label_02"
    lab.mkdir(parents=True, exist_ok=True)
    for seq in lengths:
        dst = lab / f"{seq}.txt"
        if dst.exists() or dst.is_symlink():
            dst.unlink()
        os.symlink(Path(root, "label_02", f"{seq}.txt").resolve(), dst)
    write_seqmap(folder / f"evaluate_tracking.seqmap.{split}", lengths)
    return folder


def make_tracker_folder(trackers_folder, name: str, files: Mapping[str, object], sequences: Sequence[str]) -> Path:
    """Create ``trackers_folder/name/data/SSSS.txt`` for every sequence in ``sequences``.

    ``files`` maps seq -> either a path (symlinked), or a str with the file's text (written).
    Sequences absent from ``files`` get an empty file (TrackEval refuses missing files). Returns the
    tracker's ``data`` folder.
    """
    data = Path(trackers_folder) / name / "data"
    if data.exists():
        shutil.rmtree(data)
    data.mkdir(parents=True)
    for seq in sequences:
        dst = data / f"{seq}.txt"
        src = files.get(seq)
        if src is None:
            dst.write_text("")
        elif isinstance(src, Path):
            os.symlink(src.resolve(), dst)
        else:
            dst.write_text(str(src))
    return data


_METRICS = ("HOTA", "CLEAR", "Identity", "Count")


def flatten_trackeval(res_tracker: Mapping, cls: str) -> dict[str, dict[str, object]]:
    """Flatten one tracker's TrackEval result ``res[seq][cls][metric][field]`` to ``{seq: {field: value}}``.

    ``'COMBINED_SEQ'`` becomes ``'COMBINED'``. Count's per-sequence ``Frames`` is dropped (TrackEval
    does not combine it).
    """
    out: dict[str, dict[str, object]] = {}
    for seq, per_cls in res_tracker.items():
        key = "COMBINED" if seq == "COMBINED_SEQ" else seq
        flat: dict[str, object] = {}
        for metric in _METRICS:
            for field, value in per_cls[cls][metric].items():
                if metric == "Count" and field == "Frames":
                    continue
                flat[field] = value
        out[key] = flat
    return out


def _evaluate(gt_folder, trackers_folder, classes: Sequence[str], trackers: Sequence[str] | None, quiet: bool):
    """TrackEval's Kitti2DBox with ``CLASSES_TO_EVAL = classes``; returns (raw results, metric objects)."""
    import trackeval  # lazy: only the parity tests and the benchmark need it
    from trackeval import _timing

    eval_config = trackeval.Evaluator.get_default_eval_config()
    eval_config.update(USE_PARALLEL=False, PRINT_RESULTS=False, PRINT_CONFIG=False, TIME_PROGRESS=False,
                       OUTPUT_SUMMARY=False, OUTPUT_DETAILED=False, PLOT_CURVES=False, LOG_ON_ERROR=None,
                       BREAK_ON_ERROR=True, DISPLAY_LESS_PROGRESS=True)
    ds_config = trackeval.datasets.Kitti2DBox.get_default_dataset_config()
    ds_config.update(GT_FOLDER=str(gt_folder), TRACKERS_FOLDER=str(trackers_folder), OUTPUT_FOLDER=str(trackers_folder),
                     CLASSES_TO_EVAL=list(classes), SPLIT_TO_EVAL="training", PRINT_CONFIG=False,
                     TRACKERS_TO_EVAL=None if trackers is None else list(trackers))
    metric_config = {"THRESHOLD": 0.5, "PRINT_CONFIG": False}
    _timing.DO_TIMING = False
    sink = io.StringIO()
    with contextlib.redirect_stdout(sink) if quiet else contextlib.nullcontext():
        evaluator = trackeval.Evaluator(eval_config)
        dataset = trackeval.datasets.Kitti2DBox(ds_config)
        metrics = [trackeval.metrics.HOTA(), trackeval.metrics.CLEAR(dict(metric_config)),
                   trackeval.metrics.Identity(dict(metric_config)), trackeval.metrics.Count()]
        res, _msg = evaluator.evaluate([dataset], metrics[:3])
    return res["Kitti2DBox"], metrics


def run_trackeval(gt_folder, trackers_folder, cls: str = "car", trackers: Sequence[str] | None = None,
                  quiet: bool = True) -> dict[str, dict[str, dict[str, object]]]:
    """Run TrackEval's Kitti2DBox evaluation (HOTA, CLEAR, Identity, Count) in-process, serially.

    Returns {tracker: {seq or 'COMBINED': {field: value}}} (see :func:`flatten_trackeval`).
    Raises whatever TrackEval raises (``BREAK_ON_ERROR``). With ``quiet`` TrackEval's prints are
    swallowed.
    """
    res, _ = _evaluate(gt_folder, trackers_folder, [cls], trackers, quiet)
    return {tr: flatten_trackeval(r, cls) for tr, r in res.items()}


def run_trackeval_classes(gt_folder, trackers_folder, classes: Sequence[str] = ("car", "pedestrian"),
                          trackers: Sequence[str] | None = None, quiet: bool = True) -> dict[str, dict]:
    """TrackEval's Kitti2DBox on several classes at once (``CLASSES_TO_EVAL = classes``), one run.

    Every class is scored on every sequence of the seqmap (TrackEval has one sequence list).
    Returns {tracker: {cls: {seq or 'COMBINED': {field: value}}, ..., 'average': {'COMBINED': ...}}},
    'average' being TrackEval's own ``combine_classes_class_averaged`` of each metric over the
    classes' ``COMBINED_SEQ`` (Kitti2DBox sets ``should_classes_combine = False``, so the Evaluator
    does not compute it; it is called here directly, ``ignore_empty_classes=False`` as the Evaluator
    would).
    """
    classes = [c.lower() for c in classes]
    res, metrics = _evaluate(gt_folder, trackers_folder, classes, trackers, quiet)
    out = {}
    for tr, r in res.items():
        per = {c: flatten_trackeval(r, c) for c in classes}
        avg: dict[str, object] = {}
        comb = r["COMBINED_SEQ"]
        for m in metrics:
            name = m.get_name()
            avg.update(m.combine_classes_class_averaged({c: comb[c][name] for c in classes}))
        per["average"] = {"COMBINED": avg}
        out[tr] = per
    return out
