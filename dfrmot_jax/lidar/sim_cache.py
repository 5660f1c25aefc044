"""Simulated scans kept in a cache folder, one subfolder per simulation setting: what a sweep with a
``[simulate]`` table lifts from (:func:`simulate_cached`).

``OUT/simulated/<name>/velodyne/SSSS/FFFFFF.bin`` with ``<name>`` = the beam count and a hash of the
settings and seed (``b32-1f0c...``). A sequence is simulated once: its scans are written
(atomically, one file each), then a marker ``OUT/simulated/<name>/done/SSSS.json``. The marker is
the cache's key, and names everything the scans depend on: the simulator's version
(:data:`~dfrmot_jax.lidar.simulate.SIM_VERSION`), the settings, the seed, the sequence, the frame
count and a SHA-256 digest of the bytes of the label and calibration files they were made from. A
sequence whose marker is missing or differs (labels or calibration changed, another simulator
version, a marker written before versions existed) is simulated again in the same folder, its old
scans overwritten. Two processes simulating the same sequence at once write the same bytes (the
simulation is deterministic per sequence, frame and seed), so no lock is needed.

Scans changed or removed by hand after their marker was written are not noticed here (a removed
one is, when lifting: a located error naming the frame).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from ..io.atomic import write_text_atomic
from ..io.kitti import read_calib, read_tracking_labels
from ..lidar_settings import SimSettings
from .simulate import SIM_VERSION, simulate_to_folder

__all__ = ["simulated_name", "simulate_cached", "marker_text"]


def simulated_name(settings: SimSettings, seed: int = 0) -> str:
    """The cache subfolder of one simulation setting: ``b<beams>-<12 hex digits>``."""
    s = settings.validate()
    doc = json.dumps({"settings": [float(v) for v in s], "seed": int(seed)}, sort_keys=True)
    return f"b{int(s.beams)}-{hashlib.sha1(doc.encode()).hexdigest()[:12]}"


def _file_digest(path: Path) -> str | None:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


def marker_text(root, sequence: str, n_frames: int, settings: SimSettings, seed: int = 0) -> str:
    """The marker (JSON text) of one sequence's scans simulated now: the simulator's version, the
    settings, the seed, the sequence, the frame count and the digests of ``root``'s label and
    calibration files of the sequence (None for a missing one)."""
    root = Path(root)
    values = {k: float(v) for k, v in settings.validate()._asdict().items()}
    return json.dumps({"version": SIM_VERSION, "settings": values, "seed": int(seed),
                       "sequence": str(sequence), "frames": int(n_frames),
                       "label_sha256": _file_digest(root / "label_02" / f"{sequence}.txt"),
                       "calib_sha256": _file_digest(root / "calib" / f"{sequence}.txt")}, sort_keys=True)


def simulate_cached(out, root, sequences, lengths, settings: SimSettings = SimSettings(), seed: int = 0) -> Path:
    """The folder holding simulated scans of ``sequences`` (``lengths``: their frame counts) of the
    KITTI root ``root`` for one setting, simulated into ``out/simulated/<name>/`` where missing or
    stale (the module docstring); returns that folder (a ``lidar:DIR`` folder)."""
    s = settings.validate()
    folder = Path(out) / "simulated" / simulated_name(s, seed)
    root = Path(root)
    for seq, n in zip(sequences, lengths):
        marker = folder / "done" / f"{seq}.json"
        want = marker_text(root, str(seq), int(n), s, seed)
        try:
            if marker.read_text(encoding="utf-8") == want:
                continue
        except OSError:
            pass
        simulate_to_folder(folder, read_tracking_labels(root / "label_02" / f"{seq}.txt"),
                           read_calib(root / "calib" / f"{seq}.txt"), int(n), str(seq), s, int(seed))
        write_text_atomic(marker, want)
    return folder
