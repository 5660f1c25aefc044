"""PointRCNN detection files (AB3DMOT's KITTI inputs) packed into padded ``Frames``.

A detection file holds one CSV row per detection, ``frame, type, x1, y1, x2, y2, score, h, w, l,
x, y, z, rot_y, alpha``, its rows in detection order within a frame. A sequence runs from frame 0
to the last frame of its ``label_02`` file; a sequence whose detection file is empty is skipped
(AB3DMOT writes no file for it and its id counter does not move).
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np

from ...io.kitti import sequence_lengths
from .tracker import Frames

__all__ = ["Split", "parse_detections", "pack", "read_split", "CATEGORY_FOLDERS",
           "TYPE_NAMES", "ALL_SEQUENCES"]

#: category -> detection folder under ``detections/pointrcnn``
CATEGORY_FOLDERS = {"car": "car", "pedestrian": "pedestrian", "cyclist": "cyclist"}
#: class code in the detection files -> the name AB3DMOT writes
TYPE_NAMES = {1: "Pedestrian", 2: "Car", 3: "Cyclist"}
ALL_SEQUENCES = tuple(f"{i:04d}" for i in range(21))


class Split(NamedTuple):
    """Sequences packed one after the other (host NumPy).

    frames:    ``Frames`` [T, N, ...] (``reset`` at each sequence's first frame).
    info:      [T, N, 7] float64 ``[alpha, type, x1, y1, x2, y2, score]`` of each detection.
    sequence:  [T] int32 index into ``names``; frame: [T] int32 frame number in its sequence.
    names:     the sequences' names, in order.
    dropped:   detections left out for want of a slot (N too small): none for AB3DMOT's result.
    """

    frames: Frames
    info: np.ndarray
    sequence: np.ndarray
    frame: np.ndarray
    names: tuple
    dropped: int


def parse_detections(text: str) -> dict[int, np.ndarray]:
    """{frame: rows [n, 15] float64} of a PointRCNN CSV, rows in file order; frames without rows
    are absent."""
    lines = [s for s in text.splitlines() if s.strip()]
    if not lines:
        return {}
    rows = np.array([s.split(",") for s in lines], dtype=np.float64)
    frames = rows[:, 0].astype(np.int64)
    return {int(f): rows[frames == f] for f in np.unique(frames)}


def pack(sequences: list[tuple[str, dict[int, np.ndarray], int]], capacity: int | None = None) -> Split:
    """Split of ``(name, {frame: rows [n, 15]}, n_frames)`` sequences (empty ones skipped), N =
    ``capacity`` or the most detections of a frame (at least 1)."""
    sequences = [s for s in sequences if s[1]]
    most = max([len(r) for _, d, _ in sequences for r in d.values()] or [1])
    n = capacity or most
    t_total = sum(s[2] for s in sequences)
    boxes, info = np.zeros((t_total, n, 7)), np.zeros((t_total, n, 7))
    valid, score = np.zeros((t_total, n), bool), np.zeros((t_total, n))
    reset, seq, frame = np.zeros(t_total, bool), np.zeros(t_total, np.int32), np.zeros(t_total, np.int32)
    t, dropped = 0, 0
    for s, (_, dets, n_frames) in enumerate(sequences):
        reset[t] = True
        seq[t:t + n_frames], frame[t:t + n_frames] = s, np.arange(n_frames)
        for f, rows in dets.items():
            if not 0 <= f < n_frames:
                raise ValueError(f"sequence {sequences[s][0]}: detections at frame {f}, outside 0..{n_frames - 1}")
            k = min(len(rows), n)
            dropped += len(rows) - k
            boxes[t + f, :k] = rows[:k, [10, 11, 12, 13, 9, 8, 7]]          # x y z rot_y l w h
            info[t + f, :k] = rows[:k][:, [14, 1, 2, 3, 4, 5, 6]]
            valid[t + f, :k] = True
            score[t + f, :k] = rows[:k, 6]
        t += n_frames
    return Split(Frames(boxes, valid, score, reset), info, seq, frame, tuple(s[0] for s in sequences), dropped)


def read_split(root, category: str = "car", sequences=ALL_SEQUENCES, capacity: int | None = None) -> Split:
    """The sequences of a KITTI tracking training root: detections from
    ``root/detections/pointrcnn/<category>/SSSS.txt``, frames from ``root/label_02/SSSS.txt``."""
    root = Path(root)
    folder = root / "detections" / "pointrcnn" / CATEGORY_FOLDERS[category.lower()]
    lengths = sequence_lengths(root, sequences)          # the last label frame + 1
    out = []
    for name in sequences:
        dets = parse_detections((folder / f"{name}.txt").read_text())
        out.append((name, dets, max(lengths[name], 1)))   # a label file without rows: one frame, as before
    return pack(out, capacity)
