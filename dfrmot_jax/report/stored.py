"""A sweep or tune directory read back: its manifest (:func:`read_manifest`), the ledger's records
of its files (:func:`read_ledger`, :func:`file_problem`) and its tidy table (:func:`load_results`,
:func:`finish_table`). The directory's layout and its writing are :mod:`dfrmot_jax.sweep.store`'s;
these readers were moved here from it so that the report reads a stored table without JAX.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import NamedTuple, Sequence

import numpy as np
import pandas as pd

from ..io.atomic import sha256
from ..metrics.columns import class_average_columns, class_combiner
from ..metrics.kitti2d.evaluate import RAW_FIELDS
from ..trackers.protocol import DEFAULT_FAMILY
from ..trackers.registry import family_names
from ..table_columns import AVERAGE, COMBINED, RAW_COLUMN, settings_of

__all__ = ["LEDGER", "NO_RECORD", "chunk_name", "Record", "read_ledger", "file_problem", "finish_table", "load_results",
           "read_manifest", "manifest_problem", "manifest_family"]


#: The ledger of a sweep directory (module docstring).
LEDGER = "ledger.jsonl"
NO_RECORD = "no checksum record"


def chunk_name(chunk_id: str) -> str:
    """A chunk file's name relative to the sweep directory (its ledger key)."""
    return f"chunks/{chunk_id}.parquet"


class Record(NamedTuple):
    sha256: str
    rows: int
    computed: str = "1"         # what the rows were computed with (:func:`computed_by`); "1": not recorded


def read_ledger(out: Path) -> dict[str, Record]:
    """File name (relative to ``out``) -> its last record; lines that do not parse are skipped."""
    try:
        lines = (out / LEDGER).read_bytes().splitlines()
    except OSError:
        return {}
    records = {}
    for line in lines:
        try:
            doc = json.loads(line)
            name, rec = doc["file"], Record(doc["sha256"], doc["rows"], str(doc.get("computed", "1")))
        except (ValueError, KeyError, TypeError):
            continue
        if isinstance(name, str) and isinstance(rec.sha256, str) and len(rec.sha256) == 64 and \
                type(rec.rows) is int and rec.rows >= 0:
            records[name] = rec
    return records


def file_problem(path: Path, rec: Record | None, rows: int | None = None) -> str | None:
    """Why the file at ``path`` cannot be trusted; None if its bytes are those of its record."""
    if rec is None:
        return NO_RECORD
    if rows is not None and rec.rows != rows:
        return f"recorded with {rec.rows} rows, expected {rows}"
    try:
        digest = sha256(path)
    except OSError as e:
        return f"unreadable: {e.strerror or e}"
    return None if digest == rec.sha256 else "checksum mismatch: changed or truncated"


def finish_table(df: pd.DataFrame, classes: Sequence[str] = (), family=DEFAULT_FAMILY) -> pd.DataFrame:
    """Rows by config (within a config: classes in order, each its sequences then COMBINED); with
    several classes, each config's class-average row last (:func:`_average_rows`). Rows of chunks
    written before an option of the tracker ``family``'s ``late_options`` (a parameter of its
    ``late_params``) existed get its default."""
    fc = settings_of(family)
    df = df[df["class"] != AVERAGE] if "class" in df.columns else df
    late = {n: d for n, d in {**fc.late_options, **fc.late_params}.items() if n in df.columns}
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
    ledger = read_ledger(out) if "ledger" in manifest else None
    names = [chunk_name(cid) for cid in manifest["chunks"]]
    tables, damaged = {}, []

    def read(name: str) -> pd.DataFrame | None:
        rec = ledger.get(name) if ledger is not None else None
        problem = file_problem(out / name, rec) if ledger is not None else None
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
    return finish_table(pd.concat(list(tables.values()), ignore_index=True), manifest.get("classes", ()),
                        manifest_family(manifest))


#: the fields of a manifest's ``data`` (the sweep's data: ``sweep.plan.DataSettings.identity``) that its
#: readers use, with their JSON types (``det2d`` null: a tracker family that reads 3D detections only;
#: ``det3d`` null: one that reads 2D detections only)
_DATA_FIELDS = {"root": str, "det2d": (str, type(None)), "det3d": (str, type(None)), "sequences": list}
#: fields a manifest may lack, and their JSON types where present
_OPTIONAL_FIELDS = {"kind": (str,), "family": (str,), "objective": (str,), "classes": (list,), "lengths": (list,),
                    "folds": (int, type(None)), "report_class": (str, type(None))}


