"""ByteTrack's padded output as the reference runs' result lines (KITTI tracking columns)."""

from __future__ import annotations

import numpy as np

from .batch import RunOutput

__all__ = ["demo_keep", "lane_lines"]


def demo_keep(tlwh: np.ndarray) -> np.ndarray:
    """``tools/demo_track.py``'s writer filter: ``w * h > 10`` and not ``w / h > 1.6``."""
    w, h = tlwh[..., 2], tlwh[..., 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        return (w * h > 10) & ~(w / h > 1.6)


def lane_lines(out: RunOutput, lane: int, typ: str = "Car", demo_filter: bool = False,
               frame_offset: int = 0, frames: slice | None = None) -> list[str]:
    """The lines of one lane (frames ``frames`` of the run, numbered from 0 + ``frame_offset``):
    ``frame id Type 0 0 -10 x1 y1 x2 y2 -1 -1 -1 -1000 -1000 -1000 -10 score``, boxes from ``tlwh``
    (``x2 = x1 + w``), ``%.6f``; slots in slot order inside a frame."""
    sl = frames or slice(None)
    tid, tlwh, score, written = (np.asarray(a[lane, sl]) for a in (out.tid, out.tlwh, out.score, out.written))
    keep = written & demo_keep(tlwh) if demo_filter else written
    lines = []
    for t, k in zip(*np.nonzero(keep)):
        x1, y1, w, h = tlwh[t, k].tolist()
        lines.append(f"{t + frame_offset} {tid[t, k]} {typ} 0 0 -10 {x1:.6f} {y1:.6f} {x1 + w:.6f} "
                     f"{y1 + h:.6f} -1 -1 -1 -1000 -1000 -1000 -10 {score[t, k]:.6f}")
    return lines


def sequence_lines(out: RunOutput, lane: int, lengths: list[int], typ: str = "Car",
                   demo_filter: bool = False) -> list[list[str]]:
    """The lines of each sequence of a run packed from sequences of ``lengths`` frames
    (``batch.pack_frames``), frames numbered from 0 in each."""
    res, t0 = [], 0
    for n in lengths:
        res.append(lane_lines(out, lane, typ, demo_filter, 0, slice(t0, t0 + n)))
        t0 += n
    return res
