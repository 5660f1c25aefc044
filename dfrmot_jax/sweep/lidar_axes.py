"""The LiDAR tables of a sweep with ``data.det3d = "lidar:DIR"``: ``[lift]`` (the lifting settings,
:class:`dfrmot_jax.lidar.LiftSettings`) and ``[simulate]`` (scans simulated per setting,
:class:`dfrmot_jax.lidar.SimSettings` and the seed), each key a value or a list of values.

Every config of the sweep is crossed with every LiDAR setting (the product of the listed values,
the first key slowest). Different settings are different data: each distinct (simulation, lifting)
setting is lifted once into its own split (``plan.DataSettings.lidar``), and the configs of that
setting are vmapped on it as any sweep's. The settings are columns of the config table
(``lift.shrink``, ``simulate.beams``, ...; ``LIDAR_AXES``) and enter a config's hash only off their
default, so a config at the default settings hashes as before.

With ``[simulate]``, ``DIR`` is a cache folder: each simulation setting's scans are written under
``DIR/simulated/<name>/`` (:func:`dfrmot_jax.lidar.simulate_cached`) and lifted from there.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any, Mapping, NamedTuple

import numpy as np
import pandas as pd

from ..lidar import LIFT_SETTINGS, LiftSettings, SimSettings, lidar_dir, tie_scores, with_setting
from ..checks import Table, config_error, is_number
from ..table_columns import CROP as _CROP, LIDAR_AXES, LIFT_COLUMNS, SIM_COLUMNS, SIM_INT as _SIM_INT
from ..table_columns import lift_value as _lift_value
from ..trackers.protocol import FamilyConfig

__all__ = ["LIFT_COLUMNS", "SIM_COLUMNS", "LIDAR_AXES", "LidarAxes", "LidarKey", "parse_lidar", "lidar_key",
           "key_settings", "tie_table_scores", "describe_key"]

SIM_KEYS = tuple(SimSettings._fields) + ("seed",)


@dataclass(frozen=True)
class LidarAxes:
    """The resolved [lift] / [simulate] tables: ``axes`` ((column, values), ...) in file order
    (lift first), ``simulate``: whether scans are simulated (a [simulate] table, even empty).

    An axis kind of the config table (:class:`~dfrmot_jax.sweep.axes.AxisKind`): every config x
    every setting; the baseline on :meth:`baseline`; each setting its own split (``lidar_key``)."""

    axes: tuple[tuple[str, tuple], ...]
    simulate: bool = False

    def settings(self) -> list[dict]:
        """Every LiDAR setting of the sweep, ``{column: value}``, the first axis slowest."""
        names = [c for c, _ in self.axes]
        return [dict(zip(names, combo)) for combo in itertools.product(*(v for _, v in self.axes))]

    @property
    def columns(self) -> dict[str, Any]:
        """The listed columns -> their defaults."""
        return {c: LIDAR_AXES[c] for c, _ in self.axes}

    def baseline(self) -> dict:
        """The setting the baseline runs on: the defaults when the sweep lists them, else the first."""
        every = self.settings()
        default = dict(self.columns)
        return default if default in every else every[0]

    def values(self, baseline: bool) -> list[dict]:
        """Every setting; for the baseline, :meth:`baseline` first."""
        every = self.settings()
        if not baseline:
            return every
        first = self.baseline()
        return [first] + [s for s in every if s != first]

    def size(self, configs: int) -> tuple[int, str, list[tuple[int, str]]]:
        n = len(self.settings())
        return configs * n, f"x {n:,} LiDAR settings", [(len(v), c) for c, v in self.axes]

    def hash_settings(self, row: Mapping) -> dict:
        return {}           # (the settings are the row's columns)

    def split_key(self, row: Mapping) -> LidarKey:
        return lidar_key(row, self.simulate)

    def chunk_identity(self) -> dict:
        return {}           # (in the chunks' data identity: DataSettings.lidar)


def _values(doc, key: str, source, crop: bool) -> list[tuple[str, Any]]:
    """(key, raw value) of one table entry: a value or a non-empty list of values (a crop corner is
    itself a list of three numbers or a comma-separated text: a list of such lists is an axis)."""
    if isinstance(doc, Mapping):
        if list(doc) != ["grid"]:
            raise config_error(key, "expected a value, a list of values or {grid = [...]}", source)
        doc, key = doc["grid"], f"{key}.grid"
    if isinstance(doc, list):
        if crop and doc and not all(isinstance(v, (list, str)) for v in doc):
            return [(key, doc)]
        if not doc:
            raise config_error(key, "empty list: nothing to sweep", source)
        return [(f"{key}[{i}]", v) for i, v in enumerate(doc)]
    return [(key, doc)]


def _lift_axis(name: str, doc, key: str, source) -> tuple:
    out = []
    for k, v in _values(doc, key, source, name in _CROP):
        if not (is_number(v) or name in _CROP and isinstance(v, (list, str))):
            raise config_error(k, f"{v!r} is not a number", source)
        try:
            s = with_setting(LiftSettings(), name, v)
        except ValueError as e:
            raise config_error(k, str(e), source) from None
        out.append(_lift_value(name, getattr(s, name)))
    return tuple(dict.fromkeys(out))


def _sim_axis(name: str, doc, key: str, source) -> tuple:
    out = []
    for k, v in _values(doc, key, source, False):
        if not is_number(v):
            raise config_error(k, f"{v!r} is not a number", source)
        if name in _SIM_INT and not float(v).is_integer():
            raise config_error(k, f"{v!r}: expected an integer", source)
        v = int(v) if name in _SIM_INT else float(v)
        if name == "seed":
            if not 0 <= v < 2 ** 31:
                raise config_error(k, f"{v!r}: a seed is an integer in [0, 2**31)", source)
        else:
            try:
                SimSettings(**{name: v}).validate()
            except ValueError as e:
                raise config_error(k, str(e), source) from None
        out.append(v)
    return tuple(dict.fromkeys(out))


def parse_lidar(doc: Mapping, source=None) -> LidarAxes | None:
    """The ``[lift]`` and ``[simulate]`` tables of a sweep document (None without either); bad
    values raise :class:`~dfrmot_jax.checks.SweepConfigError` naming the key."""
    lift, sim = doc.get("lift"), doc.get("simulate")
    if lift is None and sim is None:
        return None
    det3d = (doc.get("data") or {}).get("det3d", "pointrcnn") if isinstance(doc.get("data"), Mapping) else None
    try:
        scans = lidar_dir(det3d) if isinstance(det3d, str) else None
    except ValueError as e:
        raise config_error("data.det3d", str(e), source) from None
    table = "lift" if lift is not None else "simulate"
    if scans is None:
        raise config_error(table, f"LiDAR settings need data.det3d = \"lidar:DIR\" (got {det3d!r})", source)
    axes = []
    for name, tdoc, keys, parse in (("lift", lift, LIFT_SETTINGS, _lift_axis), ("simulate", sim, SIM_KEYS, _sim_axis)):
        if tdoc is None:
            continue
        t = Table(tdoc, name, source, keys)       # (a table, its keys known, errors naming the full key)
        for k, v in t.doc.items():
            axes.append((t.key(k), parse(k, v, t.key(k), source)))
    out = LidarAxes(tuple(axes), simulate=sim is not None)
    for s in out.settings():            # the settings together (a crop corner above the other)
        try:
            key_settings(lidar_key(s, out.simulate))
        except ValueError as e:
            raise config_error("lift", str(e), source) from None
    return out


class LidarKey(NamedTuple):
    """A LiDAR setting as data (:func:`lidar_key`), the split key of :class:`LidarAxes`: ``lift`` the
    (name, value) pairs of the lifting settings off their defaults, ``sim`` None (scans read from
    DIR) or every simulation setting's (name, value) pair (scans simulated)."""

    lift: tuple
    sim: tuple | None

    def identity(self) -> dict:
        """Its part of its split's data identity (``plan.DataSettings.identity``, in every chunk id)."""
        return {"lidar": {"lift": dict(self.lift), "simulate": None if self.sim is None else dict(self.sim)}}


