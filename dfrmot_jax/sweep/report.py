"""The text report of a sweep: best configs, the baseline beside them, sensitivity, cross-validation
and (distortion sweeps) robustness curves and contrasts."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

import numpy as np
import pandas as pd

from ..metrics.table import canonical_objective
from .analysis import (
    check_objective,
    class_view,
    classes_of,
    cross_validate,
    fmt_value,
    json_value,
    objective_direction,
    pareto_front,
    rank_configs,
    report_class_of,
    sensitivity,
    varied_axes,
)
from .robustness import contrast_text, robustness_curves, robustness_text
from .spec import AVERAGE, Contrast, contrast_doc, parse_contrast
from .store import load_results, read_manifest
from .table import COMBINED
from .text import WIDTH, paragraph, text_table  # noqa: F401  (WIDTH: the report's width)


#: the widest line of the printed report, except its last (one JSON object)
@dataclass
class SweepReport:
    """``text`` (the printed report) and ``summary`` (the JSON-able dict of its last line)."""

    text: str
    summary: dict
    top: pd.DataFrame
    sensitivity: pd.DataFrame
    cv: dict | None = None
    curves: pd.DataFrame | None = None          # distortion sweeps: robustness_curves(df, objective)
    contrast: list | None = None                # with a contrast: robustness_summary rows (dicts)
    data: pd.DataFrame | None = None            # the table reported on (every class)
    view: pd.DataFrame | None = None            # its rows ranked: the report's class (class_view), or all
    manifest: dict | None = None                # a directory's manifest

    def __str__(self) -> str:
        return self.text


def sweep_report(results, objective: str = "HOTA", folds: int | None = None, top: int = 10,
                 contrast: Contrast | Mapping | None = None, cls: str | None = None) -> SweepReport:
    """Best configs by ``objective`` (HOTA, MOTA, IDF1, AssA, ... maximised; IDSW, Frag, ...
    minimised), the baseline beside them, the sensitivity per axis and, with ``folds``, the
    cross-validated best. ``results``: a table from :func:`sweep` or a sweep directory.

    Distortion sweeps add the objective per distortion level and kind (mean ± SE over seeds) for
    the ``top`` settings and, with ``contrast`` (a :class:`Contrast`, a dict ``{axis, high, low,
    by}`` or, for a directory, the sweep file's ``report.contrast``), the gap between two groups of
    an axis per level (:func:`robustness_contrast`) and where it stops helping
    (:func:`robustness_summary`).

    A sweep over several classes ranks on ``cls``: one class (its rows with its own parameter values,
    :func:`class_view`) or ``"average"`` (default; for a directory: the file's ``report.class``):
    the class average (ratios averaged over the classes, counts summed), cross-validated with each
    class's sequences folded on their own (:func:`cross_validate`)."""
    if not isinstance(results, pd.DataFrame):
        d = Path(results)
        manifest = read_manifest(d)
        df = load_results(d, allow_partial=True)
        if folds is None:
            folds = manifest.get("folds")
        if contrast is None and manifest.get("contrast"):
            contrast = manifest["contrast"]
        if cls is None:
            cls = manifest.get("report_class")
        n_expected = manifest.get("configs")
        tune = (d, manifest) if manifest.get("kind") == "tune" else None
    else:
        df, n_expected, tune, manifest = results, None, None, None
    if isinstance(contrast, Mapping):
        contrast = parse_contrast(dict(contrast), None)
    objective = canonical_objective(objective)
    if not isinstance(top, (int, np.integer)) or isinstance(top, bool) or top < 1:
        raise ValueError(f"top={top!r}: expected a whole number >= 1 (configs listed)")
    check_objective(df, objective)
    full = df
    classes = classes_of(full)
    cls = report_class_of(full, cls)
    if classes:
        df = class_view(full, cls)
    comb = df[df["sequence"] == COMBINED].reset_index(drop=True)
    axes = varied_axes(df)
    order = rank_configs(comb[objective].to_numpy(), objective)
    best = comb.iloc[int(order[0])]
    base_rows = comb[comb["baseline"]]
    baseline = base_rows.iloc[0] if len(base_rows) else None
    show = list(dict.fromkeys([objective, "HOTA", "DetA", "AssA", "MOTA", "IDF1", "IDSW"]))
    show = [c for c in show if c in comb.columns]
    topdf = comb.iloc[order[:top]][["config", "config_hash"] + show + axes + ["overflow"]].copy()
    topdf.insert(0, "rank", np.arange(1, len(topdf) + 1))
    lines = []
    name = df["sweep"].iloc[0] if "sweep" in df.columns else "sweep"
    n_cfg = int(full["config"].nunique())
    partial = f" (partial: {n_cfg} of {n_expected} configs)" if n_expected and n_expected != n_cfg else ""
    better = "lower" if objective_direction(objective) < 0 else "higher"
    if len(classes) > 1:
        per = {k: full.loc[(full["class"] == k) & (full["sequence"] != COMBINED), "sequence"].nunique()
               for k in classes}
        seqs = per[cls] if cls != AVERAGE else sum(per.values())
        on = (f"the class average ({', '.join(classes)}: ratios averaged over the classes, counts summed)"
              if cls == AVERAGE else f"class {cls}" + (f" ({len(comb):,} distinct configs for it)"
                                                        if len(comb) != n_cfg else ""))
        lines.append(paragraph(f"sweep {name}: objective {objective} ({better} is better) on {on}; {n_cfg:,} configs "
                           f"x classes {', '.join(f'{k} ({n} sequences)' for k, n in per.items())}{partial}"))
    else:
        seqs = df.loc[df["sequence"] != COMBINED, "sequence"].nunique()
        lines.append(paragraph(f"sweep {name}: {len(comb):,} configs x {seqs} sequences{partial}; objective {objective} "
                           f"({better} is better)" + (f"; class {cls}" if cls and cls != "car" else "")))
    lines.append("")
    lines.append(f"top {len(topdf)} configs (in-sample, COMBINED over all sequences):")
    view = topdf.copy()
    if baseline is not None:
        brow = {"rank": "base", "config": baseline["config"], "config_hash": baseline["config_hash"],
                **{c: baseline[c] for c in show + axes + ["overflow"]}}
        view = pd.concat([view, pd.DataFrame([brow])], ignore_index=True)
    lines.append(text_table(view, keys=("rank",), float_format=lambda v: f"{v:.3f}"))
    if baseline is not None:
        diff = [f"{a}={fmt_value(best[a])} (baseline {fmt_value(baseline[a])})" for a in axes if best[a] != baseline[a]]
        lines.append(paragraph(f"best vs baseline: {objective} {best[objective]:.3f} vs {baseline[objective]:.3f} "
                           f"({best[objective] - baseline[objective]:+.3f}); changed: {', '.join(diff) or 'nothing'}"))
    sens = sensitivity(df, objective) if axes else pd.DataFrame()
    if len(sens):
        lines.append("")
        lines.append(paragraph(f"sensitivity of {objective} per axis (spread_best: range over an axis' values of the best "
                           f"config with that value; spread_mean: range of the means; corr: rank correlation; "
                           f"oat_range: moving only this axis away from the best config):"))
        lines.append(text_table(sens, keys=("axis",), float_format=lambda v: f"{v:.3f}"))
    curves = answers = None
    if "distortion.kind" in df.columns and (df["distortion.kind"] != "none").any():
        rob_lines, rob_summary = robustness_text(df, objective, top)
        lines.append("")
        lines.extend(rob_lines)
        curves = robustness_curves(df, [objective])
        if contrast is not None:
            con_lines, answers = contrast_text(df, contrast, objective)
            lines.extend(con_lines)
    cv = None
    if folds:
        cv = cross_validate(full, folds, objective, cls)
        lines.append("")
        lines.append(paragraph(f"{folds}-fold cross-validation over sequences (stratified by frame count"
                           + ("; each class's sequences folded on their own" if cv.get("class") == AVERAGE else "")
                           + "): best config chosen on the training folds, scored on the held-out fold"))
        fold_rows = []
        for p in cv["per_fold"]:
            row = comb[comb["config"] == p["config"]].iloc[0]
            changed = ", ".join(f"{a}={fmt_value(row[a])}" for a in axes if baseline is None or row[a] != baseline[a])
            test = p["test_sequences"]
            held = (" ".join(f"{k}:{','.join(v)}" for k, v in test.items()) if isinstance(test, Mapping)
                    else ",".join(test))
            fold_rows.append({"fold": p["fold"], "held_out_sequences": held,
                              "config": p["config"], "train": p["train"], "held_out": p["held_out"],
                              "baseline_held_out": p["baseline_held_out"], "changed": changed or "(baseline)"})
        lines.append(text_table(pd.DataFrame(fold_rows), keys=("fold",), text=("held_out_sequences", "changed"),
                            float_format=lambda v: f"{v:.3f}"))
        lines.append(paragraph(f"{objective}: cross-validated {cv['cross_validated']:.3f} (each sequence scored with the "
                           f"config chosen without it) | in-sample best {best[objective]:.3f}"
                           + (f" | baseline {baseline[objective]:.3f}" if baseline is not None else "")))
    tune_summary = None
    if tune is not None:
        tune_lines, tune_summary = _tune_section(*tune, objective)
        lines.extend(tune_lines)
    summary = {"objective": objective, "direction": "min" if objective_direction(objective) < 0 else "max",
               "configs": int(len(comb)), "sequences": int(seqs),
               **({"class": cls} if classes else {}), **({"classes": classes} if len(classes) > 1 else {}),
               "baseline": None if baseline is None else float(baseline[objective]),
               "best_in_sample": float(best[objective]),
               "best_config": {"config": int(best["config"]), "config_hash": best["config_hash"],
                               **{a: json_value(best[a]) for a in axes}}}
    if baseline is not None:
        summary["baseline_config_hash"] = baseline["config_hash"]
    if cv is not None:
        summary["best_cross_validated"] = cv["cross_validated"]
        summary["folds"] = folds
        summary["mean_held_out"] = cv["mean_held_out"]
        summary["fold_configs"] = [p["config_hash"] for p in cv["per_fold"]]
    if tune_summary is not None:
        summary["tune"] = tune_summary
    if curves is not None:
        summary["robustness"] = rob_summary
    if answers is not None:
        summary["contrast"] = {**contrast_doc(contrast), "answer": answers}
    lines.append("")
    lines.append(json.dumps(summary))
    return SweepReport("\n".join(lines), summary, topdf, sens, cv, curves, answers, full, df, manifest)


def _tune_section(d: Path, manifest: dict, objective: str) -> tuple[list[str], dict]:
    """A tune directory's own figures: the search, the nested cross-validation (``nested.json``: the
    honest figure; a flat ``--folds`` over a tune's trials would choose among configs the tuner
    proposed after seeing every sequence) and, with two objectives, the Pareto front."""
    t = manifest.get("tune", {})
    lines = ["", paragraph(f"tune: sampler {t.get('sampler')}, budget {t.get('budget')} configs in batches of "
                       f"{t.get('batch')}, objectives {', '.join(t.get('objectives', []))}, seed {t.get('seed')}"
                       + ("; gradient refinement" if t.get("refine") else ""))]
    out: dict = {"sampler": t.get("sampler"), "budget": t.get("budget")}
    nested = d / "nested.json"
    if nested.is_file():
        n = json.loads(nested.read_text())
        lines.append(paragraph(f"nested {n['folds']}-fold cross-validation (the tune rerun per fold on the training "
                           f"sequences only, its choice scored on the held-out fold): {n['objective']} cross-validated "
                           f"{n['cross_validated']:.3f} | baseline {n['baseline']:.3f} on the same sequences"))
        out.update(cross_validated=n["cross_validated"], baseline_cross_validated=n["baseline"], folds=n["folds"])
    elif t.get("folds"):
        lines.append("nested cross-validation: not finished (rerun the tune to resume)")
    transfer = d / "transfer.json"
    if transfer.is_file():
        tr = json.loads(transfer.read_text())
        pairs = ", ".join(f"{k} {v:.3f} (baseline {tr['baseline'][k]:.3f})" for k, v in tr["chosen"].items())
        lines.append(paragraph(f"transfer: the chosen config unchanged on {tr['det2d']} + {tr['det3d']}, beside that "
                           f"pair's baseline ({', '.join(f'{k} = {v}' for k, v in tr['baseline_params'].items()) or 'the tune baseline'}): {pairs}"))
        out["transfer"] = tr
    objs = manifest.get("objectives", [])
    trials = d / "trials.parquet"
    if len(objs) == 2 and trials.is_file():
        front = pareto_front(pd.read_parquet(trials), objs, manifest["directions"])
        lines.append(f"Pareto front ({objs[0]} vs {objs[1]}, {len(front)} trials):")
        lines.append(text_table(front[["trial"] + objs].reset_index(drop=True), keys=("trial",),
                            float_format=lambda x: f"{x:.3f}"))
        out["pareto"] = front[["trial"] + objs].to_dict("records")
    return lines, out
