"""lap.lapjv(extend_cost=True, cost_limit) as lap decides it: the oracle's port and the JAX emulation."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dfrmot_jax.testing import bytetrack_oracle as O
from dfrmot_jax.trackers.bytetrack import lapjv as L

# (cost, limit, lap 0.5.13's x): read off lap itself
LAP_CASES = [
    ([[0.5, 0.5]], 0.75, [0]),
    ([[0.8]], 0.8, [0]),                       # exactly at the limit: matched
    ([[0.5], [0.5]], 0.75, [0, -1]),
    ([[0.1, 0.2], [0.2, 0.1]], 0.5, [0, 1]),
    ([[0.3, 0.3], [0.3, 0.3]], 0.8, [1, 0]),   # tied totals: scipy gives [0, 1]
    ([[0.8, 0.8]], 0.8, [0]),
]


@pytest.mark.parametrize("cost,limit,want", LAP_CASES)
def test_oracle_lapjv_known_cases(cost, limit, want):
    assert O.lapjv(np.array(cost), limit)[0] == want


def test_lapjv_differs_from_scipy_on_tied_totals():
    from scipy.optimize import linear_sum_assignment
    c = np.array([[0.3, 0.3], [0.3, 0.3]])
    assert list(linear_sum_assignment(c)[1]) == [0, 1]
    assert O.lapjv(c, 0.8)[0] == [1, 0]


def _want(c, rm, key, cm, th):
    rows = np.argsort(np.where(rm, key, 1 << 30), kind="stable")[:rm.sum()]
    cols = np.nonzero(cm)[0]
    want = np.full(len(rm), -1)
    if len(rows) and len(cols):
        x, _ = O.lapjv(c[np.ix_(rows, cols)], th)
        for p, q in enumerate(x):
            if q >= 0:
                want[rows[p]] = cols[q]
    return want


def test_jax_assign_equals_lapjv_random_and_ties():
    rng = np.random.default_rng(7)
    k, d = 7, 6
    with jax.enable_x64(True):
        f = jax.jit(jax.vmap(L.assign, in_axes=(0, 0, 0, 0, 0)))
        cs, rms, keys, cms, ths = [], [], [], [], []
        for t in range(256):
            kind = t % 4
            if kind == 0:
                c = rng.uniform(0, 1, (k, d))
            elif kind == 1:
                c = rng.choice([0.1, 0.25, 0.4, 0.5, 0.75, 1.0], (k, d))
            elif kind == 2:
                c = np.round(rng.uniform(0, 1, (k, d)), 1)
            else:
                c = rng.choice([0.3, 0.8, 1.0], (k, d))
            cs.append(c)
            rms.append(rng.random(k) < 0.7)
            keys.append(rng.permutation(k))
            cms.append(rng.random(d) < 0.7)
            ths.append(float(rng.choice([0.5, 0.7, 0.75, 0.8, 0.9])))
        got, _ = f(*(jnp.asarray(np.array(a)) for a in (cs, rms, keys, cms, ths)))
        got = np.asarray(got)
    for i in range(len(cs)):
        np.testing.assert_array_equal(got[i], _want(cs[i], rms[i], keys[i], cms[i], ths[i]), err_msg=str(i))


@pytest.mark.parametrize("cost,limit,want", LAP_CASES)
def test_jax_assign_known_cases(cost, limit, want):
    c = np.array(cost)
    with jax.enable_x64(True):
        got, full = L.assign(jnp.asarray(c), jnp.ones(c.shape[0], bool), jnp.arange(c.shape[0]),
                             jnp.ones(c.shape[1], bool), limit)
    assert np.asarray(got).tolist() == want
