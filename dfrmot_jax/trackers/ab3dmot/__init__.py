"""AB3DMOT's 3D multi-object tracker (xinshuoweng/AB3DMOT at 61f3bd7, ``main.py`` with ego-motion
compensation off) in pure JAX, exact to its code: the lines of its result files, for many settings
at once (``vmap`` over a ``Params`` batch, ``lax.scan`` over frames).

    from dfrmot_jax import ab3dmot
    split = ab3dmot.read_split(kitti_root, "car")
    params, options = ab3dmot.ab3dmot_car(capacity=48)
    out = ab3dmot.run(params, split.frames, options)
    lines = ab3dmot.result_lines(split, out)          # {sequence: AB3DMOT's lines}

Imports only NumPy, JAX, its own modules and ``io.kitti.sequence_lengths`` (a sequence runs to its last
label frame). The names below are imported on first use (PEP 562), so that ``ab3dmot.config`` (the
settings, the family's ``FamilyConfig``) is read without JAX.
"""

__all__ = ["ALGORITHMS", "PARAM_RANGES", "PRESETS", "Options", "Params", "ab3dmot_car", "ab3dmot_pedestrian",
           "as_arrays", "compared_threshold", "option_problem", "param_problem", "problems", "stack_params",
           "validate", "DISTANCE_METRICS", "METRICS", "ALL_SEQUENCES", "TYPE_NAMES", "Split", "pack",
           "parse_detections", "read_split", "LINE_FORMAT", "result_lines", "write_results",
           "RunOutput", "clear_programs", "run", "run_lane", "Frames", "State", "StepOutput", "init", "step"]

#: public name -> the module of this package that defines it
_HOMES = {
    **dict.fromkeys(("ALGORITHMS", "PARAM_RANGES", "PRESETS", "Options", "Params", "ab3dmot_car", "ab3dmot_pedestrian",
                     "as_arrays", "compared_threshold", "option_problem", "param_problem", "problems",
                     "stack_params", "validate", "DISTANCE_METRICS", "METRICS"), "config"),
    **dict.fromkeys(("ALL_SEQUENCES", "TYPE_NAMES", "Split", "pack", "parse_detections", "read_split"), "data"),
    **dict.fromkeys(("LINE_FORMAT", "result_lines", "write_results"), "results"),
    **dict.fromkeys(("RunOutput", "clear_programs", "run", "run_lane"), "batch"),
    **dict.fromkeys(("Frames", "State", "StepOutput", "init", "step"), "tracker"),
}


def __getattr__(name: str):
    """A public name, imported from its module when first asked for (then kept here)."""
    home = _HOMES.get(name)
    if home == "config":
        from . import config as module
    elif home == "data":
        from . import data as module
    elif home == "results":
        from . import results as module
    elif home == "batch":
        from . import batch as module
    elif home == "tracker":
        from . import tracker as module
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(module, name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
