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

The figures are those of one way of summing track scores (:mod:`~dfrmot_jax.metrics.samota.sums`,
``ab3dmot_sum`` names it: ``compensated`` by default); :data:`AB3DMOT_OTHER_COLUMNS` hold the headline
figures with the other sum (``other_sAMOTA other_AMOTA other_ab3dmot_MOTA``; NaN where not computed),
so that a reader comparing with a paper sees both. :func:`recall_table`: where the recall points go,
one row per (sum, recall point).
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from dfrmot_jax.choices import METRIC_FAMILIES, parse_metric_families
from .evaluate import evaluate_ab3dmot_files
from .passes import PASS_FIELDS
from .sums import DEFAULT_SUM, other_sum, python_of

__all__ = ["METRIC_FAMILIES", "AB3DMOT_RATIO_COLUMNS", "AB3DMOT_COUNT_COLUMNS", "AB3DMOT_COLUMNS",
           "AB3DMOT_OTHER_COLUMNS", "RATIO_SCALE", "RECALL_TABLE_COLUMNS", "parse_metric_families", "ab3dmot_columns",
           "ab3dmot_class_average", "evaluate_ab3dmot_classes", "ab3dmot_table", "add_ab3dmot_columns",
           "recall_table", "other_sum_line"]

#: AB3DMOT's figures as table columns (:func:`ab3dmot_columns`): ratios (x100, as the table's other
#: ratios) and counts, prefixed ``ab3dmot_`` where CLEAR has a column of the name
AB3DMOT_RATIO_COLUMNS = ("sAMOTA", "AMOTA", "AMOTP", "ab3dmot_MOTA", "ab3dmot_MOTP")
AB3DMOT_COUNT_COLUMNS = ("ab3dmot_IDS", "ab3dmot_FRAG", "ab3dmot_FP", "ab3dmot_FN")
AB3DMOT_COLUMNS = AB3DMOT_RATIO_COLUMNS + AB3DMOT_COUNT_COLUMNS
#: the headline figures with the other way of summing track scores (result key ``other``), percent
AB3DMOT_OTHER_COLUMNS = ("other_sAMOTA", "other_AMOTA", "other_ab3dmot_MOTA")
_OTHER = {"other_sAMOTA": "sAMOTA", "other_AMOTA": "AMOTA", "other_ab3dmot_MOTA": "MOTA"}
#: :func:`recall_table`'s columns after its keys (ratios in percent, ``recall_point`` too; ``threshold`` a
#: track score)
RECALL_TABLE_COLUMNS = PASS_FIELDS
_RECALL_PERCENT = ("recall_point", "recall", "precision", "MOTA", "MOTP", "sMOTA")
#: the result dict's keys -> column names
_RENAME = {"sAMOTA": "sAMOTA", "AMOTA": "AMOTA", "AMOTP": "AMOTP", "MOTA": "ab3dmot_MOTA", "MOTP": "ab3dmot_MOTP",
           "IDS": "ab3dmot_IDS", "FRAG": "ab3dmot_FRAG", "FP": "ab3dmot_FP", "FN": "ab3dmot_FN"}
assert tuple(_RENAME.values()) == AB3DMOT_COLUMNS
_COUNTS = AB3DMOT_COUNT_COLUMNS
RATIO_SCALE = 100.0


def ab3dmot_columns(res: Mapping[str, object]) -> dict:
    """One :func:`~dfrmot_jax.metrics.samota.ab3dmot_metrics` dict -> {column: value} (ratios
    x :data:`RATIO_SCALE`, counts int), and :data:`AB3DMOT_OTHER_COLUMNS` (NaN without ``other``)."""
    out = {col: (int(res[k]) if col in _COUNTS else RATIO_SCALE * float(res[k])) for k, col in _RENAME.items()}
    other = res.get("other")
    out.update({col: (RATIO_SCALE * float(other[k]) if other is not None else float("nan"))
                for col, k in _OTHER.items()})
    return out


