"""A sweep directory: chunk files and the tables built from them, atomic writes, the manifest
(``hash_version``: the scheme of the config hashes and chunk ids it was written with); reading it
back (``load_results``, the manifest, the ledger's records) is :mod:`dfrmot_jax.report.stored`'s.

Layout: ``manifest.json`` (with the sweep's ``identity``: a directory belongs to one sweep),
``configs.parquet`` (the config table), ``chunks/<chunk id>.parquet`` (one per finished chunk,
written atomically), ``results.parquet`` (the final table) and ``ledger.jsonl``: the sha256 and
row count of every chunk file and of ``results.parquet``, one JSON line each, appended after the
file is in place. A file is trusted only if its bytes match its record: a rerun recomputes (and
``load_results`` leaves out) damaged or unrecorded chunks. Directories written before the ledger
have their chunks checked by content once and recorded.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import sys
import time
from contextlib import suppress
from importlib import metadata
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import pandas as pd

from ..trackers.protocol import DEFAULT_FAMILY
from ..io.atomic import TMP_NAME, naming, sha256, write_parquet_atomic, write_text_atomic
from ..metrics.kitti2d.evaluate import RAW_FIELDS, summary_columns
from .folder import SweepDirectoryError, claim
from .plan import Chunk, DataSettings
from ..table_columns import COMBINED, RAW_COLUMN, class_columns, contrast_doc, extra_axes, settings_of
from ..report.stored import LEDGER, NO_RECORD, Record, chunk_name, file_problem, read_ledger
from .spec import SweepSpec
from ..lidar import SIM_VERSION
from ..version import RESULTS_VERSION, __version__
from .table import HASH_VERSION



class HashVersionError(ValueError):
    """A sweep directory written with another ``config_hash`` scheme than this version's."""


def chunk_frame(table, chunk: Chunk, data: DataSettings, seq_names, lengths, metrics: dict, res, versions,
                 spec_name: str, family: str = DEFAULT_FAMILY) -> pd.DataFrame:
    """The tidy rows of one chunk: per config, one row per sequence then COMBINED; the config columns
    are the tracker ``family``'s parameters (plain and per class) and options."""
    fc = settings_of(family)
    L = len(chunk.configs)
    S = len(seq_names)
    R = S + 1
    sub = table.iloc[list(chunk.configs)].reset_index(drop=True)
    cols: dict[str, Any] = {}
    cols["config"] = np.repeat(sub["config"].to_numpy(), R)
    cols["config_hash"] = np.repeat(sub["config_hash"].to_numpy(), R)
    cols["sequence"] = np.tile(np.array(list(seq_names) + [COMBINED], dtype=object), L)
    for c in ["variant", "baseline"] + list(fc.Params._fields) + class_columns(sub.columns, fc) + list(fc.Options._fields) + \
            [n for n in extra_axes() if n in sub.columns]:
        cols[c] = np.repeat(sub[c].to_numpy(), R)
    seq_sum = summary_columns(metrics["seq"])
    comb_sum = summary_columns(metrics["comb"])
    for f, sv in seq_sum.items():
        cols[f] = np.concatenate([sv, comb_sum[f][:, None]], axis=1).reshape(-1)
    # robustness: counts
    frames = np.array(list(lengths) + [int(np.sum(lengths))], np.int64)
    cols["frames"] = np.tile(frames, L)
    offs = np.concatenate([[0], np.cumsum(lengths)])
    cs = np.concatenate([np.zeros((L, 1), np.int64), np.cumsum(res.dropped.astype(np.int64), axis=1)], axis=1)
    per_seq = cs[:, offs[1:]] - cs[:, offs[:-1]]
    cols["overflow"] = np.concatenate([per_seq, res.overflow.astype(np.int64)[:, None]], axis=1).reshape(-1)
    cols["peak_tracks"] = np.repeat(res.peak.astype(np.int64), R)
    # the track slots each lane ran with (``capacity`` is what was asked: 0 = from the data)
    cols["capacity_used"] = np.repeat(np.asarray(res.capacity, np.int64), R)
    cols["det2d"] = np.repeat(np.array([data.det2d], dtype=object), L * R)
    cols["det3d"] = np.repeat(np.array([data.det3d], dtype=object), L * R)
    cols["class"] = np.repeat(np.array([data.cls], dtype=object), L * R)
    cols["sweep"] = np.repeat(np.array([spec_name], dtype=object), L * R)
    cols["chunk"] = np.repeat(np.array([chunk.id], dtype=object), L * R)
    cols["dfrmot_jax_version"] = np.repeat(np.array([versions[0]], dtype=object), L * R)
    cols["jax_version"] = np.repeat(np.array([versions[1]], dtype=object), L * R)
    raw = np.concatenate([_raw_stack(metrics["seq"]), _raw_stack(metrics["comb"])[:, None, :]], axis=1)
    cols[RAW_COLUMN] = list(raw.reshape(L * R, -1))
    return pd.DataFrame(cols)


