"""Reports of stored sweep and tune tables: what a sweep directory holds, read back and analysed,
without JAX (nothing here imports JAX or a tracker family's folder through any chain of imports: ``dfrmot
report DIR`` starts without them).

Modules: :mod:`.columns` (the tables' columns: ``COMBINED``, ``AVERAGE``, the per-alpha column, the
parameter / option / per-class / per-lane axis columns, the report's ``Contrast``), :mod:`.stored`
(``load_results``, the manifest, the ledger's records), :mod:`.analysis` (ranking, sensitivity,
folds, cross-validation), :mod:`.robustness`, :mod:`.text`, :mod:`.report` (``sweep_report``: the
report computed once, its numbers and text in one ``SweepReport``), :mod:`.html` (``html_report``,
``write_html``: that report as one self-contained page) and :mod:`.figures` (its plots). The sweep
package (:mod:`dfrmot_jax.sweep`) names all of these too::

    from dfrmot_jax.report import load_results, sweep_report
    rep = sweep_report(load_results("results/grid"), objective="HOTA", folds=5); print(rep.text)
"""

from .analysis import (MINIMISE, OBJECTIVES, axis_profiles, class_view, cross_validate, make_folds, objective_on,
                       per_sequence_arrays, sensitivity)
from ..table_columns import (AVERAGE, COMBINED, DISTORTION_AXES, EXTRA_AXES, OPTION_NAMES, PARAM_NAMES, RAW_COLUMN, Contrast, class_columns, extra_axes, option_names, param_names, parse_contrast, table_family)
from .html import html_report, render_html, write_html
from .report import SweepReport, report_folds, sweep_report
from .robustness import robustness_contrast, robustness_curves, robustness_summary, setting_axes
from .stored import load_results, read_manifest

__all__ = [
    "sweep_report", "SweepReport", "report_folds", "html_report", "render_html", "write_html", "load_results",
    "read_manifest", "cross_validate", "make_folds", "sensitivity", "axis_profiles", "class_view", "objective_on",
    "per_sequence_arrays", "OBJECTIVES", "MINIMISE", "robustness_curves", "robustness_contrast", "robustness_summary",
    "setting_axes", "Contrast", "parse_contrast", "COMBINED", "RAW_COLUMN", "AVERAGE", "PARAM_NAMES", "OPTION_NAMES",
    "EXTRA_AXES", "DISTORTION_AXES", "class_columns", "extra_axes", "param_names", "option_names", "table_family",
]
