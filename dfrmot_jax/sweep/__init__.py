"""Declarative parameter sweeps: a TOML file -> a config table -> chunked, resumable, batched runs
(track + metrics in-process) -> one tidy ``pandas.DataFrame``; reports with honest cross-validation.

The pipeline::

    load_spec(FILE) ─▶ SweepSpec ─▶ expand() ─▶ config table (one row per config: every parameter,
        every static option, config_hash; with a [distortion] table also the per-lane columns
        distortion.kind, distortion.level, distortion.seed: configs x levels x seeds)
    plan() ─▶ groups of rows with equal static Options (one compilation each) ─▶ chunks of
        ``chunk`` configs; chunk id = hash(data settings + the chunk's config hashes
        [+ the distortion settings])
    run ─▶ per chunk: dfrmot_jax.track (one [B] batch; distortion lanes vmapped with the parameter
        lanes, one DistortSpec per option group) ─▶ metrics on the padded arrays (prepared
        ground truth reused, identical tracker outputs scored once) ─▶ DIR/chunks/<id>.parquet
        written atomically (tmp file + os.replace) and recorded (sha256, rows) in DIR/ledger.jsonl; a
        rerun skips chunks whose file matches its record and recomputes the others
    table ─▶ one row per (config, sequence) + one ``COMBINED`` row per config
    several classes (data.class = ["car", "pedestrian"]) ─▶ every config run per class, each class
        on its own split (its chunks, its compilation); per-class axes ``pedestrian.a_l`` are
        columns of the config table (in config_hash only where they differ from the plain value);
        rows carry ``class``, plus one class-average row per config (class "average")
    report() ─▶ best configs by an objective, the baseline beside them, sensitivity per axis,
        k-fold cross-validation over sequences (best chosen on training folds, scored held out);
        with distortion: the objective per level and kind (mean ± SE over seeds) per setting, and
        an optional contrast of two groups of an axis (e.g. long vs short memory) paired by seed

Modules: :mod:`.spec` (the file: dataclasses, parsing, validation), :mod:`.distortion` (the
[distortion] table), :mod:`.table` (``expand``, ``config_hash``, ``HASH_VERSION``), :mod:`.plan`
(data settings, option groups, chunks), :mod:`.runner` (``run_sweep``, the run loop), :mod:`.store`
(the directory: chunk files, manifest, ``load_results``), :mod:`.analysis` (ranking, sensitivity,
folds, cross-validation), :mod:`.robustness`, :mod:`.report` (``sweep_report``). The metrics
(summary columns, sequence re-combination, lane scoring, worker pools) are
:mod:`dfrmot_jax.metrics.evaluate`'s.

``run_sweep`` is the function; ``dfrmot_jax.sweep`` is this package. For one release calling the
package (``dm.sweep(...)``) or ``dfrmot_jax.sweep.sweep(...)`` still runs a sweep, with a
``DeprecationWarning``.

See ``sweeps/README.md`` for the file format. Python use::

    import dfrmot_jax as dm
    df = dm.run_sweep("sweeps/kitti_dfr_grid.toml", out="results/grid")     # or a dict spec
    rep = dm.sweep_report(df, objective="HOTA", folds=5); print(rep.text)
    rep = dm.sweep_report(df, cls="pedestrian")          # several classes: one class or "average"
    from dfrmot_jax.sweep import robustness_contrast, robustness_curves     # distortion sweeps
    curves = robustness_curves(df, ("HOTA", "AssA", "IDSW"))                # per setting, kind, level
    gaps = robustness_contrast(df, "epsilon", high=[30, 60], low=[1, 2, 3], by=["filter"])
"""


from __future__ import annotations

import sys
import types
import warnings

from ..metrics.evaluate import RAW_FIELDS, combine_sequences, summary_columns
from .analysis import (MINIMISE, OBJECTIVES, _check_objective, _classes_of, _direction, _objective_on,
                       _per_sequence_arrays, _rank, class_view, cross_validate, make_folds, report_class_of,
                       sensitivity, varied_axes)
from .distortion import DISTORTION_KEYS, PROBABILITY_KINDS, DistortionAxes
from .plan import MAX_MEMORY_GB, Chunk, DataSettings, _groups, check_memory, plan, resolve_data, resolve_data_all
from .report import SweepReport, sweep_report
from .robustness import robustness_contrast, robustness_curves, robustness_summary, setting_axes
from .runner import TRACK_CHUNK, run_sweep, sweep
from .spec import (AVERAGE, DISTORTION_AXES, EXTRA_AXES, OPTION_NAMES, PARAM_NAMES, Axis, Contrast, SweepConfigError,
                   SweepSpec, Variant, load_spec, parse_spec)
from .store import HashVersionError, SweepDirectoryError, hash_version, load_results
from .table import (COMBINED, HASH_VERSION, MAX_CONFIGS, RAW_COLUMN, _params_of, class_columns, config_count,
                    config_hash, expand, n_settings)

__all__ = [
    "SweepConfigError", "SweepSpec", "DataSettings", "Axis", "load_spec", "parse_spec", "expand", "config_hash",
    "resolve_data", "plan", "run_sweep", "sweep", "load_results", "sweep_report", "SweepReport", "cross_validate",
    "make_folds", "sensitivity", "combine_sequences", "PARAM_NAMES", "OPTION_NAMES", "EXTRA_AXES",
    "OBJECTIVES", "MINIMISE", "DISTORTION_AXES", "DistortionAxes", "robustness_curves", "robustness_contrast",
    "robustness_summary", "Contrast", "n_settings", "setting_axes", "resolve_data_all", "class_view",
    "class_columns", "AVERAGE", "HASH_VERSION", "HashVersionError", "hash_version",
    "SweepDirectoryError", "MAX_CONFIGS", "MAX_MEMORY_GB", "config_count", "check_memory",
]


class _SweepPackage(types.ModuleType):
    """``dfrmot_jax.sweep`` is this package; calling it is the deprecated spelling of :func:`run_sweep`."""

    def __call__(self, *args, **kwargs):
        warnings.warn("calling dfrmot_jax.sweep(...) is deprecated: use dfrmot_jax.run_sweep(...) "
                      "(dfrmot_jax.sweep is the sweep package)", DeprecationWarning, stacklevel=2)
        return run_sweep(*args, **kwargs)


sys.modules[__name__].__class__ = _SweepPackage
