"""Running a sweep: :func:`prepare_sweep` (the file read and checked, the config table expanded, the
data resolved, the chunks planned: everything before any work, which ``dfrmot sweep --dry-run``
shows) and :func:`run_sweep` (skip finished chunks, run the rest on a backend, gather the table).
A chunk is computed by :class:`dfrmot_jax.sweep.chunks.ChunkRunner`, whichever backend runs it.
"""

from __future__ import annotations

import sys
import warnings
from dataclasses import dataclass, replace
from pathlib import Path

import pandas as pd

from ..trackers.protocol import preset_class_note
from ..trackers.registry import family_config
from ..io.lock import folder_lock
from .backend import make_backend
from ..checks import SweepConfigError
from .chunks import progress_bar
from .lidar_axes import describe_key
from .plan import Chunk, DataSettings, check_memory, plan, resolve_data_all
from .spec import SweepSpec, as_spec
from .store import chunk_path, computed_by, finished_chunks, write_chunk, write_manifest, write_results
from ..table_columns import RAW_COLUMN
from ..report.stored import finish_table
from .table import expand, n_settings


@dataclass(frozen=True)
class PreparedSweep:
    """A sweep ready to run: ``spec`` (with the caller's overrides), ``table`` (the config table),
    ``datas`` (one :class:`~dfrmot_jax.sweep.plan.DataSettings` per class) and ``chunks`` (planned,
    memory checked)."""

    spec: SweepSpec
    table: pd.DataFrame
    datas: tuple[DataSettings, ...]
    chunks: tuple[Chunk, ...]


def prepare_sweep(spec, *, data_root=None, chunk: int | None = None, folds: int | None = None,
                  table: pd.DataFrame | None = None, max_configs: int | None = None,
                  max_memory: float | None = None) -> PreparedSweep:
    """Everything :func:`run_sweep` does before any work, with its arguments' meanings: read and
    check the sweep (TOML path, dict or :class:`SweepSpec`), apply ``chunk`` / ``folds``, expand the
    config table (or take ``table``), resolve each class's data and plan the chunks. A bad file,
    setting or data fails here with a :class:`SweepConfigError` naming the key."""
    spec = as_spec(spec)
    note = preset_class_note(family_config(spec.family), spec.baseline,
                             [spec.baseline_class] if spec.baseline_class else spec.classes, " (the baseline)")
    if note is not None:
        warnings.warn(f"{spec.source or 'the sweep'}: data.class {', '.join(spec.classes)}: {note}", stacklevel=2)
    if chunk is not None:
        if chunk < 1:
            raise SweepConfigError("chunk", f"{chunk}: expected an integer >= 1", spec.source)
        spec = replace(spec, chunk=int(chunk))
    if folds is not None:
        spec = replace(spec, folds=int(folds))
    table = expand(spec, max_configs=max_configs) if table is None else table
    datas = resolve_data_all(spec, data_root)
    n_seq = min(len(d.sequences) for d in datas)
    if spec.folds is not None and not 2 <= spec.folds <= n_seq:
        raise SweepConfigError("folds", f"{spec.folds}: expected 2 .. {n_seq} (the sequences"
                               + (" of the class with the fewest)" if len(datas) > 1 else ")"), spec.source)
    chunks = plan(table, datas, spec.chunk, spec.axes, spec.metrics_identity(), spec.family)
    check_memory(chunks, datas, spec.distortion, max_memory, spec.source, spec.family)
    return PreparedSweep(spec, table, tuple(datas), tuple(chunks))


def run_sweep(spec, out=None, *, data_root=None, chunk: int | None = None, folds: int | None = None,
              progress: bool = True, workers: int | None = None, log=None, raw: bool = True,
              table: pd.DataFrame | None = None, max_configs: int | None = None, max_memory: float | None = None,
              force: bool = False, backend="local", address: str | None = None,
              worker_cpus: int | None = None, compact: bool = True) -> pd.DataFrame:
    """Run a sweep (TOML path, dict or :class:`SweepSpec`) and return its tidy table.

    One row per (config, sequence) and one ``COMBINED`` row per config, with every parameter and
    option, the metrics (TrackEval summary names, as ``dfrmot eval``), overflow counts, versions and
    ``config_hash``. ``out``: a directory; each finished chunk is written there as Parquet and a
    rerun skips finished chunks (resume); ``results.parquet`` holds the final table. Without
    ``out`` nothing is written. ``data_root`` / ``chunk`` override the file; ``folds`` is stored for
    the report (``sweep_report``); ``workers``: metric processes running beside the tracker
    (default: 2 for large sweeps, 0 = in-process); ``raw=False`` drops the per-alpha column
    ``_hota_alpha`` (needed for cross-validation).
    ``table``: run these configs (a config table as :func:`expand` makes, e.g. a tuner's batch)
    instead of the file's expansion; the spec then gives the data, baseline and chunking.
    Bad files fail before any work with a :class:`SweepConfigError` naming the key, and so do
    sweeps of more than ``max_configs`` configs (default ``MAX_CONFIGS``) or whose chunks would hold
    more than ``max_memory`` GB of tracker output (default ``plan.MAX_MEMORY_GB``).

    ``out`` belongs to one sweep: another sweep's directory is refused (``SweepDirectoryError``)
    unless ``force``, which deletes that sweep's files first. A chunk file whose bytes do not match
    its ledger record (truncated, changed, never recorded) is reported through ``log`` and recomputed.

    ``backend``: ``"local"`` (this process) or ``"ray"`` (a Ray cluster at ``address``, default a
    local instance; one worker per ``worker_cpus`` CPUs of a node, default one per node), or a
    :mod:`~dfrmot_jax.sweep.backend` object. Tables and store are the same either way.
    ``compact``: track each class on its split compacted to the table's loosest score thresholds
    (:func:`dfrmot_jax.data.compact_split`: the same results, fewer dead detection slots).

    Several classes (``data.class = ["car", "pedestrian"]``): every config is run for every class,
    each on its own split; rows carry their ``class``, and each config gets one more row, ``class =
    "average"``, ``sequence = COMBINED``: the class average (TrackEval's / KITTI's: ratios averaged
    over the classes, counts summed; :func:`dfrmot_jax.metrics.kitti2d.evaluate.class_average`).
    """
    backend = make_backend(backend, workers=workers, address=address, worker_cpus=worker_cpus)
    prep = prepare_sweep(spec, data_root=data_root, chunk=chunk, folds=folds, table=table,
                         max_configs=max_configs, max_memory=max_memory)
    spec, table, datas, chunks = prep.spec, prep.table, prep.datas, prep.chunks
    log = log if log is not None else (lambda msg: print(msg, file=sys.stderr, flush=True))
    backend.check()             # an unreachable cluster is refused before anything is written
    outdir = Path(out) if out is not None else None
    if outdir is None:
        return _run(spec, table, datas, chunks, None, force, backend, progress, log, compact, raw)
    with folder_lock(outdir, "sweep"):
        return _run(spec, table, datas, chunks, outdir, force, backend, progress, log, compact, raw)


