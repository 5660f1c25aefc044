"""``dfrmot report DIR --html OUT.html``: a sweep or tune directory's report as one self-contained
HTML page (inline CSS and SVG figures; no script, no network, nothing beside the file).

The page is drawn from one computed report (:func:`render_html` / :func:`write_html` of a
:class:`~.report.SweepReport`, the object whose text ``dfrmot report`` prints: ranking, baseline,
sensitivity, cross-validation, robustness curves and contrast, the tune's figures), so page and
printed report never disagree; :func:`html_report` computes one and writes it. The figures'
series come from the analysis functions (:func:`~.analysis.axis_profiles`,
:func:`~.robustness.robustness_contrast`, :func:`~.analysis.pareto_front`) and are drawn by
:mod:`.figures`. Sections: the run's
identity (sweep file, data, versions, machine), the top configs beside the baseline, sensitivity
per axis, the objective per sequence of the top configs, the cross-validated figure, and where the
directory holds them the robustness curves and contrast, the tune's history and Pareto front.
"""

from __future__ import annotations

import json
import time
from html import escape
from pathlib import Path
from typing import Mapping

import numpy as np
import pandas as pd

from ..io.atomic import write_text_atomic
from ..version import __version__
from . import figures
from .analysis import MINIMISE, axis_profiles, fmt_value, pareto_front, varied_axes
from .report import SweepReport, held_out_gain, report_folds, sweep_report
from .robustness import robustness_contrast
from ..trackers.protocol import DEFAULT_FAMILY
from ..trackers.registry import family_config
from ..table_columns import AVERAGE, COMBINED
from .stored import read_manifest

#: settings drawn per kind in the robustness curves (the report's best first)
CURVES_SHOWN = 6
CSS = """
body { font-family: system-ui, -apple-system, 'Segoe UI', Roboto, sans-serif; margin: 0 auto; max-width: 1180px;
       padding: 0 24px 48px; color: #1d1d1f; line-height: 1.45; }
h1 { font-size: 1.6em; margin: 28px 0 4px; } h2 { font-size: 1.2em; margin: 34px 0 8px; border-bottom: 1px solid #ddd; }
p.lead { color: #555; margin-top: 0; } .note { color: #555; font-size: 0.9em; }
table { border-collapse: collapse; font-size: 0.86em; margin: 8px 0; }
th, td { padding: 3px 9px; border-bottom: 1px solid #e5e5e5; text-align: right; white-space: nowrap; }
th { background: #f4f4f6; } td.text, th.text { text-align: left; white-space: normal; }
table.top tr:last-child td { background: #fff4d6; font-style: italic; }
table.kv td:first-child { text-align: left; color: #555; } table.kv td { text-align: left; white-space: normal; }
figure { margin: 12px 0 20px; } figure svg { max-width: 100%; height: auto; }
figcaption { color: #555; font-size: 0.88em; max-width: 900px; }
pre { background: #f7f7f9; padding: 10px; overflow-x: auto; font-size: 0.8em; }
"""


def _table(df: pd.DataFrame, css: str = "", digits: int = 3) -> str:
    def fmt(v):
        if v is None:
            return ""
        if isinstance(v, (float, np.floating)):
            return "" if np.isnan(v) else f"{v:.{digits}f}"
        return fmt_value(v)

    return df.to_html(index=False, classes=css or None, border=0, escape=True, na_rep="",
                      formatters={c: fmt for c in df.columns})


def _figure(svg: str, caption: str) -> str:
    return f'<figure>{svg}<figcaption>{escape(caption)}</figcaption></figure>'


def _kv(rows: Mapping[str, object]) -> str:
    cells = "".join(f"<tr><td>{escape(str(k))}</td><td>{escape(str(v))}</td></tr>" for k, v in rows.items()
                    if v not in (None, "", [], {}))
    return f'<table class="kv">{cells}</table>'


