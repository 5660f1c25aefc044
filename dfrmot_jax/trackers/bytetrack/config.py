"""ByteTrack's settings (ifzhang/ByteTrack at d1bf019, ``BYTETracker`` and ``tools/demo_track.py``'s
arguments), without its tracker.

``Params`` are dynamic (float64 / int32 leaves; a batch of them shares one ``vmap`` and one
compilation), ``Options`` static (one program each). Each parameter's comment quotes ByteTrack's
own argparse help string.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..capacity import MAX_CAPACITY
from ..protocol import FamilyConfig, number_problem, parse_setting

__all__ = ["Params", "Options", "PRESETS", "bytetrack_car", "bytetrack_pedestrian", "stack_params",
           "max_time_lost", "bytetrack_car_tuned", "FAMILY_CONFIG", "preset", "param_problem", "option_problem", "parse_assignment",
           "as_arrays", "validate"]


class Params(NamedTuple):
    """Dynamic settings (a batch: every leaf [B]), with ByteTrack's own words for each.

    track_thresh:      "tracking confidence threshold" (--track_thresh): high detections score >
                       track_thresh, low ones 0.1 < score < track_thresh
    match_thresh:      "matching threshold for tracking" (--match_thresh): the first association's
                       cost limit
    track_buffer:      "the frames for keep lost tracks" (--track_buffer): a lost track is removed after
                       int(frame_rate / 30 * track_buffer) frames
    det_thresh_margin: det_thresh = track_thresh + 0.1 in its code: a new track needs score >=
                       track_thresh + det_thresh_margin
    """
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
    """Static settings (one compilation each), with ByteTrack's own words for each.

    fuse_score:  not --mot20 ("test mot20."): the IoU cost fused with the detection score in the first
                 and the unconfirmed associations
    frame_rate:  BYTETracker(args, frame_rate), --fps "frame rate (fps)" (KITTI: 10)
    demo_filter: tools/demo_track.py's writer filter (--min_box_area 10, --aspect_ratio_thresh 1.6): a
                 written box needs w * h > 10 and not w / h > 1.6 (not part of the tracker)
    capacity:    track slots per lane (0 = from the data; an overflowing lane runs again with twice as
                 many); ByteTrack's lists have no bound
    """
    #: ``not args.mot20`` ("test mot20." ``--mot20``, default False): the IoU cost fused with the
    #: detection score (``matching.fuse_score``) in the first and the unconfirmed associations
    fuse_score: bool = True
    #: ``BYTETracker(args, frame_rate)``, "frame rate (fps)" (``--fps``, 30 there; KITTI is 10)
    frame_rate: int = 10
    #: ``tools/demo_track.py``'s writer filter (``--min_box_area`` 10, ``--aspect_ratio_thresh``
    #: 1.6): a written box needs ``w * h > 10`` and not ``w / h > 1.6`` (not part of the tracker)
    demo_filter: bool = False
    #: track slots per lane (0 = from the data, grown where a lane overflows:
    #: ``trackers.capacity``); ByteTrack's lists have no bound
    capacity: int = 0


def bytetrack_car() -> tuple[Params, Options]:
    """ByteTrack's defaults at KITTI's 10 frames/s (the reference run ``car_default``)."""
    return Params(0.5, 0.8, 30, 0.1), Options(True, 10)


def bytetrack_pedestrian() -> tuple[Params, Options]:
    """ByteTrack's defaults at KITTI's 10 frames/s (the reference run ``pedestrian_default``)."""
    return Params(0.5, 0.8, 30, 0.1), Options(True, 10)


def bytetrack_car_tuned() -> tuple[Params, Options]:
    """The best of 256 batched-TPE trials on AB3DMOT's car train split for HOTA
    (``sweeps/kitti_tune_bytetrack.toml``, seed 0: train HOTA 76.650 vs the default's 75.418)."""
    return Params(0.21459806506676637, 0.8496441103950539, 66, 0.03679447822076752), Options(True, 10)


PRESETS = {"bytetrack_car": bytetrack_car, "bytetrack_pedestrian": bytetrack_pedestrian,
           "bytetrack_car_tuned": bytetrack_car_tuned}


def stack_params(params: list[Params]) -> Params:
    """A batch [B] of Params (float64 thresholds, int32 buffers)."""
    return Params(np.array([p.track_thresh for p in params], np.float64),
                  np.array([p.match_thresh for p in params], np.float64),
                  np.array([p.track_buffer for p in params], np.int32),
                  np.array([p.det_thresh_margin for p in params], np.float64))


def max_time_lost(frame_rate: int, track_buffer) -> np.ndarray:
    """``int(frame_rate / 30.0 * track_buffer)`` (float64, truncated)."""
    return np.floor(frame_rate / 30.0 * np.asarray(track_buffer, np.float64)).astype(np.int64)


# ---- the family's settings (``FAMILY_CONFIG``) ------------------------------------------------------

CLASSES = ("car", "pedestrian")
#: preset name -> (Params, Options)
PRESET_SETTINGS = {name: make() for name, make in PRESETS.items()}
PARAM_RANGES: dict[str, tuple[float, float]] = {"track_thresh": (0.0, 1.0), "match_thresh": (0.0, 1.0),
                                                "track_buffer": (0, 100000), "det_thresh_margin": (-1.0, 1.0)}
INT_PARAMS = frozenset({"track_buffer"})
BOOL_OPTIONS = ("fuse_score", "demo_filter")
OPTION_RANGES: dict[str, tuple[int, int]] = {"frame_rate": (1, 1000), "capacity": (0, MAX_CAPACITY)}


def preset(name: str, cls: str = "car") -> tuple[Params, Options]:
    """A preset's (Params, Options) (each preset the same for every class of ``CLASSES``)."""
    if name not in PRESET_SETTINGS:
        raise ValueError(f"unknown preset {name!r}: expected one of {sorted(PRESET_SETTINGS)}")
    if cls not in CLASSES:
        raise ValueError(f"unknown class {cls!r}: expected one of {list(CLASSES)}")
    return PRESET_SETTINGS[name]


def param_problem(name: str, value) -> str | None:
    """What is wrong with ``value`` for parameter ``name`` (None: nothing): the one check of parameters."""
    if name not in PARAM_RANGES:
        return f"unknown parameter; parameters are {list(Params._fields)}"
    return number_problem(value, PARAM_RANGES[name], name in INT_PARAMS)


def option_problem(name: str, value) -> str | None:
    """What is wrong with ``value`` for option ``name`` (None: nothing): the one check of options."""
    if name in BOOL_OPTIONS:
        return None if isinstance(value, (bool, np.bool_)) else "expected true or false"
    if name in OPTION_RANGES:
        lo, hi = OPTION_RANGES[name]
        ok = isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_)) and lo <= value <= hi
        return None if ok else f"expected an integer from {lo} to {hi}"
    return f"unknown option; options are {list(Options._fields)}"