def _raw_stack(seq) -> np.ndarray:
    """[..., 7 * 19] the per-alpha fields needed to re-combine sequences."""
    return np.concatenate([np.asarray(seq[f], np.float64) for f in RAW_FIELDS], axis=-1)


def chunk_path(out: Path, chunk: Chunk) -> Path:
    return out / chunk_name(chunk.id)


def computed_by(datas: Sequence[DataSettings]) -> str:
    """What a sweep's chunk rows are computed with: ``RESULTS_VERSION`` (``version.py``), and the LiDAR
    simulator's ``SIM_VERSION`` when some class's scans are simulated. A chunk recorded with another
    value is recomputed on resume (:func:`finished_chunks`)."""
    sim = any(d.lidar is not None and d.lidar[1] is not None for d in datas)
    return f"{RESULTS_VERSION}" + (f"+sim{SIM_VERSION}" if sim else "")


def _ledger_line(name: str, rec: Record) -> str:
    return json.dumps({"file": name, "sha256": rec.sha256, "rows": rec.rows, "computed": rec.computed}) + "\n"


def _record(out: Path, name: str, digest: str, rows: int, computed: str = "1") -> None:
    """Append the record of a file just put in place."""
    path = out / LEDGER
    with naming(path), open(path, "a", encoding="utf-8") as f:
        f.write(_ledger_line(name, Record(digest, int(rows), computed)))


def write_chunk(out: Path, chunk: Chunk, df: pd.DataFrame, computed: str) -> None:
    """Write a chunk's table atomically, then its ledger record (``computed``: :func:`computed_by`)."""
    _record(out, chunk_name(chunk.id), write_parquet_atomic(chunk_path(out, chunk), df, digest=True), len(df),
            computed)


def write_results(out: Path, df: pd.DataFrame) -> None:
    """Write ``results.parquet`` atomically, then its ledger record."""
    _record(out, "results.parquet", write_parquet_atomic(out / "results.parquet", df, digest=True), len(df))


def finished_chunks(out: Path, table: pd.DataFrame, chunks: Sequence[Chunk], datas: Sequence[DataSettings],
                    legacy: bool = False) -> tuple[set[str], list[str]]:
    """(ids of the chunks whose file matches its ledger record, ``"chunks/<id>.parquet (why)"`` of
    the chunk files that do not, or were computed by another version (:func:`computed_by`): to
    recompute). ``legacy``: a directory written before the ledger,
    whose unrecorded chunks are checked by content instead (readable, their rows, chunk id and
    config hashes) and recorded. The ledger is rewritten with the records of the finished chunks."""
    sequences = {d.cls: len(d.sequences) for d in datas}
    now = computed_by(datas)
    ledger = read_ledger(out)
    keep: dict[str, Record] = {}
    damaged = []
    for c in chunks:
        name, path = chunk_name(c.id), chunk_path(out, c)
        if not path.is_file():
            continue
        rows = len(c.configs) * (sequences[c.cls] + 1)
        problem = file_problem(path, ledger.get(name), rows)
        if problem == NO_RECORD and legacy and _legacy_chunk_ok(path, c, table, rows):
            ledger[name], problem = Record(sha256(path), rows), None
        if problem is None and ledger[name].computed != now:
            problem = f"computed by results version {ledger[name].computed}, this one is {now}"
        if problem is None:
            keep[name] = ledger[name]
        else:
            damaged.append(f"{name} ({problem})")
    write_text_atomic(out / LEDGER, "".join(_ledger_line(n, r) for n, r in keep.items()), parents=False)
    return {c.id for c in chunks if chunk_name(c.id) in keep}, damaged


