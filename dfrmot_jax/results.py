"""From the tracker's padded output to rows and KITTI result files."""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np

from .data import CLASS_NAMES, Frames, Split, object_boxes
from .io.kitti import write_tracking_results
from .params import Options


class LaneRows(NamedTuple):
    """One lane's written lines for one sequence, in output order (frame, then slot).

    frame [R] int64 (within the sequence), track_id [R] int64, box [R, 4] float64,
    slot [R] int64 output slot (object slot with output "detections", track slot with "filtered").
    """

    frame: np.ndarray
    track_id: np.ndarray
    box: np.ndarray
    slot: np.ndarray


def output_boxes(frames: Frames, options: Options, boxes: np.ndarray | None = None) -> np.ndarray:
    """[T, K, 4] the written boxes: the objects' boxes (output "detections") or the lane's boxes."""
    if options.output == "detections":
        return object_boxes(frames, options)
    return boxes


def lane_rows(split: Split, s: int, ids: np.ndarray, boxes: np.ndarray) -> LaneRows:
    """Rows of sequence s from one lane: ids [T, K], boxes [T, K, 4] (whole split)."""
    sl = split.sequence_slice(s)
    ids_s = ids[sl]
    t, k = np.nonzero(ids_s >= 0)
    return LaneRows(t.astype(np.int64), ids_s[t, k].astype(np.int64), boxes[sl][t, k].astype(np.float64),
                    k.astype(np.int64))


def write_lane(out_dir, split: Split, frames: Frames, options: Options, ids: np.ndarray,
               boxes: np.ndarray | None = None) -> list[Path]:
    """Write one KITTI result file per sequence of the split for one lane (ids [T, K])."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    allboxes = output_boxes(frames, options, boxes)
    paths = []
    for s, name in enumerate(split.names):
        r = lane_rows(split, s, ids, allboxes)
        path = out_dir / f"{name}.txt"
        write_tracking_results(path, r.frame, r.track_id, r.box, type_name=CLASS_NAMES[split.cls])
        paths.append(path)
    return paths
