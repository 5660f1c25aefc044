"""Tidy tables of metric results (TrackEval's summary view: percentages x100, counts as ints)."""

from __future__ import annotations

from typing import Mapping

import numpy as np
import pandas as pd

from dfrmot_jax.metrics.kitti2d import clear, hota, identity

# TrackEval's summary fields, in its order (HOTA, CLEAR, Identity, Count). In a class average row
# (``class = 'average'``) the PERCENT_FIELDS (ratios) are the mean over the classes and the
# COUNT_FIELDS are summed (see dfrmot_jax.metrics.kitti2d.evaluate.class_average).
PERCENT_FIELDS = (hota.FLOAT_ARRAY_FIELDS + hota.FLOAT_FIELDS + clear.MAIN_FLOAT_FIELDS + identity.FLOAT_FIELDS)
COUNT_FIELDS = clear.MAIN_INTEGER_FIELDS + identity.INTEGER_FIELDS + ("Dets", "GT_Dets", "IDs", "GT_IDs")
TABLE_FIELDS = (hota.FLOAT_ARRAY_FIELDS + hota.FLOAT_FIELDS + clear.MAIN_FLOAT_FIELDS + clear.MAIN_INTEGER_FIELDS
                + identity.FLOAT_FIELDS + identity.INTEGER_FIELDS + ("Dets", "GT_Dets", "IDs", "GT_IDs"))
COMPACT_FIELDS = ("HOTA", "DetA", "AssA", "MOTA", "MOTP", "IDSW", "IDF1", "MT", "ML", "Frag")


def summary_row(res: Mapping[str, object]) -> dict[str, object]:
    """One result dict ({field: value}) -> {field: summary value} for ``TABLE_FIELDS``.

    HOTA's per-alpha arrays become their mean x100, other ratios x100, counts ints.
    """
    row = {}
    for f in TABLE_FIELDS:
        if f not in res:
            continue
        v = res[f]
        if f in COUNT_FIELDS:
            row[f] = int(round(float(v)))
        elif f in hota.FLOAT_ARRAY_FIELDS:
            row[f] = 100.0 * float(np.mean(v))
        else:
            row[f] = 100.0 * float(v)
    return row


def metrics_table(results: Mapping[str, Mapping[str, object]], tracker: str | None = None) -> pd.DataFrame:
    """One row per sequence and ``COMBINED`` (last), TrackEval field names as columns.

    results: ``{seq or 'COMBINED': {field: value}}`` from :func:`evaluate_files` /
    :func:`evaluate_arrays`. Percent columns (HOTA, DetA, AssA, DetRe, DetPr, AssRe, AssPr, LocA,
    OWTA, HOTA(0), LocA(0), HOTALocA(0), MOTA, MOTP, MODA, CLR_Re, CLR_Pr, MTR, PTR, MLR, sMOTA,
    IDF1, IDR, IDP) are x100 (HOTA family: mean over the 19 alphas); counts (CLR_TP, CLR_FN,
    CLR_FP, IDSW, MT, PT, ML, Frag, IDTP, IDFN, IDFP, Dets, GT_Dets, IDs, GT_IDs) are ints.
    With ``tracker`` a first column ``tracker`` is added. The index is ``seq``.
    """
    keys = [k for k in results if k != "COMBINED"] + (["COMBINED"] if "COMBINED" in results else [])
    rows = []
    for k in keys:
        row = {"tracker": tracker} if tracker is not None else {}
        row["seq"] = k
        row.update(summary_row(results[k]))
        rows.append(row)
    df = pd.DataFrame(rows).set_index("seq")
    for f in COUNT_FIELDS:
        if f in df:
            df[f] = df[f].astype("int64")
    return df


def classes_table(results_by_class: Mapping[str, Mapping[str, Mapping[str, object]]],
                  tracker: str | None = None) -> pd.DataFrame:
    """Tidy table of several classes: columns ``[tracker,] class, seq`` and the summary fields.

    results_by_class: ``{cls: {seq or 'COMBINED': {field: value}}}`` as from
    :func:`dfrmot_jax.metrics.kitti2d.evaluate.evaluate_files_classes` (a class ``'average'`` holds only
    ``COMBINED``: ratios averaged over the classes, counts summed). Rows: per class its sequences
    then ``COMBINED``, classes in the given order; a plain RangeIndex.
    """
    parts = []
    for cls, res in results_by_class.items():
        df = metrics_table(res, tracker=tracker).reset_index()
        df["class"] = cls
        parts.append(df)
    out = pd.concat(parts, ignore_index=True)
    keys = (["tracker"] if tracker is not None else []) + ["class", "seq"]
    out = out[keys + [c for c in out.columns if c not in keys]]
    for f in COUNT_FIELDS:
        if f in out:
            out[f] = out[f].astype("int64")
    return out
