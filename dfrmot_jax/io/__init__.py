"""Input and output of KITTI tracking files."""

from dfrmot_jax.io.kitti import (
    Calib,
    Detections2D,
    Detections3D,
    KittiFormatError,
    TrackingLabels,
    read_calib,
    read_detections_2d,
    read_detections_3d,
    read_tracking_labels,
    sequence_lengths,
)
from dfrmot_jax.io.result_writer import write_tracking_results
from dfrmot_jax.io.sequence import SequenceDets

__all__ = [
    "Calib",
    "Detections2D",
    "Detections3D",
    "KittiFormatError",
    "SequenceDets",
    "TrackingLabels",
    "read_calib",
    "read_detections_2d",
    "read_detections_3d",
    "read_tracking_labels",
    "sequence_lengths",
    "write_tracking_results",
]