def _legacy_chunk_ok(path: Path, chunk: Chunk, table: pd.DataFrame, rows: int) -> bool:
    try:
        df = pd.read_parquet(path, columns=["chunk", "config_hash"])
    except Exception:           # any damage: pyarrow / pandas metadata errors of every kind
        return False
    want = table["config_hash"].to_numpy()[list(chunk.configs)]
    return len(df) == rows and bool((df["chunk"] == chunk.id).all()) and \
        list(pd.unique(df["config_hash"])) == list(want)



def jsonable(obj):
    try:
        return json.loads(json.dumps(obj, default=str))
    except (TypeError, ValueError):
        return None


def environment() -> dict:
    """The software and machine a directory was last written with (its manifest's ``environment``,
    shown by the report): versions, Python, OS, CPU model and count, the time."""
    cpu = platform.processor() or platform.machine()
    with suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    versions = {}
    for name in ("jax", "jaxlib", "numpy", "pandas"):
        with suppress(metadata.PackageNotFoundError):
            versions[name] = metadata.version(name)
    return {"dfrmot_jax": __version__, **versions, "python": platform.python_version(), "os": platform.platform(),
            "cpu": cpu, "cpus": os.cpu_count(), "written": time.strftime("%Y-%m-%d %H:%M:%S %Z")}


def hash_version(manifest: dict) -> int:
    """The ``config_hash`` scheme a directory was written with (no ``hash_version``: 1)."""
    return int(manifest.get("hash_version", 1))


def sweep_identity(spec: SweepSpec, datas: Sequence[DataSettings], table: pd.DataFrame) -> str:
    """What a sweep directory's results are of (its manifest's ``identity``): every class's data
    settings, the configs in order (hashes, variants, baseline flags) and the distortion settings.
    Not the sweep's name, the chunk size nor the report settings."""
    doc = {"data": [d.identity() for d in datas],
           "configs": {c: table[c].tolist() for c in ("config_hash", "variant", "baseline") if c in table.columns},
           "distortion": None if spec.distortion is None else spec.distortion.identity()}
    return hashlib.sha256(json.dumps(doc, sort_keys=True, default=str).encode()).hexdigest()[:24]


def write_manifest(outdir: Path, spec: SweepSpec, datas: Sequence[DataSettings], table: pd.DataFrame,
                   chunks: Sequence[Chunk], *, force: bool = False) -> bool:
    """Make ``outdir`` this sweep's directory and write its manifest and config table; returns
    whether it was written before the ledger (its chunks are then checked by content once:
    :func:`finished_chunks`).

    A directory of another sweep (another :func:`sweep_identity`) or with a damaged manifest raises
    :class:`SweepDirectoryError`, one of another ``config_hash`` scheme :class:`HashVersionError`,
    unless ``force``: its sweep files are then deleted first. Temp files of writes that never
    finished (a killed run, a full disk) are removed."""
    chunk_dir = outdir / "chunks"
    if outdir.exists() and not outdir.is_dir():
        raise SweepDirectoryError(f"{outdir} is a file, not a directory (the sweep's output directory)")
    if chunk_dir.exists() and not chunk_dir.is_dir():
        raise SweepDirectoryError(f"{chunk_dir} is a file, but the sweep keeps its chunk files in a directory of "
                                  f"that name: move it away or use another --out")
    identity = sweep_identity(spec, datas, table)
    old = _claim(outdir, spec, datas, table, chunks, identity, force)
    chunk_dir.mkdir(parents=True, exist_ok=True)
    _remove_orphans(outdir)
    data = datas[0]
    manifest = {"name": spec.name, "description": spec.description, "source": spec.source,
                "data": data.identity(), "lengths": list(data.lengths), "baseline": spec.baseline,
                "chunk": spec.chunk, "objective": spec.objective, "folds": spec.folds, "top": spec.top,
                "configs": len(table), "chunks": [c.id for c in chunks], "spec": jsonable(spec.raw),
                "hash_version": HASH_VERSION, "identity": identity, "ledger": LEDGER, "environment": environment()}
    if len(spec.classes) > 1:
        manifest["classes"] = list(spec.classes)
        manifest["class_data"] = {d.cls: {**d.identity(), "lengths": list(d.lengths)} for d in datas}
    if spec.lidar is not None:
        manifest["lidar"] = [d.identity()["lidar"] for d in datas if d.cls == data.cls]
    if spec.baseline_class is not None:
        manifest["baseline_class"] = spec.baseline_class
    if spec.report_class is not None:
        manifest["report_class"] = spec.report_class
    if spec.distortion is not None:
        manifest["distortion"] = {"kinds": {k: list(v) for k, v in spec.distortion.kinds},
                                  "seeds": list(spec.distortion.seeds), **spec.distortion.identity()}
    if spec.contrast is not None:
        manifest["contrast"] = contrast_doc(spec.contrast)
    if spec.ab3dmot is not None:
        manifest["ab3dmot_sum"] = spec.ab3dmot_sum
    if spec.family != DEFAULT_FAMILY:           # (a manifest without it is the default family's)
        manifest["family"] = spec.family
    write_text_atomic(outdir / "manifest.json", json.dumps(manifest, indent=1), parents=False)
    write_parquet_atomic(outdir / "configs.parquet", table)
    return old is not None and "ledger" not in old


