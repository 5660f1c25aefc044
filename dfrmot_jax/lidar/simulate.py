"""Simulated LiDAR scans: a ray-cast of a spinning multi-beam LiDAR against the labelled 3D boxes.

KITTI's scans are not on these machines, so the lifting is studied on scans made from the ground
truth: an HDL-64E-like sensor (``beams`` lasers evenly spaced in elevation from +2 deg to -24.9 deg,
azimuth step 0.09 deg, mounted ``height`` = 1.73 m above a flat ground plane at the origin of the
LiDAR frame: x forward, y left, z up) against every labelled 3D box of the frame (``label_02``:
cars, vans, pedestrians, cyclists, ...; ``DontCare`` rows have no box). Boxes are placed in the
LiDAR frame through the calibration (``(R_rect . Tr_velo_cam)^-1``). Each ray returns its first
hit (a box face or the ground) within ``max_range``, with Gaussian range noise; a return is lost
with probability ``dropout``; with probability ``clutter`` a ray instead returns from a rain drop at
a uniform range in [1, ``clutter_range``] m when that is nearer than its hit. By default only the
camera's view (azimuth within ``fov`` = +-45 deg of forward) is cast: the lifting projects into
image 02 and keeps nothing outside it (``fov=180`` casts a whole turn).

Deterministic per (sequence, frame, seed): each frame draws from its own
``numpy.random.default_rng([seed, sequence, frame])``. Vectorised: per frame, each box is tested
only against the rays of its angular window (a bounding-sphere window of beams x azimuths, built
with ``numpy.repeat``), slab tests for all those rays at once, the nearest hit per ray by
``numpy.minimum.at``; no Python loop over rays or points.

Points are ``[N, 4]`` float32 ``x y z reflectance`` in beam-major order (reflectance 0.5 on boxes,
0.2 on the ground, 0.05 for clutter).

:data:`SIM_VERSION` names the simulator's output: bump it with any change that gives other scans
for the same settings, seed, labels and calibration (the scan cache, :mod:`.sim_cache`, then
simulates again what an older version made).
"""

from __future__ import annotations

import zlib
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..geometry import box3d_corners
from ..io.kitti import Calib, TrackingLabels
from ..lidar_settings import SimSettings
from .scans import scan_path, write_scan

__all__ = ["SIM_VERSION", "Sensor", "sensor", "velo_boxes", "cast_frame", "frame_rng",
           "simulate_sequence", "simulate_to_folder"]

#: the simulator's version: bumped whenever its scans change for the same inputs (module docstring)
SIM_VERSION = 1


class Sensor(NamedTuple):
    """The rays of a setting: elevation [B] and azimuth [A] (radians, elevation descending), unit
    directions dirs [B, A, 3], and each beam's ground range ground [B] (inf when it never reaches);
    flat32 [B * A, 3] and ground32 [B * A]: the same per ray, float32."""

    elevation: np.ndarray
    azimuth: np.ndarray
    dirs: np.ndarray
    ground: np.ndarray
    flat32: np.ndarray
    ground32: np.ndarray


def sensor(settings: SimSettings) -> Sensor:
    s = settings.validate()
    el = np.radians(np.linspace(s.top, s.bottom, s.beams)) if s.beams > 1 else np.radians([s.bottom])
    n_half = int(np.floor(s.fov / s.az_step + 1e-9))
    az = np.radians(np.arange(-n_half, n_half + 1) * s.az_step)
    if s.fov >= 180:
        az = np.radians(np.arange(int(round(360 / s.az_step))) * s.az_step - 180.0)
    ce, se = np.cos(el)[:, None], np.sin(el)[:, None]
    dirs = np.stack(np.broadcast_arrays(ce * np.cos(az)[None], ce * np.sin(az)[None], se), axis=-1)
    with np.errstate(divide="ignore"):
        ground = np.where(np.sin(el) < 0, s.height / -np.sin(el), np.inf)
    return Sensor(el, az, dirs, ground, dirs.reshape(-1, 3).astype(np.float32),
                  np.repeat(ground, az.size).astype(np.float32))


