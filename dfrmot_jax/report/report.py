"""The report of a sweep, computed once: best configs, the baseline beside them, sensitivity,
cross-validation and (distortion sweeps) robustness curves and contrasts, as one
:class:`SweepReport` holding both the numbers and the printed text; the HTML page
(:mod:`.html`) is drawn from the same object, so the two always show the same figures."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

import numpy as np
import pandas as pd

from ..metrics.samota.sums import other_sum, python_of
from ..metrics.samota.table import AB3DMOT_COLUMNS
from ..trackers.protocol import DEFAULT_FAMILY
from ..trackers.registry import family_config
from ..metrics.columns import canonical_objective
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
from .intervals import interval_problem, report_intervals
from .robustness import contrast_text, robustness_curves, robustness_text
from ..table_columns import AVERAGE, COMBINED, Contrast, canonical_params, contrast_doc, parse_contrast, table_family
from .stored import load_results, manifest_family, read_manifest
from .text import WIDTH, paragraph, text_table  # noqa: F401  (WIDTH: the report's width)

#: the columns of the top-configs table, after the objective (those the table holds)
SHOWN = ("HOTA", "DetA", "AssA", "MOTA", "IDF1", "IDSW")


@dataclass
class SweepReport:
    """One report's numbers and its printed form: ``text`` (the printed report) and ``summary`` (the
    JSON-able dict of its last line), the tables they were written from, and for a directory its
    path and manifest. The HTML page (:func:`~.html.render_html`) is drawn from this object."""

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
    directory: Path | None = None               # the sweep or tune directory reported on
    baseline: pd.Series | None = None           # the baseline's COMBINED row of ``view`` (None: no baseline)
    folds_note: str = ""                        # how the folds were chosen, when the report chose them
    intervals: dict | None = None               # the paired bootstrap's figures (report.intervals)
    family: str | None = None                   # the tracker family of the table's configs (its columns)
    cv_note: str = ""                           # why there is no cross-validation, when the file asked for one

    def __str__(self) -> str:
        return self.text

    def top_with_baseline(self, n: int | None = None, label: str = "base") -> pd.DataFrame:
        """The first ``n`` rows of ``top`` (all by default) and the baseline's row below them, its
        ``rank`` set to ``label``: the table the report prints."""
        view = self.top if n is None else self.top.head(n)
        if self.baseline is None:
            return view.copy()
        row = {c: self.baseline[c] for c in view.columns if c in self.baseline.index}
        return pd.concat([view, pd.DataFrame([{**row, "rank": label}])], ignore_index=True)


def report_folds(directory, folds: int | None = None, objective: str = "") -> tuple[int | None, str]:
    """The folds of a directory's report that comes with a page (``dfrmot report --html``, the
    demo), and a note when chosen here: ``folds`` when given, else the sweep file's, else for a
    sweep of 2 or more sequences min(5, sequences). A tune keeps its own nested cross-validation;
    an AB3DMOT ``objective`` has none (its figures are not sums over sequences)."""
    if folds is not None:
        return folds, ""
    if canonical_objective(objective or "HOTA") in AB3DMOT_COLUMNS:
        return None, ""
    m = read_manifest(Path(directory))
    n = len(m.get("lengths") or [])
    if m.get("kind") == "tune" or m.get("folds") or n < 2:
        return None, ""
    k = min(5, n)
    return k, f"{k} folds: the sweep file sets none, so the report chose min(5, sequences)"


@dataclass
class _Source:
    """What a report is of: the table, and for a directory its path, manifest and stored settings."""

    df: pd.DataFrame
    folds: int | None
    contrast: Contrast | None
    cls: str | None
    n_expected: int | None = None
    directory: Path | None = None
    manifest: dict | None = None
    family: str | None = None           # the table's tracker family (None: read from its columns)


def _source(results, folds, contrast, cls, family=None, objective: str = "") -> _Source:
    """The table (given, or a directory's with its manifest's folds, contrast, class and tracker family
    as defaults). The sweep file's folds are not taken for an AB3DMOT ``objective``: its figures are
    not sums over sequences, so its rows cannot be folded (``--folds`` given says so, an error)."""
    if isinstance(results, pd.DataFrame):
        src = _Source(results, folds, contrast, cls, family=family)
    else:
        d = Path(results)
        m = read_manifest(d)
        file_folds = None if objective in AB3DMOT_COLUMNS else m.get("folds")
        src = _Source(load_results(d, allow_partial=True), file_folds if folds is None else folds,
                      contrast if contrast is not None or not m.get("contrast") else m["contrast"],
                      m.get("report_class") if cls is None else cls, m.get("configs"), d, m,
                      manifest_family(m) if family is None else family)
    src.family = table_family(src.df.columns, src.family).name
    if isinstance(src.contrast, Mapping):
        src.contrast = parse_contrast(dict(src.contrast), None, src.family)
    return src


def sweep_report(results, objective: str = "HOTA", folds: int | None = None, top: int = 10,
                 contrast: Contrast | Mapping | None = None, cls: str | None = None,
                 folds_note: str = "", family: str | None = None) -> SweepReport:
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
    class's sequences folded on their own (:func:`cross_validate`). ``folds_note``: how ``folds``
    was chosen (:func:`report_folds`), said beside the cross-validation. ``family``: the tracker family of
    its configs (its columns; default: a directory's manifest's, else read from them: ``table_family``)."""
    objective = canonical_objective(objective)
    src = _source(results, folds, contrast, cls, family, objective)
    fam = src.family
    if not isinstance(top, (int, np.integer)) or isinstance(top, bool) or top < 1:
        raise ValueError(f"top={top!r}: expected a whole number >= 1 (configs listed)")
    full = canonical_params(src.df, fam)         # one value per setting (the config hash's identity)
    check_objective(full, objective, fam)
    classes = classes_of(full)
    cls = report_class_of(full, src.cls)
    df = class_view(full, cls, fam) if classes else full
    comb = df[df["sequence"] == COMBINED].reset_index(drop=True)
    axes = varied_axes(df, fam)
    order = rank_configs(comb[objective].to_numpy(), objective)
    best = comb.iloc[int(order[0])]
    base_rows = comb[comb["baseline"]]
    baseline = base_rows.iloc[0] if len(base_rows) else None
    show = [c for c in dict.fromkeys([objective, *SHOWN]) if c in comb.columns]
    topdf = comb.iloc[order[:top]][["config", "config_hash"] + show + axes + ["overflow"]].copy()
    topdf.insert(0, "rank", np.arange(1, len(topdf) + 1))
    rep = SweepReport("", {}, topdf, pd.DataFrame(), data=full, view=df, manifest=src.manifest,
                      directory=src.directory, baseline=baseline, folds_note=folds_note, family=fam)
    kind = "tune" if src.manifest is not None and src.manifest.get("kind") == "tune" else "sweep"
    title = None if fam == DEFAULT_FAMILY else family_config(fam).title      # (another tracker family: named)
    head, seqs = _headline(full, df, comb, classes, cls, objective, src.n_expected, kind, title)
    rob_lines, rob_summary = [], None
    if "distortion.kind" in df.columns and (df["distortion.kind"] != "none").any():
        # a robustness study's answer first: its tables, then the generic sections (ranked over every lane)
        rob_lines, rob_summary = robustness_text(df, objective, top)
        rob_lines = ["", *rob_lines]
        rep.curves = robustness_curves(df, [objective])
        if src.contrast is not None:
            con_lines, rep.contrast = contrast_text(df, src.contrast, objective)
            rob_lines += con_lines
    lines = [head, *rob_lines, "", f"top {len(topdf)} configs (in-sample, COMBINED over all sequences):",
             text_table(rep.top_with_baseline(), keys=("rank",), float_format=lambda v: f"{v:.3f}")]
    if baseline is not None:
        diff = [f"{a}={fmt_value(best[a])} (baseline {fmt_value(baseline[a])})" for a in axes if best[a] != baseline[a]]
        lines.append(paragraph(f"best vs baseline: {objective} {best[objective]:.3f} vs {baseline[objective]:.3f} "
                               f"({best[objective] - baseline[objective]:+.3f}); changed: {', '.join(diff) or 'nothing'}"))
    if sum_line := ab3dmot_sum_line(comb, best, baseline, src.manifest):
        lines.append(paragraph(sum_line))
    lines += _interval_lines(rep, df, cls, objective)
    rep.sensitivity = sensitivity(df, objective, family=fam) if axes else pd.DataFrame()
    lines += _sensitivity_lines(rep.sensitivity, objective)
    if src.folds:
        rep.cv = cross_validate(full, src.folds, objective, cls, fam)
        lines += _cv_lines(rep, src.folds, comb, axes, best, objective)
    lines += _no_cv(rep, src, objective)
    tune_summary = None
    if src.manifest is not None and src.manifest.get("kind") == "tune":
        tune_lines, tune_summary = _tune_section(src.directory, src.manifest, objective)
        lines += tune_lines
    rep.summary = _summary(rep, objective, comb, seqs, classes, cls, best, axes, src.folds)
    if tune_summary is not None:
        rep.summary["tune"] = tune_summary
    if rob_summary is not None:
        rep.summary["robustness"] = rob_summary
    if rep.contrast is not None:
        rep.summary["contrast"] = {**contrast_doc(src.contrast), "answer": rep.contrast}
    rep.text = "\n".join(lines + ["", json.dumps(rep.summary)])
    return rep


