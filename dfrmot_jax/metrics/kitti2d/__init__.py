"""TrackEval's KITTI 2D-box family: HOTA, CLEAR and Identity, exactly as TrackEval's ``Kitti2DBox``.

Modules: ``kitti`` (ground truth and tracker preprocessing), ``boxes`` (TrackEval's box IoU, bit for
bit), ``box_table`` (the IoU of each distinct (frame, box) of a batch, computed once), ``similarity``
(image, 3D or BEV IoU as the metrics' similarity), ``hota``, ``clear``, ``identity`` (the metrics),
``evaluate`` (entry points, class averages, worker pools, per-sequence summaries),
``lane_scorer`` (many lanes, each distinct output of a sequence scored once: ``LaneScorer``,
``evaluate_arrays``), ``tracker_files`` (result files read as TrackEval reads them), ``table`` (the
family's columns, TrackEval's summary view). What it shares with AB3DMOT's family is in
:mod:`dfrmot_jax.metrics.common`; it imports nothing of :mod:`dfrmot_jax.metrics.samota`.
"""

from . import box_table, boxes, clear, evaluate, hota, identity, kitti, lane_scorer, similarity, table, tracker_files

__all__ = ["box_table", "boxes", "clear", "evaluate", "hota", "identity", "kitti", "lane_scorer", "similarity",
           "table", "tracker_files"]
