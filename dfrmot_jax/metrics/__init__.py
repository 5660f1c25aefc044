"""KITTI tracking metrics, exact to their reference evaluators, fast and batched: two families.

* :mod:`~dfrmot_jax.metrics.kitti2d`: TrackEval's KITTI 2D-box HOTA, CLEAR and Identity
  (``kitti``: ground truth and tracker preprocessing, as TrackEval's Kitti2DBox; ``hota``,
  ``clear``, ``identity``: the metrics; ``boxes``: TrackEval's IoU; ``evaluate``: entry points;
  ``lane_scorer``: many padded outputs; ``table``: its columns). With ``similarity='3d'`` or
  ``'bev'`` on every entry point the metrics match on the 3D or bird's-eye-view IoU instead of the
  image IoU (``similarity``; the KITTI preprocessing stays 2D). ``dfrmot_jax.metrics`` offers this
  family's entry points (``__all__``, typical use below).
* :mod:`~dfrmot_jax.metrics.samota`: AB3DMOT's KITTI 3D MOT metrics, sAMOTA, AMOTA, AMOTP and its
  best-threshold CLEAR figures, exact to its evaluator (``evaluate``: ``evaluate_ab3dmot_files``;
  ``prep`` reading its inputs, ``passes``, ``arrays`` scoring padded outputs, ``table`` its columns).

What both use is :mod:`~dfrmot_jax.metrics.common`, the one place where they meet (neither imports
the other): the rotated 3D / BEV box IoU (``box3d``), the one set of rules for a row's 3D fields
(``fields3d``), pair bookkeeping (``pairs``), distinct rows (``distinct``), a class's sequence list
(``sequences``). Both families' columns together, for sweeps and tunes: :mod:`~dfrmot_jax.metrics.columns`.
Around them: :mod:`~dfrmot_jax.cli.eval` (``dfrmot eval``), :mod:`~dfrmot_jax.testing.trackeval_adapter`
(running the reference ``trackeval`` package) and :mod:`~dfrmot_jax.testing.metric_edits` (test outputs).

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