def _run(spec: SweepSpec, table: pd.DataFrame, datas, chunks, outdir: Path | None, force: bool, backend, progress,
         log, compact: bool, raw: bool) -> pd.DataFrame:
    """The sweep itself, in its folder (claimed here, locked by the caller) or in memory."""
    done: set[str] = set()
    computed = computed_by(datas)
    if outdir is not None:
        legacy = write_manifest(outdir, spec, datas, table, chunks, force=force)
        done, damaged = finished_chunks(outdir, table, chunks, datas, legacy)
        if damaged:
            log(f"sweep {spec.name}: {len(damaged)} chunk file(s) damaged, not recorded or computed by another "
                "version, recomputed: "
                + "; ".join(damaged))
    frames_out: dict[str, pd.DataFrame] = {}
    for d in datas:
        cchunks = [c for c in chunks if c.of(d)]
        todo = [c for c in cchunks if c.id not in done]
        n_done = sum(len(c.configs) for c in cchunks if c.id in done)
        n_cfg = sum(len(c.configs) for c in cchunks)
        total_cf = n_cfg * sum(d.lengths)
        n_groups = len({c.group for c in cchunks})
        lanes = ""
        if spec.distortion is not None:
            n_set = n_settings(table, spec.family)
            lanes = (f" = {n_set:,} settings x {spec.distortion.n_lanes} distortion lanes (kinds "
                     f"{', '.join(k for k, _ in spec.distortion.kinds)}; {len(spec.distortion.seeds)} seeds)")
        name = spec.name if len(spec.classes) == 1 else f"{spec.name} [{d.cls}]"
        if d.lidar is not None:
            name = f"{name} [{describe_key(d.lidar)}]"
        log(f"sweep {name}: {n_cfg:,} configs{lanes} ({n_groups} option group(s), {len(cchunks)} chunks of <= "
            f"{spec.chunk}; {sum(c.id in done for c in cchunks)} done) x {len(d.sequences)} sequences / "
            f"{sum(d.lengths):,} frames = {total_cf / 1e6:.1f} M config-frames" + (f" -> {outdir}" if outdir else ""))
        if todo:
            def keep(c: Chunk, df: pd.DataFrame) -> None:
                if outdir is not None:
                    write_chunk(outdir, c, df, computed)
                else:
                    frames_out[c.id] = df

            bar = progress_bar(progress, n_cfg, n_done, name)
            try:
                backend.run_chunks(spec, table, d, todo, keep, bar, _beside(bar, log), compact=compact)
            finally:
                if bar is not None:
                    bar.close()
    if outdir is None:
        df = pd.concat([frames_out[c.id] for c in chunks], ignore_index=True)
    else:
        df = pd.concat([pd.read_parquet(chunk_path(outdir, c)) for c in chunks], ignore_index=True)
        df["sweep"] = spec.name             # (a renamed sweep keeps its directory and chunks)
    df = finish_table(df, spec.classes, spec.family)
    if outdir is not None:
        write_results(outdir, df)
    if not raw:
        df = df.drop(columns=[RAW_COLUMN])
    return df


def _beside(bar, log):
    """``log`` for lines written while the progress ``bar`` (or None) is shown: each on a line of its own,
    never run into the bar's. A finished bar is closed first (its last line ends, and the run's summary
    follows it); an unfinished one is cleared, the line written, and the bar drawn again below it."""
    if bar is None:
        return log

    def write(message: str) -> None:
        if bar.total is not None and bar.n >= bar.total:
            bar.close()
            log(message)
            return
        bar.clear()
        log(message)
        bar.refresh()

    return write


def sweep(*args, **kwargs) -> pd.DataFrame:
    """Deprecated alias of :func:`run_sweep` (kept for one release)."""
    warnings.warn("dfrmot_jax.sweep.sweep(...) is deprecated: use dfrmot_jax.run_sweep(...) "
                  "(dfrmot_jax.sweep is the sweep package)", DeprecationWarning, stacklevel=2)
    return run_sweep(*args, **kwargs)