def velo_boxes(labels: TrackingLabels, calib: Calib):
    """Per label row with a box (not DontCare, positive sizes): (frame [K], centre [K, 3], axes [K, 3, 3]
    rows = unit length / height / width axes, half [K, 3] half extents), in the LiDAR frame."""
    ok = (np.char.lower(labels.type.astype(str)) != "dontcare") & np.all(labels.dims > 0, axis=1)
    corners = box3d_corners(labels.dims[ok], labels.loc[ok], labels.rot_y[ok])         # [K, 8, 3] rect cam
    R = np.eye(4)
    R[:3, :3] = calib.R0_rect
    T = np.eye(4)
    T[:3, :] = calib.Tr_velo_to_cam
    inv = np.linalg.inv(R @ T)
    cv = corners @ inv[:3, :3].T + inv[:3, 3]                                         # [K, 8, 3] LiDAR
    vec = np.stack([cv[:, 0] - cv[:, 3], cv[:, 4] - cv[:, 0], cv[:, 0] - cv[:, 1]], axis=1)   # l, h, w edges
    size = np.linalg.norm(vec, axis=2)
    return labels.frame[ok], cv.mean(axis=1), vec / size[..., None], size / 2.0


def _windows(centre, axes, half, sens: Sensor):
    """Per box the candidate beam range [b0, b1) and azimuth range [a0, a1) (conservative).

    Azimuth: the corners' range (exact for a convex box clear of the z axis). Elevation: the top
    and bottom corner heights over the nearest and farthest horizontal distance of the box's
    bounding circle, which bounds every point of the box.
    """
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)   # [8, 3]
    corners = centre[:, None, :] + np.einsum("ci,kij->kcj", signs, axes * half[:, :, None])         # [K, 8, 3]
    rad_xy = np.linalg.norm(half, axis=1) * 1.0001 + 1e-6
    dxy = np.hypot(centre[:, 0], centre[:, 1])
    clear = dxy > rad_xy                                                    # the z axis misses the box
    r_min = np.where(clear, dxy - rad_xy, 1e-9)
    r_max = dxy + rad_xy
    z_hi, z_lo = corners[..., 2].max(axis=1), corners[..., 2].min(axis=1)
    el_hi = np.arctan2(z_hi, np.where(z_hi > 0, r_min, r_max)) + 1e-9
    el_lo = np.arctan2(z_lo, np.where(z_lo < 0, r_min, r_max)) - 1e-9
    el = sens.elevation                                                     # descending
    b0 = np.searchsorted(-el, -el_hi, side="left")
    b1 = np.searchsorted(-el, -el_lo, side="right")
    az_c = np.arctan2(centre[:, 1], centre[:, 0])
    rel = (np.arctan2(corners[..., 1], corners[..., 0]) - az_c[:, None] + np.pi) % (2 * np.pi) - np.pi
    lo, hi = az_c + rel.min(axis=1) - 1e-9, az_c + rel.max(axis=1) + 1e-9
    az = sens.azimuth
    a0 = np.searchsorted(az, lo, side="left")
    a1 = np.searchsorted(az, hi, side="right")
    wide = ~clear | (lo < -np.pi) | (hi > np.pi)
    a0 = np.where(wide, 0, a0)
    a1 = np.where(wide, az.size, a1)
    return b0, b1, a0, a1


