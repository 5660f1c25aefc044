"""The [distortion] table of a sweep: per-lane axes (kind, level, seed) crossed with every config,
their ``DistortParams`` / ``DistortSpec`` and the parsing of the table (the sweep package's only
user of :mod:`dfrmot_jax.distort`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from .. import distort
from ..checks import GRID_KINDS, Table, check_count, clean_float, config_error, is_number
from ..table_columns import DISTORTION_AXES

DISTORTION_KEYS = ("kind", "level", "levels", "seeds", "clutter_slots", "burst_dist", "burst_max", "burst_rate",
                   "burst_len")
#: Kinds whose level is a probability (<= 1).
PROBABILITY_KINDS = ("drop", "drop_2d", "drop_3d", "burst_rate")
#: (The per-lane distortion axes, ``DISTORTION_AXES``, are defined with the stored tables' columns in
#: ``table_columns``.) The undistorted lane (level 0 of every kind and seed).
UNDISTORTED = ("none", 0.0, 0)


@dataclass(frozen=True)
class DistortionAxes:
    """The resolved [distortion] table: per-lane axes crossed with every config of the sweep.

    ``kinds``: ((kind, levels), ...) in file order (levels ascending, distinct, 0 included when
    listed); ``seeds``: the seeds of every nonzero level. Level 0 is the identity for every kind
    and seed: its lane is the undistorted config (kind "none", seed 0: the same ``config_hash`` as
    without distortion) and starts every kind's curve. ``clutter_slots``, ``burst_dist`` and
    ``burst_max`` are the static ``DistortSpec`` fields; ``burst_rate`` is the start rate of kind
    "burst" (whose level is the mean length) and ``burst_len`` the mean length of kind
    "burst_rate" (whose level is the start rate).

    An axis kind of the config table (:class:`~dfrmot_jax.sweep.axes.AxisKind`): every config x the
    lanes (:meth:`lanes`), the baseline undistorted; a lane's settings off their defaults enter its
    hash (:meth:`hash_extra`), all of them every chunk's identity (:meth:`identity`).
    """

    kinds: tuple[tuple[str, tuple[float, ...]], ...]
    seeds: tuple[int, ...]
    clutter_slots: int = 0
    burst_dist: str = "fixed"
    burst_max: int = 30
    burst_rate: float = distort.BURST_RATE
    burst_len: float = distort.BURST_LEN

    def lane(self, kind: str, level: float, seed: int) -> distort.DistortParams:
        """The ``DistortParams`` of one lane (kind "none" / level 0: all zero)."""
        if kind == "none" or float(level) == 0.0:
            return distort.level_params("none", 0.0, seed=0)
        kw = {}
        if kind == "burst":
            kw["burst_rate"] = self.burst_rate
        elif kind == "burst_rate":
            kw["burst_len"] = self.burst_len
        return distort.level_params(kind, float(level), seed=int(seed), **kw)

    def hash_extra(self, kind: str) -> dict:
        """Settings off the module's defaults that change a lane of ``kind`` (part of its hash)."""
        if kind == "none":
            return {}
        out = {}
        if kind == "burst" and self.burst_rate != distort.BURST_RATE:
            out["burst_rate"] = repr(float(self.burst_rate))
        if kind == "burst_rate" and self.burst_len != distort.BURST_LEN:
            out["burst_len"] = repr(float(self.burst_len))
        if kind in ("burst", "burst_rate"):
            if self.burst_dist != "fixed":
                out["burst_dist"] = self.burst_dist
            if self.burst_max != 30:
                out["burst_max"] = int(self.burst_max)
        if kind.startswith("clutter"):
            out["clutter_slots"] = int(self.clutter_slots)
        return out

    def identity(self) -> dict:
        """The settings that can change any result (part of every chunk's identity)."""
        return {"clutter_slots": int(self.clutter_slots), "burst_dist": self.burst_dist,
                "burst_max": int(self.burst_max), "burst_rate": float(self.burst_rate),
                "burst_len": float(self.burst_len)}

    def make_spec(self, options, frames=None, dps=None, family=None) -> distort.DistortSpec:
        """The ``DistortSpec`` of the lanes: the tracker ``family``'s own (its ``distortion_spec``
        for its ``options`` and ``frames``; None: DFR-FastMOT's, ``distort.make_spec``)."""
        make = distort.make_spec if family is None else family.distortion_spec
        if make is None:
            raise ValueError(f"tracker family {family.name!r} takes no distortion of its detections")
        return make(options, clutter_slots=self.clutter_slots, burst_max=self.burst_max, burst_dist=self.burst_dist,
                    frames=frames, dps=dps)

    @property
    def n_lanes(self) -> int:
        """Lanes per config (level 0 counted once)."""
        zero = any(0.0 in lv for _, lv in self.kinds)
        return int(zero) + sum(sum(1 for v in lv if v != 0.0) for _, lv in self.kinds) * len(self.seeds)

    def lanes(self) -> list[tuple[str, float, int]]:
        """Every lane (kind, level, seed) of a config: level 0 once (undistorted, first), then per kind
        its nonzero levels x the seeds."""
        out = [UNDISTORTED] if any(0.0 in lv for _, lv in self.kinds) else []
        for kind, levels in self.kinds:
            out.extend((kind, float(v), int(s)) for v in levels if v != 0.0 for s in self.seeds)
        return out

    # the axis kind (AxisKind)
    @property
    def columns(self) -> dict[str, Any]:
        return dict(DISTORTION_AXES)

    def values(self, baseline: bool) -> list[dict]:
        """The lanes; the baseline's first is the undistorted one (added when no kind lists level 0)."""
        lanes = self.lanes()
        if baseline and UNDISTORTED not in lanes:
            lanes = [UNDISTORTED] + lanes
        return [dict(zip(DISTORTION_AXES, lane)) for lane in lanes]

    def size(self, configs: int) -> tuple[int, str, list[tuple[int, str]]]:
        """Configs x lanes, + the baseline's undistorted lane (when no kind lists level 0)."""
        n = self.n_lanes
        return configs * n + 1, f"x {n:,} distortion lanes", [(len(self.seeds), "distortion.seeds")]

    def hash_settings(self, row: Mapping) -> dict:
        return self.hash_extra(row["distortion.kind"])

    def split_key(self, row: Mapping) -> None:
        return None         # (every lane runs on its config's split)

    def chunk_identity(self) -> dict:
        return {"distortion": self.identity()}



