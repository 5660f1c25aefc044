"""A tracker family as one idea: the protocol every family of trackers gives the machinery around it.

A family (DFR-FastMOT is the first, ``dfr``) is a tracker with settings of its own, as gymnax's and
dynamax's models are: pure ``init`` / ``step`` functions over padded frames, its settings as
NamedTuple pytrees, and the host code that runs a batch of settings and turns the output into rows and
result files. The sweep, the tune, the result files of a stored config and the report speak to a
family through these records, never to one family's modules:

- :class:`FamilyConfig`, what its settings are, without its tracker (NumPy only, no JAX: what a sweep
  file's validation, a stored table's columns and ``--help`` need): ``Params`` (dynamic: numbers, a
  batch is the same NamedTuple with leaves [B], one ``vmap``), ``Options`` (static: hashable, each
  value its own compiled program), presets per class, the validators, ranges, the parameters added
  after config hashes were first written (so that a table written before them keeps its hashes);
  the registry of configs is :mod:`dfrmot_jax.trackers.registry`;
- :class:`TrackerFamily`, the whole family: its ``config`` and its tracker (``init``, ``step``,
  ``run_batch``, the batch entry point ``track``), what a step writes and how it becomes rows and
  result files, the table-level checks of its settings, its oracle; the registry of families is
  :mod:`dfrmot_jax.trackers.registry`;
- :class:`TrackResult`, what a family's batch entry point gives back (its fields written out here).

``family`` is a static option of a sweep (``[options] family = "dfr"``, the default
:data:`DEFAULT_FAMILY`): which family's ``Params`` / ``Options`` its tables hold. A family joins by
its folder under ``trackers/`` and one line of the registry (ARCHITECTURE.md, "Adding a tracker
family"), or at run time through ``registry.register``. This module names no family's code and
imports nothing of the package but ``rows`` (NumPy only: :func:`number_problem`, the check of a
parameter's value every family's ``param_problem`` makes).
"""

from __future__ import annotations

from typing import Any, Callable, Mapping, NamedTuple

import numpy as np

from ..rows import Rows

__all__ = ["BOX_FORMATS", "DEFAULT_FAMILY", "FamilyConfig", "class_columns", "split_class_column", "TrackResult", "TrackerFamily",
           "config_problems", "family_problems", "number_problem", "parse_setting", "preset_class_note"]

#: the family of a sweep or a stored table that names none (every table written before families existed)
DEFAULT_FAMILY = "dfr"
#: how result files print a row's image box (``TrackerFamily.box_format``): 6 significant digits, or ``%f``
BOX_FORMATS = ("g6", "f6")


def number_problem(value, bounds: tuple[float, float], integer: bool) -> str | None:
    """What is wrong with ``value`` (a number or an array of them) for a parameter taking numbers in
    ``bounds`` (inclusive; ``integer``: integers only), or None: not a number, not finite, outside
    the range, not an integer."""
    if isinstance(value, (str, bytes, bool, np.bool_)):
        return "not a number"
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        return "not a number"
    lo, hi = bounds
    if not np.all(np.isfinite(arr)):
        return "not finite"
    if np.any(arr < lo) or np.any(arr > hi):
        return f"outside the valid range [{lo:g}, {hi:g}]"
    if integer and np.any(arr != np.round(arr)):
        return "expected an integer"
    return None


