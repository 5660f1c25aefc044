"""AB3DMOT's settings: dynamic ``Params`` (numbers: a batch of them shares one compiled program
under ``vmap``), static ``Options`` (each value its own compilation), the presets of AB3DMOT's
``get_param`` for PointRCNN on KITTI, and the validator.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from .affinity import DISTANCE_METRICS, METRICS

__all__ = ["Params", "Options", "ALGORITHMS", "PARAM_RANGES", "PRESETS", "ab3dmot_car", "ab3dmot_pedestrian",
           "param_problem", "option_problem", "problems", "validate", "as_arrays", "stack_params",
           "compared_threshold", "AUTO_BUCKETS_MIN_T"]

ALGORITHMS = ("hungarian", "greedy")


class Params(NamedTuple):
    """Dynamic settings (scalars, or leaves [B] for a batch). Defaults: AB3DMOT's car preset.

    threshold:        ``get_param``'s ``thres`` as written there: an assigned pair is rejected when
                      its affinity (float32, compared in float64) is below it, or, for the distance
                      metrics (``dist_2d``, ``dist_3d``, ``m_dis``), below ``-threshold`` (the
                      affinity is the negated distance, and ``get_param`` negates the value).
    min_hits:         a track is written once it has been matched (its birth included) min_hits
                      times, or in the sequence's first min_hits frames.
    max_age:          a track unmatched for max_age frames is deleted (and not written).
    score_threshold:  a written track's line goes to the result file only when its last
                      detection's score is >= score_threshold (``save_results``; -10000 keeps all).
    """

    threshold: Any = -0.2
    min_hits: Any = 3
    max_age: Any = 2
    score_threshold: Any = -10000.0


INT_PARAMS = ("min_hits", "max_age")
#: the valid range of each parameter (inclusive)
PARAM_RANGES = {"threshold": (-1e6, 1e6), "min_hits": (0, 1_000_000), "max_age": (1, 1_000_000),
                "score_threshold": (-1e12, 1e12)}


class Options(NamedTuple):
    """Static settings: one compiled program per distinct value (and frame shape).

    metric:     one of ``METRICS`` (``iou_2d``, ``iou_3d``, ``giou_2d``, ``giou_3d``, ``dist_2d``,
                ``dist_3d``, ``m_dis``).
    algorithm:  ``hungarian`` (scipy's linear sum assignment) or ``greedy``.
    tracks:     track capacity K: live tracks plus the frame's births; births beyond it are
                dropped and counted (``State.overflow``).
    pairs:      IoU metrics, ``tracker.step`` (one lane): the most (detection, track) pairs per
                frame whose footprints may overlap that are clipped (0: every pair, N K); pairs
                beyond it are counted (``State.pairs_left``) and taken as not overlapping.
                ``batch.run`` clips every such pair (its lists of pairs grow with the frame).
    boxes:      write the tracks' 3D boxes (``StepOutput.boxes`` [K, 7]); False: [K, 0].
    buckets:    ``batch.run``: the sizes a frame's work is chosen from, smallest holding it (the
                same result, less work on small frames, more compilations): the lists of pairs of
                all lanes (``buckets`` sizes, x4 apart; the clipped pairs one more) and the
                assignment's slots (N, K halved ``buckets`` - 1 times); 0: 3 on splits of at
                least ``AUTO_BUCKETS_MIN_T`` frames, else 1.
    """

    metric: str = "giou_3d"
    algorithm: str = "hungarian"
    tracks: int = 64
    pairs: int = 64
    boxes: bool = True
    buckets: int = 0


#: ``Options.buckets = 0`` takes 3 buckets from this many frames on (their two compilations more,
#: ~10-20 s for the IoU metrics on 2 cores, pay on long splits: KITTI car, 670 frames, B = 1, 3.4x)
AUTO_BUCKETS_MIN_T = 2000


PRESETS: dict[str, tuple[Params, Options]] = {
    # AB3DMOT 61f3bd7, get_param, KITTI, det_name 'pointrcnn'
    "ab3dmot_car": (Params(-0.2, 3, 2), Options("giou_3d", "hungarian")),
    "ab3dmot_pedestrian": (Params(-0.4, 1, 4), Options("giou_3d", "greedy")),
}


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


def compared_threshold(threshold, metric: str):
    """The value affinities are compared with: ``-threshold`` for the distance metrics."""
    return -threshold if metric in DISTANCE_METRICS else threshold


def param_problem(name: str, value) -> str | None:
    """What is wrong with ``value`` (a number or an array of them) for parameter ``name``, or None."""
    if name not in PARAM_RANGES:
        return f"unknown parameter {name!r}; parameters are {list(Params._fields)}"
    if isinstance(value, (str, bytes, bool, np.bool_)):
        return f"{name}: not a number ({value!r})"
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        return f"{name}: not a number ({value!r})"
    lo, hi = PARAM_RANGES[name]
    if not np.all(np.isfinite(arr)):
        return f"{name}: not finite"
    if np.any(arr < lo) or np.any(arr > hi):
        return f"{name}: outside the valid range [{lo:g}, {hi:g}] ({value!r})"
    if name in INT_PARAMS and np.any(arr != np.round(arr)):
        return f"{name}: expected an integer ({value!r})"
    return None


def option_problem(name: str, value) -> str | None:
    """What is wrong with ``value`` for option ``name``, or None."""
    choices = {"metric": METRICS, "algorithm": ALGORITHMS}
    if name in choices:
        return None if value in choices[name] else f"{name}: {value!r} is not one of {list(choices[name])}"
    if name in ("tracks", "pairs", "buckets"):
        lo, hi = (1, 1 << 16) if name == "tracks" else (0, 1 << 16) if name == "pairs" else (0, 4)
        ok = isinstance(value, (int, np.integer)) and not isinstance(value, bool) and lo <= value <= hi
        return None if ok else f"{name}: expected an integer in [{lo}, {hi}] ({value!r})"
    if name == "boxes":
        return None if isinstance(value, (bool, np.bool_)) else f"boxes: expected True or False ({value!r})"
    return f"unknown option {name!r}; options are {list(Options._fields)}"


def problems(params: Params, options: Options) -> list[str]:
    """Every problem of a setting, readable (empty: valid). Batched leaves must share one length."""
    out = [p for name, v in zip(Params._fields, params) if (p := param_problem(name, v))]
    out += [p for name, v in zip(Options._fields, options) if (p := option_problem(name, v))]
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


def as_arrays(params: Params) -> Params:
    """Leaves as NumPy arrays: the float leaves float64, the integer ones int32."""
    return Params(*(np.asarray(v, np.int32 if name in INT_PARAMS else np.float64)
                    for name, v in zip(Params._fields, params)))


def stack_params(settings: list[Params]) -> Params:
    """A batch [B] of settings."""
    return as_arrays(Params(*(np.array([getattr(p, f) for p in settings]) for f in Params._fields)))
