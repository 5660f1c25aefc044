"""The antithetic Gaussian-smoothing gradient estimator and the optax refinement loop."""

import numpy as np
import pytest

from dfrmot_jax.tuning.gradient import antithetic_gradient, antithetic_samples, refine
from dfrmot_jax.tuning.settings import RefineSettings
from dfrmot_jax.tuning.space import Dim, from_unconstrained, to_unconstrained


def _estimate(f, z, sigma, pairs, seed):
    eps, pts = antithetic_samples(z, sigma, pairs, np.random.default_rng(seed))
    vals = np.array([f(p) for p in pts])
    return antithetic_gradient(vals[:pairs], vals[pairs:], eps, sigma)


def test_smoothed_sine_gradient_is_recovered():
    # E[sum sin(z + s eps)] = exp(-s^2/2) sum sin z: its gradient is exp(-s^2/2) cos z (not cos z)
    z = np.array([0.3, -1.2, 2.0])
    sigma = 0.8
    est = _estimate(lambda p: np.sin(p).sum(), z, sigma, 200_000, 0)
    exact = np.exp(-sigma ** 2 / 2) * np.cos(z)
    assert np.allclose(est, exact, atol=6e-3), (est, exact)
    assert not np.allclose(est, np.cos(z), atol=6e-3)       # the smoothing is what is estimated


def test_quadratic_gradient_unbiased_and_exact_in_expectation():
    c = np.array([1.0, -2.0])
    z = np.array([0.0, 0.5])
    ests = np.stack([_estimate(lambda p: -((p - c) ** 2).sum(), z, 0.3, 4, s) for s in range(4000)])
    assert np.allclose(ests.mean(0), -2 * (z - c), atol=0.05)


def test_unconstrained_coordinates_round_trip():
    for dim, x in [(Dim("a_l", "logfloat", (2.0, 12.0), "k"), 5.5), (Dim("a_c", "float", (0.0, 0.3), "k"), 0.07)]:
        assert from_unconstrained(dim, to_unconstrained(dim, x)) == pytest.approx(x, rel=1e-12)
        assert dim.values[0] <= from_unconstrained(dim, 50.0) <= dim.values[1]


def test_refine_climbs_a_smooth_objective():
    dims = (Dim("x", "float", (0.0, 1.0), "params.x"), Dim("c", "categorical", ("a", "b"), "options.c"))
    calls = []

    def evaluate(configs, step):
        calls.append(len(configs))
        return np.array([-(c["x"] - 0.8) ** 2 for c in configs])

    start = {"x": 0.2, "c": "a"}
    out = refine(evaluate, start, -(0.2 - 0.8) ** 2, dims, RefineSettings(steps=30, pairs=4, sigma=0.1,
                                                                        learning_rate=0.3, patience=5), seed=0)
    assert out.best["c"] == "a"
    assert abs(out.best["x"] - 0.8) < 0.1 < abs(start["x"] - 0.8)
    assert set(calls) == {9}                 # each step: the centre + 2 x 4 samples in one call