def _cast_boxes(centre, axes, half, sens: Sensor) -> np.ndarray:
    """[B * A] nearest box hit range per ray (inf: none)."""
    n_b, n_a = sens.dirs.shape[:2]
    t_ray = np.full(n_b * n_a, np.inf)
    if not centre.shape[0]:
        return t_ray
    b0, b1, a0, a1 = _windows(centre, axes, half, sens)
    nb, na = np.maximum(b1 - b0, 0), np.maximum(a1 - a0, 0)
    count = nb * na
    total = int(count.sum())
    if not total:
        return t_ray
    box = np.repeat(np.arange(centre.shape[0]), count)
    k = np.arange(total) - np.repeat(np.cumsum(count) - count, count)      # index within the box's window
    na_r = np.repeat(na, count)
    ray = (np.repeat(b0, count) + k // na_r) * n_a + np.repeat(a0, count) + k % na_r
    d = sens.dirs.reshape(-1, 3)[ray]                                       # [C, 3]
    ax = axes[box]                                                          # [C, 3, 3]
    o = np.einsum("kij,kj->ki", axes, -centre)[box]                         # the sensor in box frames
    v = np.einsum("cij,cj->ci", ax, d)
    v = np.where(v == 0, 1e-300, v)
    h = half[box]
    t1 = (-h - o) / v
    t2 = (h - o) / v
    t_in = np.minimum(t1, t2).max(axis=1)
    t_out = np.maximum(t1, t2).min(axis=1)
    hit = (t_in <= t_out) & (t_in > 0)
    np.minimum.at(t_ray, ray[hit], t_in[hit])
    return t_ray


def cast_frame(centre, axes, half, sens: Sensor, settings: SimSettings, rng: np.random.Generator) -> np.ndarray:
    """One frame's scan ``[N, 4]`` float32 from its boxes (LiDAR frame, :func:`velo_boxes`)."""
    t_box = _cast_boxes(centre, axes, half, sens).astype(np.float32)
    on_box = t_box <= sens.ground32
    t = np.minimum(t_box, sens.ground32)
    refl = np.where(on_box, np.float32(0.5), np.float32(0.2))
    if settings.clutter > 0:
        drop = rng.random(t.size, dtype=np.float32) < settings.clutter
        r = np.float32(1.0) + rng.random(t.size, dtype=np.float32) * np.float32(max(0.0, settings.clutter_range - 1))
        rain = drop & (r < t)
        t = np.where(rain, r, t)
        refl = np.where(rain, np.float32(0.05), refl)
    if settings.range_noise > 0:
        t = t + rng.standard_normal(t.size, dtype=np.float32) * np.float32(settings.range_noise)
    keep = (t <= np.float32(settings.max_range)) & (t > 0)                  # inf (no hit) fails the first
    if settings.dropout > 0:
        keep &= rng.random(t.size, dtype=np.float32) >= settings.dropout
    idx = np.flatnonzero(keep)
    pts = np.empty((idx.size, 4), np.float32)
    pts[:, :3] = sens.flat32[idx] * t[idx, None]
    pts[:, 3] = refl[idx]
    return pts


def frame_rng(seed: int, sequence: str, frame: int) -> np.random.Generator:
    """The generator of one (seed, sequence, frame): ``default_rng([seed, sequence number, frame])``
    (a sequence name that is not a number enters as its CRC-32)."""
    seq = int(sequence) if str(sequence).isdigit() else zlib.crc32(str(sequence).encode())
    return np.random.default_rng([int(seed), seq, int(frame)])


def simulate_sequence(labels: TrackingLabels, calib: Calib, n_frames: int, sequence: str,
                      settings: SimSettings = SimSettings(), seed: int = 0, frames=None):
    """Yield ``(frame, points [N, 4] float32)`` for frames ``0 .. n_frames - 1`` (or ``frames``) of one
    sequence from its labels and calibration."""
    s = settings.validate()
    sens = sensor(s)
    frame, centre, axes, half = velo_boxes(labels, calib)
    order = np.argsort(frame, kind="stable")
    frame, centre, axes, half = frame[order], centre[order], axes[order], half[order]
    wanted = range(n_frames) if frames is None else frames
    for f in wanted:
        a, b = np.searchsorted(frame, [f, f + 1])
        rng = frame_rng(seed, sequence, f)
        yield int(f), cast_frame(centre[a:b], axes[a:b], half[a:b], sens, s, rng)


def simulate_to_folder(out, labels: TrackingLabels, calib: Calib, n_frames: int, sequence: str,
                       settings: SimSettings = SimSettings(), seed: int = 0) -> int:
    """Write a sequence's simulated scans as ``OUT/velodyne/SSSS/FFFFFF.bin``; returns the points written."""
    total = 0
    for f, pts in simulate_sequence(labels, calib, n_frames, sequence, settings, seed):
        write_scan(scan_path(Path(out), sequence, f), pts)
        total += pts.shape[0]
    return total