def ab3dmot_class_average(rows: Sequence[Mapping[str, object]]) -> dict:
    """Columns of several classes -> their class average (ratios averaged, counts summed)."""
    return {c: (int(sum(r[c] for r in rows)) if c in _COUNTS else float(np.mean([r[c] for r in rows])))
            for c in AB3DMOT_COLUMNS + AB3DMOT_OTHER_COLUMNS}


def evaluate_ab3dmot_classes(results_dir, root, sequences_by_class: Mapping[str, Sequence], iou="3d:0.25",
                             missing: str = "empty", sum_mode: str = DEFAULT_SUM, other: bool = True) -> dict:
    """AB3DMOT's figures of one result folder per class: ``{cls: result dict}`` (each class on its
    own sequences, :func:`~dfrmot_jax.metrics.samota.evaluate_ab3dmot_files`, with ``sum_mode`` and,
    with ``other``, the other sum's figures too)."""
    return {c: evaluate_ab3dmot_files(results_dir, root, c, seqs, iou=iou, missing=missing, sum_mode=sum_mode,
                                      other=other)
            for c, seqs in sequences_by_class.items()}


def recall_table(res: Mapping[str, object], **keys) -> pd.DataFrame:
    """Where the recall points go: one row per (sum, recall point) of a result dict (its own sum,
    then ``other``'s when computed) -> columns ``*keys, sum,`` + :data:`RECALL_TABLE_COLUMNS`.

    Every ratio is a percent, the recall point too (``recall_point`` 2.5, 5, 7.5, ... as ``recall``).
    Per pass: the recall point ``r`` and its score threshold, the recall reached, the pass's TP,
    FP, FN, IDS, FRAG, MOTA, MOTP, sMOTA (percent), ``TP_ignored`` (matches to ignored ground truth:
    counted in the recall that places the points, not in sMOTA's denominator) and ``drifted`` (tracks
    dropped only because the re-averaged score drifted below the threshold, their first mean not)."""
    parts = []
    for r in (res, res.get("other")):
        if r is None:
            continue
        p = pd.DataFrame({k: r["passes"][k] for k in PASS_FIELDS})
        for k in _RECALL_PERCENT:
            p[k] = RATIO_SCALE * p[k].astype(np.float64)
        p["recall_point"] = np.round(p["recall_point"], 9)       # a label: 7.5, not 7.500000000000001
        p.insert(0, "sum", r["sum"])
        parts.append(p)
    df = pd.concat(parts, ignore_index=True)
    for i, (k, v) in enumerate(keys.items()):
        df.insert(i, k, v)
    return df


def other_sum_line(res: Mapping[str, object], label: str = "") -> str | None:
    """One line giving the other sum's headline figures where they differ from ``res``'s (None where
    they agree or were not computed): what a reader comparing with a paper needs to know."""
    other = res.get("other")
    if other is None:
        return None
    keys = ("sAMOTA", "AMOTA", "MOTA")
    if all(other[k] == res[k] for k in keys):
        return None
    mode = res["sum"]
    figs = ", ".join(f"{k} {RATIO_SCALE * other[k]:.2f}" for k in keys)
    return (f"{label + ': ' if label else ''}with the {other_sum(mode)} sum of AB3DMOT's evaluator on "
            f"{python_of(other_sum(mode))}: {figs} (above: {mode}, {python_of(mode)})")


def ab3dmot_table(per_class: Mapping[str, Mapping[str, object]], tracker: str | None = None) -> pd.DataFrame:
    """``{cls: result dict}`` -> rows ``[tracker,] class, seq='COMBINED'`` + :data:`AB3DMOT_COLUMNS` +
    :data:`AB3DMOT_OTHER_COLUMNS` + ``ab3dmot_sum`` (the sum of the main columns), one per class
    and, with two or more classes, ``class = 'average'``."""
    rows = [{"class": c, "seq": "COMBINED", **ab3dmot_columns(r)} for c, r in per_class.items()]
    if len(rows) > 1:
        rows.append({"class": "average", "seq": "COMBINED", **ab3dmot_class_average(rows)})
    df = pd.DataFrame(rows)
    df["ab3dmot_sum"] = next(iter(per_class.values()))["sum"] if per_class else DEFAULT_SUM
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
