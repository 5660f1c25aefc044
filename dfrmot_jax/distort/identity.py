"""Host side: the ground-truth identity of every detection slot (reads ``label_02`` files).

Bursts occlude objects, not slots: :func:`gt_identity` gives each detection the track id of the
ground-truth box it overlaps most (2D IoU >= 0.5), :func:`pad_identity` pads the ids like the
clutter slots (``clutter.pad_for_clutter``). Ids restart per sequence.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..boxes import iou
from ..data import Split
from ..io.kitti import read_tracking_labels
from .clutter import pad_slots
from .spec import DistortSpec


def pad_identity(gid2: np.ndarray, gid3: np.ndarray, spec: DistortSpec) -> tuple[np.ndarray, np.ndarray]:
    """Host side: ``gid2 [T, M2]``, ``gid3 [T, M3]`` padded with -1 like ``clutter.pad_for_clutter``."""
    n = int(spec.clutter_slots)
    return (pad_slots(gid2, n, -1).astype(np.int32), pad_slots(gid3, n, -1).astype(np.int32))


def _match_ids(det_box: np.ndarray, det_valid: np.ndarray, gt_box: np.ndarray, gt_id: np.ndarray,
               min_iou: float) -> np.ndarray:
    out = np.full(det_box.shape[0], -1, np.int32)
    if gt_box.shape[0] == 0 or not det_valid.any():
        return out
    overlap = iou(np.asarray(det_box, np.float64)[:, None, :], np.asarray(gt_box, np.float64)[None, :, :])  # [M, G]
    best = np.argmax(overlap, axis=1)
    ok = det_valid & (overlap[np.arange(det_box.shape[0]), best] >= min_iou)
    out[ok] = gt_id[best[ok]]
    return out


def gt_identity(split: Split, root, box3: np.ndarray | None = None,
                min_iou: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Host side: the ground-truth track id of every detection slot.

    Returns ``gid2 [T, M2]`` and ``gid3 [T, M3]`` int32: the ``track_id`` (as in
    ``root/label_02/SSSS.txt``, every class except ``DontCare``) of the ground-truth box of the same
    frame with the highest 2D IoU with the detection's image box, when that IoU >= ``min_iou``;
    -1 otherwise (and for empty slots). 2D detections use their raw (untruncated) box; 3D
    detections ``box3`` [T, M3, 4], the image box the tracker gives each (default the detector's own,
    ``split.box3d``; DFR-FastMOT's with ``merge="calib_projection"`` or ``modality="3d"``: the calib
    projection, ``trackers.dfr.frames.image_box_3d``).
    Each detection takes its best ground truth independently (several detections may share one
    identity: an occluded object's duplicates vanish with it). Ids restart per sequence.
    """
    root = Path(root)
    box3 = split.box3d if box3 is None else box3
    gid2 = np.full(split.valid2d.shape, -1, np.int32)
    gid3 = np.full(split.valid3d.shape, -1, np.int32)
    for k, name in enumerate(split.names):
        labels = read_tracking_labels(root / "label_02" / f"{name}.txt")
        keep = labels.type != "DontCare"
        frame, tid, gbox = labels.frame[keep], labels.track_id[keep], labels.box[keep]
        o = int(split.offsets[k])
        for f in range(int(split.lengths[k])):
            sel = frame == f
            t = o + f
            gid2[t] = _match_ids(split.box2d[t], split.valid2d[t], gbox[sel], tid[sel], min_iou)
            gid3[t] = _match_ids(box3[t], split.valid3d[t], gbox[sel], tid[sel], min_iou)
    return gid2, gid3