def lidar_key(row: Mapping, simulate: bool = False) -> LidarKey:
    """A row's LiDAR setting as data: ``(lift, sim)`` (:class:`LidarKey`)."""
    lift = tuple((c.split(".", 1)[1], row[c]) for c in LIFT_COLUMNS if c in row and row[c] != LIFT_COLUMNS[c])
    if not simulate:
        return LidarKey(tuple((n, _plain(v)) for n, v in lift), None)
    sim = tuple((c.split(".", 1)[1], row.get(c, d)) for c, d in SIM_COLUMNS.items())
    return LidarKey(tuple((n, _plain(v)) for n, v in lift), tuple((n, _plain(v)) for n, v in sim))


def _plain(v):
    if isinstance(v, (np.integer, int)) and not isinstance(v, bool):
        return int(v)
    if isinstance(v, (np.floating, float)):
        return float(v)
    return v


def key_settings(key: tuple) -> tuple[LiftSettings, SimSettings | None, int]:
    """(LiftSettings, SimSettings or None, seed) of a :func:`lidar_key`, validated (ValueError)."""
    lift, sim = key
    s = LiftSettings()
    for n, v in lift:
        s = with_setting(s, n, v)
    if sim is None:
        return s, None, 0
    d = dict(sim)
    seed = int(d.pop("seed", 0))
    return s, SimSettings(**d).validate(), seed


def describe_key(key: tuple) -> str:
    """A short text of a LiDAR setting (logs): ``shrink=0.1 beams=32``."""
    lift, sim = key
    parts = [f"{n}={v}" for n, v in lift]
    if sim is not None:
        parts += [f"{n}={v}" for n, v in sim if SIM_COLUMNS[f"simulate.{n}"] != v]
        parts.insert(0, "simulated")
    return " ".join(parts) or "default lifting"


def tie_table_scores(table: pd.DataFrame, explicit: set[str], fc: FamilyConfig) -> pd.DataFrame:
    """The config rows of a sweep on lifted boxes with ``score_3d = score_2d`` (``lidar.tie_scores``:
    a lifted box carries its 2D detection's score, so it is kept exactly when that detection is), as
    ``dfrmot track`` does; the class columns ``<class>.score_3d`` likewise. ``explicit``: the axis
    names of the sweep (a sweep that lists ``score_3d`` keeps its values). ``fc``: the settings of the
    sweep's tracker family; a family without both score thresholds (AB3DMOT's) keeps its table."""
    if "score_3d" in explicit or any(n.endswith(".score_3d") for n in explicit) or \
            not {"score_2d", "score_3d"} <= set(fc.Params._fields):
        return table
    table = table.copy()
    for pre in [""] + [f"{c}." for c in fc.classes if f"{c}.score_2d" in table.columns or f"{c}.score_3d" in table.columns]:
        cols = {n: table[pre + n].to_numpy() if pre + n in table.columns else table[n].to_numpy()
                for n in fc.Params._fields}
        table[pre + "score_3d"] = np.asarray(tie_scores(fc.Params(**cols)).score_3d)
    return table
