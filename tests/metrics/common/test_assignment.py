"""The compiled assignment (metrics/common/assignment.py) returns scipy's answer, ties included."""

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment as scipy_lsa

from dfrmot_jax.metrics.common.assignment import linear_sum_assignment, solve_many
from dfrmot_jax.metrics.common.pairs import solve_blocks


def _matrices(rng, n, max_side):
    """Random and tie-heavy matrices: uniform floats, small integers (many tied optima), repeated
    rows, repeated columns, constant, sparse positives with TrackEval's +1000 continuation bonus,
    rounded floats; every shape from 1 x 1 to max_side x max_side, tall and wide."""
    for k in range(n):
        nr, nc = (int(x) for x in rng.integers(1, max_side + 1, 2))
        kind = k % 7
        if kind == 0:
            m = rng.random((nr, nc))
        elif kind == 1:
            m = rng.integers(0, 3, (nr, nc)).astype(float)
        elif kind == 2:
            m = np.repeat(rng.integers(0, 4, (1, nc)), nr, 0).astype(float)
        elif kind == 3:
            m = np.repeat(rng.integers(0, 4, (nr, 1)), nc, 1).astype(float)
        elif kind == 4:
            m = np.full((nr, nc), float(rng.integers(-2, 3)) / 4)
        elif kind == 5:
            m = (rng.random((nr, nc)) < 0.4) * (rng.integers(0, 2, (nr, nc)) * 1000 + np.round(rng.random((nr, nc)), 1))
        else:
            m = np.round(rng.random((nr, nc)), 1)
        yield m


@pytest.mark.parametrize("maximize", [False, True])
def test_same_pairs_as_scipy_on_random_and_tied_matrices(maximize):
    rng = np.random.default_rng(7 + maximize)
    mats = list(_matrices(rng, 6000, 8)) + list(_matrices(rng, 300, 30))
    differ = [i for i, m in enumerate(mats)
              if not all(np.array_equal(a, b) for a, b in zip(scipy_lsa(m, maximize=maximize),
                                                                linear_sum_assignment(m, maximize=maximize)))]
    assert differ == []
    # the same blocks in one call
    rows, cols, ps = solve_many(np.concatenate([m.ravel() for m in mats]), [m.shape[0] for m in mats],
                                [m.shape[1] for m in mats], maximize)
    for i in (0, 1, 2, 3, 4, 5, 6, 6299):
        r, c = scipy_lsa(mats[i], maximize=maximize)
        assert np.array_equal(rows[ps[i]:ps[i + 1]], r) and np.array_equal(cols[ps[i]:ps[i + 1]], c)


def test_forbidden_pairs_empty_and_invalid_as_scipy():
    rng = np.random.default_rng(3)
    n_raised = 0
    for _ in range(400):
        m = rng.integers(0, 4, tuple(rng.integers(1, 7, 2))).astype(float)
        m[rng.random(m.shape) < 0.35] = np.inf
        try:
            want = scipy_lsa(m)
        except ValueError:
            n_raised += 1
            with pytest.raises(ValueError, match="infeasible"):
                linear_sum_assignment(m)
            continue
        got = linear_sum_assignment(m)
        assert np.array_equal(want[0], got[0]) and np.array_equal(want[1], got[1])
    assert 0 < n_raised < 400
    for m in (np.zeros((0, 3)), np.zeros((4, 0))):
        assert all(len(x) == 0 for x in linear_sum_assignment(m))
    with pytest.raises(ValueError, match="invalid"):          # refused before any certificate answers
        solve_many(np.array([np.nan, 1.0]), [1], [2], maximize=True, positive_only=True)
    with pytest.raises(ValueError, match="beyond"):           # checked before the compiled code runs
        solve_many(np.ones(5), [2, 2], [2, 1])
    for m in (np.array([[np.nan, 1.0]]), np.array([[-np.inf, 1.0]])):
        with pytest.raises(ValueError, match="invalid"):
            scipy_lsa(m)
        with pytest.raises(ValueError, match="invalid"):
            linear_sum_assignment(m)