class TrackResult(NamedTuple):
    """What a family's batch entry point (``TrackerFamily.track``) gives back for B lanes over a split
    of T frames, K the output's slots per frame (a family's rows and result files read it back).

    ids [B, T, K] int32 (-1 = nothing written); boxes: the written image boxes, [T, K, 4] (the same
    for every lane: the frames' own boxes) or [B, T, K, 4] (each lane's own), or, with
    ``rows_only``, a :class:`dfrmot_jax.rows.Rows` (values at ids >= 0 only); dropped [B, T] births
    lost per frame; overflow [B] births lost in total (0 unless a lane overflowed at the largest
    capacity tried); peak [B] most live tracks; src3 [B, T, K] int32, own3 [B, T, K] bool, box3
    [B, T, K, 6] float32 (or Rows): with ``detail``, the 3D detection each row carries and a track's
    own 3D box (a family without them: None, or its own per-row record); capacity [B] the track
    slots each lane ran with; frames: the frames tracked (the family's own record); options: the
    validated ``Options``; distortion: with a distortion study, a ``distort.LaneDistortion`` (each
    lane's levels, the spec, the frames it read), else None; score [B, T, K] float64 (or Rows): the
    score each row carries where the family keeps it per row (a family whose rows' scores follow from
    their detections: None).
    """

    ids: np.ndarray
    boxes: Any
    dropped: np.ndarray
    overflow: np.ndarray
    peak: np.ndarray
    src3: Any
    own3: Any
    box3: Any
    capacity: np.ndarray
    frames: Any
    options: Any
    distortion: Any = None
    score: Any = None

    def lane_boxes(self, b: int) -> np.ndarray:
        """Lane b's boxes [T, K, 4] (NaN off its rows where they are kept as rows only)."""
        if isinstance(self.boxes, Rows):
            return self.boxes.lane_dense(b, self.ids[b])
        return self.boxes if self.boxes.ndim == 3 else self.boxes[b]


class FamilyConfig(NamedTuple):
    """What a family's settings are (no JAX). Callables take and give plain values.

    name:             the family's name, the value of the static option ``family`` (``"dfr"``).
    title:            its name for people (``"DFR-FastMOT"``).
    Params:           NamedTuple of numbers, the dynamic settings (a batch: leaves [B] under one
                      ``vmap``); its docstring lists each field as ``name: meaning`` (``--help``).
    Options:          NamedTuple of hashable values, the static settings (each value its own
                      compilation); its docstring likewise.
    presets:          preset name -> (Params, Options).
    default_preset:   the preset a sweep's baseline is unless its file names another.
    classes:          the object classes it has settings for, in order.
    class_defaults:   class -> {parameter: value} applied on top of every preset.
    preset:           ``preset(name, cls) -> (Params, Options)``: a preset for one class.
    param_ranges:     parameter -> (low, high), inclusive: the valid values.
    int_params:       the parameters that take integers.
    option_choices:   option -> its allowed values (the options chosen from a list).
    option_ranges:    option -> (low, high) of the options that take integers.
    param_problem:    ``(name, value) -> str | None``: what is wrong with a parameter's value (None:
                      nothing); the one check of parameters.
    option_problem:   ``(name, value) -> str | None``: the same for an option.
    parse_assignment: ``(text, params, options) -> (params, options)``: one ``name=value`` applied.
    as_arrays:        ``Params -> Params`` with its numpy leaves as the tracker takes them (any
                      leading batch axis kept).
    late_params:      parameter -> default of the parameters added after config hashes were first
                      written: at its default such a parameter is left out of a config's hash, and
                      a stored row without its column has the default.
    late_options:     the same for options.
    detections:       the detections it reads: ``("2d", "3d")``, ``("3d",)``, ...
    tracker:          the module holding its ``TrackerFamily`` as ``FAMILY`` (imported by the
                      registry when the tracker is first asked for, so that settings need no JAX).
    preset_classes:   preset -> the one class it was chosen for (AB3DMOT's ``ab3dmot_pedestrian``:
                      ``"pedestrian"``); a preset not named is for every class. Running a preset on
                      another class is said in a warning (:func:`preset_class_note`).
    default_sequences: what a run without ``--seqs`` tracks: ``"with_class"`` (the sequences whose
                      ground truth has the class) or ``"all"`` (every ``label_02`` sequence, as the
                      family's own code runs them: AB3DMOT's reference runs cover all 21 with one id
                      counter, so that its default run gives its files line for line).
    unit_of:          parameter -> the option whose value sets the parameter's unit (AB3DMOT's
                      ``threshold``: an IoU for the IoU metrics, metres for the distances: ``metric``);
                      a report's sensitivity shows such a parameter once per value of that option
                      (``threshold [metric=giou_3d]``, ...), never one axis binning both units.
    """

    name: str
    title: str
    Params: type
    Options: type
    presets: Mapping[str, tuple]
    default_preset: str
    classes: tuple[str, ...]
    class_defaults: Mapping[str, Mapping[str, Any]]
    preset: Callable[..., tuple]
    param_ranges: Mapping[str, tuple[float, float]]
    int_params: frozenset
    option_choices: Mapping[str, tuple]
    option_ranges: Mapping[str, tuple[int, int]]
    param_problem: Callable[[str, Any], "str | None"]
    option_problem: Callable[[str, Any], "str | None"]
    parse_assignment: Callable[..., tuple]
    as_arrays: Callable[[Any], Any]
    late_params: Mapping[str, Any]
    late_options: Mapping[str, Any]
    detections: tuple[str, ...]
    preset_classes: Mapping[str, str] = {}
    default_sequences: str = "with_class"
    unit_of: Mapping[str, str] = {}
    tracker: str = ""


