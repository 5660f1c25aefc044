"""One config of a sweep or tune directory written as result files: ``dfrmot compare DIR:best ...``.

A reference ``DIR:best`` (the directory's best config by its objective, the report's ranking),
``DIR:baseline`` or ``DIR:config=N`` names a row of the stored table; :func:`write_config_output`
tracks that config alone on the directory's data (its manifest: root, detectors, class, sequences) and
writes one KITTI result file per sequence, which score what the row says (a sweep row equals the config
run alone). Distortion and LiDAR sweeps, whose rows also depend on lanes or simulated scans, are refused.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..api import track
from ..config import Options
from ..data import load_split
from ..report.analysis import rank_configs
from ..report.columns import COMBINED, OPTION_NAMES, extra_axes
from ..report.stored import load_results, read_manifest
from ..results import write_lane
from .table import params_of

__all__ = ["write_config_output"]


def _row(directory: Path, which, manifest: dict):
    """The COMBINED row (of the manifest's class) that ``which`` names, and the table."""
    df = load_results(directory)
    cls = manifest.get("data", {}).get("class", "car")
    if "class" in df.columns:
        df = df[df["class"] == cls]
    comb = df[df["sequence"] == COMBINED].drop_duplicates("config").reset_index(drop=True)
    if which == "best":
        objective = manifest.get("objective", "HOTA")
        return comb.iloc[int(rank_configs(comb[objective].to_numpy(), objective)[0])], comb
    if which == "baseline":
        base = comb[comb["baseline"]]
        if not len(base):
            raise ValueError(f"{directory}: the directory has no baseline row")
        return base.iloc[0], comb
    hit = comb[comb["config"] == which]
    if not len(hit):
        raise ValueError(f"{directory}: no config {which} (configs {int(comb['config'].min())} to "
                         f"{int(comb['config'].max())})")
    return hit.iloc[0], comb


def write_config_output(directory, which, out_dir) -> str:
    """Track config ``which`` ('best', 'baseline' or a config number) of a sweep / tune directory alone
    and write its result files to ``out_dir``; returns a description (``DIR config N (hash ...)``)."""
    directory = Path(directory)
    manifest = read_manifest(directory)
    row, comb = _row(directory, which, manifest)
    for name, default in extra_axes().items():
        if name in row.index and row[name] != default:
            raise ValueError(f"{directory}: config {int(row['config'])} has {name} = {row[name]!r}: a distortion or "
                             f"LiDAR sweep's rows are not one config's output; track it with dfrmot track")
    data = manifest["data"]
    pos = int(np.flatnonzero(comb["config"].to_numpy() == row["config"])[0])
    params = params_of(comb, [pos], data.get("class", "car"))
    options = Options(**{n: (row[n].item() if hasattr(row[n], "item") else row[n]) for n in OPTION_NAMES
                         if n in row.index}).validate()
    split = load_split(data["root"], data["det2d"], data["det3d"], data.get("class", "car"), data["sequences"])
    res = track(split, params, options, detail=True)
    write_lane(out_dir, split, res.frames, res.options, res.ids[0], res.lane_boxes(0), src3=res.src3[0],
               own3=res.own3[0], box3=None if res.box3 is None else res.box3[0])
    return f"{directory} config {int(row['config'])} (hash {row['config_hash']})"
