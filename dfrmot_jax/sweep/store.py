"""A sweep directory: chunk files and the tables built from them, atomic writes, the manifest
(``hash_version``: the scheme of the config hashes and chunk ids it was written with) and
``load_results``.

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
import warnings
from contextlib import suppress
from importlib import metadata
from pathlib import Path
from typing import Any, NamedTuple, Sequence

import numpy as np
import pandas as pd

from ..io.atomic import TMP_NAME, naming, sha256, write_parquet_atomic, write_text_atomic
from ..metrics.columns import class_average_columns, class_combiner
from ..metrics.kitti2d.evaluate import RAW_FIELDS, summary_columns
from .folder import SweepDirectoryError, claim
from .plan import Chunk, DataSettings
from .spec import AVERAGE, LATE_OPTIONS, LATE_PARAMS, OPTION_NAMES, PARAM_NAMES, SweepSpec, contrast_doc, extra_axes
from ..lidar import SIM_VERSION
from ..version import RESULTS_VERSION, __version__
from .table import COMBINED, HASH_VERSION, RAW_COLUMN, class_columns

#: The ledger of a sweep directory (module docstring).
LEDGER = "ledger.jsonl"
_NO_RECORD = "no checksum record"


class HashVersionError(ValueError):
    """A sweep directory written with another ``config_hash`` scheme than this version's."""


def chunk_frame(table, chunk: Chunk, data: DataSettings, seq_names, lengths, metrics: dict, res, versions,
                 spec_name: str) -> pd.DataFrame:
    """The tidy rows of one chunk: per config, one row per sequence then COMBINED."""
    L = len(chunk.configs)
    S = len(seq_names)
    R = S + 1
    sub = table.iloc[list(chunk.configs)].reset_index(drop=True)
    cols: dict[str, Any] = {}
    cols["config"] = np.repeat(sub["config"].to_numpy(), R)
    cols["config_hash"] = np.repeat(sub["config_hash"].to_numpy(), R)
    cols["sequence"] = np.tile(np.array(list(seq_names) + [COMBINED], dtype=object), L)
    for c in ["variant", "baseline"] + list(PARAM_NAMES) + class_columns(sub.columns) + list(OPTION_NAMES) + \
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


def _chunk_name(chunk_id: str) -> str:
    """A chunk file's name relative to the sweep directory (its ledger key)."""
    return f"chunks/{chunk_id}.parquet"


def chunk_path(out: Path, chunk: Chunk) -> Path:
    return out / _chunk_name(chunk.id)


class _Record(NamedTuple):
    sha256: str
    rows: int
    computed: str = "1"         # what the rows were computed with (:func:`computed_by`); "1": not recorded


def computed_by(datas: Sequence[DataSettings]) -> str:
    """What a sweep's chunk rows are computed with: ``RESULTS_VERSION`` (``version.py``), and the LiDAR
    simulator's ``SIM_VERSION`` when some class's scans are simulated. A chunk recorded with another
    value is recomputed on resume (:func:`finished_chunks`)."""
    sim = any(d.lidar is not None and d.lidar[1] is not None for d in datas)
    return f"{RESULTS_VERSION}" + (f"+sim{SIM_VERSION}" if sim else "")


def _read_ledger(out: Path) -> dict[str, _Record]:
    """File name (relative to ``out``) -> its last record; lines that do not parse are skipped."""
    try:
        lines = (out / LEDGER).read_bytes().splitlines()
    except OSError:
        return {}
    records = {}
    for line in lines:
        try:
            doc = json.loads(line)
            name, rec = doc["file"], _Record(doc["sha256"], doc["rows"], str(doc.get("computed", "1")))
        except (ValueError, KeyError, TypeError):
            continue
        if isinstance(name, str) and isinstance(rec.sha256, str) and len(rec.sha256) == 64 and \
                type(rec.rows) is int and rec.rows >= 0:
            records[name] = rec
    return records


def _ledger_line(name: str, rec: _Record) -> str:
    return json.dumps({"file": name, "sha256": rec.sha256, "rows": rec.rows, "computed": rec.computed}) + "\n"


def _record(out: Path, name: str, digest: str, rows: int, computed: str = "1") -> None:
    """Append the record of a file just put in place."""
    path = out / LEDGER
    with naming(path), open(path, "a", encoding="utf-8") as f:
        f.write(_ledger_line(name, _Record(digest, int(rows), computed)))


