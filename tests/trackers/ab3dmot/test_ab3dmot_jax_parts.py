"""The parts of AB3DMOT in JAX (dfrmot_jax.trackers.ab3dmot) against their references, bit for bit: the
emulated fused multiply-add against exact rational arithmetic, the Kalman filter in closed form
against the oracle's filterpy arithmetic, every affinity metric against AB3DMOT's own values (the
oracle's pair fixture) and the oracle on random boxes, the Hungarian port against scipy, the
introsort order against the oracle's NumPy 1.23 argsort, and the batch's blockwise pair loops
against the whole matrix at once. The whole tracker: test_ab3dmot_jax.py."""

from __future__ import annotations

import json
from fractions import Fraction
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment

from dfrmot_jax.trackers.ab3dmot import exact, greedy, hungarian, kalman
from dfrmot_jax.trackers.ab3dmot.affinity import METRICS, affinity
from dfrmot_jax.testing import ab3dmot_geometry as geo
from dfrmot_jax.testing import ab3dmot_oracle as ab

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures" / "ab3dmot_oracle"


def x64(fn):
    """fn jitted, called under x64."""
    jitted = jax.jit(fn)

    def call(*args):
        with jax.enable_x64(True):
            return jax.tree.map(np.asarray, jitted(*args))
    return call


def test_fma_is_correctly_rounded_and_mul_never_fused():
    rng = np.random.default_rng(0)
    a = rng.normal(size=400) * 10.0 ** rng.integers(-6, 6, 400)
    b = rng.normal(size=400) * 10.0 ** rng.integers(-6, 6, 400)
    c = np.concatenate([-(a * b)[:200] * (1 + rng.normal(size=200) * 1e-13), rng.normal(size=200)])   # cancellations
    got = x64(lambda a, b, c, t: exact.fma(a, b, c, exact.runtime_zero(t)))(a, b, c, 5)
    want = [float(Fraction(x) * Fraction(y) + Fraction(z)) for x, y, z in zip(a, b, c)]
    np.testing.assert_array_equal(got, want)
    got = x64(lambda a, b, c, t: exact.mul(a, b, exact.runtime_zero(t)) + c)(a, b, c, 5)
    np.testing.assert_array_equal(got, a * b + c)


def test_kalman_closed_form_is_the_oracles_filter_bit_for_bit():
    """Predict / correct / update cycles of many tracks: the closed form's state and covariance
    blocks equal the oracle's 10x10 filterpy arithmetic exactly."""
    rng = np.random.default_rng(1)
    n = 64
    boxes = np.column_stack([rng.uniform(-20, 20, n), rng.uniform(0, 3, n), rng.uniform(5, 60, n),
                             rng.uniform(-3.9, 3.9, n), rng.uniform(3, 5, n), rng.uniform(1.4, 2, n),
                             rng.uniform(1.3, 1.8, n)])
    tracks = [ab.Track(b, np.zeros(7), 1) for b in boxes]

    def cycle(g, z, t):
        g = kalman.predict(g)
        zero = exact.runtime_zero(t)
        pre, obs = kalman.orientation_correction(g.x[:, 3], z[:, 3], zero)
        g2 = kalman.update(g._replace(x=g.x.at[:, 3].set(pre)), z.at[:, 3].set(obs), zero)
        return g, g2

    step = x64(cycle)
    with jax.enable_x64(True):
        g = jax.tree.map(np.asarray, kalman.birth(jnp.asarray(boxes)))
    for k in range(12):
        z = boxes + rng.normal(0, 0.4, boxes.shape) + np.where(rng.random((n, 1)) < 0.2, [0, 0, 0, np.pi, 0, 0, 0], 0)
        predicted, updated = step(g, z, k + 1)
        for i, t in enumerate(tracks):
            t.predict()
            np.testing.assert_array_equal(predicted.x[i], t.x[:, 0])
            zi = z[i].copy()
            t.x[3, 0], zi[3] = ab.orientation_correction(t.x[3, 0], zi[3])
            t.update(zi)
            np.testing.assert_array_equal(updated.x[i], t.x[:, 0])
            P = t.P
            np.testing.assert_array_equal(updated.a[i], np.diag(P)[:3])
            np.testing.assert_array_equal(updated.b[i], P[[0, 1, 2], [7, 8, 9]])
            np.testing.assert_array_equal(updated.c[i], P[[7, 8, 9], [0, 1, 2]])
            np.testing.assert_array_equal(updated.d[i], np.diag(P)[7:])
            np.testing.assert_array_equal(updated.q[i], np.diag(P)[3:7])
        g = updated


def _geometry_marks(metric):
    return [pytest.mark.slow] if "iou" in metric else []


