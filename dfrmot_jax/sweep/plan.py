"""Planning a sweep: the data settings resolved and checked, configs grouped by static options (one
compilation each) and cut into chunks (the resume unit; chunk id = hash of the data settings, the
chunk's config hashes and what the sweep's axis kinds add, ``AxisKind.chunk_identity``: with
distortion, the distortion settings). An axis kind that needs data of its own (``AxisKind.split_key``:
the LiDAR settings) gives each of its keys its own split per class. The options are the sweep's
tracker family's (``SweepSpec.family``): one group per family and ``Options`` value."""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Sequence

import pandas as pd

from ..data import detection_dir, sequences_with_class
from ..trackers.protocol import DEFAULT_FAMILY
from ..trackers.registry import family_config
from ..trackers.registry import family_of
from ..io.kitti import KittiFormatError, sequence_lengths
from ..lidar import lidar_dir
from ..paths import default_data_root
from .axes import AxisKind, split_key, split_keys
from ..checks import config_error
from .distortion import DistortionAxes
from .spec import as_spec

#: Default most tracker output one chunk may hold, GB (``run_sweep(max_memory=...)``, ``dfrmot sweep
#: --max-memory``), checked before any work (:func:`check_memory`).
MAX_MEMORY_GB = 2.0


@dataclass(frozen=True)
class DataSettings:
    """Resolved data settings of a sweep (part of every chunk's identity). ``det2d`` None: a tracker
    family that reads 3D detections only (AB3DMOT's), no 2D detections read."""
    root: str
    det2d: str | None
    det3d: str
    cls: str
    sequences: tuple[str, ...]
    lengths: tuple[int, ...] = ()
    lidar: tuple | None = None      # the split key of an axis kind (AxisKind.split_key: a lidar_axes.LidarKey)

    def identity(self) -> dict:
        out = {"root": self.root, "det2d": self.det2d, "det3d": self.det3d, "class": self.cls,
               "sequences": list(self.sequences)}
        if self.lidar is not None:
            out.update(self.lidar.identity())
        return out


def resolve_data_all(spec, data_root=None) -> tuple[DataSettings, ...]:
    """The data settings of every class of the sweep (``data.class`` order), each checked before any
    work: each class has its own split (the sequences whose ground truth has the class, or
    ``data.sequences``), and with an axis kind that needs data of its own (``AxisKind.split_key``:
    [lift] / [simulate]) each class one split per key (per LiDAR setting)."""
    spec = as_spec(spec)
    datas = [resolve_data(spec, data_root, cls=c) for c in spec.classes]
    keys = split_keys(spec.axes)
    if not keys:
        return tuple(datas)
    return tuple(replace(d, lidar=k) for d in datas for k in keys)


def resolve_data(spec, data_root=None, cls: str | None = None) -> DataSettings:
    """Resolve and check the data settings (root, detectors, class, sequences) before any work.

    ``cls``: which of the sweep's classes (default: the first; :func:`resolve_data_all` gives all)."""
    spec = as_spec(spec)
    if cls is not None:
        if cls not in spec.classes:
            raise ValueError(f"class {cls!r} is not one of the sweep's classes {list(spec.classes)}")
        spec = replace(spec, cls=cls)
    src = spec.source
    root = Path(data_root if data_root is not None else (spec.data_root or default_data_root())).expanduser()
    if not (root / "label_02").is_dir():
        raise config_error("data.root", f"{root} has no label_02/ (the KITTI tracking training root; set it in the "
                                f"sweep file, with --data, or with $DFRMOT_DATA)", src)
    root = root.resolve()
    try:
        scans = lidar_dir(spec.det3d)
    except ValueError as e:
        raise config_error("data.det3d", str(e), src) from None
    simulated = spec.lidar is not None and spec.lidar.simulate
    if scans is not None and not simulated and not scans.is_dir():
        raise config_error("data.det3d", f"LiDAR scan folder {scans} not found (lidar:DIR expects "
                                         f"DIR/velodyne/SSSS/FFFFFF.bin; with [simulate] DIR is a cache folder)", src)
    reads = family_config(spec.family).detections       # (the detections its tracker family reads)
    det2d = spec.det2d if "2d" in reads or scans is not None else None      # (lifted boxes are of the 2D ones)
    for key, det in ((("data.det2d", spec.det2d),) if det2d is not None else ()) + \
            ((("data.det3d", spec.det3d),) if scans is None and "3d" in reads else ()):
        try:
            detection_dir(root, det, spec.cls)
        except KittiFormatError as e:
            raise config_error(key, e.message, src) from None
    if spec.sequences is None:
        seqs = tuple(sequences_with_class(root, spec.cls))
        if not seqs:
            raise config_error("data.sequences", f"no sequence under {root / 'label_02'} has class {spec.cls}", src)
    else:
        missing = [s for s in spec.sequences if not (root / "label_02" / f"{s}.txt").is_file()]
        if missing:
            raise config_error("data.sequences", f"no ground truth for {missing} under {root / 'label_02'}", src)
        seqs = spec.sequences
    lengths = sequence_lengths(root, list(seqs))
    det3d = str(spec.det3d) if "3d" in reads or scans is not None else None        # (a camera-only family: none)
    return DataSettings(str(root), det2d if det2d is None else str(det2d), det3d, spec.cls, tuple(seqs),
                        tuple(int(lengths[s]) for s in seqs))



