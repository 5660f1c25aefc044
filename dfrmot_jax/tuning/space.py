"""The search space of a tune: the sweep file's ``[params]`` / ``[options]`` axes as Optuna
distributions, trial values -> config tables, and the unconstrained coordinates of the continuous
parameters (for gradient refinement).

Axis kinds map to distributions: ``uniform`` -> ``FloatDistribution(low, high)``, ``loguniform``
-> ``FloatDistribution(low, high, log=True)``, ``randint [low, high)`` -> ``IntDistribution(low,
high - 1)``, ``choice`` / ``grid`` / ``linspace`` / ``logspace`` / a list -> ``CategoricalDistribution``
(options too). An axis with one value is fixed, not searched.

``[[variants]]`` (as in a sweep file) become one more categorical dim, ``variant``: the variants
search the same axes and differ only in one-valued settings (e.g. the fixed-filter gains moving
together as one two-level axis), which the chosen variant sets.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np
import pandas as pd
from optuna.distributions import CategoricalDistribution, FloatDistribution, IntDistribution

from ..trackers.protocol import DEFAULT_FAMILY
from ..trackers.registry import family_config
from ..sweep.spec import SweepConfigError, SweepSpec
from ..sweep.table import baseline_row, canonical_value, config_hash, typed_table

#: the dim of a tune over ``[[variants]]`` (its values are the variants' names)
VARIANT = "variant"


@dataclass(frozen=True)
class Dim:
    """One searched name: ``kind`` 'float' | 'logfloat' | 'int' | 'categorical'; ``values`` (low,
    high) inclusive for numbers, the choices for categoricals."""
    name: str
    kind: str
    values: tuple
    key: str

    @property
    def continuous(self) -> bool:
        return self.kind in ("float", "logfloat")


@dataclass(frozen=True)
class SearchSpace:
    """The searched dims and the fixed values (the baseline overridden by one-valued axes);
    ``variants``: {name: the values that variant fixes} of a tune over ``[[variants]]``; ``family``: the
    tracker family of its configs (the tune file's ``[options] family``)."""
    dims: tuple[Dim, ...]
    fixed: Mapping[str, Any]
    variants: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    family: str = DEFAULT_FAMILY

    def distributions(self) -> dict:
        out = {}
        for d in self.dims:
            if d.kind == "categorical":
                out[d.name] = CategoricalDistribution(list(d.values))
            elif d.kind == "int":
                out[d.name] = IntDistribution(int(d.values[0]), int(d.values[1]))
            else:
                out[d.name] = FloatDistribution(float(d.values[0]), float(d.values[1]), log=d.kind == "logfloat")
        return out

    def grid(self) -> dict[str, list]:
        """The grid of an all-categorical space (``GridSampler``)."""
        return {d.name: list(d.values) for d in self.dims}

    def row(self, values: Mapping[str, Any]) -> dict:
        """A config row: the fixed values overridden by ``values`` (names of dims; the ``variant``
        dim by the values its variant fixes)."""
        row = dict(self.fixed)
        row.update(self.variants.get(values.get(VARIANT), {}))
        fc = family_config(self.family)
        for d in self.dims:
            v = values[d.name]
            row[d.name] = int(v) if d.name in fc.int_params else float(v) if d.name in fc.Params._fields else v
        return row

    def config_hash(self, values: Mapping[str, Any]) -> str:
        """The ``config_hash`` of the config of ``values`` (as :meth:`table` computes it)."""
        return config_hash(self.row(values), family=self.family)

    def table(self, rows: Sequence[Mapping[str, Any]], baseline: Sequence[bool] | None = None) -> pd.DataFrame:
        """Config table (as :func:`dfrmot_jax.sweep.expand` makes: ``config``, ``config_hash``,
        ``variant``, ``baseline``, parameters, options) of full rows, in order, duplicates kept."""
        base = [False] * len(rows) if baseline is None else list(baseline)
        recs = [{**r, "variant": "baseline" if b else r.get(VARIANT, "tune"), "baseline": bool(b)}
                for r, b in zip(rows, base)]
        fc = family_config(self.family)
        df = pd.DataFrame(recs, columns=["variant", "baseline"] + list(fc.Params._fields) + list(fc.Options._fields))
        df = typed_table(df, self.family)
        df.insert(0, "config", np.arange(len(df), dtype=np.int64))
        return df

    def baseline_values(self) -> dict:
        """The baseline's value of every dim (possibly outside the dim's range; ``variant``: the
        variant fixing the baseline's values, None if there is none)."""
        out = {d.name: self.fixed[d.name] for d in self.dims if d.name != VARIANT}
        if self.variants:
            out[VARIANT] = next((n for n, v in self.variants.items()
                                 if all(canonical_value(k, self.fixed[k], self.family) == canonical_value(k, x, self.family)
                                        for k, x in v.items())), None)
        return out

    def contains(self, values: Mapping[str, Any]) -> bool:
        """Whether every value lies in its dim (Optuna can enqueue only such a trial)."""
        for d in self.dims:
            v = values[d.name]
            if not (v in d.values if d.kind == "categorical" else d.values[0] <= v <= d.values[1]):
                return False
        return True


def search_space(spec: SweepSpec) -> SearchSpace:
    """The space of a one-class tune file: its axes, and with several ``[[variants]]`` a ``variant``
    dim choosing among the values they fix (module docstring)."""
    if len(spec.classes) != 1:
        raise SweepConfigError("data.class", "a tune optimises one class: run one tune per class", spec.source)
    spaces = [_variant_space(spec, v) for v in spec.variants]
    if len(spaces) == 1:
        return spaces[0]
    first = spaces[0]
    for v, s in zip(spec.variants, spaces):
        if s.dims != first.dims:
            raise SweepConfigError(f"variants.{v.name}", "the variants of a tune must search the same axes "
                                   "(they may differ only in one-valued settings)", spec.source)
    base = baseline_row(spec)
    variants = {v.name: {k: x for k, x in s.fixed.items()
                         if canonical_value(k, x, spec.family) != canonical_value(k, base[k], spec.family)}
                for v, s in zip(spec.variants, spaces)}
    dim = Dim(VARIANT, "categorical", tuple(variants), "variants")
    return SearchSpace(first.dims + (dim,), base, variants, spec.family)


def _variant_space(spec: SweepSpec, variant) -> SearchSpace:
    fixed = baseline_row(spec)
    dims = []
    for a in list(variant.params) + list(variant.options):
        if a.cls:
            raise SweepConfigError(a.key, "per-class axes need several classes; a tune runs one class", spec.source)
        if a.kind in ("uniform", "loguniform", "randint"):
            lo, hi = a.values
            if a.kind == "randint":
                dims.append(Dim(a.name, "int", (int(lo), int(hi) - 1), a.key))
            else:
                dims.append(Dim(a.name, "float" if a.kind == "uniform" else "logfloat", (float(lo), float(hi)), a.key))
        elif len(a.values) == 1:
            fixed[a.name] = a.values[0]
        else:
            dims.append(Dim(a.name, "categorical", tuple(a.values), a.key))
    if not dims:
        raise SweepConfigError("params", "nothing to tune: give [params] distributions or lists", spec.source)
    return SearchSpace(tuple(dims), fixed, family=spec.family)


# ---------------------------------------------------------------------------------------------
# unconstrained coordinates of the continuous dims (gradient refinement)


def to_unconstrained(dim: Dim, x: float) -> float:
    """log for a log-uniform dim, logit of the position in [low, high] for a uniform one."""
    lo, hi = dim.values
    if dim.kind == "logfloat":
        return float(np.log(x))
    u = np.clip((x - lo) / (hi - lo), 1e-6, 1 - 1e-6)
    return float(np.log(u) - np.log1p(-u))


def from_unconstrained(dim: Dim, z: np.ndarray) -> np.ndarray:
    """The inverse of :func:`to_unconstrained` (log dims clipped to their range)."""
    lo, hi = dim.values
    z = np.asarray(z, np.float64)
    if dim.kind == "logfloat":
        return np.clip(np.exp(z), lo, hi)
    return lo + (hi - lo) / (1.0 + np.exp(-z))
