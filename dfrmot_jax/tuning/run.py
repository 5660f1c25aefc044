"""``run_tune``: a tune file -> batched search (+ gradient refinement) -> tables, plots, and with
``folds`` the nested cross-validated figure (:mod:`.nested`)."""

from __future__ import annotations

import json
import sys
from dataclasses import replace
from pathlib import Path
from typing import Mapping

from ..trackers.protocol import DEFAULT_FAMILY
from ..io.atomic import write_text_atomic
from ..io.lock import folder_lock
from ..choices import DEFAULT_AB3DMOT_IOU
from ..metrics.samota.table import AB3DMOT_COLUMNS
from ..sweep.backend import make_backend
from ..sweep.plan import resolve_data
from ..sweep.runner import run_sweep
from ..sweep.spec import SweepConfigError, SweepSpec
from ..sweep.folder import MANIFEST, claim
from ..sweep.store import environment, jsonable
from ..sweep.table import HASH_VERSION
from .nested import nested_cv
from .once import TuneResult, tune_once
from .plots import save_plots
from .settings import RefineSettings, TuneSettings, load_tune, parse_tune_file
from .space import SearchSpace, search_space

def _load(tune) -> tuple[SweepSpec, TuneSettings]:
    if isinstance(tune, tuple):
        return tune
    if isinstance(tune, Mapping):
        return parse_tune_file(tune)
    return load_tune(tune)


def _identity(spec: SweepSpec, settings: TuneSettings, data) -> dict:
    return {"spec": jsonable({k: v for k, v in (spec.raw or {}).items() if k != "tune"}),
            "tune": settings.identity(), "data": data.identity()}


def _write_manifest(outdir: Path, spec: SweepSpec, settings: TuneSettings, data, identity: dict) -> None:
    m = {"kind": "tune", "name": spec.name, "description": spec.description, "source": spec.source,
         "data": data.identity(), "lengths": list(data.lengths), "baseline": spec.baseline, "chunk": spec.chunk,
         "objective": settings.objectives[0], "objectives": list(settings.objectives),
         "directions": list(settings.directions), "folds": None, "top": spec.top,
         "tune": settings.identity(), "identity": identity, "chunks": [], "hash_version": HASH_VERSION,
         "environment": environment()}
    if spec.family != DEFAULT_FAMILY:           # (a manifest without it is the default family's)
        m["family"] = spec.family
    write_text_atomic(outdir / MANIFEST, json.dumps(m, indent=1, default=str), parents=False)


