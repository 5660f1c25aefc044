"""The output folder of a sweep or a tune belongs to one of them: :func:`claim`, the one mechanism
``run_sweep`` (:func:`dfrmot_jax.sweep.store.write_manifest`) and ``run_tune`` use to make a folder
theirs, resume in it, or refuse it (``--force``: delete what the other run wrote, nothing else).
The writers hold the folder's lock (:func:`dfrmot_jax.io.lock.folder_lock`) meanwhile."""

from __future__ import annotations

import json
import shutil
from contextlib import suppress
from pathlib import Path
from typing import Callable

from ..io.atomic import TMP_NAME
from ..io.lock import LOCK_NAME

MANIFEST = "manifest.json"
#: what each kind of run writes in its folder (files, and folders of its own): what ``force``
#: deletes, for the run that held the folder and for the one taking it (a study or chunks left
#: behind would otherwise be resumed as the new run's)
FILES = {"sweep": ("manifest.json", "configs.parquet", "results.parquet", "ledger.jsonl"),
         "tune": ("manifest.json", "configs.parquet", "results.parquet", "ledger.jsonl", "journal.log",
                  "trials.parquet", "nested.json", "transfer.json")}
FOLDERS = {"sweep": (), "tune": ("batches", "plots", "heldout", "transfer", "fold_*")}


class SweepDirectoryError(ValueError):
    """The output directory cannot take this sweep or tune: it is a file, its manifest is damaged,
    or it belongs to another sweep or tune (``force=True`` / ``--force`` deletes that run's files)."""


def read_old_manifest(outdir: Path) -> tuple[dict | None, str | None]:
    """(the folder's manifest, None) or (None, why it cannot be read); (None, None) without one."""
    path = outdir / MANIFEST
    if not path.is_file():
        return None, None
    try:
        old = json.loads(path.read_text())
        if not isinstance(old, dict):
            raise ValueError("not a JSON object")
    except (OSError, ValueError) as e:
        return None, f"has a damaged {MANIFEST} ({e})"
    return old, None


def kind_of(manifest: dict) -> str:
    return manifest.get("kind", "sweep")


def claim(outdir: Path, kind: str, same: Callable[[dict], bool], force: bool, *,
          other: Callable[[dict], str] | None = None, check: Callable[[dict], None] | None = None,
          empty: bool = False) -> dict | None:
    """Make ``outdir`` the folder of this run of ``kind`` ("sweep" or "tune").

    Returns the folder's manifest when it is this run's already (same kind and ``same(manifest)``:
    resume), else None (a new folder, or one whose other run was deleted with ``force``).
    ``check(manifest)`` may refuse a manifest before anything else (a sweep: another hash scheme).
    A folder of another run (``other(manifest)`` says how it differs, a phrase after the folder's
    name), with a damaged manifest or, with ``empty``, with other files and no manifest, raises
    :class:`SweepDirectoryError` unless ``force``: the files of both kinds of run (:data:`FILES`,
    :data:`FOLDERS`, the chunks) are then deleted, and nothing else."""
    if outdir.exists() and not outdir.is_dir():
        raise SweepDirectoryError(f"{outdir} is a file, not a directory (the {kind}'s output directory)")
    old, problem = read_old_manifest(outdir)
    if old is not None:
        if check is not None:
            check(old)
        if kind_of(old) == kind and same(old):
            return old
        problem = other(old) if other is not None and kind_of(old) == kind else \
            f"holds {'another' if kind_of(old) == kind else 'a'} {kind_of(old)} ({old.get('name')!r})"
    elif problem is None:
        if not empty or not outdir.is_dir() or not [p for p in outdir.iterdir() if p.name != LOCK_NAME]:
            return None
        problem = f"is not empty and holds no {kind}"
    if not force:
        raise SweepDirectoryError(f"{outdir} {problem}: its results would be replaced; use another --out, or --force "
                                  f"to delete its {'files' if old is None else kind_of(old) + ' files'} first")
    clear(outdir, {kind} | ({kind_of(old)} if old is not None else set()))
    return None


def clear(outdir: Path, kinds) -> None:
    """Delete the files the runs of ``kinds`` write in ``outdir`` (and nothing else)."""
    chunk_dir = outdir / "chunks"
    if chunk_dir.is_dir():
        for p in chunk_dir.iterdir():
            if p.is_file() and (p.suffix == ".parquet" or TMP_NAME.match(p.name)):
                p.unlink()
        with suppress(OSError):
            chunk_dir.rmdir()                  # only if nothing else is in it
    for k in kinds:
        for name in FILES[k]:
            (outdir / name).unlink(missing_ok=True)
        for pattern in FOLDERS[k]:
            for q in outdir.glob(pattern):
                shutil.rmtree(q) if q.is_dir() else q.unlink(missing_ok=True)
