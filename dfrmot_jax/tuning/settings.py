"""The tune file: a sweep file (``[data]``, ``[baseline]``, ``[params]``, ``[options]``) plus a
``[tune]`` table, parsed into a :class:`~dfrmot_jax.sweep.SweepSpec` and a :class:`TuneSettings`.

``[tune]`` keys (every one optional)::

    sampler    = "tpe"          # tpe | cmaes | gp | pairwise | nsga2 | random | grid
    budget     = 256            # evaluated configs (trials), the baseline included
    batch      = 128            # configs per ask: one vmapped track + score call
    objectives = ["HOTA"]       # or ["HOTA", "IDSW"]: directions from the metric (IDSW, FP... minimised)
    folds      = 5              # nested cross-validation over sequences (omit: in-sample only)
    seed       = 0
    [tune.refine]               # gradient refinement of the continuous parameters from the best trial
    steps = 8, pairs = 8, sigma = 0.15, learning_rate = 0.1, patience = 3
    [tune.transfer]             # the chosen config applied unchanged to other detections, beside
    det3d = "pointgnn"          # their own baseline (the file's baseline with these parameters)
    baseline = {a_l = 4.0}
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

from ..choices import SAMPLERS
from ..trackers.protocol import FamilyConfig
from ..trackers.registry import family_config
from ..metrics.columns import canonical_objective
from ..report.analysis import MINIMISE
from ..checks import Table, is_number, type_name
from ..sweep.spec import SweepConfigError, SweepSpec, parse_family, parse_spec, read_toml

TUNE_KEYS = ("sampler", "budget", "batch", "objectives", "folds", "seed", "refine", "transfer")
TRANSFER_KEYS = ("det2d", "det3d", "baseline")
REFINE_KEYS = ("steps", "pairs", "sigma", "learning_rate", "patience")
#: the most configs a tune evaluates unless ``budget`` says otherwise (and at most this many per ask)
DEFAULT_BUDGET, DEFAULT_BATCH = 256, 128


@dataclass(frozen=True)
class RefineSettings:
    """Gradient refinement (:mod:`dfrmot_jax.tuning.gradient`): ``steps`` optax steps at most, each
    from ONE batched call of ``2 * pairs`` antithetic samples (+ the centre), perturbation scale
    ``sigma`` in the unconstrained coordinates, adam with ``learning_rate`` (cosine decay), stop
    after ``patience`` steps without a better centre."""
    steps: int = 8
    pairs: int = 8
    sigma: float = 0.15
    learning_rate: float = 0.1
    patience: int = 3


@dataclass(frozen=True)
class TransferSettings:
    """Other detections to score the chosen config on (``det2d`` / ``det3d``: None = the tune's),
    beside the baseline with ``baseline`` parameter values (e.g. PointGNN's a_l = 4)."""
    det2d: str | None = None
    det3d: str | None = None
    baseline: tuple = ()


@dataclass(frozen=True)
class TuneSettings:
    sampler: str = "tpe"
    budget: int = DEFAULT_BUDGET
    batch: int = DEFAULT_BATCH
    objectives: tuple[str, ...] = ("HOTA",)
    folds: int | None = None
    seed: int = 0
    refine: RefineSettings | None = None
    transfer: TransferSettings | None = None

    @property
    def directions(self) -> tuple[str, ...]:
        return tuple("minimize" if o in MINIMISE else "maximize" for o in self.objectives)

    def identity(self) -> dict:
        """What makes a tune directory this tune's: the search itself (sampler, batch, objectives,
        seed). ``budget`` may grow (a rerun adds batches), ``refine`` and ``folds`` add to the same
        search, so they are not part of it."""
        return {"sampler": self.sampler, "batch": self.batch, "objectives": list(self.objectives), "seed": self.seed}


def _float(t: Table, key: str, default) -> float:
    v = t.get(key, default)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not v > 0 or not math.isfinite(v):
        raise t.error(key, f"{v!r}: expected a number > 0")
    return float(v)


def parse_tune(doc: Mapping | None, source: str | None = None, family: FamilyConfig | None = None) -> TuneSettings:
    """Validate a ``[tune]`` table; raises :class:`SweepConfigError` naming the full key."""
    t = Table({} if doc is None else doc, "tune", source, TUNE_KEYS)
    sampler = t.choice("sampler", "tpe", SAMPLERS)
    budget = t.integer("budget", DEFAULT_BUDGET, minimum=2)
    batch = t.integer("batch", min(DEFAULT_BATCH, budget))
    objs = t.get("objectives", ["HOTA"])
    objs = [objs] if isinstance(objs, str) else objs
    if not isinstance(objs, list) or not 1 <= len(objs) <= 2 or not all(isinstance(o, str) for o in objs):
        raise t.error("objectives", f"{objs!r}: expected one or two metric names, e.g. [\"HOTA\"] or "
                                    f"[\"HOTA\", \"IDSW\"]")
    try:
        objectives = tuple(canonical_objective(o) for o in objs)
    except ValueError as e:
        raise t.error("objectives", str(e).removeprefix("objective ")) from None
    if len(set(objectives)) != len(objectives):
        raise t.error("objectives", "an objective is listed twice")
    folds = t.integer("folds", None, minimum=2)
    seed = t.integer("seed", 0, minimum=0)
    refine = None
    if "refine" in t:
        if t.get("refine") is True:
            r = Table({}, "tune.refine", source)
        elif isinstance(t.get("refine"), Mapping):
            r = t.table("refine", REFINE_KEYS)
        else:
            raise t.error("refine", f"{t.get('refine')!r}: expected a table (or true)")
        if len(objectives) > 1:
            raise t.error("refine", "gradient refinement needs one objective")
        d = RefineSettings()
        refine = RefineSettings(steps=r.integer("steps", d.steps), pairs=r.integer("pairs", d.pairs),
                                sigma=_float(r, "sigma", d.sigma),
                                learning_rate=_float(r, "learning_rate", d.learning_rate),
                                patience=r.integer("patience", d.patience))
    return TuneSettings(sampler, budget, batch, objectives, folds, seed, refine,
                        _parse_transfer(t.get("transfer"), source, family or family_config()))


def _parse_transfer(doc, source, fc: FamilyConfig) -> TransferSettings | None:
    if doc is None:
        return None
    t = Table(doc, "tune.transfer", source, TRANSFER_KEYS)
    for k in ("det2d", "det3d"):
        t.string(k, None)
    if "det2d" not in t and "det3d" not in t:
        raise SweepConfigError("tune.transfer", "name the other detections: det2d and / or det3d", source)
    base = t.table("baseline")
    for k, v in base.doc.items():
        problem = "unknown parameter" if k not in fc.Params._fields else \
            fc.param_problem(k, v) if is_number(v) else f"not a number ({type_name(v)})"
        if problem:
            raise base.error(k, f"{v!r}: {problem}")
    return TransferSettings(t.get("det2d"), t.get("det3d"), tuple(sorted(base.doc.items())))


def parse_tune_file(doc: Mapping, source: str | None = None) -> tuple[SweepSpec, TuneSettings]:
    """A tune document (the parsed TOML) -> (its sweep part, its ``[tune]`` settings)."""
    if not isinstance(doc, Mapping):
        raise SweepConfigError("(file)", "expected a table", source)
    rest = {k: v for k, v in doc.items() if k != "tune"}
    tune = parse_tune(doc.get("tune"), source, family_config(parse_family(rest, source)))
    if "distortion" in rest:
        raise SweepConfigError("distortion", "tuning under distortion is not supported: tune on clean data, "
                                             "then sweep the chosen setting with [distortion]", source)
    return parse_spec(rest, source=source), tune


def load_tune(path) -> tuple[SweepSpec, TuneSettings]:
    """Read and validate a tune file (a sweep file with a ``[tune]`` table)."""
    return parse_tune_file(read_toml(path, "tune file"), source=str(path))