def _identity(d: Path, m: dict, rep) -> str:
    df = rep.data
    data = m.get("data") or {}
    seqs = data.get("sequences") or []
    env = m.get("environment") or {}
    versions = {c: ", ".join(sorted(map(str, pd.unique(df[c])))) for c in ("dfrmot_jax_version", "jax_version")
                if c in df.columns}
    rows = {"directory": str(d.resolve()), "kind": m.get("kind", "sweep"), "description": m.get("description"),
            "sweep file": m.get("source") or "(given as a table, not a file)",
            "tracker family": None if rep.family in (None, DEFAULT_FAMILY) else
            f"{family_config(rep.family).title} ({rep.family})",
            "data": f"{data.get('root')} — "
                    + (f"{data.get('det2d')} + " if data.get("det2d") is not None else "")
                    + f"{data.get('det3d')}, class "
                    f"{', '.join(m.get('classes') or [data.get('class', '?')])}",
            "sequences": f"{len(seqs)} ({', '.join(seqs)}), {sum(m.get('lengths') or []):,} frames",
            "configs": f"{m.get('configs', df['config'].nunique()):,}" if not m.get("tune") else
            f"{df['config'].nunique():,} evaluated",
            "baseline": m.get("baseline"),
            "tune": ", ".join(f"{k} {v}" for k, v in (m.get("tune") or {}).items()),
            "results written by": ", ".join(f"{k.removesuffix('_version')} {v}" for k, v in versions.items()),
            "last run": env.get("written"),
            "machine": (f"{env.get('cpu')}, {env.get('cpus')} cores; {env.get('os')}; Python {env.get('python')}"
                        if env else "not recorded (written before dfrmot_jax recorded it)"),
            "software": ", ".join(f"{k} {v}" for k, v in env.items() if k in ("dfrmot_jax", "jax", "jaxlib",
                                                                             "numpy", "pandas")),
            "this page": f"dfrmot_jax {__version__}, {time.strftime('%Y-%m-%d %H:%M:%S %Z')}"}
    spec = json.dumps(m.get("spec"), indent=1, default=str) if m.get("spec") is not None else None
    return (_kv(rows) + (f"<details><summary>the sweep file as run (JSON)</summary><pre>{escape(spec)}</pre></details>"
                         if spec else ""))


def _top(rep, objective: str) -> str:
    baseline = rep.baseline
    view = rep.top_with_baseline(label="baseline").drop(columns=["config_hash"])
    best = rep.top.iloc[0]
    text = (f"<p>Best {escape(objective)} {best[objective]:.3f} (config {int(best['config'])})"
            + (f", baseline {baseline[objective]:.3f} ({best[objective] - baseline[objective]:+.3f})"
               if baseline is not None else "") + ". In-sample: ranked on every sequence (COMBINED). "
            + _honest(rep) + " The baseline is the highlighted last row.</p>")
    return text + _interval(rep, objective) + _table(view, "top")


def _honest(rep) -> str:
    """What the in-sample ranking is to be read beside: the cross-validated figure below, a tune's nested
    one, or (none on the page) that there is none and why."""
    nested = rep.directory is not None and (rep.directory / "nested.json").is_file() and \
        (rep.manifest or {}).get("kind") == "tune"
    if rep.cv is not None or nested:
        return "The cross-validated figure below is the honest estimate for unseen sequences."
    if rep.cv_note:
        return escape(rep.cv_note[0].upper() + rep.cv_note[1:]) + "."
    return ("There is no cross-validation on this page (dfrmot report --folds K adds one), so it overstates what "
            "unseen sequences would give.")


def _interval(rep, objective: str) -> str:
    """The paired bootstrap's paragraph (``report.intervals``), or why there is none."""
    iv = rep.intervals
    if iv is None:
        line = next((s for s in rep.text.splitlines() if s.startswith("no bootstrap interval")), "")
        return f"<p>{escape(line)}.</p>" if line else ""
    pct = int(round(100 * iv["level"]))
    text = f"<p>Paired bootstrap over sequences ({iv['resamples']:,} resamples, in-sample like the ranking): "
    if "best_minus_baseline" in iv:
        lo, hi = iv["best_minus_baseline"]
        text += (f"best &minus; baseline {escape(objective)} {pct} % interval <b>[{lo:+.3f}, {hi:+.3f}]</b>, the best "
                 f"better in {100 * iv['p_best_better']:.1f} % of resamples. ")
    tied = iv["not_distinguishable"]
    return text + (f"<b>{len(tied)}</b> configs are not distinguishable from the best at {pct} % (configs "
                   f"{escape(', '.join(str(c) for c in tied[:20]))}{', ...' if len(tied) > 20 else ''}).</p>")


def _heatmap(rep, objective: str, baseline) -> str:
    configs = list(rep.top["config"]) + ([int(baseline["config"])] if baseline is not None and
                                         int(baseline["config"]) not in set(rep.top["config"]) else [])
    rows = rep.view
    if not (rows["sequence"] != COMBINED).any() and "class" in rep.data.columns:        # the class average
        rows = rep.data[rep.data["class"] != AVERAGE]
        rows = rows.assign(sequence=rows["class"] + " " + rows["sequence"])
    rows = rows[(rows["sequence"] != COMBINED) & rows["config"].isin(configs)]
    if not len(rows):
        return ""
    grid = rows.pivot_table(index="config", columns="sequence", values=objective, aggfunc="first", sort=False)
    if not grid.notna().to_numpy().any():      # a figure of the whole sequence list only (AB3DMOT's sAMOTA)
        return (f"<p>{escape(objective)} is a figure of the whole sequence list (its COMBINED row): there is no "
                f"per-sequence heatmap of it.</p>")
    grid = grid.reindex(configs)
    base = None if baseline is None else int(baseline["config"])
    grid.index = [(f"#{i + 1} " if i < len(rep.top) else "") + ("baseline " if c == base else "") + f"(config {c})"
                  for i, c in enumerate(configs)]
    return _figure(figures.heatmap_figure(grid, objective),
                   f"{objective} per sequence of the top {len(rep.top)} configs (in rank order) and the baseline: "
                   f"where the best configs win and lose.")


