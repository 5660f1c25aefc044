"""One config of a sweep or tune directory written as result files: ``dfrmot compare DIR:best ...``.

A reference ``DIR:best`` (the directory's best config by its objective, ranked as ``dfrmot report DIR``
ranks it: on the class average of a sweep over several classes unless its file's ``report.class``
names one class), ``DIR:baseline`` or ``DIR:config=N`` names a config of the stored table;
:func:`write_config_output` tracks that config alone, for every class the directory tracked, on the
directory's data (its manifest: root, detectors, class, sequences) and writes one KITTI result file per
sequence (the classes merged, as ``dfrmot track --class car,pedestrian`` writes them), which score what
the rows say (a sweep row equals the config run alone), all by the directory's tracker family (its
manifest's ``family``; none: the default). Distortion and LiDAR sweeps, whose rows also depend on
lanes or simulated scans, are refused.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..data import load_split
from ..trackers.protocol import TrackerFamily
from ..trackers.registry import family_of
from ..metrics.columns import canonical_objective
from ..report.analysis import class_view, classes_of, rank_configs, report_class_of
from ..table_columns import AVERAGE, COMBINED, extra_axes
from ..report.stored import load_results, manifest_family, read_manifest
from .table import params_of

__all__ = ["write_config_output", "sweep_classes", "class_data"]


def sweep_classes(manifest: dict) -> list[str]:
    """The classes a directory tracked (its manifest's), in order."""
    return list(manifest.get("classes") or [manifest["data"].get("class", "car")])


def class_data(manifest: dict, cls: str) -> dict:
    """The data a directory tracked class ``cls`` on (root, detectors, class, sequences)."""
    return (manifest.get("class_data") or {}).get(cls) or manifest["data"]


def _config(directory: Path, which, manifest: dict, df: pd.DataFrame) -> tuple[int, str]:
    """The config number ``which`` names, and how it was chosen ("" unless by ranking)."""
    classes = classes_of(df)
    cls = report_class_of(df, manifest.get("report_class")) if classes else None
    view = class_view(df, cls, manifest_family(manifest)) if classes else df
    comb = view[view["sequence"] == COMBINED].drop_duplicates("config").reset_index(drop=True)
    if which == "best":
        objective = canonical_objective(manifest.get("objective") or "HOTA")
        row = comb.iloc[int(rank_configs(comb[objective].to_numpy(), objective)[0])]
        on = "the class average" if cls == AVERAGE else f"{cls}" if len(classes) > 1 else ""
        return int(row["config"]), f"best by {objective}" + (f" on {on}" if on else "")
    if which == "baseline":
        base = comb[comb["baseline"]]
        if not len(base):
            raise ValueError(f"{directory}: the directory has no baseline row")
        return int(base.iloc[0]["config"]), ""
    if not (comb["config"] == which).any():
        raise ValueError(f"{directory}: no config {which} (configs {int(comb['config'].min())} to "
                         f"{int(comb['config'].max())})")
    return int(which), ""


def _class_run(directory: Path, df: pd.DataFrame, config: int, cls: str, data: dict, family: TrackerFamily):
    """Config ``config`` tracked alone by ``family`` for class ``cls`` on ``data`` (the family's run of
    one lane, as its ``write_runs`` takes it), and its hash."""
    rows = df[df["class"] == cls] if "class" in df.columns else df
    comb = rows[rows["sequence"] == COMBINED].drop_duplicates("config").reset_index(drop=True)
    pos = int(np.flatnonzero(comb["config"].to_numpy() == config)[0])
    row = comb.iloc[pos]
    for name, default in extra_axes().items():
        if name in row.index and row[name] != default:
            raise ValueError(f"{directory}: config {config} has {name} = {row[name]!r}: a distortion or "
                             f"LiDAR sweep's rows are not one config's output; track it with dfrmot track")
    fc = family.config
    params = params_of(comb, [pos], cls, family.name)
    options = fc.Options(**{n: (row[n].item() if hasattr(row[n], "item") else row[n]) for n in fc.Options._fields
                            if n in row.index})
    for name, value in options._asdict().items():
        problem = fc.option_problem(name, value)
        if problem:
            raise ValueError(f"option {name}={value!r}: {problem}")
    split = load_split(data["root"], data["det2d"], data["det3d"], cls, data["sequences"])
    res = family.track(split, params, options, detail=True)
    return family.class_run(split, res, 0), str(row["config_hash"])


def write_config_output(directory, which, out_dir) -> str:
    """Track config ``which`` ('best', 'baseline' or a config number) of a sweep / tune directory alone,
    for every class it tracked, and write its result files to ``out_dir``; returns a description
    (``DIR config N (hash ..., best by HOTA on the class average)``)."""
    directory = Path(directory)
    manifest = read_manifest(directory)
    df = load_results(directory)
    config, how = _config(directory, which, manifest, df)
    family = family_of(manifest_family(manifest))
    runs, hashes = [], []
    for cls in sweep_classes(manifest):
        run, h = _class_run(directory, df, config, cls, class_data(manifest, cls), family)
        runs.append(run)
        hashes.append(h)
    family.write_runs(out_dir, runs)
    return f"{directory} config {config} (hash {hashes[0]}{', ' + how if how else ''})"
