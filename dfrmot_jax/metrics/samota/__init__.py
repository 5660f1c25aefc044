"""AB3DMOT's KITTI 3D MOT family: sAMOTA, AMOTA, AMOTP and its best-threshold CLEAR figures, exactly
as the evaluator of xinshuoweng/AB3DMOT.

Modules: ``evaluate`` (the rules and the entry points, ``evaluate_ab3dmot_files``), ``prep`` (its
inputs read by its rules: ground truth, result files, seqmaps), ``passes`` (all thresholds of one
output at once), ``arrays`` (many padded outputs at once, what sweeps use), ``table`` (the family's
columns, ``dfrmot eval --metrics ab3dmot``). What it shares with TrackEval's family is in
:mod:`dfrmot_jax.metrics.common`; it imports nothing of :mod:`dfrmot_jax.metrics.kitti2d`.
"""

from . import arrays, evaluate, passes, prep, table

__all__ = ["arrays", "evaluate", "passes", "prep", "table"]
