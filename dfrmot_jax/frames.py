"""The padded detection frames a camera + LiDAR tracker steps over: one record, shared by the families
that read both detections, the distortions of a study and the point-cloud path (NumPy only)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["Frames"]


class Frames(NamedTuple):
    """Per-frame device inputs of the tracker (float32 / bool), leading axis T.

    reset [T]; box2 [T, M2, 4] and box3 [T, M3, 4] (x1, y1, x2, y2; integer-valued when truncating;
    box3 is the 3D detection's image box chosen by ``Options.merge``); score2 [T, M2]; score3 [T, M3];
    valid2 [T, M2]; valid3 [T, M3]; lo3, hi3 [T, M3, 3]: the internal 3D box corners (``Options.centroid``).
    """

    reset: np.ndarray
    box2: np.ndarray
    score2: np.ndarray
    valid2: np.ndarray
    box3: np.ndarray
    score3: np.ndarray
    valid3: np.ndarray
    lo3: np.ndarray
    hi3: np.ndarray

