"""Declarative parameter sweeps: a TOML file -> a config table -> chunked, resumable, batched runs
(track + metrics in-process) -> one tidy ``pandas.DataFrame``; reports with honest cross-validation.

The pipeline::

    load_spec(FILE) ─▶ SweepSpec ─▶ expand() ─▶ config table (one row per config: every parameter,
        every static option of the sweep's tracker family, ``[options] family``: DFR-FastMOT's by
        default, AB3DMOT's with "ab3dmot", ``param_names(family)`` / ``option_names(family)``;
        config_hash; with a [distortion] table (DFR-FastMOT's) also the per-lane columns
        distortion.kind, distortion.level, distortion.seed: configs x levels x seeds)
    plan() ─▶ groups of rows with equal static Options (one compilation each) ─▶ chunks of
        ``chunk`` configs; chunk id = hash(data settings + the chunk's config hashes
        [+ the distortion settings])
    run ─▶ per chunk: the family's track (DFR-FastMOT's dfrmot_jax.track; one [B] batch; distortion lanes vmapped with the parameter
        lanes, one DistortSpec per option group) ─▶ metrics on the padded arrays (prepared ground
        truth reused, each distinct output of each sequence scored once) ─▶ DIR/chunks/<id>.parquet
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

Modules: :mod:`.spec` (the file: dataclasses, parsing, validation; its value checks and
``SweepConfigError`` are :mod:`dfrmot_jax.checks`'), :mod:`.distortion` (the [distortion] table),
:mod:`.table` (``expand``, ``config_hash``, ``HASH_VERSION``), :mod:`.plan` (data settings, option
groups, chunks), :mod:`.chunks` (``ChunkRunner``: one class's chunks tracked and scored, the unit
every backend runs), :mod:`.scoring` (``ChunkScorer``, ``InOrderScoring``: the chunks' metrics beside
the tracker, completed in order), :mod:`.backend` (local or Ray: ``check()`` and ``run_chunks(...)``),
:mod:`.ray_backend`, :mod:`.runner` (``prepare_sweep``, ``run_sweep``), :mod:`.folder` (``claim``: a
folder belongs to one sweep or tune) and :mod:`.store` (the directory: chunk files, manifest, ledger).
The reports are :mod:`dfrmot_jax.report`'s (reading the stored tables back, ``load_results``;
ranking, sensitivity, folds, cross-validation, robustness, ``sweep_report``, the HTML page), which
imports no JAX; their names are exported here too. The metrics
(summary columns, sequence re-combination, lane scoring, worker pools) are
:mod:`dfrmot_jax.metrics.kitti2d.evaluate`'s. ``dfrmot_jax.sweep.sweep(...)`` is a deprecated alias of
``run_sweep`` (one release, with a ``DeprecationWarning``).

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

from ..checks import SweepConfigError
from ..metrics.kitti2d.evaluate import combine_sequences, summary_columns
from ..report import (AVERAGE, COMBINED, DISTORTION_AXES, EXTRA_AXES, MINIMISE, OBJECTIVES, OPTION_NAMES, PARAM_NAMES,
                      RAW_COLUMN, Contrast, SweepReport, axis_profiles, class_columns, class_view, cross_validate,
                      html_report, load_results, make_folds, objective_on, per_sequence_arrays, render_html,
                      report_folds, robustness_contrast, robustness_curves, robustness_summary, sensitivity,
                      setting_axes, sweep_report, write_html, param_names, option_names, table_family)
from .backend import LocalBackend, RayBackend, make_backend
from .distortion import DistortionAxes
from .plan import MAX_MEMORY_GB, DataSettings, check_memory, plan, resolve_data, resolve_data_all
from .runner import PreparedSweep, prepare_sweep, run_sweep, sweep
from .spec import Axis, SweepSpec, load_spec, parse_spec
from .store import HashVersionError, SweepDirectoryError, hash_version
from .table import (HASH_VERSION, MAX_CONFIGS, config_count, config_hash, expand, n_settings, params_of)

__all__ = [
    "SweepConfigError", "SweepSpec", "DataSettings", "Axis", "load_spec", "parse_spec", "expand", "config_hash",
    "resolve_data", "plan", "prepare_sweep", "PreparedSweep", "run_sweep", "sweep", "load_results", "sweep_report",
    "SweepReport", "cross_validate", "make_folds", "sensitivity", "combine_sequences", "summary_columns",
    "PARAM_NAMES", "OPTION_NAMES", "EXTRA_AXES", "OBJECTIVES", "MINIMISE", "DISTORTION_AXES", "DistortionAxes",
    "robustness_curves", "robustness_contrast", "robustness_summary", "Contrast", "n_settings", "setting_axes",
    "resolve_data_all", "class_view", "class_columns", "AVERAGE", "HASH_VERSION", "HashVersionError",
    "hash_version", "SweepDirectoryError", "MAX_CONFIGS", "MAX_MEMORY_GB", "config_count", "check_memory",
    "COMBINED", "RAW_COLUMN", "params_of", "per_sequence_arrays", "objective_on", "LocalBackend", "RayBackend",
    "make_backend", "html_report", "write_html", "render_html", "report_folds", "axis_profiles",
    "param_names", "option_names", "table_family",
]