@pytest.mark.parametrize("metric", [pytest.param(m, marks=_geometry_marks(m)) for m in METRICS])
def test_affinity_is_ab3dmots_float32_value(metric):
    """AB3DMOT's own float32 values of the fixture's 120 pairs (degenerate ones included, where it
    did not raise), and the oracle's on 40 x 30 random boxes (overlapping, turned by pi, pi/2,
    2 pi, equal), with AB3DMOT's raises reported as degenerate."""
    fn = x64(lambda d, t, s, c: affinity(d, t, metric, exact.runtime_zero(c), s))
    pairs = json.loads((FIXTURES / "affinity_pairs.json").read_text())["pairs"]
    det = np.array([p["det"] for p in pairs])
    trk = np.array([p["trk"] for p in pairs])
    s = np.array([p["S_diag"] for p in pairs])
    got, bad, _ = fn(det, trk, s, 3)
    for i, p in enumerate(pairs):
        want = p["affinity"][metric]
        if want is not None:
            assert (got[i, i], bad[i, i]) == (np.float32(want), False), (i, p)
    rng = np.random.default_rng(7)

    def rbox(n):
        return np.column_stack([rng.uniform(-8, 8, n), rng.uniform(0, 3, n), rng.uniform(5, 25, n),
                                rng.uniform(-3.9, 3.9, n),
                                rng.uniform(3, 5, n), rng.uniform(1.4, 2, n), rng.uniform(1.3, 1.8, n)]).round(4)
    det = rbox(40)
    trk = np.concatenate([rbox(18), det[:6] + rng.normal(0, 0.2, (6, 7)) * [1, .1, 1, .2, .1, .05, .05], det[6:12]])
    trk[-6:, 3] += np.pi * np.array([1, 0.5, -0.5, 2, 0, 1])
    s = rng.uniform(1, 20, (len(trk), 7))
    got, bad, _ = fn(det, trk, s, 3)
    for i in range(len(det)):
        for j in range(len(trk)):
            try:
                want = ab.affinity_matrix(det[i:i + 1], trk[j:j + 1], metric, np.linalg.inv(np.diag(s[j]))[None])[0, 0]
                assert (got[i, j], bad[i, j]) == (want, False), (i, j)
            except geo.DegenerateGeometry:
                assert bad[i, j], (i, j)


@pytest.mark.slow
def test_hungarian_is_scipys_on_tied_matrices():
    """Random, small-integer, mostly-zero and constant matrices of every shape up to 10 x 12:
    scipy's pairs exactly (its tie choices)."""
    rng = np.random.default_rng(0)
    n_det, n_trk, count = 10, 12, 800
    mats = np.zeros((count, n_det, n_trk), np.float32)
    ns, ms = rng.integers(0, n_det + 1, count), rng.integers(0, n_trk + 1, count)
    for k in range(count):
        n, m = ns[k], ms[k]
        mats[k, :n, :m] = [rng.normal(size=(n, m)), rng.integers(0, 3, (n, m)) * 0.5,
                           np.where(rng.random((n, m)) < 0.7, 0.0, rng.random((n, m))), np.zeros((n, m))][k % 4]
    got = x64(jax.vmap(hungarian.assign))(mats, ns.astype(np.int32), ms.astype(np.int32))
    for k in range(count):
        want = -np.ones(n_det, int)
        if ns[k] and ms[k]:
            r, c = linear_sum_assignment(-mats[k, :ns[k], :ms[k]])
            want[r] = c
        np.testing.assert_array_equal(got[k], want, err_msg=str(k))


@pytest.mark.slow
def test_introsort_order_and_greedy_are_numpys():
    """The visiting order of tied costs is NumPy 1.23's introsort's (the oracle's numpy_argsort,
    itself checked against NumPy 1.23 records), and greedy takes the oracle's pairs in its order."""
    rng = np.random.default_rng(1)
    size, count = 14 * 20, 600
    vs, cs = np.full((count, size), np.inf, np.float32), rng.integers(0, size + 1, count)
    for k in range(count):
        c = cs[k]
        vs[k, :c] = [rng.integers(0, 3, c), np.where(rng.random(c) < 0.8, 0.0, -rng.random(c)) * rng.choice([-1, 1], c),
                     np.zeros(c), rng.normal(size=c)][k % 4]
    order, heap = x64(jax.vmap(lambda v, c: greedy.introsort_order(v, c, jnp.bool_(True))))(vs, cs.astype(np.int32))
    assert not heap.any()
    for k in range(count):
        assert order[k, :cs[k]].tolist() == ab.numpy_argsort(vs[k, :cs[k]]), k
    mats = np.zeros((count, 14, 20), np.float32)
    ns, ms = rng.integers(0, 15, count), rng.integers(0, 21, count)
    for k in range(count):
        n, m = ns[k], ms[k]
        mats[k, :n, :m] = [np.where(rng.random((n, m)) < 0.8, 0.0, rng.random((n, m))),
                           rng.integers(0, 3, (n, m)) * 0.5,
                           rng.normal(size=(n, m))][k % 3]
    det_track, key, _ = x64(jax.vmap(greedy.greedy))(mats, ns.astype(np.int32), ms.astype(np.int32))
    for k in range(count):
        n, m = ns[k], ms[k]
        want = ab.greedy_assignment(-mats[k, :n, :m]) if n and m else np.zeros((0, 2), int)
        taken = sorted(np.flatnonzero(det_track[k] >= 0), key=lambda d: key[k][d])
        assert [(d, det_track[k][d]) for d in taken] == [tuple(p) for p in want], k


