"""The LiDAR source's settings, apart from the code that uses them: :class:`LiftSettings` (the
lifting of 2D detections to 3D boxes, :mod:`dfrmot_jax.lidar.lift`; ``--set NAME=VALUE`` and the
sweep axes ``lift.NAME``: :func:`lift_setting_name`, :func:`with_setting`) and :class:`SimSettings`
(the simulated sensor, :mod:`dfrmot_jax.lidar.simulate`).

A module of the package root that imports nothing of the package (NumPy only; the ``lidar`` package
reaches the tracker's box rules, ``core.boxes``): a sweep's stored tables name their LiDAR columns
from these settings (:mod:`dfrmot_jax.table_columns`), and the report reads them without JAX.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["LiftSettings", "LIFT_SETTINGS", "lift_setting_name", "with_setting", "SimSettings"]


class LiftSettings(NamedTuple):
    """The lifting's settings (defaults: the authors' constants; ``shrink`` from their ``main.cpp``,
    ``SHRINK_FACTOR = 0.2``, "shrink 10 % of the bounding box" on each side).

    shrink:      fraction of a 2D box's width and height removed (half on each side), in [0, 1).
    leaf:        voxel grid cell size (m).
    crop_lo, crop_hi:  the crop box in LiDAR coordinates (x, y, z), both bounds inclusive (m).
    tolerance:   Euclidean cluster tolerance (m): neighbours when closer than this (strictly).
    min_cluster: the fewest points a cluster may have.
    score_cut:   2D detections with a score below this are dropped before lifting (``util.cpp``).
    """

    shrink: float = 0.2
    leaf: float = 0.2
    crop_lo: tuple = (0.5, -20.0, -1.2)
    crop_hi: tuple = (180.0, 20.0, 0.5)
    tolerance: float = 0.5
    min_cluster: int = 5
    score_cut: float = 0.45

    def validate(self) -> "LiftSettings":
        """The settings as plain floats / ints, or ValueError naming the bad one (a NaN or infinite
        value included: each number must be finite, ``min_cluster`` a whole number in [1, 1000000])."""
        s = self._replace(shrink=float(self.shrink), leaf=float(self.leaf), tolerance=float(self.tolerance),
                          score_cut=float(self.score_cut), crop_lo=tuple(float(v) for v in self.crop_lo),
                          crop_hi=tuple(float(v) for v in self.crop_hi))
        if not 0.0 <= s.shrink < 1.0:
            raise ValueError(f"lift shrink {s.shrink}: expected a number in [0, 1)")
        if not 0.01 <= s.leaf <= 10.0:
            raise ValueError(f"lift leaf {s.leaf}: expected a cell size in [0.01, 10] m")
        if not 0.0 < s.tolerance <= 10.0:
            raise ValueError(f"lift tolerance {s.tolerance}: expected a distance in (0, 10] m")
        if not _whole(self.min_cluster) or not 1 <= int(float(self.min_cluster)) <= 1_000_000:
            raise ValueError(f"lift min_cluster {self.min_cluster}: expected an integer in [1, 1000000]")
        if len(s.crop_lo) != 3 or len(s.crop_hi) != 3 or not all(np.isfinite(s.crop_lo + s.crop_hi)):
            raise ValueError(f"lift crop {s.crop_lo} .. {s.crop_hi}: expected three finite numbers each")
        if any(a > b for a, b in zip(s.crop_lo, s.crop_hi)):
            raise ValueError(f"lift crop {s.crop_lo} .. {s.crop_hi}: a lower bound above its upper bound")
        if not np.isfinite(s.score_cut):
            raise ValueError(f"lift score_cut {s.score_cut}: expected a finite number")
        return s._replace(min_cluster=int(float(self.min_cluster)))


def _whole(v) -> bool:
    """A finite whole number (an int, or a float such as 5.0; not a boolean, inf or NaN)."""
    if isinstance(v, (bool, np.bool_)):
        return False
    try:
        return bool(np.isfinite(float(v))) and float(v) == int(v)
    except (TypeError, ValueError, OverflowError):
        return False


#: the settings' names, as ``--set NAME=VALUE`` and sweep axes (``lift.NAME``) spell them
LIFT_SETTINGS = LiftSettings._fields


def lift_setting_name(name: str) -> str | None:
    """``"shrink"`` or ``"lift.shrink"`` -> ``"shrink"``; None for a name that is no lifting setting."""
    name = name.strip()
    name = name[len("lift."):] if name.startswith("lift.") else name
    return name if name in LIFT_SETTINGS else None


def with_setting(settings: LiftSettings, name: str, raw) -> LiftSettings:
    """``settings`` with one setting from text or a number (``crop_lo`` / ``crop_hi``: three numbers,
    comma-separated), validated; ValueError naming the setting."""
    key = lift_setting_name(name)
    if key is None:
        raise ValueError(f"lift setting {name!r}: unknown; the settings are {list(LIFT_SETTINGS)}")
    try:
        if key in ("crop_lo", "crop_hi"):
            parts = raw.split(",") if isinstance(raw, str) else list(raw)
            value = tuple(float(v) for v in parts)
        elif key == "min_cluster":
            value = float(raw)                # a fraction, inf or nan: validate() names the setting and its range
            value = int(value) if _whole(value) else value
        else:
            value = float(raw)
    except (TypeError, ValueError):
        raise ValueError(f"lift setting {key}: {raw!r} is not a valid value") from None
    return settings._replace(**{key: value}).validate()


class SimSettings(NamedTuple):
    """Settings of the simulated sensor.

    beams:         lasers, evenly spaced in elevation from ``top`` to ``bottom`` (degrees).
    az_step:       azimuth step (degrees).
    fov:           half-width of the azimuth range cast, degrees from forward (180: a whole turn).
    height:        sensor height above the ground plane (m).
    max_range:     farthest return (m).
    range_noise:   standard deviation of the range noise (m).
    dropout:       probability that a return is lost.
    clutter:       probability that a ray returns from a rain drop (when nearer than its hit).
    clutter_range: rain drops lie at a uniform range in [1, clutter_range] m.
    """

    beams: int = 64
    az_step: float = 0.09
    fov: float = 45.0
    height: float = 1.73
    max_range: float = 120.0
    range_noise: float = 0.02
    dropout: float = 0.0
    clutter: float = 0.0
    clutter_range: float = 30.0
    top: float = 2.0
    bottom: float = -24.9

    def validate(self) -> "SimSettings":
        beams = float(self.beams)             # (inf / nan first: int() of inf raises OverflowError)
        if isinstance(self.beams, bool) or not np.isfinite(beams) or not beams.is_integer() or not 1 <= beams <= 512:
            raise ValueError(f"simulate beams {self.beams}: expected an integer in [1, 512]")
        if not 0.005 <= float(self.az_step) <= 10:
            raise ValueError(f"simulate az_step {self.az_step}: expected degrees in [0.005, 10]")
        if not 0 < float(self.fov) <= 180:
            raise ValueError(f"simulate fov {self.fov}: expected degrees in (0, 180]")
        for name in ("range_noise", "height", "max_range", "clutter_range"):
            if not float(getattr(self, name)) >= 0 or not np.isfinite(float(getattr(self, name))):
                raise ValueError(f"simulate {name} {getattr(self, name)}: expected a finite number >= 0")
        for name in ("dropout", "clutter"):
            if not 0.0 <= float(getattr(self, name)) <= 1.0:
                raise ValueError(f"simulate {name} {getattr(self, name)}: expected a probability in [0, 1]")
        if not float(self.bottom) < float(self.top) or abs(float(self.bottom)) >= 90 or abs(float(self.top)) >= 90:
            raise ValueError(f"simulate elevations {self.top} .. {self.bottom}: expected -90 < bottom < top < 90")
        return self._replace(beams=int(beams))
