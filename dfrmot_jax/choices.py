"""What a user picks by name, and the defaults of those picks, apart from the code that uses them: the
classes TrackEval's KITTI 2D box evaluates, the metric families, AB3DMOT's matching and sums, the
comparisons' resamples, the tune samplers and the sweep backends. Plain Python (no NumPy), so that
``dfrmot CMD --help`` builds every command's parser (their choices, argument types and defaults)
without importing the metrics, the report, the sweep or the tuner; those modules take these names
from here (and offer them under their own names too, as before).
"""

from __future__ import annotations

__all__ = ["name_list", "EVAL_CLASSES", "parse_classes", "METRIC_FAMILIES", "parse_metric_families",
           "DEFAULT_AB3DMOT_IOU", "parse_iou", "SUMS", "DEFAULT_SUM", "SUM_HELP", "DEFAULT_RESAMPLES",
           "AB3DMOT_RESAMPLES", "AB3DMOT_MAX_RESAMPLES", "SAMPLERS", "BACKENDS"]


def name_list(text, allowed, unknown, empty: str) -> tuple:
    """``'a,b'`` or a list -> the names, stripped and lower case, in the given order, duplicates
    dropped. ValueError(``unknown(name)``) for a name not in ``allowed``, ValueError(``empty``) for none."""
    out = []
    for name in (text.split(",") if isinstance(text, str) else list(text)):
        name = str(name).strip().lower()
        if not name:
            continue
        if name not in allowed:
            raise ValueError(unknown(name))
        if name not in out:
            out.append(name)
    if not out:
        raise ValueError(empty)
    return tuple(out)


# ---- TrackEval's family (metrics/kitti2d/) --------------------------------------------------------

#: the classes TrackEval's KITTI 2D box evaluates
EVAL_CLASSES = ("car", "pedestrian")


def parse_classes(classes) -> tuple:
    """``'car,pedestrian'`` / ``['Car', 'pedestrian']`` -> ``('car', 'pedestrian')`` (lower case, in
    the given order, duplicates dropped). Raises ValueError for an empty list or a class TrackEval's
    KITTI 2D box cannot evaluate (only ``car`` and ``pedestrian``)."""
    return name_list(classes, EVAL_CLASSES, lambda c: f"class {c!r} is not evaluatable (TrackEval's KITTI 2D "
                                                      f"box: {', '.join(EVAL_CLASSES)})", "no class given")


#: metric families ``dfrmot eval --metrics`` can pick
METRIC_FAMILIES = ("kitti2d", "ab3dmot")


def parse_metric_families(text) -> tuple:
    """``'kitti2d,ab3dmot'`` (or a list) -> ``('kitti2d', 'ab3dmot')`` in the given order, lower
    case, duplicates dropped; ValueError naming the families for anything else or nothing."""
    return name_list(text, METRIC_FAMILIES,
                     lambda m: f"metric family {m!r}: expected {', '.join(METRIC_FAMILIES)} (comma-separated)",
                     f"no metric family given (expected {', '.join(METRIC_FAMILIES)})")


# ---- AB3DMOT's family (metrics/ab3dmot/) ----------------------------------------------------------

#: the IoU AB3DMOT's KITTI results are usually given at (its 3D IoU 0.25)
DEFAULT_AB3DMOT_IOU = "3d:0.25"


def parse_iou(spec) -> tuple[str, float]:
    """``'3d:0.25'`` / ``'2d:0.5'`` / ``('3d', 0.25)`` -> ``('3d', 0.25)``; ValueError otherwise.

    The threshold must be in (0, 1] (at 0 every pair, even of disjoint boxes, would match)."""
    if isinstance(spec, str):
        kind, sep, thr = spec.strip().lower().partition(":")
        if not sep:
            raise ValueError(f"AB3DMOT IoU {spec!r}: expected 2d:T or 3d:T, e.g. 3d:0.25")
        try:
            value = float(thr)
        except ValueError:
            raise ValueError(f"AB3DMOT IoU {spec!r}: threshold {thr!r} is not a number") from None
    else:
        kind, value = spec
        kind = str(kind).lower()
        value = float(value)
    if kind not in ("2d", "3d"):
        raise ValueError(f"AB3DMOT IoU {spec!r}: kind must be 2d or 3d, got {kind!r}")
    if not (0.0 < value <= 1.0):
        raise ValueError(f"AB3DMOT IoU {spec!r}: threshold must be in (0, 1], got {value}")
    return kind, value


#: the two ways AB3DMOT's evaluator sums track scores, by name (:mod:`dfrmot_jax.metrics.samota.sums`)
SUMS = ("compensated", "sequential")
#: the default: CPython >= 3.12's compensated sum
DEFAULT_SUM = "compensated"
#: one line for the command line's and the sweep files' help
SUM_HELP = ("how AB3DMOT's evaluator sums track scores: compensated (CPython >= 3.12, the default: no drift) or "
            "sequential (CPython <= 3.11: re-averaged scores drift by ulps and tracks at their own threshold drop)")

# ---- comparisons (report/compare, report/compare_ab3dmot) -----------------------------------------

#: paired bootstrap resamples of a comparison's TrackEval figures
DEFAULT_RESAMPLES = 10_000
#: fewer for AB3DMOT's figures: each resample is a full evaluation of both outputs
AB3DMOT_RESAMPLES = 200
#: the most a comparison draws: about an hour at 0.2 s a resample (AB3DMOT's 11 validation sequences)
AB3DMOT_MAX_RESAMPLES = 20_000

# ---- sweeps and tunes -------------------------------------------------------------------------------

#: the tune samplers (``[tune] sampler``, ``dfrmot tune --sampler``: :mod:`dfrmot_jax.tuning.study`)
SAMPLERS = ("tpe", "cmaes", "gp", "pairwise", "nsga2", "random", "grid")
#: where a sweep's chunks run (:mod:`dfrmot_jax.sweep.backend`)
BACKENDS = ("local", "ray")
