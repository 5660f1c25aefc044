"""Closed-form filters against an independent dense-matrix implementation."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dfrmot_jax.trackers.dfr import filters as kalman

F = np.array([[1, 1, 0.5], [0, 1, 1], [0, 0, 1]], dtype=np.float64)
H = np.array([[1.0, 0.0, 0.0]])


def _dense(cov6):
    a, b, c, d, e, g = cov6
    return np.array([[a, b, c], [b, d, e], [c, e, g]])


def _dense_steady_state(q, r, iters=500):
    """Gains and predicted covariance by a dense Riccati iteration (independent of kalman.steady_cov)."""
    Q = q * kalman.Q_JERK
    P = np.eye(3) * 1e3
    for _ in range(iters):
        K = P[:, 0] / (P[0, 0] + r)
        P = F @ (P - np.outer(K, P[0, :])) @ F.T + Q
    K = P[:, 0] / (P[0, 0] + r)
    return np.array([K[0], K[1], K[2] / 2.0]), P


def _random_state(rng, k=7):
    p, v, a = (rng.normal(0, s, k) for s in (100, 5, 1))
    covs = []
    for _ in range(k):
        m = rng.normal(size=(3, 3))
        P = m @ m.T + 0.1 * np.eye(3)
        covs.append([P[0, 0], P[0, 1], P[0, 2], P[1, 1], P[1, 2], P[2, 2]])
    return kalman.FilterState(jnp.asarray(p), jnp.asarray(v), jnp.asarray(a), jnp.asarray(np.array(covs).T))


@pytest.fixture(autouse=True)
def _x64():
    with jax.enable_x64(True):
        yield


def test_kalman_predict_matches_dense():
    rng = np.random.default_rng(0)
    s = _random_state(rng)
    q = 0.7
    out = kalman.predict(s, "kalman", kf_q=q)
    for i in range(s.p.shape[0]):
        x = np.array([s.p[i], s.v[i], s.a[i]])
        P = _dense(np.asarray(s.cov)[:, i])
        xn = F @ x
        Pn = F @ P @ F.T + q * kalman.Q_JERK
        np.testing.assert_allclose([out.p[i], out.v[i], out.a[i]], xn, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(_dense(np.asarray(out.cov)[:, i]), Pn, rtol=1e-12, atol=1e-9)


def test_kalman_update_matches_dense():
    rng = np.random.default_rng(1)
    s = _random_state(rng)
    z = np.asarray(s.p) + rng.normal(0, 3, s.p.shape[0])
    r = 2.5
    out = kalman.update(s, jnp.asarray(z), "kalman", kf_r=r)
    for i in range(s.p.shape[0]):
        x = np.array([s.p[i], s.v[i], s.a[i]])
        P = _dense(np.asarray(s.cov)[:, i])
        S = H @ P @ H.T + r
        K = P @ H.T / S
        xn = x + (K * (z[i] - H @ x)).ravel()
        Pn = (np.eye(3) - K @ H) @ P
        np.testing.assert_allclose([out.p[i], out.v[i], out.a[i]], xn, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(_dense(np.asarray(out.cov)[:, i]), Pn, rtol=1e-10, atol=1e-9)


def test_fixed_gain_is_the_authors_dt_free_form():
    s = kalman.FilterState(jnp.array([10.0]), jnp.array([1.0]), jnp.array([0.5]), jnp.zeros((0,)))
    u = kalman.update(s, jnp.array([12.0]), "fixed_gain", gains=(0.9, 0.9, 0.1))
    np.testing.assert_allclose([u.p[0], u.v[0], u.a[0]], [10 + 0.9 * 2, 1 + 0.9 * 2, 0.5 + 0.2 * 2])
    pr = kalman.predict(u, "fixed_gain")
    np.testing.assert_allclose([pr.p[0], pr.v[0], pr.a[0]], [u.p[0] + u.v[0] + u.a[0] / 2, u.v[0] + u.a[0], u.a[0]])


@pytest.mark.parametrize("q,r", [(1.0, 1.0), (0.1, 1.0), (10.0, 0.5)])
def test_steady_start_kalman_equals_fixed_gain_on_a_stream(q, r):
    """Born at the steady-state covariance, the Kalman filter is the fixed-gain filter with its gains."""
    gains, P = _dense_steady_state(q, r)
    np.testing.assert_allclose(np.asarray(kalman.steady_cov(q, r)), [P[0, 0], P[0, 1], P[0, 2], P[1, 1], P[1, 2], P[2, 2]],
                               rtol=1e-9)
    mine, P2 = kalman.steady_state(q, r)
    np.testing.assert_allclose(mine, gains, rtol=1e-9)
    np.testing.assert_allclose(P2, P, rtol=1e-9)
    rng = np.random.default_rng(2)
    zs = np.cumsum(rng.normal(3, 1, 200)) + rng.normal(0, 0.5, 200)
    k = kalman.init(jnp.array([zs[0]]), "kalman", cov0=kalman.steady_cov(q, r))
    f = kalman.init(jnp.array([zs[0]]), "fixed_gain")
    for z in zs[1:]:
        k = kalman.predict(kalman.update(k, jnp.array([z]), "kalman", kf_r=r), "kalman", kf_q=q)
        f = kalman.predict(kalman.update(f, jnp.array([z]), "fixed_gain", gains=tuple(gains)), "fixed_gain")
        np.testing.assert_allclose([k.p[0], k.v[0], k.a[0]], [f.p[0], f.v[0], f.a[0]], rtol=1e-9, atol=1e-9)


def test_steady_state_gains_are_a_known_alpha_beta_gamma_family():
    (a, b, g), _ = kalman.steady_state(1.0, 1.0)
    assert 0 < a < 1 and 0 < b < 2 and 0 < g < 1
    (a2, _, _), _ = kalman.steady_state(100.0, 1.0)
    assert a2 > a  # more process noise -> trust measurements more


# ---- distinct noise for the 2D and the 3D corners: tracker == oracle ------------------------------------


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    from dfrmot_jax.data import load_sequences, pack
    from dfrmot_jax.synthetic import make_scene

    root = make_scene(tmp_path_factory.mktemp("scene"), n_sequences=2, n_frames=120, n_cars=6, seed=5)
    seqs = load_sequences(root, "synth2d", "synth3d", "car")
    return seqs, pack(seqs)


def _filtered_corners(ids, src3, box3):
    """{(t, id): 3D filtered corners [6]} of one lane's written rows that carry a 3D filter."""
    t, k = np.nonzero((ids >= 0) & (src3 >= 0))
    return {(int(a), int(ids[a, b])): np.asarray(box3[a, b], np.float64) for a, b in zip(t, k)}