def _level_values(spec, key: str, source) -> list:
    """Levels given as a number, a list, or {grid | linspace | logspace = [...]} (unchecked numbers)."""
    if isinstance(spec, Mapping):
        if len(spec) != 1 or next(iter(spec)) not in GRID_KINDS:
            raise config_error(key, f"levels are a number, a list or one of {{{', '.join(GRID_KINDS)} = [...]}}, got "
                            f"{dict(spec)!r}", source)
        kind, arg = next(iter(spec.items()))
        key = f"{key}.{kind}"
        if not isinstance(arg, list):
            raise config_error(key, f"expected a list, got {arg!r}", source)
        if kind == "grid":
            spec = arg
        else:
            if len(arg) != 3 or not all(is_number(a) for a in arg) or not float(arg[2]).is_integer() or arg[2] < 1:
                raise config_error(key, f"expected [low, high, count >= 1], got {arg!r}", source)
            lo, hi, n = float(arg[0]), float(arg[1]), int(arg[2])
            check_count(n, key, source)
            if kind == "logspace" and (lo <= 0 or hi <= 0):
                raise config_error(key, f"logspace needs positive ends, got {arg!r}", source)
            raw = np.geomspace(lo, hi, n) if kind == "logspace" else np.linspace(lo, hi, n)
            return [(key, clean_float(v)) for v in raw]
    if isinstance(spec, list):
        if not spec:
            raise config_error(key, "empty list: nothing to sweep", source)
        return [(f"{key}[{i}]", v) for i, v in enumerate(spec)]
    return [(key, spec)]


