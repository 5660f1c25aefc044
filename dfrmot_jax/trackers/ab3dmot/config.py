"""AB3DMOT's settings, without its tracker (NumPy only: nothing here reaches JAX): dynamic
``Params`` (numbers: a batch of them shares one compiled program under ``vmap``), static ``Options``
(each value its own compilation), the presets of AB3DMOT's ``get_param`` for PointRCNN on KITTI, the
validators, and the family's settings record :data:`FAMILY_CONFIG` (family ``"ab3dmot"``).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from ..protocol import FamilyConfig, number_problem, parse_setting
from ..capacity import MAX_CAPACITY

__all__ = ["Params", "Options", "ALGORITHMS", "METRICS", "DISTANCE_METRICS", "PARAM_RANGES", "INT_PARAMS",
           "OPTION_CHOICES", "OPTION_RANGES", "PRESETS", "CLASSES", "MAX_CAPACITY", "ab3dmot_car",
           "ab3dmot_pedestrian", "preset", "param_problem", "option_problem", "problems", "validate",
           "parse_assignment", "as_arrays", "stack_params", "compared_threshold", "AUTO_BUCKETS_MIN_T",
           "FAMILY_CONFIG"]

ALGORITHMS = ("hungarian", "greedy")
#: the affinity metrics of AB3DMOT's matching (``dist_metrics``)
METRICS = ("iou_2d", "iou_3d", "giou_2d", "giou_3d", "dist_2d", "dist_3d", "m_dis")
#: metrics whose affinity is a negated distance (AB3DMOT's ``get_param`` negates their threshold)
DISTANCE_METRICS = ("dist_2d", "dist_3d", "m_dis")


class Params(NamedTuple):
    """Dynamic settings (scalars, or leaves [B] for a batch). Defaults: AB3DMOT's car preset.

    threshold:        the affinity an assigned (detection, track) pair needs, AB3DMOT's ``thres``
                      as written in ``get_param`` (a pair below it is rejected and its detection
                      starts a track; for the distance metrics dist_2d, dist_3d and m_dis the
                      distance it may not exceed: the affinity is the negated distance and
                      ``get_param`` negates the value). Float32 affinities, compared in float64.
    min_hits:         matches a track needs before it is written, AB3DMOT's ``min_hits`` (its birth
                      counts as one; every track is written in a sequence's first min_hits frames).
    max_age:          frames a track may go unmatched, AB3DMOT's ``max_age`` (it is deleted, and
                      no longer written, once unmatched for max_age frames).
    score_threshold:  a written track's line goes to the result file only when its last
                      detection's score is at least this (AB3DMOT's ``save_results``; -10000 keeps all).
    """

    threshold: Any = -0.2
    min_hits: Any = 3
    max_age: Any = 2
    score_threshold: Any = -10000.0


INT_PARAMS = frozenset({"min_hits", "max_age"})
#: the valid range of each parameter (inclusive)
PARAM_RANGES = {"threshold": (-1e6, 1e6), "min_hits": (0, 1_000_000), "max_age": (1, 1_000_000),
                "score_threshold": (-1e12, 1e12)}
#: the most track slots a lane grows to (``batch.run``)


class Options(NamedTuple):
    """Static settings: one compiled program per distinct value (and frame shape).

    metric:     the affinity of a (detection, track) pair, AB3DMOT's ``metric`` (iou_2d, iou_3d,
                giou_2d, giou_3d: overlap of the boxes' ground footprints or 3D volumes; dist_2d,
                dist_3d: centre distance; m_dis: Mahalanobis distance under the track's Kalman
                innovation covariance).
    algorithm:  the assignment, AB3DMOT's ``algm`` (hungarian: scipy's linear sum assignment;
                greedy: the largest affinities first).
    capacity:   track slots per lane (live tracks plus the frame's births; 0: from the data); a
                lane that runs out runs again with twice as many, so results never depend on it.
    pairs:      the single-lane step's (``tracker.step``) limit, unused by dfrmot's runs (which
                clip every pair, ``batch.run``): with IoU metrics, the most (detection, track)
                pairs per frame whose footprints may overlap that are clipped (0: every pair,
                N K); pairs beyond it are counted (``State.pairs_left``) and taken as apart.
    boxes:      the steps write the tracks' 3D boxes (``StepOutput.boxes`` [K, 7]; False: [K, 0],
                which dfrmot's runs refuse: the result files carry the boxes).
    buckets:    ``batch.run``: the slot counts a frame's assignment is chosen from, smallest
                holding its detections and every lane's live tracks (the same result, less work on
                small frames, one more copy of the assignment's code per count): N, K halved
                ``buckets`` - 1 times; 0: 3 on splits of at least ``AUTO_BUCKETS_MIN_T`` frames,
                else 1. (The affinity's pairs run in fixed-size blocks whatever this is:
                ``batch.pooled_affinity``.)
    """

    metric: str = "giou_3d"
    algorithm: str = "hungarian"
    capacity: int = 0
    pairs: int = 64
    boxes: bool = True
    buckets: int = 0


OPTION_CHOICES: dict[str, tuple[str, ...]] = {"metric": METRICS, "algorithm": ALGORITHMS}
#: the options that take integers -> their range (inclusive)
OPTION_RANGES: dict[str, tuple[int, int]] = {"capacity": (0, MAX_CAPACITY), "pairs": (0, 1 << 16), "buckets": (0, 4)}

#: ``Options.buckets = 0`` takes 3 buckets from this many frames on (two more copies of the
#: assignment to compile, a few seconds on 2 cores, pay on long splits: KITTI car, 8008 frames, 2
#: busy cores, giou_3d: buckets 3 runs B = 1 in 2.2 s against 3.2 s (Hungarian), 2.9 against 6.4 s
#: (greedy); B = 8 in 12.1 against 12.9 s and 20 against 38 s)
AUTO_BUCKETS_MIN_T = 2000


PRESETS: dict[str, tuple[Params, Options]] = {
    # AB3DMOT 61f3bd7, get_param, KITTI, det_name 'pointrcnn'
    "ab3dmot_car": (Params(-0.2, 3, 2), Options("giou_3d", "hungarian")),
    "ab3dmot_pedestrian": (Params(-0.4, 1, 4), Options("giou_3d", "greedy")),
    # Searched on AB3DMOT's train split only (sweeps/kitti_ab3dmot_grid.toml and
    # sweeps/kitti_ab3dmot_pedestrian_grid.toml: 1,024 configs each, metric x threshold x min_hits x
    # max_age x algorithm), chosen by tuned_both's rule: on the Pareto front of (sAMOTA, HOTA) over the
    # train split, the point of largest sAMOTA + HOTA (compensated sum). Car: config 94 (train sAMOTA
    # 89.85, HOTA 67.72; ab3dmot_car 88.01, 68.97). Pedestrian: config 252 (train 73.21, 30.13;
    # ab3dmot_pedestrian 67.43, 13.63). The validation split, scored once (sweeps/README, "AB3DMOT
    # tuned"): car sAMOTA 93.20, HOTA 66.99 (ab3dmot_car 93.45, 69.76); pedestrian 78.14, 40.15
    # (ab3dmot_pedestrian 81.24, 31.72).
    "ab3dmot_car_tuned": (Params(0.0, 2, 2), Options("giou_3d", "greedy")),
    "ab3dmot_pedestrian_tuned": (Params(-0.1, 4, 6), Options("giou_3d", "hungarian")),
}
#: the classes AB3DMOT's presets are for (each preset runs on either; no per-class changes)
CLASSES = ("car", "pedestrian")


def ab3dmot_car(**options) -> tuple[Params, Options]:
    """AB3DMOT's PointRCNN car setting: Hungarian, ``giou_3d``, threshold -0.2, min_hits 3,
    max_age 2 (``options``: changes of the ``Options``, e.g. capacities)."""
    params, opts = PRESETS["ab3dmot_car"]
    return params, opts._replace(**options)


def ab3dmot_pedestrian(**options) -> tuple[Params, Options]:
    """AB3DMOT's PointRCNN pedestrian setting: greedy, ``giou_3d``, threshold -0.4, min_hits 1,
    max_age 4."""
    params, opts = PRESETS["ab3dmot_pedestrian"]
    return params, opts._replace(**options)


def preset(name: str, cls: str = "car") -> tuple[Params, Options]:
    """A preset's (Params, Options); every preset is the same for each class of ``CLASSES``."""
    if name not in PRESETS:
        raise ValueError(f"unknown preset {name!r}: expected one of {sorted(PRESETS)}")
    if cls not in CLASSES:
        raise ValueError(f"unknown class {cls!r}: expected one of {list(CLASSES)}")
    return PRESETS[name]


def compared_threshold(threshold, metric: str):
    """The value affinities are compared with: ``-threshold`` for the distance metrics."""
    return -threshold if metric in DISTANCE_METRICS else threshold


def param_problem(name: str, value) -> str | None:
    """What is wrong with ``value`` (a number or an array of them) for parameter ``name`` (None:
    nothing): the one check of parameters."""
    if name not in PARAM_RANGES:
        return f"unknown parameter; parameters are {list(Params._fields)}"
    return number_problem(value, PARAM_RANGES[name], name in INT_PARAMS)


def option_problem(name: str, value) -> str | None:
    """What is wrong with ``value`` for option ``name`` (None: nothing): the one check of options."""
    if name in OPTION_CHOICES:
        return None if isinstance(value, str) and value in OPTION_CHOICES[name] else \
            f"expected one of {OPTION_CHOICES[name]}"
    if name in OPTION_RANGES:
        lo, hi = OPTION_RANGES[name]
        ok = isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_)) and lo <= value <= hi
        return None if ok else f"expected an integer from {lo} to {hi}"
    if name == "boxes":
        return None if isinstance(value, (bool, np.bool_)) else "expected true or false"
    return f"unknown option; options are {list(Options._fields)}"