@pytest.mark.slow
@pytest.mark.parametrize("kalman_init", ["diffuse", "steady"])
def test_distinct_3d_noise_tracker_matches_oracle(scene, kalman_init):
    """kf_q3 / kf_r3 drive the 3D corners' filter in both implementations (0 = kf_q / kf_r)."""
    from dfrmot_jax.trackers.dfr.track import track
    from dfrmot_jax.trackers.dfr.config import Options, Params, stack_params
    from dfrmot_jax.testing.parity import lane_mismatches, reference_lane, reference_rows

    seqs, split = scene
    options = Options(filter="kalman", output="filtered", kalman_init=kalman_init)
    lanes = [Params(kf_q=2.0, kf_r=6.0, kf_q3=0.01, kf_r3=0.05, kf_p0=50.0, a_l=3.0),
             Params(kf_q=2.0, kf_r=6.0, kf_p0=50.0, a_l=3.0),
             Params(kf_q=2.0, kf_r=6.0, kf_q3=2.0, kf_r3=6.0, kf_p0=50.0, a_l=3.0),
             Params(kf_q=0.01, kf_r=0.05, kf_q3=2.0, kf_r3=6.0, kf_p0=50.0, a_l=3.0)]
    res = track(split, stack_params(lanes), options, detail=True)
    corners = []
    for b, params in enumerate(lanes):
        ref_rows = reference_rows(seqs, params, options)
        mm = lane_mismatches(split, res, b, ref_rows)
        assert mm["lines"] > 0 and (mm["missing"], mm["extra"], mm["id"], mm["box"]) == (0, 0, 0, 0), (b, mm)
        ref = reference_lane(split, seqs, ref_rows, options)
        got = _filtered_corners(res.ids[b], res.src3[b], res.box3[b])
        want = _filtered_corners(ref.ids, ref.src3, ref.box3)
        assert got.keys() == want.keys() and len(got) > 100
        for key in got:
            np.testing.assert_array_equal(got[key], want[key].astype(np.float32))
        corners.append(got)
    # inheriting (0) equals giving kf_q / kf_r again; the distinct 3D noise changes the 3D filter
    assert np.array_equal(res.ids[1], res.ids[2]) and np.array_equal(res.box3[1], res.box3[2], equal_nan=True)
    common = corners[0].keys() & corners[1].keys()
    assert sum(not np.array_equal(corners[0][k], corners[1][k]) for k in common) > len(common) // 2