_JSON_TYPES = {str: "a string", list: "a list", int: "a whole number", float: "a number", bool: "true or false",
               dict: "an object", type(None): "null"}


def _json_type(kind: type) -> str:
    """A Python type of parsed JSON by its JSON name: ``list`` -> "a list"."""
    return _JSON_TYPES.get(kind, kind.__name__)


def _data_problem(key: str, data: dict) -> str | None:
    """What is wrong with a manifest's data object ``data`` (at ``key``), None when nothing is."""
    for name, kind in _DATA_FIELDS.items():
        kinds = kind if isinstance(kind, tuple) else (kind,)
        if name not in data or not isinstance(data[name], kinds):
            return f"{key}.{name}: missing or not {' or '.join(_json_type(k) for k in kinds)}"
    if not all(isinstance(s, str) for s in data["sequences"]):
        return f"{key}.sequences: expected sequence names"
    if not isinstance(data.get("class", ""), str):
        return f"{key}.class: not a string"
    return None


def manifest_problem(doc) -> str | None:
    """What makes ``doc`` (a parsed ``manifest.json``) no manifest its readers can use, None when
    nothing does: an object, with a ``data`` object of the sweep's data (:data:`_DATA_FIELDS`, its
    sequences names; a sweep of several classes: each one's in ``class_data``) and, but for a tune's,
    the list of its chunks' names."""
    if not isinstance(doc, dict):
        return f"expected an object, got {_json_type(type(doc))}"
    data = doc.get("data")
    if not isinstance(data, dict):
        return "no 'data' object (the sweep's data: root, detectors, class, sequences)"
    problem = _data_problem("data", data)
    if problem is not None:
        return problem
    if isinstance(doc.get("family"), str) and doc["family"] not in family_names():
        return f"family: {doc['family']!r} is not a registered tracker family ({', '.join(family_names())})"
    for name, kinds in _OPTIONAL_FIELDS.items():
        if name in doc and not isinstance(doc[name], kinds):
            return f"{name}: {_json_type(type(doc[name]))}, expected {' or '.join(_json_type(k) for k in kinds)}"
    per_class = doc.get("class_data") if isinstance(doc.get("class_data"), dict) else {}
    for cls in doc.get("classes") or []:        # (a sweep of several classes: each class's data)
        if not isinstance(cls, str):
            return "classes: expected class names"
        per = per_class.get(cls)
        if not isinstance(per, dict):
            return f"class_data.{cls}: missing or not an object"
        problem = _data_problem(f"class_data.{cls}", per)
        if problem is not None:
            return problem
    chunks = doc.get("chunks", [] if doc.get("kind") == "tune" else None)
    if not isinstance(chunks, list) or not all(isinstance(c, str) for c in chunks):
        return "chunks: missing or not a list of chunk names"
    return None


def manifest_family(manifest: dict) -> str:
    """The tracker family of a sweep or tune directory's tables: its manifest's ``family``; a
    manifest without it (every directory written before families, and every default family's) is
    the default family's (``"dfr"``)."""
    return manifest.get("family", DEFAULT_FAMILY)


def read_manifest(out: Path) -> dict:
    """The manifest of sweep or tune directory ``out``: FileNotFoundError when there is none,
    ValueError naming it when it is damaged (not JSON, or not a manifest: :func:`manifest_problem`)."""
    path = Path(out) / "manifest.json"
    if not path.is_file():
        raise FileNotFoundError(f"{out} is not a sweep directory (no manifest.json)")
    try:
        doc = json.loads(path.read_bytes().decode("utf-8"))
    except UnicodeDecodeError as e:
        raise ValueError(f"{path}: damaged, not UTF-8 text (byte {e.start})") from None
    except json.JSONDecodeError as e:
        raise ValueError(f"{path}:{e.lineno}: damaged, not valid JSON ({e.msg}, column {e.colno})") from None
    problem = manifest_problem(doc)
    if problem is not None:
        raise ValueError(f"{path}: damaged, not a sweep manifest: {problem}")
    return doc
