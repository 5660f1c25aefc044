"""Greedy assignment by mutual-best rounds equals the sequential greedy scan, ties included."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dfrmot_jax.trackers.dfr import associate
from dfrmot_jax import boxes
from dfrmot_jax.testing import reference


@pytest.fixture(autouse=True)
def _x64():
    """The tracker runs under x64 (float64 arithmetic, int64 order keys); so do these tests."""
    with jax.enable_x64(True):
        yield


greedy_min = jax.jit(associate.greedy_min)
greedy_max = jax.jit(associate.greedy_max)


def _sequential(cost, valid, keys, limit):
    c = np.where(valid, cost, np.inf)
    return reference.greedy_match(c, list(keys), limit)


@st.composite
def _problems(draw):
    n = draw(st.integers(0, 7)); m = draw(st.integers(0, 7))
    levels = draw(st.integers(1, 5))  # few distinct values -> many ties
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    cost = np.ones((8, 8))
    valid = np.zeros((8, 8), bool)
    cost[:n, :m] = rng.integers(0, levels, (n, m)) / levels
    valid[:n, :m] = rng.random((n, m)) < 0.8
    keys = rng.permutation(24)[:8]
    return cost, valid, keys  # padded to 8 x 8 (one compilation); padding is invalid


@settings(max_examples=150, deadline=None)
@given(_problems())
def test_greedy_min_equals_sequential(problem):
    cost, valid, keys = problem
    limit = 0.9
    got = np.asarray(greedy_min(jnp.asarray(cost), jnp.asarray(valid), jnp.asarray(keys, jnp.int32), limit))
    want = np.zeros_like(got)
    for i, j in _sequential(cost, valid, keys, limit):
        want[i, j] = True
    np.testing.assert_array_equal(got, want)


def _row_major_max(score, valid, thr):
    s = np.where(valid, score, -np.inf).astype(float)
    out = np.zeros(s.shape, bool)
    while s.size:
        best, bi, bj = thr, -1, -1
        for i in range(s.shape[0]):
            for j in range(s.shape[1]):
                if s[i, j] > best:
                    best, bi, bj = s[i, j], i, j
        if bi < 0:
            break
        out[bi, bj] = True
        s[bi, :] = -np.inf; s[:, bj] = -np.inf
    return out


@settings(max_examples=150, deadline=None)
@given(_problems())
def test_greedy_max_equals_row_major_scan(problem):
    score, valid, _ = problem
    got = np.asarray(greedy_max(jnp.asarray(score), jnp.asarray(valid), 0.25))
    np.testing.assert_array_equal(got, _row_major_max(score, valid, 0.25))


@pytest.mark.slow
def test_empty_problems():
    for shape in [(0, 3), (3, 0), (0, 0)]:
        got = associate.greedy_min(jnp.zeros(shape), jnp.ones(shape, bool), jnp.arange(shape[1], dtype=jnp.int32), 1.0)
        assert got.shape == shape and not np.any(got)


@pytest.mark.slow
def test_greedy_min_under_vmap_matches_each_lane():
    rng = np.random.default_rng(3)
    cost = rng.integers(0, 3, (5, 6, 8)) / 3
    valid = rng.random((5, 6, 8)) < 0.7
    keys = np.stack([rng.permutation(8) for _ in range(5)]).astype(np.int32)
    batched = jax.vmap(associate.greedy_min, in_axes=(0, 0, 0, None))(cost, valid, keys, 0.9)
    for b in range(5):
        np.testing.assert_array_equal(batched[b], associate.greedy_min(cost[b], valid[b], keys[b], 0.9))


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(*[st.integers(0, 300)] * 4), min_size=4, max_size=4),
       st.lists(st.tuples(*[st.integers(0, 300)] * 4), min_size=4, max_size=4))
def test_iou_matrix_matches_reference(a, b):
    def box(t):
        x1, y1, w, h = t
        return np.array([x1, y1, x1 + w, y1 + h], np.float64)

    A = np.stack([box(t) for t in a]); B = np.stack([box(t) for t in b])
    got = np.asarray(boxes.iou_matrix(jnp.asarray(A), jnp.asarray(B)))
    want = np.array([[reference.iou(x, y) for y in B] for x in A])
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=0)


def test_predicted_boxes_truncate_like_the_code():
    p = jnp.array([[10.7, 20.2, 50.9, 80.99]])
    np.testing.assert_array_equal(boxes.predicted_boxes(p, True), [[10, 20, 50, 80]])
    np.testing.assert_allclose(boxes.predicted_boxes(p, False), [[10.7, 20.2, 50.9, 80.99]], rtol=1e-6)
