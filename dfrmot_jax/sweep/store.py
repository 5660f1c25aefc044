"""A sweep directory: chunk files and the tables built from them, atomic writes, the manifest
(``hash_version``: the scheme of the config hashes and chunk ids it was written with) and
``load_results``.

Layout: ``manifest.json``, ``configs.parquet`` (the config table), ``chunks/<chunk id>.parquet``
(one per finished chunk, written atomically: a rerun skips chunks whose file exists) and
``results.parquet`` (the final table).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import pandas as pd

from ..metrics.evaluate import RAW_FIELDS, class_average_columns, class_combiner, summary_columns
from .plan import Chunk, DataSettings
from .spec import OPTION_NAMES, PARAM_NAMES, SweepSpec, _contrast_doc, _extra_axes
from .spec import AVERAGE
from .table import COMBINED, HASH_VERSION, RAW_COLUMN, class_columns


class HashVersionError(RuntimeError):
    """A sweep directory written with another ``config_hash`` scheme than this version's."""


def _chunk_frame(table, chunk: Chunk, data: DataSettings, seq_names, lengths, metrics: dict, res, versions,
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
            [n for n in _extra_axes() if n in sub.columns]:
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


def _atomic_parquet(df: pd.DataFrame, path: Path) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    df.to_parquet(tmp, index=False)
    os.replace(tmp, path)


def _atomic_text(text: str, path: Path) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def _chunk_path(out: Path, chunk: Chunk) -> Path:
    return out / "chunks" / f"{chunk.id}.parquet"



def _jsonable(obj):
    try:
        return json.loads(json.dumps(obj, default=str))
    except (TypeError, ValueError):
        return None


def hash_version(manifest: dict) -> int:
    """The ``config_hash`` scheme a directory was written with (no ``hash_version``: 1)."""
    return int(manifest.get("hash_version", 1))


def write_manifest(outdir: Path, spec: SweepSpec, datas: Sequence[DataSettings], table: pd.DataFrame,
                   chunks: Sequence[Chunk]) -> None:
    """Create ``outdir`` (or check an existing one's ``hash_version``) and write its manifest and config table."""
    old = outdir / "manifest.json"
    if old.is_file():
        version = hash_version(json.loads(old.read_text()))
        if version != HASH_VERSION:
            raise HashVersionError(f"{outdir} was written with config_hash scheme {version}, this version uses "
                                   f"{HASH_VERSION}: its chunks would not be found (use another --out)")
    (outdir / "chunks").mkdir(parents=True, exist_ok=True)
    data = datas[0]
    manifest = {"name": spec.name, "description": spec.description, "source": spec.source,
                "data": data.identity(), "lengths": list(data.lengths), "baseline": spec.baseline,
                "chunk": spec.chunk, "objective": spec.objective, "folds": spec.folds, "top": spec.top,
                "configs": len(table), "chunks": [c.id for c in chunks], "spec": _jsonable(spec.raw),
                "hash_version": HASH_VERSION}
    if len(datas) > 1:
        manifest["classes"] = list(spec.classes)
        manifest["class_data"] = {d.cls: {**d.identity(), "lengths": list(d.lengths)} for d in datas}
    if spec.baseline_class is not None:
        manifest["baseline_class"] = spec.baseline_class
    if spec.report_class is not None:
        manifest["report_class"] = spec.report_class
    if spec.distortion is not None:
        manifest["distortion"] = {"kinds": {k: list(v) for k, v in spec.distortion.kinds},
                                  "seeds": list(spec.distortion.seeds), **spec.distortion.identity()}
    if spec.contrast is not None:
        manifest["contrast"] = _contrast_doc(spec.contrast)
    _atomic_text(json.dumps(manifest, indent=1), outdir / "manifest.json")
    _atomic_parquet(table, outdir / "configs.parquet")


def _finish(df: pd.DataFrame, classes: Sequence[str] = ()) -> pd.DataFrame:
    """Rows by config (within a config: classes in order, each its sequences then COMBINED); with
    several classes, each config's class-average row last (:func:`_average_rows`)."""
    df = df[df["class"] != AVERAGE] if "class" in df.columns else df
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
    and ``overflow`` summed, ``peak_tracks`` the largest, ``chunk`` empty, the per-alpha column
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
        out[f] = v.astype(out[f].dtype) if np.issubdtype(out[f].dtype, np.integer) else v
    for f, how in (("frames", "sum"), ("overflow", "sum"), ("peak_tracks", "max")):
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
    """The tidy table of a sweep directory (``results.parquet``, else its finished chunks)."""
    out = Path(out)
    manifest = _manifest(out)
    paths = [out / "chunks" / f"{cid}.parquet" for cid in manifest["chunks"]]
    final = out / "results.parquet"
    if final.is_file() and all(p.is_file() for p in paths):
        df = pd.read_parquet(final)
        if set(df.loc[df["chunk"] != "", "chunk"].unique()) == set(manifest["chunks"]):
            return df
    have = [p for p in paths if p.is_file()]
    if len(have) < len(paths) and not allow_partial:
        raise FileNotFoundError(f"{out}: {len(paths) - len(have)} of {len(paths)} chunks not finished "
                                f"(rerun the sweep to resume)")
    if not have:
        raise FileNotFoundError(f"{out}: no finished chunk yet")
    return _finish(pd.concat([pd.read_parquet(p) for p in have], ignore_index=True), manifest.get("classes", ()))


def _manifest(out: Path) -> dict:
    path = Path(out) / "manifest.json"
    if not path.is_file():
        raise FileNotFoundError(f"{out} is not a sweep directory (no manifest.json)")
    return json.loads(path.read_text())

