"""Simulated scans kept in a cache folder, one subfolder per simulation setting: what a sweep with a
``[simulate]`` table lifts from (:func:`simulate_cached`).

``OUT/simulated/<name>/velodyne/SSSS/FFFFFF.bin`` with ``<name>`` = the beam count and a hash of the
settings and seed (``b32-1f0c...``). A sequence is simulated once: its scans are written
(atomically, one file each), then a marker ``OUT/simulated/<name>/done/SSSS.json`` holding the
settings, the seed, the frame count and the size and mtime of the labels and calibration it was
made from; a sequence whose marker is missing or differs (labels changed) is simulated again. Two
processes simulating the same sequence at once write the same bytes (the simulation is
deterministic per sequence, frame and seed), so no lock is needed.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from ..io.atomic import write_text_atomic
from ..io.kitti import file_stamps, read_calib, read_tracking_labels
from .simulate import SimSettings, simulate_to_folder

__all__ = ["simulated_name", "simulate_cached"]


def simulated_name(settings: SimSettings, seed: int = 0) -> str:
    """The cache subfolder of one simulation setting: ``b<beams>-<12 hex digits>``."""
    s = settings.validate()
    doc = json.dumps({"settings": [float(v) for v in s], "seed": int(seed)}, sort_keys=True)
    return f"b{int(s.beams)}-{hashlib.sha1(doc.encode()).hexdigest()[:12]}"


def simulate_cached(out, root, sequences, lengths, settings: SimSettings = SimSettings(), seed: int = 0) -> Path:
    """The folder holding simulated scans of ``sequences`` (``lengths``: their frame counts) of the
    KITTI root ``root`` for one setting, simulated into ``out/simulated/<name>/`` where missing or
    stale; returns that folder (a ``lidar:DIR`` folder)."""
    s = settings.validate()
    folder = Path(out) / "simulated" / simulated_name(s, seed)
    root = Path(root)
    for seq, n in zip(sequences, lengths):
        label, calib = root / "label_02" / f"{seq}.txt", root / "calib" / f"{seq}.txt"
        marker = folder / "done" / f"{seq}.json"
        want = json.dumps({"settings": s._asdict(), "seed": int(seed), "frames": int(n),
                           "stamps": [list(x) if x else None for x in file_stamps([label, calib])]}, sort_keys=True)
        try:
            if marker.read_text(encoding="utf-8") == want:
                continue
        except OSError:
            pass
        simulate_to_folder(folder, read_tracking_labels(label), read_calib(calib), int(n), str(seq), s, int(seed))
        write_text_atomic(marker, want)
    return folder