def preset_class_note(fc: FamilyConfig, preset: str, classes, how: str = "") -> str | None:
    """The warning for running ``preset`` (of family ``fc``) on ``classes`` when it was chosen for one
    other class (``FamilyConfig.preset_classes``), else None; ``how`` says where the preset was given."""
    own = fc.preset_classes.get(preset)
    other = [c for c in classes if own is not None and c != own]
    if not other:
        return None
    return (f"preset {preset!r}{how} was chosen for {own}, and runs here on {', '.join(other)}: its settings "
            f"are {fc.title}'s for {own} (for {', '.join(other)} pick a preset of that class: "
            f"{', '.join(sorted(p for p, c in fc.preset_classes.items() if c in other)) or 'none'})")


class TrackerFamily(NamedTuple):
    """A family of trackers as the machinery sees it: its ``config`` and its tracker.

    config:           its :class:`FamilyConfig`.
    init:             the empty state of one lane for ``Options`` and a track capacity (pure,
                      jittable; a NamedTuple pytree); DFR's ``init(options, capacity, params)``.
    step:             one frame of padded detections: (state, what the step writes), pure and
                      jittable; DFR's ``step(params, mem, frame, options, ...) -> (mem, StepOutput)``.
    run_batch:        the compiled batch over padded frames: ``init`` then ``step`` scanned over the
                      frames, vmapped over the lanes' ``Params`` (one program per ``Options``).
    track:            the batch entry point: ``track(split or frames, params, options, *,
                      lanes_per_call, grow, detail, rows_only, distortion, spec)`` -> a
                      ``dfrmot_jax.trackers.protocol.TrackResult`` (ids [B, T, K], boxes, per-lane counts, with
                      ``detail`` the rows' 3D sources, ``capacity``, ``frames``, ``options``): track
                      capacity, compiled calls, overflow re-runs (the keywords a sweep passes).
    prepare_frames:   ``(split, options) -> frames``: a split's padded frames for these options.
    compact_split:    ``(split, params) -> split``: the split without the detections no lane of
                      ``params`` [B] keeps (the same results, fewer slots to step over).
    default_capacity: ``(frames, params, options, clutter_slots=0) -> int``: track slots from the data.
    output_slots:     ``(options, per_lane) -> (slots, bytes per slot)``: the fewest track slots a
                      lane's output holds with these options and the bytes each takes (``per_lane``:
                      every lane has boxes of its own); a chunk's memory bound.
    rows:             ``(split, result, columns, lanes=None) -> KittiRows``: the rows the result files
                      carry, as flat arrays (what the scorers read).
    row_arrays:       ``(split, result, columns) -> (boxes, scores, box3d)``: the rows padded [B, T, K].
    class_run:        ``(split, result, lane) -> run``: one lane of one class as ``write_runs`` takes it.
    write_runs:       ``(out_dir, runs, columns=...) -> paths``: one result file per sequence.
    table_problem:    ``(table) -> (key, message) | None``: the first config of a config table (one
                      row per config, a column per parameter and option) the family refuses to run,
                      with the sweep file's key to name; None when it runs every one.
    failing_rows:     ``(table) -> bool [C]``: configs whose output is known to be useless without a
                      run (a tune fails them without tracking).
    setting_problem:  ``(what, params, options) -> str | None``: why one setting (scalars; ``what``
                      names it, e.g. "the car settings") is refused, or None (``dfrmot track``).
    lane_keys:        ``(res, base) -> [B] bytes``: per lane of a result, a digest of everything its
                      rows carry beyond its ids and image boxes (``base``: their digests, extended),
                      the key of the 3D metrics' memo of lanes.
    box_format:       how a result file prints a row's image box: ``"g6"`` (6 significant digits,
                      ``%g``) or ``"f6"`` (``%f``); a sweep scores the boxes as the files read back.
    oracle:           the module of its independent NumPy implementation, the oracle its parity tests
                      compare with (under ``dfrmot_jax.testing``, which nothing in the package imports).
    distortion_spec:  ``(options, clutter_slots=, burst_max=, burst_dist=, frames=, dps=) -> DistortSpec``:
                      the static spec of a distortion study's lanes on its frames (``track(distortion=,
                      spec=)`` takes it); None: the family takes no distortion of its detections.
    """

    config: FamilyConfig
    init: Callable
    step: Callable
    run_batch: Callable
    track: Callable
    prepare_frames: Callable
    compact_split: Callable
    default_capacity: Callable
    output_slots: Callable
    rows: Callable
    row_arrays: Callable
    class_run: Callable
    write_runs: Callable
    table_problem: Callable
    failing_rows: Callable
    setting_problem: Callable
    lane_keys: Callable
    box_format: str
    oracle: str
    distortion_spec: Callable | None = None

    @property
    def name(self) -> str:
        return self.config.name