@dataclass(frozen=True)
class Chunk:
    id: str
    group: int
    options: tuple             # the tracker family's ``Options``
    configs: tuple[int, ...]
    cls: str = "car"
    lidar: tuple | None = None      # the split key of its split (DataSettings.lidar: a LiDAR setting)

    def of(self, data: "DataSettings") -> bool:
        """Whether this chunk runs on ``data``'s split."""
        return self.cls == data.cls and self.lidar == data.lidar


def option_groups(table: pd.DataFrame, family: str = DEFAULT_FAMILY) -> dict[tuple, list[int]]:
    """Config rows by static options (the tracker ``family``'s ``Options``), in first-appearance order."""
    options = family_config(family).Options
    names = options._fields
    types = {n: type(options._field_defaults[n]) for n in names}
    groups: dict[tuple, list[int]] = {}
    for row in table[["config"] + list(names)].to_dict("records"):
        groups.setdefault(options(**{n: types[n](row[n]) for n in names}), []).append(int(row["config"]))
    return groups


def plan(table: pd.DataFrame, data: DataSettings | Sequence[DataSettings], chunk: int,
         axes: AxisKind | Sequence[AxisKind] | None = None, ab3dmot: str | None = None,
         family: str = DEFAULT_FAMILY) -> list[Chunk]:
    """Group the configs by static options (first appearance order; the tracker ``family``'s
    ``Options``), cut each group into chunks.

    ``axes``: the sweep's axis kinds (``SweepSpec.axes``; one kind, e.g. a ``DistortionAxes``, or
    None). A chunk's id hashes the data settings (its class's), its config hashes, what each axis
    kind adds (``AxisKind.chunk_identity``: the distortion settings) and, when the chunks also carry
    AB3DMOT's figures, their setting ``ab3dmot`` (``SweepSpec.metrics_identity``: ``"3d:0.25"``).
    ``data``: one class's settings or, for a sweep over several classes, every class's
    (:func:`resolve_data_all`): the chunks of each class in turn, every config in every class; a
    split of an axis kind's key (``data.lidar``) gets the configs of that key only."""
    axes = () if axes is None else (axes,) if not isinstance(axes, Sequence) else tuple(axes)
    if not isinstance(data, DataSettings):
        return [c for d in data for c in plan(table, d, chunk, axes, ab3dmot, family)]
    if data.lidar is not None or split_keys(axes):      # the configs of this split's key only
        keys = [split_key(axes, r) for r in table.to_dict("records")]
        if data.lidar is not None and all(k is None for k in keys):
            raise ValueError(f"a split of key {data.lidar} but no axis kind gives the configs keys: pass the "
                             f"sweep's axis kinds (plan(..., spec.axes))")
        groups = option_groups(table[[k == data.lidar for k in keys]], family)
    else:
        groups = option_groups(table, family)
    hashes = table["config_hash"].to_numpy()
    ident = data.identity()
    out = []
    for g, (opts, idx) in enumerate(groups.items()):
        for a in range(0, len(idx), chunk):
            part = tuple(idx[a:a + chunk])
            doc = {"data": ident, "configs": [hashes[i] for i in part]}
            for kind in axes:
                doc.update(kind.chunk_identity())
            if ab3dmot is not None:
                doc["ab3dmot"] = ab3dmot
            text = json.dumps(doc, sort_keys=True)
            out.append(Chunk(hashlib.sha1(text.encode()).hexdigest()[:20], g, opts, part, data.cls, data.lidar))
    return out


def check_memory(chunks: Sequence[Chunk], datas: Sequence[DataSettings], distortion: DistortionAxes | None,
                 max_memory: float | None = None, source: str | None = None, family: str = DEFAULT_FAMILY) -> int:
    """The largest tracker output of one chunk, bytes: configs x frames x track slots x bytes per slot
    (the tracker ``family``'s ``output_slots``; DFR-FastMOT: 4 bytes of ids, + 16 of boxes when each
    lane has its own: output "filtered" or a distortion). Capacity 0 (from the data) counts the fewest
    slots it can give (``config.MIN_CAPACITY``): a lower bound. Above ``max_memory`` GB (default
    :data:`MAX_MEMORY_GB`) raises :class:`SweepConfigError` ("chunk")."""
    frames = {d.cls: int(sum(d.lengths)) for d in datas}
    output_slots = family_of(family).output_slots

    def need(c: Chunk) -> tuple[int, int, int, bool]:
        k, slot, fixed = output_slots(c.options, distortion is not None)
        return len(c.configs) * frames[c.cls] * k * slot, k, slot, fixed

    if not chunks:
        return 0
    worst = max(chunks, key=need)
    n, k, slot, fixed = need(worst)
    limit = MAX_MEMORY_GB if max_memory is None else float(max_memory)
    if n > limit * 1e9:
        slots = f"{k} track slots" + (" (options.capacity)" if fixed else
                                      " (at least: options.capacity 0 sizes them from the data)")
        raise config_error("chunk", f"a chunk of {len(worst.configs):,} configs x {frames[worst.cls]:,} frames ({worst.cls}) x "
                            f"{slots} x {slot} bytes = {n / 1e9:.3g} GB of tracker output, above the limit of "
                            f"{limit:g} GB: lower chunk (--chunk N){' or options.capacity' if fixed else ''}"
                            f", or raise the limit with --max-memory GB (run_sweep(max_memory=GB))", source)
    return n
