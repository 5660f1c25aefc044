"""TrackEval-identical KITTI 2D-box tracking metrics (HOTA, CLEAR, Identity), fast and batched.

Modules: :mod:`~dfrmot_jax.metrics.kitti2d.kitti` (ground truth and tracker preprocessing, as TrackEval's
Kitti2DBox), :mod:`~dfrmot_jax.metrics.kitti2d.hota`, :mod:`~dfrmot_jax.metrics.kitti2d.clear`,
:mod:`~dfrmot_jax.metrics.kitti2d.identity` (the metrics), :mod:`~dfrmot_jax.metrics.kitti2d.boxes` (IoU),
:mod:`~dfrmot_jax.metrics.common.pairs` (per-frame pair bookkeeping and assignments),
:mod:`~dfrmot_jax.metrics.kitti2d.evaluate` (entry points), :mod:`~dfrmot_jax.metrics.kitti2d.table`,
:mod:`~dfrmot_jax.cli.eval` (``dfrmot eval``), :mod:`~dfrmot_jax.testing.trackeval_adapter`
(running the reference ``trackeval`` package) and :mod:`~dfrmot_jax.testing.metric_edits` (test outputs).
AB3DMOT's KITTI 3D MOT metrics (sAMOTA, AMOTA, AMOTP, exact to its evaluator):
:mod:`~dfrmot_jax.metrics.ab3dmot.evaluate` (with ``ab3dmot_prep`` reading its inputs, ``ab3dmot_arrays``
scoring padded outputs, ``ab3dmot_table`` the CLI's columns); the rotated 3D / BEV box IoU:
:mod:`~dfrmot_jax.metrics.common.box3d`. HOTA / CLEAR / Identity with that similarity instead of the
image IoU: ``similarity='3d'`` or ``'bev'`` on every entry point (:mod:`~dfrmot_jax.metrics.kitti2d.similarity`;
the KITTI preprocessing stays 2D); the 3D fields of a row are read by one set of rules,
:mod:`~dfrmot_jax.metrics.common.fields3d`.

Typical use::

    gt = prepare_gt(root, "car", sequences)             # once per split
    res = evaluate_files("out/run1", gt)                 # {seq | 'COMBINED': {field: value}}
    df = evaluate_classes("out/run1", root, "car,pedestrian")  # tidy: class, seq, ...; + class 'average'
    many = evaluate_arrays(gt, ids, boxes, seq_offsets)  # B dicts from [B, T, K] tracker output
    res3 = evaluate_files("out/run1", gt, similarity="3d")  # the same fields, 3D IoU (label them HOTA_3d, ...)
    metrics_table(res)                                   # pandas, TrackEval summary (x100)
"""

from dfrmot_jax.metrics.common.sequences import class_sequences
from dfrmot_jax.metrics.kitti2d.evaluate import (ALL_FIELDS, CLASS_AVERAGED_FIELDS, CLASS_SUMMED_FIELDS, cached_gt,
                                                 class_average, evaluate_batch, evaluate_classes, evaluate_files,
                                                 evaluate_files_classes)
from dfrmot_jax.metrics.kitti2d.kitti import DuplicateIdError, PreparedGT, prepare_gt
from dfrmot_jax.metrics.kitti2d.lane_scorer import evaluate_arrays
from dfrmot_jax.metrics.kitti2d.table import classes_table, metrics_table

__all__ = ["PreparedGT", "prepare_gt", "cached_gt", "class_sequences", "evaluate_files", "evaluate_files_classes",
           "evaluate_classes", "class_average", "evaluate_arrays", "evaluate_batch", "metrics_table", "classes_table",
           "DuplicateIdError", "ALL_FIELDS", "CLASS_SUMMED_FIELDS", "CLASS_AVERAGED_FIELDS"]