def config_problems(fc: FamilyConfig) -> list[str]:
    """What keeps ``fc`` from being a family's config (empty: nothing): the protocol's promises
    checked on the values (``registry.register`` refuses a family with any)."""
    out = []
    for what, t in (("Params", fc.Params), ("Options", fc.Options)):
        if not (isinstance(t, type) and issubclass(t, tuple) and hasattr(t, "_fields")):
            out.append(f"{what} is not a NamedTuple type")
    if out:
        return out
    params, options = set(fc.Params._fields), set(fc.Options._fields)
    if params & options:
        out.append(f"names both a parameter and an option: {sorted(params & options)}")
    if set(fc.param_ranges) != params:
        out.append("param_ranges does not hold exactly the parameters")
    for what, names, among in (("int_params", fc.int_params, params), ("late_params", fc.late_params, params),
                               ("option_choices", fc.option_choices, options),
                               ("option_ranges", fc.option_ranges, options),
                               ("late_options", fc.late_options, options)):
        if set(names) - among:
            out.append(f"{what} names {sorted(set(names) - among)}, not among its fields")
    if fc.default_preset not in fc.presets:
        out.append(f"default preset {fc.default_preset!r} is not a preset")
    if set(fc.class_defaults) != set(fc.classes):
        out.append("class_defaults does not hold exactly the classes")
    if any(p not in params or o not in options for p, o in fc.unit_of.items()):
        out.append(f"unit_of {dict(fc.unit_of)!r}: expected parameter -> option of the family")
    if fc.default_sequences not in ("with_class", "all"):
        out.append(f"default_sequences {fc.default_sequences!r}: expected 'with_class' or 'all'")
    bad = {p: c for p, c in fc.preset_classes.items() if p not in fc.presets or c not in fc.classes}
    if bad:
        out.append(f"preset_classes {bad!r}: expected presets of the family, each with one of its classes")
    if not fc.detections or set(fc.detections) - {"2d", "3d"}:
        out.append(f"detections {fc.detections!r}: expected some of '2d', '3d'")
    for name in fc.presets:
        for cls in fc.classes:
            p, o = fc.preset(name, cls)
            bad = [f"{k}={v!r}: {e}" for k, v in p._asdict().items() if (e := fc.param_problem(k, v))]
            bad += [f"{k}={v!r}: {e}" for k, v in o._asdict().items() if (e := fc.option_problem(k, v))]
            if bad:
                out.append(f"preset {name!r} for {cls} is invalid: {'; '.join(bad)}")
    return out