def problems(params: Params, options: Options) -> list[str]:
    """Every problem of a setting, readable (empty: valid). Batched leaves must share one length."""
    out = [f"{name}: {p} ({v!r})" for name, v in zip(Params._fields, params) if (p := param_problem(name, v))]
    out += [f"{name}: {p} ({v!r})" for name, v in zip(Options._fields, options) if (p := option_problem(name, v))]
    sizes = {np.shape(v)[0] for v in params if np.ndim(v) == 1}
    if len(sizes) > 1 or any(np.ndim(v) > 1 for v in params):
        out.append(f"parameters: leaves must be scalars or share one length [B] (lengths {sorted(sizes)})")
    return out


def validate(params: Params, options: Options) -> tuple[Params, Options]:
    """``(params, options)`` unchanged, or ValueError listing every problem."""
    found = problems(params, options)
    if found:
        raise ValueError("invalid AB3DMOT setting:\n  " + "\n  ".join(found))
    return params, options


def parse_assignment(text: str, params: Params, options: Options) -> tuple[Params, Options]:
    """Apply one ``name=value`` (``dfrmot track --set``) to params or options; ValueError naming
    ``--set name`` and what is wrong."""
    return parse_setting(text, params, options, int_names=INT_PARAMS, number_options=OPTION_RANGES,
                         bool_options=("boxes",), param_problem=param_problem, option_problem=option_problem)