def _no_cv(rep: SweepReport, src: _Source, objective: str) -> list[str]:
    """An AB3DMOT ``objective``'s report has no cross-validation: why (``rep.cv_note``, which the page
    says), printed when the sweep file asked for folds (they are not dropped without a word)."""
    if src.folds or objective not in AB3DMOT_COLUMNS:
        return []
    file_folds = (src.manifest or {}).get("folds")
    rep.cv_note = ("no cross-validation: " + (f"the sweep file's folds ({file_folds}) are not used for "
                                              if file_folds else "none for ")
                   + f"{objective}, AB3DMOT's figures are not sums over sequences and cannot be folded; the "
                   f"in-sample ranking above overstates what unseen sequences would give (rank by HOTA for a "
                   f"cross-validated figure)")
    return ["", paragraph(rep.cv_note)] if file_folds else []


def ab3dmot_sum_line(comb: pd.DataFrame, best, baseline, manifest: Mapping | None) -> str | None:
    """Which sum AB3DMOT's figures of a sweep were computed with and, where the other sum's differ, the
    best config's and the baseline's sAMOTA with it (``other_sAMOTA``); None without AB3DMOT's figures."""
    if "sAMOTA" not in comb.columns:
        return None
    mode = (manifest or {}).get("ab3dmot_sum")
    if mode is None or "other_sAMOTA" not in comb.columns:
        return ("AB3DMOT's figures: sequential sum of track scores (CPython <= 3.11's evaluator; written before the "
                "sum was a setting): rerun with [metrics] ab3dmot_sum for the compensated figures")
    other = other_sum(mode)
    rows = [("best", best)] + ([("baseline", baseline)] if baseline is not None else [])
    diff = [f"{k} sAMOTA {r['other_sAMOTA']:.3f} (vs {r['sAMOTA']:.3f})" for k, r in rows
            if np.isfinite(r["other_sAMOTA"]) and r["other_sAMOTA"] != r["sAMOTA"]]
    text = f"AB3DMOT's figures: {mode} sum of track scores (its evaluator on {python_of(mode)})"
    return text + (f"; with the {other} sum ({python_of(other)}): {', '.join(diff)}" if diff else "")