def _robustness(rep, objective: str) -> str:
    out = []
    rob = rep.summary.get("robustness") or {}
    shown = {k: list(v["settings"])[:CURVES_SHOWN] for k, v in rob.items()}
    if rep.curves is not None and shown:
        out.append(_figure(figures.curves_figure(rep.curves, objective, shown),
                           f"{objective} (COMBINED) against the distortion level, mean ± standard error over seeds; "
                           f"the {min(CURVES_SHOWN, max(map(len, shown.values())))} best settings per kind (by their "
                           f"mean over the levels). Level 0 is the undistorted run."))
    c = rep.summary.get("contrast")
    if c:
        con = robustness_contrast(rep.view, c["axis"], c["high"], c["low"], [objective], by=c["by"])
        high = f"{c['axis']} in {c['high']}"
        low = f"{c['axis']} in {c['low']}"
        out.append(_figure(figures.contrast_figure(con, objective, high, low),
                           f"Contrast: {high} against {low}" + (f", per {', '.join(c['by'])}" if c["by"] else "")
                           + f". Top: each group's mean {objective}; bottom: the gap, paired by seed, ± standard "
                           f"error over seeds (filled: significantly better, one-sided t-test at 5 %; level 0, without seeds: "
                           f"the sign)."))
        if c.get("answer"):
            out.append("<p>Where the contrast stops helping (helps_up_to: the highest level up to which the gap "
                       "is significantly better at every distorted level; stops_at: the first level where it is "
                       "not; crossing: the first level where the mean gap changes sign):</p>")
            out.append(_table(pd.DataFrame(c["answer"])))
    return "\n".join(out)


def _tune(d: Path, m: dict, rep, objective: str) -> str:
    out = []
    trials_path = d / "trials.parquet"
    if not trials_path.is_file():
        return ""
    trials = pd.read_parquet(trials_path)
    first = (m.get("objectives") or [objective])[0]
    out.append(_figure(figures.history_figure(trials, first, first in MINIMISE),
                       f"The tune's history: {first} of every trial in the order they were asked, and the best "
                       f"so far."))
    objs = m.get("objectives") or []
    if len(objs) == 2:
        front = pareto_front(trials, objs, m.get("directions"))
        out.append(_figure(figures.pareto_figure(trials, front, objs),
                           f"Every trial's {objs[0]} and {objs[1]}, and the Pareto front: the trials no other beats "
                           f"on both."))
        out.append(_table(front[["trial"] + objs + [a for a in varied_axes(rep.data, rep.family) if a in front.columns]]))
    tr = (rep.summary.get("tune") or {}).get("transfer")
    if tr:
        out.append(f"<p>Transfer: the chosen config unchanged on {escape(tr['det2d'])} + {escape(tr['det3d'])}, "
                   f"beside that pair's baseline:</p>")
        out.append(_table(pd.DataFrame({"metric": list(tr["chosen"]), "chosen": list(tr["chosen"].values()),
                                        "baseline": [tr["baseline"][k] for k in tr["chosen"]]})))
    return "\n".join(out)


def html_report(results, out, *, objective: str | None = None, folds: int | None = None, top: int = 10,
                contrast=None, cls: str | None = None) -> Path:
    """Compute the report of a sweep or tune directory ``results`` and write it to the HTML file
    ``out``; returns its path. The arguments are :func:`~.report.sweep_report`'s (``objective``
    default: the directory's), the folds :func:`~.report.report_folds`'s. To print the report as
    well, compute it once and hand it to :func:`write_html` (``dfrmot report --html`` does)."""
    d = Path(results)
    objective = objective or read_manifest(d).get("objective") or "HOTA"
    folds, note = report_folds(d, folds, objective)
    rep = sweep_report(d, objective=objective, folds=folds,
                       top=top, contrast=contrast, cls=cls, folds_note=note)
    return write_html(rep, out)


def write_html(rep: SweepReport, out) -> Path:
    """Write the page of a directory's report ``rep`` (:func:`render_html`) to ``out``; returns its path."""
    out = Path(out)
    write_text_atomic(out, render_html(rep))
    return out


