"""ByteTrack's settings (ifzhang/ByteTrack at d1bf019, ``BYTETracker`` and ``tools/demo_track.py``'s
arguments), without its tracker.

``Params`` are dynamic (float64 / int32 leaves; a batch of them shares one ``vmap`` and one
compilation), ``Options`` static (one program each). Each parameter's comment quotes ByteTrack's
own argparse help string.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["Params", "Options", "PRESETS", "bytetrack_car", "bytetrack_pedestrian", "stack_params",
           "max_time_lost"]


class Params(NamedTuple):
    """Dynamic settings (a batch: every leaf [B])."""
    #: "tracking confidence threshold" (``--track_thresh``, 0.5): high detections ``score >
    #: track_thresh``, low ones ``0.1 < score < track_thresh``
    track_thresh: float = 0.5
    #: "matching threshold for tracking" (``--match_thresh``, 0.8): the first association's cost limit
    match_thresh: float = 0.8
    #: "the frames for keep lost tracks" (``--track_buffer``, 30): a lost track is removed after
    #: ``int(frame_rate / 30.0 * track_buffer)`` frames without a match
    track_buffer: int = 30
    #: ``BYTETracker.det_thresh = track_thresh + 0.1``: a new track needs ``score >= track_thresh +
    #: det_thresh_margin`` (ByteTrack's constant 0.1, a parameter here)
    det_thresh_margin: float = 0.1


class Options(NamedTuple):
    """Static settings (one compilation each)."""
    #: ``not args.mot20`` ("test mot20." ``--mot20``, default False): the IoU cost fused with the
    #: detection score (``matching.fuse_score``) in the first and the unconfirmed associations
    fuse_score: bool = True
    #: ``BYTETracker(args, frame_rate)``, "frame rate (fps)" (``--fps``, 30 there; KITTI is 10)
    frame_rate: int = 10
    #: ``tools/demo_track.py``'s writer filter (``--min_box_area`` 10, ``--aspect_ratio_thresh``
    #: 1.6): a written box needs ``w * h > 10`` and not ``w / h > 1.6`` (not part of the tracker)
    demo_filter: bool = False


def bytetrack_car() -> tuple[Params, Options]:
    """ByteTrack's defaults at KITTI's 10 frames/s (the reference run ``car_default``)."""
    return Params(0.5, 0.8, 30, 0.1), Options(True, 10)


def bytetrack_pedestrian() -> tuple[Params, Options]:
    """ByteTrack's defaults at KITTI's 10 frames/s (the reference run ``pedestrian_default``)."""
    return Params(0.5, 0.8, 30, 0.1), Options(True, 10)


PRESETS = {"bytetrack_car": bytetrack_car, "bytetrack_pedestrian": bytetrack_pedestrian}


def stack_params(params: list[Params]) -> Params:
    """A batch [B] of Params (float64 thresholds, int32 buffers)."""
    return Params(np.array([p.track_thresh for p in params], np.float64),
                  np.array([p.match_thresh for p in params], np.float64),
                  np.array([p.track_buffer for p in params], np.int32),
                  np.array([p.det_thresh_margin for p in params], np.float64))


def max_time_lost(frame_rate: int, track_buffer) -> np.ndarray:
    """``int(frame_rate / 30.0 * track_buffer)`` (float64, truncated)."""
    return np.floor(frame_rate / 30.0 * np.asarray(track_buffer, np.float64)).astype(np.int64)