def _check_level(kind: str, v, key: str, source, clutter_slots: int, burst_max: int) -> float:
    if not is_number(v):
        raise config_error(key, f"{v!r} is not a number", source)
    v = float(v)
    if not math.isfinite(v):
        raise config_error(key, f"{v!r} is not finite", source)
    if v < 0:
        raise config_error(key, f"level {v:g} < 0: levels are >= 0 (0 = undistorted)", source)
    if kind in PROBABILITY_KINDS and v > 1:
        raise config_error(key, f"level {v:g} of kind {kind!r} is a probability: expected <= 1", source)
    if kind == "burst" and v > burst_max:
        raise config_error(key, f"mean burst length {v:g} > burst_max = {burst_max} (lengths are capped at burst_max; "
                        f"raise distortion.burst_max)", source)
    if kind.startswith("clutter") and v > 0 and v > clutter_slots:
        raise config_error(key, f"{v:g} false positives per frame need distortion.clutter_slots >= {math.ceil(v)} "
                        f"(clutter_slots = {clutter_slots})", source)
    return v


def kinds_only(levels) -> tuple[str, ...]:
    """The kinds every level of which is one of ``levels`` (``distort.LEVELS_2D``: the kinds that
    distort 2D detections only, nothing of a 3D detection moves; ``distort.LEVELS_3D``: 3D only)."""
    return tuple(k for k in distort.KINDS if k != "none" and all(
        v == 0 or n in levels for n, v in distort.level_params(k, 1.0)._asdict().items() if n != "seed"))


def kinds_2d() -> tuple[str, ...]:
    """The kinds that distort 2D detections only (:func:`kinds_only` of ``distort.LEVELS_2D``)."""
    return kinds_only(distort.LEVELS_2D)


def kinds_3d() -> tuple[str, ...]:
    """The kinds that distort 3D detections only (:func:`kinds_only` of ``distort.LEVELS_3D``)."""
    return kinds_only(distort.LEVELS_3D)


def refused_kinds(detections) -> dict[str, tuple[str, ...]]:
    """The kinds a family reading ``detections`` (``FamilyConfig.detections``) refuses, by what they
    distort alone ("2D" / "3D"): those of the detections it does not read (its lanes would be the
    undistorted run)."""
    return {**({} if "2d" in detections else dict.fromkeys(kinds_2d(), "2D")),
            **({} if "3d" in detections else dict.fromkeys(kinds_3d(), "3D"))}


def parse_distortion(d, source, detections=("2d", "3d"), title: str = "") -> DistortionAxes | None:
    """The [distortion] table of a sweep document (None without it); bad values raise
    :class:`~dfrmot_jax.sweep.checks.SweepConfigError` naming the key. ``detections``: what the
    sweep's tracker family reads (``FamilyConfig.detections``, ``title`` its name): a family reading
    no 2D (3D) detections refuses the kinds that distort only those (:func:`refused_kinds`: its lanes
    would be the undistorted run)."""
    if d is None:
        return None
    t = Table(d, "distortion", source, DISTORTION_KEYS)
    levels_doc = d.get("levels")
    if levels_doc is not None and not isinstance(levels_doc, Mapping):
        raise config_error("distortion.levels", f"expected a table kind = [levels], got {levels_doc!r}", source)
    kinds = _parse_kinds(d.get("kind"), levels_doc, source, refused_kinds(detections), title)
    clutter_slots = t.integer("clutter_slots", 0, minimum=0)
    burst_max = t.integer("burst_max", 30)
    burst_dist = t.choice("burst_dist", "fixed", distort.BURST_DISTS)
    burst_rate = d.get("burst_rate", distort.BURST_RATE)
    if not is_number(burst_rate) or not 0 < float(burst_rate) <= 1:
        raise config_error("distortion.burst_rate", f"{burst_rate!r}: the burst start rate of kind \"burst\" is a "
                                            f"probability in (0, 1]", source)
    burst_len = d.get("burst_len", distort.BURST_LEN)
    if not is_number(burst_len) or not 0 < float(burst_len) <= (burst_max if "burst_rate" in kinds else math.inf):
        raise config_error("distortion.burst_len", f"{burst_len!r}: the mean burst length of kind \"burst_rate\" is in "
                                           f"(0, burst_max = {burst_max}]", source)
    out = []
    for k in kinds:
        if levels_doc and k in levels_doc:
            raw = _level_values(levels_doc[k], f"distortion.levels.{k}", source)
        elif "level" in d:
            raw = _level_values(d["level"], "distortion.level", source)
        else:
            raise config_error("distortion.levels", f"no levels for kind {k!r}: give distortion.level = [...] or "
                                            f"distortion.levels.{k} = [...]", source)
        vals = [_check_level(k, v, key, source, clutter_slots, burst_max) for key, v in raw]
        out.append((k, tuple(sorted(dict.fromkeys(vals)))))
    seeds = _parse_seeds(d.get("seeds", 1), source)
    axes = DistortionAxes(tuple(out), seeds, clutter_slots=int(clutter_slots), burst_dist=burst_dist,
                          burst_max=int(burst_max), burst_rate=float(burst_rate), burst_len=float(burst_len))
    try:        # the distortion module's own checks on every lane (belt and braces)
        dps = distort.stack_distort([axes.lane(k, v, s) for k, lv in axes.kinds for v in lv for s in seeds[:1]])
        distort.check_params(dps, axes.make_spec(None, dps=dps))
    except ValueError as e:
        raise config_error("distortion", str(e), source) from None
    return axes