def family_problems(family: TrackerFamily) -> list[str]:
    """What keeps ``family`` from being a family (empty: nothing): its config's problems, and every
    field of the tracker present."""
    out = config_problems(family.config)
    out += [f"{name} is not callable" for name in TrackerFamily._fields
            if name not in ("config", "box_format", "oracle") and not callable(getattr(family, name))
            and not (name == "distortion_spec" and family.distortion_spec is None)]
    if family.box_format not in BOX_FORMATS:
        out.append(f"box_format {family.box_format!r}: expected one of {BOX_FORMATS}")
    if not isinstance(family.oracle, str) or not family.oracle.startswith("dfrmot_jax.testing."):
        out.append(f"oracle {family.oracle!r}: expected a module of dfrmot_jax.testing")
    return out


def split_class_column(name: str, fc: FamilyConfig) -> tuple[str, str] | None:
    """``"pedestrian.a_l"`` -> ("pedestrian", "a_l"): a per-class parameter column of a table of the
    family ``fc``; None for any other column."""
    if not isinstance(name, str) or "." not in name:
        return None
    cls, param = name.split(".", 1)
    return (cls, param) if cls in fc.classes and param in fc.Params._fields else None


def class_columns(columns, fc: FamilyConfig) -> list[str]:
    """The per-class parameter columns (``<class>.<parameter>``) of the family ``fc`` among
    ``columns``, in their order."""
    return [c for c in columns if split_class_column(c, fc) is not None]


def parse_setting(text: str, params, options, *, int_names, number_options, bool_options, param_problem,
                  option_problem) -> tuple:
    """Apply one ``name=value`` (``dfrmot track --set``) to a family's ``params`` or ``options``: a
    parameter or an option of ``number_options`` read as a number (an integer where ``int_names`` or
    ``number_options`` name it and it is whole), an option of ``bool_options`` as true / false, any
    other option as its text; each checked by the family's ``param_problem`` / ``option_problem``.
    ValueError naming ``--set name`` and what is wrong."""
    if "=" not in text:
        raise ValueError(f"--set {text!r}: expected name=value")
    name, raw = (s.strip() for s in text.split("=", 1))
    p_fields, o_fields = type(params)._fields, type(options)._fields
    if name in p_fields or name in number_options:
        try:
            value = float(raw)
        except ValueError:
            raise ValueError(f"--set {name}: {raw!r} is not a number") from None
        if (name in int_names or name in number_options) and np.isfinite(value) and value == int(value):
            value = int(value)
        problem = param_problem(name, value) if name in p_fields else option_problem(name, value)
        if problem:
            raise ValueError(f"--set {name}={raw}: {problem}")
        if name in p_fields:
            return params._replace(**{name: value}), options
        return params, options._replace(**{name: value})
    if name in o_fields:
        value = raw
        if name in bool_options:
            if raw.lower() not in ("true", "false", "1", "0"):
                raise ValueError(f"--set {name}: {raw!r} is not true/false")
            value = raw.lower() in ("true", "1")
        problem = option_problem(name, value)
        if problem:
            raise ValueError(f"--set {name}={raw}: {problem}")
        return params, options._replace(**{name: value})
    raise ValueError(f"--set {name}: unknown; parameters are {list(p_fields)}, options {list(o_fields)}")