def run_tune(tune, out=None, *, data_root=None, sampler: str | None = None, budget: int | None = None,
             batch: int | None = None, folds: int | None = None, seed: int | None = None, refine_steps=None,
             progress: bool = True, workers: int | None = None, log=None, force: bool = False,
             plots: bool = True, backend="local", address: str | None = None,
             worker_cpus: int | None = None) -> TuneResult:
    """Tune a tune file (path, dict or ``(SweepSpec, TuneSettings)``): see ``sweeps/README.md``.

    The keyword arguments override the file's ``[tune]`` table (``refine_steps=0`` switches
    refinement off). ``out``: the tune directory (resumable; without it nothing is written and a
    killed tune starts again). With ``folds`` the tune also runs once per fold on the other folds'
    sequences and scores each chosen config on its held-out fold (``result.nested``).
    ``backend`` / ``address`` / ``worker_cpus`` / ``workers``: where each batch runs, as
    :func:`~dfrmot_jax.sweep.run_sweep`'s (``backend="ray"``: every batch on the cluster's workers,
    which keep their compilations from batch to batch)."""
    backend = make_backend(backend, workers=workers, address=address, worker_cpus=worker_cpus)
    spec, settings = _load(tune)
    over = {k: v for k, v in dict(sampler=sampler, budget=budget, batch=batch, folds=folds, seed=seed).items()
            if v is not None}
    settings = replace(settings, **over)
    if batch is None and budget is not None:
        settings = replace(settings, batch=min(settings.batch, settings.budget))
    if refine_steps is not None:
        settings = replace(settings, refine=None if refine_steps == 0 else
                           replace(settings.refine or RefineSettings(), steps=int(refine_steps)))
    log = log if log is not None else (lambda m: print(m, file=sys.stderr, flush=True))
    if spec.ab3dmot is None and any(o in AB3DMOT_COLUMNS for o in settings.objectives):
        spec = replace(spec, ab3dmot=DEFAULT_AB3DMOT_IOU)      # the objective needs AB3DMOT's figures
    data = resolve_data(spec, data_root)
    n_seq = len(data.sequences)
    if settings.folds is not None and not 2 <= settings.folds <= n_seq:   # before anything is written
        why = f"{settings.folds}: expected 2 .. {n_seq} (the sequences of the data)"
        if folds is not None:
            raise ValueError(f"--folds {why}")
        raise SweepConfigError("tune.folds", why, spec.source)
    space = search_space(spec)
    finite = {"grid": ("categorical",), "pairwise": ("categorical", "int")}.get(settings.sampler)
    bad = next((d for d in space.dims if finite and d.kind not in finite), None)
    if bad is not None:
        raise SweepConfigError(bad.key, f"sampler \"{settings.sampler}\" needs lists or grids"
                               f"{' (or randint)' if settings.sampler == 'pairwise' else ''}, not distributions",
                               spec.source)
    backend.check()             # a missing GPU, an unreachable cluster: refused before anything is written
    outdir = Path(out) if out is not None else None
    if outdir is None:
        return _run(spec, settings, space, data, None, data_root, backend, progress, log, plots)
    with folder_lock(outdir, "tune"):
        identity = _identity(spec, settings, data)
        claim(outdir, "tune", lambda old: old.get("identity") == identity, force, empty=True)
        _write_manifest(outdir, spec, settings, data, identity)
        return _run(spec, settings, space, data, outdir, data_root, backend, progress, log, plots)


def _run(spec: SweepSpec, settings: TuneSettings, space: SearchSpace, data, outdir: Path | None, data_root, backend,
         progress: bool, log, plots: bool) -> TuneResult:
    """The tune itself, once its folder (if any) is claimed and locked."""
    result = tune_once(spec, settings, space, outdir, data_root, backend, progress, log)
    if settings.folds:
        result.nested = nested_cv(spec, settings, space, data, outdir, data_root, backend, progress, log)
        if outdir is not None:
            write_text_atomic(outdir / "nested.json", json.dumps(result.nested, indent=1, default=str), parents=False)
    if settings.transfer is not None:
        result.transfer = transfer(result, space, outdir, data_root, backend)
        if outdir is not None:
            write_text_atomic(outdir / "transfer.json", json.dumps(result.transfer, indent=1, default=str), parents=False)
    if outdir is not None and plots:
        save_plots(result, outdir / "plots")
    return result


TRANSFER_FIELDS = ("HOTA", "DetA", "AssA", "MOTA", "IDF1", "IDSW")


def transfer(result: TuneResult, space: SearchSpace, outdir: Path | None, data_root, backend) -> dict:
    """The chosen config applied unchanged to other detections (``[tune.transfer]``), beside their
    baseline (the tune's baseline with the transfer's parameter values), in one call."""
    t = result.settings.transfer
    spec = replace(result.spec, det2d=t.det2d or result.spec.det2d, det3d=t.det3d or result.spec.det3d)
    base = {**space.fixed, **dict(t.baseline)}
    table = space.table([space.row(result.best), base], [False, True])
    df = run_sweep(spec, None if outdir is None else outdir / "transfer", data_root=data_root, progress=False,
                   backend=backend, log=lambda m: None, table=table)
    comb = df[df["sequence"] == "COMBINED"].set_index("baseline")
    fields = [f for f in dict.fromkeys(list(result.settings.objectives) + list(TRANSFER_FIELDS)) if f in comb.columns]
    return {"det2d": spec.det2d, "det3d": spec.det3d, "baseline_params": dict(t.baseline),
            "chosen": {f: float(comb.loc[False, f]) for f in fields},
            "baseline": {f: float(comb.loc[True, f]) for f in fields}}
