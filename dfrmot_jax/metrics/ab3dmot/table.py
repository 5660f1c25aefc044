"""AB3DMOT's KITTI figures as table columns, for several classes: what ``dfrmot eval --metrics
ab3dmot`` adds beside ``tracker class seq``.

Columns (:data:`AB3DMOT_COLUMNS`): ``sAMOTA AMOTA AMOTP`` and the best-threshold figures AB3DMOT
prints, prefixed to keep them apart from TrackEval's CLEAR columns: ``ab3dmot_MOTA ab3dmot_MOTP
ab3dmot_IDS ab3dmot_FRAG ab3dmot_FP ab3dmot_FN``. Ratios are on the scale of the table's other ratio
columns (percent, :data:`RATIO_SCALE`: ``metrics_table`` writes HOTA, MOTA, MOTP, ... x100), counts
are ints. AB3DMOT's figures exist for a whole sequence list only (its recall thresholds are drawn
from all sequences together): they fill the ``COMBINED`` rows; per-sequence rows hold NaN. The class
average (``class = average``) averages the ratios over the classes and sums the counts, as the
TrackEval class average does.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from dfrmot_jax.metrics.ab3dmot.evaluate import evaluate_ab3dmot_files
from dfrmot_jax.metrics.common.names import name_list

__all__ = ["METRIC_FAMILIES", "AB3DMOT_RATIO_COLUMNS", "AB3DMOT_COUNT_COLUMNS", "AB3DMOT_COLUMNS", "RATIO_SCALE",
           "parse_metric_families", "ab3dmot_columns", "ab3dmot_class_average", "evaluate_ab3dmot_classes",
           "ab3dmot_table", "add_ab3dmot_columns"]

#: AB3DMOT's figures as table columns (:func:`ab3dmot_columns`): ratios (x100, as the table's other
#: ratios) and counts, prefixed ``ab3dmot_`` where CLEAR has a column of the name
AB3DMOT_RATIO_COLUMNS = ("sAMOTA", "AMOTA", "AMOTP", "ab3dmot_MOTA", "ab3dmot_MOTP")
AB3DMOT_COUNT_COLUMNS = ("ab3dmot_IDS", "ab3dmot_FRAG", "ab3dmot_FP", "ab3dmot_FN")
AB3DMOT_COLUMNS = AB3DMOT_RATIO_COLUMNS + AB3DMOT_COUNT_COLUMNS
#: metric families ``dfrmot eval --metrics`` can pick
METRIC_FAMILIES = ("kitti2d", "ab3dmot")
#: the result dict's keys -> column names
_RENAME = {"sAMOTA": "sAMOTA", "AMOTA": "AMOTA", "AMOTP": "AMOTP", "MOTA": "ab3dmot_MOTA", "MOTP": "ab3dmot_MOTP",
           "IDS": "ab3dmot_IDS", "FRAG": "ab3dmot_FRAG", "FP": "ab3dmot_FP", "FN": "ab3dmot_FN"}
assert tuple(_RENAME.values()) == AB3DMOT_COLUMNS
_COUNTS = AB3DMOT_COUNT_COLUMNS
RATIO_SCALE = 100.0


def parse_metric_families(text) -> tuple:
    """``'kitti2d,ab3dmot'`` (or a list) -> ``('kitti2d', 'ab3dmot')`` in the given order, lower
    case, duplicates dropped; ValueError naming the families for anything else or nothing."""
    return name_list(text, METRIC_FAMILIES,
                     lambda m: f"metric family {m!r}: expected {', '.join(METRIC_FAMILIES)} (comma-separated)",
                     f"no metric family given (expected {', '.join(METRIC_FAMILIES)})")


def ab3dmot_columns(res: Mapping[str, object]) -> dict:
    """One :func:`~dfrmot_jax.metrics.ab3dmot.ab3dmot_metrics` dict -> {column: value} (ratios
    x :data:`RATIO_SCALE`, counts int)."""
    return {col: (int(res[k]) if col in _COUNTS else RATIO_SCALE * float(res[k])) for k, col in _RENAME.items()}


def ab3dmot_class_average(rows: Sequence[Mapping[str, object]]) -> dict:
    """Columns of several classes -> their class average (ratios averaged, counts summed)."""
    return {c: (int(sum(r[c] for r in rows)) if c in _COUNTS else float(np.mean([r[c] for r in rows])))
            for c in AB3DMOT_COLUMNS}


def evaluate_ab3dmot_classes(results_dir, root, sequences_by_class: Mapping[str, Sequence], iou="3d:0.25",
                             missing: str = "empty") -> dict:
    """AB3DMOT's figures of one result folder per class: ``{cls: result dict}`` (each class on its
    own sequences, :func:`~dfrmot_jax.metrics.ab3dmot.evaluate_ab3dmot_files`)."""
    return {c: evaluate_ab3dmot_files(results_dir, root, c, seqs, iou=iou, missing=missing)
            for c, seqs in sequences_by_class.items()}


def ab3dmot_table(per_class: Mapping[str, Mapping[str, object]], tracker: str | None = None) -> pd.DataFrame:
    """``{cls: result dict}`` -> rows ``[tracker,] class, seq='COMBINED'`` + :data:`AB3DMOT_COLUMNS`,
    one per class and, with two or more classes, ``class = 'average'``."""
    rows = [{"class": c, "seq": "COMBINED", **ab3dmot_columns(r)} for c, r in per_class.items()]
    if len(rows) > 1:
        rows.append({"class": "average", "seq": "COMBINED", **ab3dmot_class_average(rows)})
    df = pd.DataFrame(rows)
    if tracker is not None:
        df.insert(0, "tracker", tracker)
    return df


def add_ab3dmot_columns(table: pd.DataFrame | None, ab: pd.DataFrame) -> pd.DataFrame:
    """The kitti2d table (or None) with :func:`ab3dmot_table`'s columns joined on ``tracker class
    seq`` (NaN on per-sequence rows); its row order is kept. Counts stay integers (pandas ``Int64``
    where a row has none)."""
    if table is None:
        return ab.reset_index(drop=True)
    keys = [k for k in ("tracker", "class", "seq") if k in table.columns and k in ab.columns]
    out = table.merge(ab, on=keys, how="left")
    for c in _COUNTS:
        out[c] = out[c].astype("Int64")
    return out