def write_chunk(out: Path, chunk: Chunk, df: pd.DataFrame, computed: str) -> None:
    """Write a chunk's table atomically, then its ledger record (``computed``: :func:`computed_by`)."""
    _record(out, _chunk_name(chunk.id), write_parquet_atomic(chunk_path(out, chunk), df, digest=True), len(df),
            computed)


def write_results(out: Path, df: pd.DataFrame) -> None:
    """Write ``results.parquet`` atomically, then its ledger record."""
    _record(out, "results.parquet", write_parquet_atomic(out / "results.parquet", df, digest=True), len(df))


def _problem(path: Path, rec: _Record | None, rows: int | None = None) -> str | None:
    """Why the file at ``path`` cannot be trusted; None if its bytes are those of its record."""
    if rec is None:
        return _NO_RECORD
    if rows is not None and rec.rows != rows:
        return f"recorded with {rec.rows} rows, expected {rows}"
    try:
        digest = sha256(path)
    except OSError as e:
        return f"unreadable: {e.strerror or e}"
    return None if digest == rec.sha256 else "checksum mismatch: changed or truncated"


def finished_chunks(out: Path, table: pd.DataFrame, chunks: Sequence[Chunk], datas: Sequence[DataSettings],
                    legacy: bool = False) -> tuple[set[str], list[str]]:
    """(ids of the chunks whose file matches its ledger record, ``"chunks/<id>.parquet (why)"`` of
    the chunk files that do not, or were computed by another version (:func:`computed_by`): to
    recompute). ``legacy``: a directory written before the ledger,
    whose unrecorded chunks are checked by content instead (readable, their rows, chunk id and
    config hashes) and recorded. The ledger is rewritten with the records of the finished chunks."""
    sequences = {d.cls: len(d.sequences) for d in datas}
    now = computed_by(datas)
    ledger = _read_ledger(out)
    keep: dict[str, _Record] = {}
    damaged = []
    for c in chunks:
        name, path = _chunk_name(c.id), chunk_path(out, c)
        if not path.is_file():
            continue
        rows = len(c.configs) * (sequences[c.cls] + 1)
        problem = _problem(path, ledger.get(name), rows)
        if problem == _NO_RECORD and legacy and _legacy_chunk_ok(path, c, table, rows):
            ledger[name], problem = _Record(sha256(path), rows), None
        if problem is None and ledger[name].computed != now:
            problem = f"computed by results version {ledger[name].computed}, this one is {now}"
        if problem is None:
            keep[name] = ledger[name]
        else:
            damaged.append(f"{name} ({problem})")
    write_text_atomic(out / LEDGER, "".join(_ledger_line(n, r) for n, r in keep.items()), parents=False)
    return {c.id for c in chunks if _chunk_name(c.id) in keep}, damaged


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


def finish_table(df: pd.DataFrame, classes: Sequence[str] = ()) -> pd.DataFrame:
    """Rows by config (within a config: classes in order, each its sequences then COMBINED); with
    several classes, each config's class-average row last (:func:`_average_rows`). Rows of chunks
    written before an option of ``LATE_OPTIONS`` (a parameter of ``LATE_PARAMS``) existed get its default."""
    df = df[df["class"] != AVERAGE] if "class" in df.columns else df
    late = {n: d for n, d in {**LATE_OPTIONS, **LATE_PARAMS}.items() if n in df.columns}
    df = df.fillna(late) if late else df
    classes = list(classes) or list(pd.unique(df["class"])) if "class" in df.columns else []
    if len(classes) > 1:
        df = pd.concat([df, _average_rows(df, classes)], ignore_index=True)
        order = {c: i for i, c in enumerate(list(classes) + [AVERAGE])}
        key = df["class"].map(order).to_numpy()
        df = df.iloc[np.lexsort((np.arange(len(df)), key, df["config"].to_numpy()))]
    else:
        df = df.sort_values("config", kind="mergesort")
    return df.reset_index(drop=True)


