"""Plots of a tune (Optuna's matplotlib visualisations): optimisation history, Pareto front (two
objectives), parameter importances; and the Pareto front as a table."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from ..report import analysis


def pareto_front(trials: pd.DataFrame, settings) -> pd.DataFrame:
    """The non-dominated trials under the tune's objectives and directions, best first by the first."""
    return analysis.pareto_front(trials, settings.objectives, settings.directions)


def save_plots(result, folder: Path) -> list[Path]:
    """Write history.png, importances.png and (two objectives) pareto.png; returns the files written.
    A plot Optuna cannot draw (e.g. importances of too few trials) is skipped."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    import optuna.visualization.matplotlib as ovm

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    study, objs = result.study, list(result.settings.objectives)
    target = (lambda t: t.values[0]) if len(objs) > 1 else None
    jobs = {"history.png": lambda: ovm.plot_optimization_history(study, target=target, target_name=objs[0]),
            "importances.png": lambda: ovm.plot_param_importances(study, target=target, target_name=objs[0])}
    if len(objs) == 2:
        jobs["pareto.png"] = lambda: ovm.plot_pareto_front(study, target_names=objs)
    written = []

    for name, draw in jobs.items():
        try:
            # Optuna's plots call plt.style.use("ggplot"), a global setting: kept inside this context,
            # so that the process's later figures (the HTML report's) are drawn as without a tune
            with warnings.catch_warnings(), matplotlib.rc_context():
                warnings.simplefilter("ignore")
                ax = draw()
                fig = ax.figure if hasattr(ax, "figure") else np.ravel(ax)[0].figure
                fig.set_size_inches(8, 5)
                fig.tight_layout()
                fig.savefig(folder / name, dpi=100)
                plt.close(fig)
            written.append(folder / name)
        except (ValueError, RuntimeError, ZeroDivisionError):
            continue
    return written