def validate(params: Params, options: Options) -> None:
    """ValueError naming every setting that is wrong."""
    bad = [f"{k}={v!r}: {e}" for k, v in params._asdict().items() if (e := param_problem(k, v))]
    bad += [f"{k}={v!r}: {e}" for k, v in options._asdict().items() if (e := option_problem(k, v))]
    if bad:
        raise ValueError("ByteTrack: " + "; ".join(bad))


def parse_assignment(text: str, params: Params, options: Options) -> tuple[Params, Options]:
    """Apply one ``name=value`` (``dfrmot track --set``) to params or options; ValueError naming
    ``--set name`` and what is wrong."""
    return parse_setting(text, params, options, int_names=INT_PARAMS, number_options=OPTION_RANGES,
                         bool_options=BOOL_OPTIONS, param_problem=param_problem, option_problem=option_problem)


def as_arrays(params: Params) -> Params:
    """Leaves as NumPy arrays: the thresholds float64, the buffer int32 (any leading batch axis kept)."""
    return Params(*(np.asarray(v, np.int32 if name in INT_PARAMS else np.float64)
                    for name, v in zip(Params._fields, params)))


#: ByteTrack's settings as a family's (:class:`dfrmot_jax.trackers.protocol.FamilyConfig`):
#: ``family = "bytetrack"``; its tracker is ``trackers.bytetrack.family.FAMILY``. It reads 2D detections only.
FAMILY_CONFIG = FamilyConfig(
    name="bytetrack", title="ByteTrack", Params=Params, Options=Options, presets=PRESET_SETTINGS,
    default_preset="bytetrack_car", classes=CLASSES, class_defaults={c: {} for c in CLASSES}, preset=preset,
    param_ranges=PARAM_RANGES, int_params=INT_PARAMS, option_choices={}, option_ranges=OPTION_RANGES,
    param_problem=param_problem, option_problem=option_problem, parse_assignment=parse_assignment,
    as_arrays=as_arrays, late_params={}, late_options={}, detections=("2d",),
    preset_classes={"bytetrack_car_tuned": "car"}, default_sequences="all",
    tracker="dfrmot_jax.trackers.bytetrack.family")
