"""One sequence's parsed detection files, as the KITTI readers return them (no packing, no tracker)."""

from __future__ import annotations

from typing import NamedTuple

from .kitti import Calib, Detections2D, Detections3D


class SequenceDets(NamedTuple):
    """One sequence's raw detections as read from its files (rows in file order). fused3d: the 3D
    rows were lifted from the 2D ones (``det3d="lidar:DIR"``): each one's image box is its 2D
    detection's, also as ``Split.proj3d``."""

    name: str
    n_frames: int
    det2d: Detections2D
    det3d: Detections3D
    calib: Calib
    fused3d: bool = False
