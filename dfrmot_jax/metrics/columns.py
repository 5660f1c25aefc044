"""The columns of both metric families together, for sweep tables and tunes: the columns an objective
may name (:func:`canonical_objective`) and how a class average combines each column
(:func:`class_combiner`, :func:`class_average_columns`). TrackEval's columns are
:mod:`dfrmot_jax.metrics.kitti2d`'s, AB3DMOT's :mod:`dfrmot_jax.metrics.samota`'s; this module is
where a user of both finds them together (the families themselves meet only in
:mod:`dfrmot_jax.metrics.common`).
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from .samota.table import AB3DMOT_COLUMNS, AB3DMOT_COUNT_COLUMNS, AB3DMOT_RATIO_COLUMNS
from dfrmot_jax.metrics.kitti2d.evaluate import CLASS_AVERAGED_FIELDS, CLASS_SUMMED_FIELDS
from dfrmot_jax.metrics.kitti2d.table import TABLE_FIELDS

__all__ = ["OBJECTIVE_FIELDS", "canonical_objective", "class_combiner", "class_average_columns"]

#: every column an objective (a sweep's report, a tune) may name
OBJECTIVE_FIELDS = TABLE_FIELDS + AB3DMOT_COLUMNS


def canonical_objective(objective) -> str:
    """A metric name in any case (``hota``, ``idf1``) -> its column name (``HOTA``, ``IDF1``);
    ValueError naming the metrics when it is none of them."""
    if isinstance(objective, str):
        by_lower = {f.lower(): f for f in OBJECTIVE_FIELDS}
        if objective.lower() in by_lower:
            return by_lower[objective.lower()]
    raise ValueError(f"objective {objective!r}: not a metric; expected one of {list(OBJECTIVE_FIELDS)} (any case)")


def class_combiner(field: str) -> str | None:
    """How the class average treats a field or summary column: "sum" (:data:`CLASS_SUMMED_FIELDS`),
    "mean" (:data:`CLASS_AVERAGED_FIELDS`) or None (not a metric)."""
    if field in CLASS_SUMMED_FIELDS or field in AB3DMOT_COUNT_COLUMNS:
        return "sum"
    if field in CLASS_AVERAGED_FIELDS or field in AB3DMOT_RATIO_COLUMNS:
        return "mean"
    return None


def class_average_columns(per_class: Sequence[Mapping[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """The class average of summary columns (arrays [C] per class, x100 ratios): TrackEval's
    ``combine_classes_class_averaged`` as
    :func:`~dfrmot_jax.metrics.kitti2d.evaluate.class_average` does it (``CLASS_SUMMED_FIELDS``
    summed, ``CLASS_AVERAGED_FIELDS`` averaged), vectorised over rows. A summary column is a linear
    function of its field (a ratio x100, HOTA's the mean over alphas), so averaging the columns
    equals the summary of the averaged fields."""
    out = {}
    for f in per_class[0]:
        how = class_combiner(f)
        if how is None or not all(f in p for p in per_class):
            continue
        stack = np.stack([np.asarray(p[f]) for p in per_class])
        out[f] = stack.sum(axis=0) if how == "sum" else stack.astype(np.float64).mean(axis=0)
    return out