def _headline(full: pd.DataFrame, df: pd.DataFrame, comb: pd.DataFrame, classes: list, cls, objective: str,
              n_expected: int | None, kind: str = "sweep", title: str | None = None) -> tuple[str, int]:
    """The report's first paragraph (what was swept or tuned (``kind``; ``title``: its tracker family's,
    said when not the default's), on what, ranked how) and the sequences counted."""
    name = df["sweep"].iloc[0] if "sweep" in df.columns else kind
    name = name if title is None else f"{name} ({title})"
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
        return paragraph(f"{kind} {name}: objective {objective} ({better} is better) on {on}; {n_cfg:,} configs "
                         f"x classes {', '.join(f'{k} ({n} sequences)' for k, n in per.items())}{partial}"), seqs
    seqs = df.loc[df["sequence"] != COMBINED, "sequence"].nunique()
    return paragraph(f"{kind} {name}: {len(comb):,} configs x {seqs} sequences{partial}; objective {objective} "
                     f"({better} is better)" + (f"; class {cls}" if cls and cls != "car" else "")), seqs


def _interval_lines(rep: SweepReport, df: pd.DataFrame, cls, objective: str) -> list[str]:
    """The paired bootstrap's paragraph (``report.intervals``): best vs baseline and the configs not
    distinguishable from the best; sets ``rep.intervals``."""
    problem = interval_problem(df, objective) or ("the class average is not resampled (report one class: "
                                                   "--class)" if cls == AVERAGE else None)
    if problem:
        return [paragraph(f"no bootstrap interval: {problem}")]
    base = None if rep.baseline is None else int(rep.baseline["config"])
    iv = rep.intervals = report_intervals(df, objective, base)
    pct = int(round(100 * iv["level"]))
    text = (f"paired bootstrap over sequences ({iv['resamples']:,} resamples, seed {iv['seed']}; in-sample, like "
            f"the ranking): ")
    if "best_minus_baseline" in iv:
        lo, hi = iv["best_minus_baseline"]
        text += (f"best - baseline {objective} {pct} % interval [{lo:+.3f}, {hi:+.3f}], best better in "
                 f"{100 * iv['p_best_better']:.1f} % of resamples; ")
    tied = iv["not_distinguishable"]
    shown = ", ".join(str(c) for c in tied[:10]) + (f", ... ({len(tied) - 10} more)" if len(tied) > 10 else "")
    text += (f"{len(tied)} of {rep.view['config'].nunique():,} configs not distinguishable from the best at "
             f"{pct} % (the interval of best - config reaches 0): configs {shown}")
    return [paragraph(text)]