def _average_rows(df: pd.DataFrame, classes: Sequence[str]) -> pd.DataFrame:
    """One ``class = "average"``, ``sequence = COMBINED`` row per config that has every class's
    COMBINED row: metric columns the class average (:func:`_class_average_columns`), ``frames``
    and ``overflow`` summed, ``peak_tracks`` and ``capacity_used`` the largest, ``chunk`` empty, the per-alpha column
    the class average of its fields; the config's other columns as in its rows."""
    comb = df[df["sequence"] == COMBINED]
    parts = [comb[comb["class"] == c].set_index("config") for c in classes]
    configs = parts[0].index
    for p in parts[1:]:
        configs = configs.intersection(p.index, sort=False)
    if not len(configs):
        return df.iloc[:0]
    parts = [p.loc[configs] for p in parts]
    out = parts[0].copy()
    metrics = class_average_columns([{c: p[c].to_numpy() for c in p.columns if class_combiner(c)}
                                      for p in parts])
    for f, v in metrics.items():
        # counts stay integers (AB3DMOT's are nullable Int64: empty on per-sequence rows)
        out[f] = pd.array(np.asarray(v, np.int64), dtype=out[f].dtype) if pd.api.types.is_integer_dtype(out[f].dtype) \
            else v
    for f, how in (("frames", "sum"), ("overflow", "sum"), ("peak_tracks", "max"), ("capacity_used", "max")):
        if f in out.columns:
            stack = np.stack([p[f].to_numpy() for p in parts])
            out[f] = stack.sum(axis=0) if how == "sum" else stack.max(axis=0)
    if RAW_COLUMN in out.columns:
        raws = np.stack([np.stack(p[RAW_COLUMN].to_numpy()) for p in parts])      # [K, C, 7 * 19]
        raws = raws.reshape(raws.shape[:2] + (len(RAW_FIELDS), -1))
        avg = np.stack([raws[:, :, i].sum(axis=0) if class_combiner(f) == "sum" else raws[:, :, i].mean(axis=0)
                        for i, f in enumerate(RAW_FIELDS)], axis=1)
        out[RAW_COLUMN] = list(avg.reshape(len(configs), -1))
    out["class"] = AVERAGE
    if "chunk" in out.columns:
        out["chunk"] = ""
    return out.reset_index()[df.columns]


def load_results(out, *, allow_partial: bool = False) -> pd.DataFrame:
    """The tidy table of a sweep directory (``results.parquet``, else its finished chunks).

    Only files that match their ledger record are read (a directory written before the ledger:
    files that read); damaged chunks are left out with a ``RuntimeWarning`` naming them. Chunks
    not finished or damaged raise ``FileNotFoundError`` unless ``allow_partial``."""
    out = Path(out)
    manifest = read_manifest(out)
    final = out / "results.parquet"
    if manifest.get("kind") == "tune":      # a tune directory (dfrmot_jax.tuning): its table is written per batch
        if not final.is_file():
            raise FileNotFoundError(f"{out}: the tune has not finished a batch yet (rerun it to resume)")
        return pd.read_parquet(final)
    ledger = _read_ledger(out) if "ledger" in manifest else None
    names = [_chunk_name(cid) for cid in manifest["chunks"]]
    tables, damaged = {}, []

    def read(name: str) -> pd.DataFrame | None:
        rec = ledger.get(name) if ledger is not None else None
        problem = _problem(out / name, rec) if ledger is not None else None
        if problem is None:
            try:
                df = pd.read_parquet(out / name)
            except Exception as e:      # any damage: pyarrow / pandas metadata errors of every kind
                problem = f"unreadable: {type(e).__name__}: {e}"
            else:
                if rec is None or len(df) == rec.rows:
                    return df
                problem = f"{len(df)} rows, recorded {rec.rows}"
        damaged.append(f"{name} ({problem})")
        return None

    present = [n for n in names if (out / n).is_file()]
    if len(present) == len(names) and final.is_file():
        df = read(final.name)
        if df is not None and set(df.loc[df["chunk"] != "", "chunk"].unique()) == set(manifest["chunks"]):
            return df
        damaged.clear()             # a damaged results.parquet: rebuilt from the chunks
    for n in present:
        df = read(n)
        if df is not None:
            tables[n] = df
    if damaged:
        warnings.warn(f"{out}: {len(damaged)} damaged chunk file(s) left out (rerun the sweep to recompute them): "
                      + "; ".join(damaged), RuntimeWarning, stacklevel=2)
    if len(tables) < len(names) and not allow_partial:
        raise FileNotFoundError(f"{out}: {len(names) - len(present)} of {len(names)} chunks not finished"
                                + (f", {len(present) - len(tables)} damaged" if len(present) > len(tables) else "")
                                + " (rerun the sweep to resume)")
    if not tables:
        raise FileNotFoundError(f"{out}: no finished chunk yet")
    return finish_table(pd.concat(list(tables.values()), ignore_index=True), manifest.get("classes", ()))


def read_manifest(out: Path) -> dict:
    path = Path(out) / "manifest.json"
    if not path.is_file():
        raise FileNotFoundError(f"{out} is not a sweep directory (no manifest.json)")
    return json.loads(path.read_text())