def render_html(rep: SweepReport) -> str:
    """The page of a sweep or tune directory's report, drawn from ``rep`` as computed (its numbers,
    tables and text; nothing is computed again but the figures' and per-axis profiles' layout)."""
    if rep.directory is None or rep.manifest is None:
        raise ValueError("the HTML page is made from the report of a sweep or tune directory, not of a table")
    d, m = rep.directory, rep.manifest
    tune = m.get("kind") == "tune"
    objective = rep.summary["objective"]
    baseline = rep.baseline
    name = m.get("name") or d.name
    body = [f"<h1>{'Tune' if tune else 'Sweep'} {escape(name)}</h1>",
            f'<p class="lead">{escape(rep.text.splitlines()[0])}</p>',
            "<h2>The run</h2>", _identity(d, m, rep)]
    rob = _robustness(rep, objective)
    if rob:             # a robustness study's answer first, as in the text report
        body += ["<h2>Robustness</h2>", rob]
    body += [f"<h2>Top configs by {escape(objective)}</h2>", _top(rep, objective)]
    profiles = axis_profiles(rep.view, objective, family=rep.family)
    if profiles:
        body += ["<h2>Sensitivity per axis</h2>",
                 _figure(figures.sensitivity_figure(profiles, objective, None if baseline is None else
                                                    float(baseline[objective])),
                         f"{objective} against each swept axis: the best config having each value (solid) and the "
                         f"mean over all configs having it (dashed); numeric axes with more than 8 values in "
                         f"quantile bins (at their median). Axes that always move together are one panel; a parameter "
                         f"whose unit an option sets (AB3DMOT's threshold: IoU or metres by metric) one panel per "
                         f"value of the option."),
                 _table(rep.sensitivity)]
    heat = _heatmap(rep, objective, baseline)
    if heat:
        body += ["<h2>Per sequence</h2>", heat]
    body += _cross_validated(rep, objective)
    if tune:
        body += ["<h2>The tune</h2>", _tune(d, m, rep, objective)]
    body += ["<h2>The text report</h2>",
             f"<details><summary>dfrmot report, as printed</summary><pre>{escape(rep.text)}</pre></details>"]
    return (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
            f'<meta name="viewport" content="width=device-width, initial-scale=1">'
            f"<title>{escape(name)}: dfrmot report</title><style>{CSS}</style></head>\n<body>\n"
            + "\n".join(body) + "\n</body></html>\n")


def _gain_text(cv: Mapping) -> str:
    """The held-out gain over the baseline (mean ± sd over folds, folds better), as the text report says it."""
    gain = held_out_gain(cv)
    return ("" if gain is None else f"; held-out gain over the baseline {gain['mean']:+.3f} ± {gain['sd']:.3f} "
            f"(sd over {gain['folds']} folds; {gain['positive']} of {gain['folds']} folds better)")


def _cross_validated(rep: SweepReport, objective: str) -> list[str]:
    """The cross-validated section (the report's folds) or a tune's nested cross-validation."""
    out = []
    if rep.cv is not None:
        note = f" ({rep.folds_note})" if rep.folds_note else ""
        out += ["<h2>Cross-validated</h2>",
                f"<p>{rep.cv['folds']}-fold cross-validation over sequences{escape(note)}: per fold the best config "
                f"is chosen on the other folds and scored on the held-out one. Cross-validated {objective} "
                f"{rep.cv['cross_validated']:.3f} against the in-sample best {rep.top.iloc[0][objective]:.3f}; "
                f"the folds' held-out figures range {min(p['held_out'] for p in rep.cv['per_fold']):.3f} .. "
                f"{max(p['held_out'] for p in rep.cv['per_fold']):.3f}{_gain_text(rep.cv)}.</p>",
                _figure(figures.folds_figure(rep.cv, objective, float(rep.top.iloc[0][objective])),
                        "Per fold: the chosen config on its training folds and on the held-out fold, and the "
                        "baseline on the held-out fold.")]
    nested = rep.directory / "nested.json"
    if rep.manifest.get("kind") == "tune" and nested.is_file():
        n = json.loads(nested.read_text())
        out += ["<h2>Nested cross-validation</h2>",
                f"<p>The tune rerun per fold on the training sequences only, its choice scored on the held-out "
                f"fold: {escape(n['objective'])} cross-validated {n['cross_validated']:.3f}, baseline "
                f"{n['baseline']:.3f} on the same sequences.</p>",
                _figure(figures.folds_figure(n, n["objective"]), "Per fold: the config the tune chose on the "
                        "training folds, there and on the held-out fold, and the baseline on the held-out fold.")]
    return out