def as_arrays(params: Params) -> Params:
    """Leaves as NumPy arrays: the float leaves float64, the integer ones int32."""
    return Params(*(np.asarray(v, np.int32 if name in INT_PARAMS else np.float64)
                    for name, v in zip(Params._fields, params)))


def stack_params(settings: list[Params]) -> Params:
    """A batch [B] of settings."""
    return as_arrays(Params(*(np.array([getattr(p, f) for p in settings]) for f in Params._fields)))


#: AB3DMOT's settings as a family's (:class:`dfrmot_jax.trackers.protocol.FamilyConfig`): ``family = "ab3dmot"``;
#: its tracker is :data:`dfrmot_jax.trackers.ab3dmot.family.FAMILY`. It reads 3D detections only.
FAMILY_CONFIG = FamilyConfig(
    name="ab3dmot", title="AB3DMOT", Params=Params, Options=Options, presets=PRESETS, default_preset="ab3dmot_car",
    classes=CLASSES, class_defaults={c: {} for c in CLASSES}, preset=preset, param_ranges=PARAM_RANGES,
    int_params=INT_PARAMS, option_choices=OPTION_CHOICES, option_ranges=OPTION_RANGES, param_problem=param_problem,
    option_problem=option_problem, parse_assignment=parse_assignment, as_arrays=as_arrays, late_params={},
    late_options={}, detections=("3d",),
    preset_classes={"ab3dmot_car": "car", "ab3dmot_car_tuned": "car", "ab3dmot_pedestrian": "pedestrian",
                    "ab3dmot_pedestrian_tuned": "pedestrian"},
    default_sequences="all", unit_of={"threshold": "metric"},
    tracker="dfrmot_jax.trackers.ab3dmot.family")
