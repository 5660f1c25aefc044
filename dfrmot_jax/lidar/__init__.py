"""LiDAR: KITTI velodyne scans (``scans``), simulated scans (``simulate``), the authors' lifting of
2D detections to 3D boxes by point-cloud projection (``lift``) and the lifted boxes as a 3D
detection source, ``det3d="lidar:DIR"`` (``source``); the lifting's first stage reads a sequence's
scans one at a time (``prepare``). The settings of the lifting and the simulation are
:mod:`dfrmot_jax.lidar_settings`' (exported here too)."""

from dfrmot_jax.lidar.lift import Lifted, Prepared, lift_prepared
from dfrmot_jax.lidar.prepare import lift_frames, prepare_points
from dfrmot_jax.lidar.scans import check_frames, read_scan, scan_path, write_scan
from dfrmot_jax.lidar.sim_cache import simulate_cached, simulated_name
from dfrmot_jax.lidar.simulate import SIM_VERSION, simulate_sequence, simulate_to_folder
from dfrmot_jax.lidar.source import (LIDAR_PREFIX, clear_cache, inputs_digest, lidar_dir, lift_sequence, tie_scores,
                                     to_detections3d, write_detections3d)
from dfrmot_jax.lidar_settings import LIFT_SETTINGS, LiftSettings, SimSettings, lift_setting_name, with_setting

__all__ = [
    "LIFT_SETTINGS", "LIDAR_PREFIX", "Lifted", "LiftSettings", "Prepared", "SIM_VERSION", "SimSettings",
    "check_frames", "clear_cache", "inputs_digest", "lidar_dir", "lift_frames", "lift_prepared", "lift_sequence",
    "lift_setting_name", "prepare_points", "read_scan", "scan_path", "simulate_cached", "simulate_sequence",
    "simulate_to_folder", "simulated_name", "tie_scores", "to_detections3d", "with_setting", "write_detections3d",
    "write_scan",
]
