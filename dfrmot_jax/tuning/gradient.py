"""Gradient refinement: stochastic gradient ascent on the smoothed objective E[f(z + sigma eps)].

The metrics are NumPy, not JAX-traceable, so ``optax.perturbations.make_perturbed_fun`` cannot
differentiate them; this is the same Gaussian-smoothing estimator written out, with antithetic
pairs: for eps_k ~ N(0, I), k = 1..K,

    g = 1 / (2 K sigma) * sum_k (f(z + sigma eps_k) - f(z - sigma eps_k)) eps_k,

an unbiased estimate of grad_z E[f(z + sigma eps)] (Stein's identity; the pairs cancel the even
part of f). ``z`` are the unconstrained coordinates of the continuous dims (``tune.space``: log
for log-uniform, logit for bounded), so every sample is a valid config. Each step evaluates the
2K samples and the centre in ONE batched call and moves z with an optax optimiser (adam, cosine
decayed learning rate); refinement stops after ``patience`` steps without a better centre.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
import optax

from .settings import RefineSettings
from .space import Dim, from_unconstrained, to_unconstrained


def antithetic_gradient(f_plus: np.ndarray, f_minus: np.ndarray, eps: np.ndarray, sigma: float) -> np.ndarray:
    """The estimate [D] of grad E[f(z + sigma eps)] from values f(z ± sigma eps_k) [K] and eps [K, D]."""
    f_plus, f_minus, eps = np.asarray(f_plus, np.float64), np.asarray(f_minus, np.float64), np.asarray(eps)
    return ((f_plus - f_minus)[:, None] * eps).sum(0) / (2.0 * len(eps) * sigma)


def antithetic_samples(z: np.ndarray, sigma: float, pairs: int, rng: np.random.Generator):
    """(eps [K, D], points [2K, D]: z + sigma eps_k for every k, then z - sigma eps_k)."""
    eps = rng.standard_normal((pairs, len(z)))
    return eps, np.concatenate([z + sigma * eps, z - sigma * eps])


@dataclass
class Step:
    """One refinement step: the centre's values and objective, the samples' objectives, the estimate."""

    step: int
    centre: dict
    value: float
    samples: np.ndarray
    gradient: np.ndarray


@dataclass
class Refinement:
    best: dict
    best_value: float
    steps: list = field(default_factory=list)


def refine(evaluate: Callable[[Sequence[dict], int], np.ndarray], start: dict, start_value: float,
           dims: Sequence[Dim], settings: RefineSettings, seed: int, maximize: bool = True, log=None) -> Refinement:
    """Refine the continuous ``dims`` of ``start`` (values of every dim of the space).

    ``evaluate(configs, step)``: the objective of each config (dicts of dim values), one batched
    call; ``step`` names the call (its trials' batch). Per step: the centre and ``2 * pairs``
    antithetic samples (``numpy.random.default_rng([seed, step])``), the estimate, an optax adam
    step (learning rate ``settings.learning_rate`` with cosine decay over ``settings.steps``).
    Returns the best centre seen (``start`` if none beat it) and the steps."""
    cont = [d for d in dims if d.continuous]
    if not cont:
        return Refinement(dict(start), float(start_value))
    sign = 1.0 if maximize else -1.0
    z = np.array([to_unconstrained(d, start[d.name]) for d in cont])
    sched = optax.cosine_decay_schedule(settings.learning_rate, max(1, settings.steps))
    opt = optax.adam(sched)
    state = opt.init(z)
    out = Refinement(dict(start), float(start_value))
    stale = 0

    def config(zz):
        c = dict(start)
        c.update({d.name: float(from_unconstrained(d, zz[i])) for i, d in enumerate(cont)})
        return c

    for k in range(settings.steps):
        rng = np.random.default_rng([seed, k])
        eps, pts = antithetic_samples(z, settings.sigma, settings.pairs, rng)
        centre = config(z)
        values = np.asarray(evaluate([centre] + [config(p) for p in pts], k), np.float64)
        f0, fs = values[0], sign * values[1:]
        g = antithetic_gradient(fs[:settings.pairs], fs[settings.pairs:], eps, settings.sigma)
        out.steps.append(Step(k, centre, float(f0), values[1:], g))
        if sign * f0 > sign * out.best_value:
            out.best, out.best_value, stale = centre, float(f0), 0
        elif k > 0:
            stale += 1
        if log is not None:
            log(f"refine step {k}: centre {f0:.4f} (best {out.best_value:.4f}), |g| {np.linalg.norm(g):.3g}")
        if stale >= settings.patience:
            break
        updates, state = opt.update(-g, state, z)          # optax minimises: ascend on the estimate
        z = np.asarray(optax.apply_updates(z, updates), np.float64)
    return out