def _claim(outdir: Path, spec: SweepSpec, datas: Sequence[DataSettings], table: pd.DataFrame,
           chunks: Sequence[Chunk], identity: str, force: bool) -> dict | None:
    """The manifest ``outdir`` holds if it is this sweep's (None: none, or deleted with ``force``):
    :func:`.folder.claim` with the sweep's identity (or, for a directory written before it, the
    same chunks and configs) and its hash scheme."""
    def version(old: dict) -> int | None:
        try:
            return hash_version(old)
        except (TypeError, ValueError):
            return None

    def check(old: dict) -> None:
        if version(old) not in (None, HASH_VERSION) and not force:
            raise HashVersionError(f"{outdir} was written with config_hash scheme {version(old)}, this version "
                                   f"uses {HASH_VERSION}: its chunks would not be found (use another --out, or "
                                   f"--force to delete them)")

    def same(old: dict) -> bool:
        return version(old) == HASH_VERSION and (old.get("identity") == identity or old.get("chunks") == [
            c.id for c in chunks] and _same_configs(outdir, table))

    return claim(outdir, "sweep", same, force, other=lambda old: _other_sweep(old, spec, datas, table), check=check)


def _same_configs(outdir: Path, table: pd.DataFrame) -> bool:
    """Whether the directory's config table has this table's configs in order (same hashes, variants,
    baseline flags): the same sweep whatever identity scheme its manifest was written with (the
    chunk ids already pin the data settings and the configs of every chunk)."""
    try:
        old = pd.read_parquet(outdir / "configs.parquet", columns=["config_hash", "variant", "baseline"])
    except (OSError, ValueError, KeyError):
        return False
    return all(old[c].tolist() == table[c].tolist() for c in old.columns if c in table.columns)


def _other_sweep(old: dict, spec: SweepSpec, datas: Sequence[DataSettings], table: pd.DataFrame) -> str:
    """How the sweep of manifest ``old`` differs from this one (a phrase)."""
    if (old.get("class_data") or {datas[0].cls: old.get("data")}) != \
            {d.cls: (d.identity() if len(spec.classes) == 1 else {**d.identity(), "lengths": list(d.lengths)}) for d in datas}:
        what = "data"
    else:
        what = "configs"
    return (f"holds another sweep ({old.get('name')!r}, {old.get('configs')} configs; this one: {spec.name!r}, "
            f"{len(table)} configs, differs in its {what})")


def _remove_orphans(outdir: Path) -> None:
    """Delete the temp files of writes that never finished: those of processes no longer running."""
    for d in (outdir, outdir / "chunks"):
        for p in d.iterdir():
            m = TMP_NAME.match(p.name)
            if m and p.is_file() and not _running(int(m.group(1))):
                with suppress(OSError):
                    p.unlink()


def _running(pid: int) -> bool:
    if sys.platform == "win32":
        return True             # (os.kill would end it): leave its files
    if pid == os.getpid():
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:     # another user's process
        return True
    except (OverflowError, OSError):
        return False
    return True