def _parse_kinds(kinds_doc, levels_doc, source, refused=None, title: str = "") -> list[str]:
    """``distortion.kind`` (a kind or a list; without it, the kinds of ``distortion.levels``), checked;
    ``refused``: {kind: what alone it distorts} (:func:`refused_kinds`)."""
    refused = refused or {}
    if kinds_doc is None:
        if not levels_doc:
            raise config_error("distortion.kind", "missing: the distortion kind(s) to sweep, e.g. kind = [\"drop\", "
                                          "\"burst\"]", source)
        kinds = [(f"distortion.levels.{k}", k) for k in levels_doc]
    elif isinstance(kinds_doc, str):
        kinds = [("distortion.kind", kinds_doc)]
    elif isinstance(kinds_doc, list) and kinds_doc:
        kinds = [(f"distortion.kind[{i}]", k) for i, k in enumerate(kinds_doc)]
    else:
        raise config_error("distortion.kind", f"{kinds_doc!r}: expected a kind or a non-empty list of kinds", source)
    known = tuple(k for k in distort.KINDS if k != "none")
    for key, k in kinds:
        if not isinstance(k, str) or k not in known:
            hint = " (level 0 of every kind is the undistorted run: add 0 to the levels)" if k == "none" else ""
            raise config_error(key, f"unknown distortion kind {k!r}{hint}; expected one of {list(known)}", source)
        if k in refused:
            base = k.split("_")[0]
            use = [base] + [o for o in known if o.split("_")[0] == base and o != base and o not in refused]
            raise config_error(key, f"kind {k!r} distorts {refused[k]} detections only, which {title or 'this family'} "
                                    f"does not read (its lanes would be the undistorted run); use "
                                    f"{' or '.join(map(repr, use))}", source)
    names = [k for _, k in kinds]
    if len(set(names)) != len(names):
        raise config_error("distortion.kind", "a kind is listed twice", source)
    for k in levels_doc or ():
        if k not in names:
            raise config_error(f"distortion.levels.{k}", f"kind {k!r} is not in distortion.kind {names}", source)
    return names


def _parse_seeds(seeds_doc, source) -> tuple[int, ...]:
    """``distortion.seeds``: a count n (seeds 0 .. n-1) or a list of distinct seeds."""
    if isinstance(seeds_doc, list):
        if not seeds_doc:
            raise config_error("distortion.seeds", "empty list: give a count (seeds = 10) or a list of seeds", source)
        check_count(len(seeds_doc), "distortion.seeds", source)
        for i, v in enumerate(seeds_doc):
            if not isinstance(v, int) or isinstance(v, bool) or not 0 <= v < 2 ** 31:
                raise config_error(f"distortion.seeds[{i}]", f"{v!r}: a seed is an integer in [0, 2**31)", source)
        if len(set(seeds_doc)) != len(seeds_doc):
            raise config_error("distortion.seeds", "a seed is listed twice", source)
        return tuple(int(v) for v in seeds_doc)
    if isinstance(seeds_doc, int) and not isinstance(seeds_doc, bool):
        if seeds_doc < 1:
            raise config_error("distortion.seeds", f"{seeds_doc!r}: expected a count >= 1 (seeds 0 .. n-1) or a "
                                                   f"list of seeds", source)
        check_count(seeds_doc, "distortion.seeds", source)
        return tuple(range(seeds_doc))
    raise config_error("distortion.seeds", f"{seeds_doc!r}: expected a count >= 1 or a list of seeds", source)