@pytest.mark.slow
@pytest.mark.parametrize("metric", ["iou_3d", "giou_3d"])
def test_degenerate_pairs_are_reported_where_ab3dmot_raises(metric):
    """A zero-width or zero-size box makes AB3DMOT's qhull raise (the oracle's DegenerateGeometry):
    the pair is reported (``bad``); a NaN box far from everything gives 0 for iou_3d in both (the
    footprints count as apart) and raises for giou_3d (its hull)."""
    cases = [([1.0, 1.5, 20.0, 0.3, 4.0, 0.0, 1.5], [1.2, 1.5, 20.1, 0.3, 4.0, 1.6, 1.5]),
             ([1.0, 1.5, 20.0, 0.3, 0.0, 0.0, 1.5], [1.0, 1.5, 20.0, 0.3, 4.0, 1.6, 1.5]),
             ([np.nan, 1.5, 20.0, 0.3, 4.0, 1.6, 1.5], [1.0, 1.5, 20.0, 0.3, 4.0, 1.6, 1.5])]
    det, trk = np.array([c[0] for c in cases]), np.array([c[1] for c in cases])
    got, bad, _ = x64(lambda d, t, c: affinity(d, t, metric, exact.runtime_zero(c)))(det, trk, 3)
    for i in range(len(cases)):
        try:
            want = ab.affinity_matrix(det[i:i + 1], trk[i:i + 1], metric, None)[0, 0]
            assert (got[i, i], bad[i, i]) == (want, False), i
        except geo.DegenerateGeometry:
            assert bad[i, i], i


@pytest.mark.slow
def test_blockwise_gives_each_pairs_values_whatever_the_block():
    """``batch.blockwise`` (the pooled affinity's loops over blocks of the packed pairs): every
    block size gives the pairs' values (a distance, the apart test, the clip's intersection) of the
    whole matrix at once, bit for bit, 0 / False where the mask is not set; an empty mask runs no
    trip. (The boxes are the programs' arguments, as in a run: XLA folds computations on constants
    with other roundings.)"""
    from dfrmot_jax.trackers.ab3dmot.affinity import distance, pair_apart, pair_intersection
    from dfrmot_jax.trackers.ab3dmot.batch import blockwise
    from dfrmot_jax.trackers.ab3dmot.exact import runtime_zero

    rng = np.random.default_rng(3)
    det, trk = rng.normal(size=(2, 5, 7)) * 1.5, rng.normal(size=(2, 6, 7)) * 1.5
    det[..., 4:] = trk[..., 4:] = 2.0
    mask = rng.random((2, 5, 6)) < 0.5

    def metrics(a, b, m):
        zero = runtime_zero(jnp.sum(m))
        return (distance(a, b, "dist_3d", zero), pair_apart(a, b, zero), *pair_intersection(a, b, zero))

    whole = x64(lambda m, d, t: metrics(d[:, :, None], t[:, None, :], m))(mask, det, trk)
    want = tuple(np.where(mask, w, np.zeros((), w.dtype)) for w in whole)

    def program(block):
        def lanes(m, d, t):
            def values(sel):
                sel = jnp.minimum(sel, m.size - 1)
                lane, i, j = sel // 30, (sel // 6) % 5, sel % 6
                return metrics(d[lane, i], t[lane, j], m)
            return blockwise(m, block, values)
        return x64(lanes)

    assert np.sum(want[2] > 0) >= 5                     # (footprints that overlap: clipped)
    for block in (1, 8, 64):
        run = program(block)
        got = run(mask, det, trk)
        assert all(g.dtype == w.dtype and np.array_equal(g, w) for g, w in zip(got, want)), block
    assert not any(np.any(g) for g in run(np.zeros_like(mask), det, trk))
