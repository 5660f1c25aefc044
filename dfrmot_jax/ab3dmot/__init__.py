"""AB3DMOT's 3D multi-object tracker (xinshuoweng/AB3DMOT at 61f3bd7, ``main.py`` with ego-motion
compensation off) in pure JAX, exact to its code: the lines of its result files, for many settings
at once (``vmap`` over a ``Params`` batch, ``lax.scan`` over frames).

    from dfrmot_jax import ab3dmot
    split = ab3dmot.read_split(kitti_root, "car")
    params, options = ab3dmot.ab3dmot_car(tracks=48)
    out = ab3dmot.run(params, split.frames, options)
    lines = ab3dmot.result_lines(split, out)          # {sequence: AB3DMOT's lines}

Imports only NumPy, JAX, its own modules and ``io.kitti.sequence_lengths`` (a sequence runs to its last label frame).
"""

from .config import (ALGORITHMS, PARAM_RANGES, PRESETS, Options, Params, ab3dmot_car, ab3dmot_pedestrian,
                     as_arrays, compared_threshold, option_problem, param_problem, problems, stack_params, validate)
from .affinity import DISTANCE_METRICS, METRICS
from .data import ALL_SEQUENCES, TYPE_NAMES, Split, pack, parse_detections, read_split
from .results import LINE_FORMAT, result_lines, write_results
from .batch import RunOutput, clear_programs, run, run_lane
from .tracker import Frames, State, StepOutput, init, step

__all__ = ["ALGORITHMS", "PARAM_RANGES", "PRESETS", "Options", "Params", "ab3dmot_car", "ab3dmot_pedestrian",
           "as_arrays", "compared_threshold", "option_problem", "param_problem", "problems", "stack_params",
           "validate", "DISTANCE_METRICS", "METRICS", "ALL_SEQUENCES", "TYPE_NAMES", "Split", "pack",
           "parse_detections", "read_split", "LINE_FORMAT", "result_lines", "write_results",
           "RunOutput", "clear_programs", "run", "run_lane", "Frames", "State", "StepOutput", "init", "step"]