def _sensitivity_lines(sens: pd.DataFrame, objective: str) -> list[str]:
    if not len(sens):
        return []
    return ["", paragraph(f"sensitivity of {objective} per axis (spread_best: range over an axis' values of the best "
                          f"config with that value; spread_mean: range of the means; corr: rank correlation; "
                          f"oat_range: moving only this axis away from the best config):"),
            text_table(sens, keys=("axis",), float_format=lambda v: f"{v:.3f}")]


def _cv_lines(rep: SweepReport, folds: int, comb: pd.DataFrame, axes: list, best, objective: str) -> list[str]:
    """The cross-validation's paragraphs: how, per fold, and the cross-validated figure."""
    cv, baseline = rep.cv, rep.baseline
    how = "stratified by frame count" + ("; each class's sequences folded on their own"
                                         if cv.get("class") == AVERAGE else "")
    lines = ["", paragraph(f"{folds}-fold cross-validation over sequences ("
                           + (f"{rep.folds_note}; " if rep.folds_note else "") + how
                           + "): best config chosen on the training folds, scored on the held-out fold")]
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
    held = np.array([p["held_out"] for p in cv["per_fold"]])
    gain = held_out_gain(cv)
    spread = (f"; folds' held-out {held.min():.3f} .. {held.max():.3f}"
              + (f", held-out gain over the baseline {gain['mean']:+.3f} +- {gain['sd']:.3f} (sd over "
                 f"{gain['folds']} folds; {gain['positive']} of {gain['folds']} folds better)" if gain else ""))
    lines.append(paragraph(f"{objective}: cross-validated {cv['cross_validated']:.3f} (each sequence scored with the "
                           f"config chosen without it{spread}) | in-sample best {best[objective]:.3f}"
                           + (f" | baseline {baseline[objective]:.3f}" if baseline is not None else "")))
    return lines


def held_out_gain(cv: Mapping) -> dict | None:
    """The held-out gain over the baseline of a cross-validation (``cross_validate``'s result): per fold
    the chosen config's held-out figure minus the baseline's on the same fold, as ``mean``, ``sd`` (over
    the folds, ddof 1), ``folds`` and ``positive`` (folds with a gain above 0); None with fewer than two
    folds that score the baseline. What the text report and the page both say."""
    gain = np.array([p["held_out"] - p["baseline_held_out"] for p in cv["per_fold"]
                     if p["baseline_held_out"] is not None])
    if len(gain) < 2:
        return None
    return {"mean": float(gain.mean()), "sd": float(gain.std(ddof=1)), "folds": int(len(gain)),
            "positive": int((gain > 0).sum())}


def _summary(rep: SweepReport, objective: str, comb: pd.DataFrame, seqs: int, classes: list, cls, best,
             axes: list, folds: int | None) -> dict:
    """The JSON-able summary (the report's last line), without its tune, robustness and contrast parts."""
    baseline, cv = rep.baseline, rep.cv
    summary = {"objective": objective, "direction": "min" if objective_direction(objective) < 0 else "max",
               "configs": int(len(comb)), "sequences": int(seqs),
               **({"class": cls} if classes else {}), **({"classes": classes} if len(classes) > 1 else {}),
               "baseline": None if baseline is None else float(baseline[objective]),
               "best_in_sample": float(best[objective]),
               "best_config": {"config": int(best["config"]), "config_hash": best["config_hash"],
                               **{a: json_value(best[a]) for a in axes}}}
    if baseline is not None:
        summary["baseline_config_hash"] = baseline["config_hash"]
    if rep.intervals is not None:
        iv = rep.intervals
        summary["bootstrap"] = {"resamples": iv["resamples"], "level": iv["level"],
                                "not_distinguishable_from_best": len(iv["not_distinguishable"]),
                                **({"best_minus_baseline": iv["best_minus_baseline"],
                                    "p_best_better": iv["p_best_better"]} if "best_minus_baseline" in iv else {})}
    if cv is not None:
        summary["best_cross_validated"] = cv["cross_validated"]
        summary["folds"] = folds
        summary["mean_held_out"] = cv["mean_held_out"]
        summary["fold_configs"] = [p["config_hash"] for p in cv["per_fold"]]
    return summary


def _tune_section(d: Path, manifest: dict, objective: str) -> tuple[list[str], dict]:
    """A tune directory's own figures: the search, the nested cross-validation (``nested.json``: the
    honest figure; a flat ``--folds`` over a tune's trials would choose among configs the tuner
    proposed after seeing every sequence) and, with two objectives, the Pareto front."""
    t = manifest.get("tune", {})
    trials = d / "trials.parquet"            # the budget extends a tune, so its identity does not hold it
    size = (f"budget {t['budget']} configs" if t.get("budget") is not None else
            f"{len(pd.read_parquet(trials)):,} trials" if trials.is_file() else "budget unknown")
    lines = ["", paragraph(f"tune: sampler {t.get('sampler')}, {size} in batches of "
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