def test_solve_blocks_takes_scipys_positive_pairs():
    rng = np.random.default_rng(11)
    mats = [np.abs(m) for m in _matrices(rng, 2000, 6)]
    got = solve_blocks(np.array([m.shape[0] for m in mats]), np.array([m.shape[1] for m in mats]),
                       np.concatenate([m.ravel() for m in mats]))
    want = []
    for m in mats:
        take = np.zeros(m.shape, bool)
        r, c = scipy_lsa(-m)
        take[r, c] = m[r, c] > 0
        want.append(take.ravel())
    assert np.array_equal(got, np.concatenate(want))


def test_certified_blocks_keep_scipys_positive_pairs():
    """positive_only: blocks whose optimum the certificate proves unique skip the solver; the
    positive pairs are scipy's all the same, and near ties (inside the margin) still go to it."""
    rng = np.random.default_rng(5)
    mats = []
    for i in range(3000):
        g, k = (int(x) for x in rng.integers(1, 8, 2))
        m = 0.1 * rng.random((g, k)) * (rng.random((g, k)) < 0.5)
        d = np.arange(min(g, k))
        m[d, d] = 0.5 + 0.5 * rng.random(len(d))
        if i % 3 == 1 and min(g, k) > 1:           # a near tie: the certificate must not decide it
            m[0, 1] = m[0, 0] - 1e-13
        if i % 3 == 2:                             # an empty row and column: a certified answer leaves them -1
            m = np.pad(m, ((0, 1), (0, 1)))
        mats.append(m)
    rows, cols, ps = solve_many(np.concatenate([m.ravel() for m in mats]), [m.shape[0] for m in mats],
                                [m.shape[1] for m in mats], maximize=True, positive_only=True)
    n_certified = 0
    for i, m in enumerate(mats):
        r, c = rows[ps[i]:ps[i + 1]], cols[ps[i]:ps[i + 1]]
        n_certified += bool((r < 0).any())
        keep = r >= 0
        got = {(a, b) for a, b in zip(r[keep], c[keep]) if m[a, b] > 0}
        wr, wc = scipy_lsa(-m)
        assert got == {(a, b) for a, b in zip(wr, wc) if m[a, b] > 0}
    assert n_certified > 300                           # the certificate was taken
    with pytest.raises(ValueError, match="maximize"):
        solve_many(np.ones(1), [1], [1], positive_only=True)


def test_match_block_takes_scipys_pairs_above_the_bound():
    """match_block (a frame's matching, compiled callers): the pairs of scipy's assignment with an entry
    above the bound, on random and tie-heavy blocks (crowded or not; with TrackEval's +1000 bonus) and
    on blocks whose positive entries share no row or column (taken without the solver)."""
    from dfrmot_jax.metrics.common.assignment import match_block, workspace

    rng = np.random.default_rng(21)
    mats = [np.abs(m) for m in _matrices(rng, 1500, 7)]
    for _ in range(300):                               # positives on distinct rows and columns
        nr, nc = (int(x) for x in rng.integers(1, 8, 2))
        m = np.zeros((nr, nc))
        d = rng.permutation(nc)[:min(nr, nc)]
        m[np.arange(len(d)), d] = rng.random(len(d)) * (rng.random(len(d)) < 0.8)
        mats.append(m)
    ws = workspace(7, 49)
    rows, cols = np.empty(7, np.int64), np.empty(7, np.int64)
    for above in (0.0, 2.2e-16, 0.25):
        for m in mats:
            n = match_block(np.ascontiguousarray(m.ravel()), m.shape[0], m.shape[1], above, rows, cols, ws)
            r, c = scipy_lsa(-m)
            want = [(a, b) for a, b in zip(r, c) if m[a, b] > above]
            assert list(zip(rows[:n].tolist(), cols[:n].tolist())) == want, (m, above)
