"""Kalman noise by maximum likelihood (``tune.kalman_noise``): the scan likelihood against a dense
Gaussian, recovery of known noise from simulated series, gradients, and the label series."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.stats import multivariate_normal

from dfrmot_jax.trackers.dfr.config import Params, validate_params
from dfrmot_jax.io.kitti import KittiFormatError
from dfrmot_jax.synthetic import make_scene
from dfrmot_jax.trackers.dfr import kalman_noise as kn

F = np.array([[1, 1, 0.5], [0, 1, 1], [0, 0, 1]], dtype=np.float64)
Q_JERK = np.array([[1 / 20, 1 / 8, 1 / 6], [1 / 8, 1 / 3, 1 / 2], [1 / 6, 1 / 2, 1.0]])


@pytest.fixture(autouse=True)
def _x64():
    with jax.enable_x64(True):
        yield


def _initial_cov(q, r, p0, kalman_init):
    """The tracker's covariance at a birth: diag(r, p0, p0), or the steady-state predicted covariance
    by a dense Riccati iteration (independent of ``core.filters``)."""
    if kalman_init == "diffuse":
        return np.diag([r, p0, p0])
    P = np.eye(3) * 1e3
    for _ in range(500):
        K = P[:, 0] / (P[0, 0] + r)
        P = F @ (P - np.outer(K, P[0, :])) @ F.T + q * Q_JERK
    return P


def _dense_loglik(z, mask, q, r, p0, kalman_init):
    """log p(z[observed frames > 0] | z[0]) from the whole-trajectory Gaussian of the tracker's model:
    the state at frame 1 is the birth state x ~ N((z[0], 0, 0), P0) (no prediction in the birth frame),
    then s_t = F s_{t-1} + w_t, w_t ~ N(0, q Q_JERK); z_t = s_t[0] + e_t, e_t ~ N(0, r)."""
    P0 = _initial_cov(q, r, p0, kalman_init)
    obs = np.flatnonzero(mask[1:]) + 1
    powers = [np.linalg.matrix_power(F, n)[0] for n in range(len(z))]     # H F^n
    a = np.array([powers[t - 1] for t in obs])                          # [n, 3]: frame t from the birth state
    cov = a @ P0 @ a.T + r * np.eye(len(obs))
    for i, t in enumerate(obs):
        for j, u in enumerate(obs):
            cov[i, j] += q * sum(powers[t - k] @ Q_JERK @ powers[u - k] for k in range(2, min(t, u) + 1))
    mean = a @ np.array([z[0], 0.0, 0.0])
    return multivariate_normal(mean, cov).logpdf(z[obs])


def _random_series(rng, n, t, gap=0.25):
    z = np.cumsum(rng.normal(0, 3, (n, t)), axis=1) + rng.normal(0, 50, (n, 1))
    mask = rng.random((n, t)) > gap
    mask[:, 0] = True
    z[~mask] = 0.0
    return z, mask


@pytest.mark.parametrize("kalman_init", ["diffuse", "steady"])
@pytest.mark.parametrize("q, r, p0", [(0.5, 2.0, 100.0), (3.0, 0.7, 5.0), (0.05, 9.0, 1.0)])
def test_scan_loglik_equals_dense_gaussian(kalman_init, q, r, p0):
    rng = np.random.default_rng(int(q * 100 + r * 10))
    z, mask = _random_series(rng, 6, 18)
    mask[0, 1:4] = False                     # a gap right after the birth
    mask[1, -5:] = False                     # trailing padding
    got = np.asarray(kn.loglik(jnp.asarray(z), jnp.asarray(mask), q, r, p0, kalman_init))
    want = np.array([_dense_loglik(z[i], mask[i], q, r, p0, kalman_init) for i in range(len(z))])
    np.testing.assert_allclose(got, want, rtol=1e-9)


def _simulate(rng, n, t, q, r, p0, kalman_init, gap=0.1):
    """Series drawn from the model the likelihood assumes (see ``_dense_loglik``)."""
    z = np.zeros((n, t))
    z[:, 0] = rng.normal(0, 100, n)
    birth = np.linalg.cholesky(_initial_cov(q, r, p0, kalman_init))
    s = np.stack([z[:, 0], np.zeros(n), np.zeros(n)], axis=1) + rng.normal(size=(n, 3)) @ birth.T
    jerk = np.linalg.cholesky(q * Q_JERK)
    for k in range(1, t):
        if k > 1:
            s = s @ F.T + rng.normal(size=(n, 3)) @ jerk.T
        z[:, k] = s[:, 0] + rng.normal(0, np.sqrt(r), n)
    mask = rng.random((n, t)) > gap
    mask[:, 0] = True
    return kn.Series(np.where(mask, z, 0.0), mask)


@pytest.mark.slow
@pytest.mark.parametrize("kalman_init", ["diffuse", "steady"])
def test_fit_recovers_known_noise(kalman_init):
    q, r, p0 = 0.3, 2.0, 4.0
    series = _simulate(np.random.default_rng(7), 200, 60, q, r, p0, kalman_init)
    fit = kn.fit_series(series, kf_p0=p0, kalman_init=kalman_init, start=(5.0, 0.2))
    assert fit.grad_norm < 1e-6 and fit.iterations < 200
    # Tolerance: the maximum-likelihood estimate is asymptotically normal with covariance the inverse
    # observed information (Hessian of the total negative log-likelihood in log q, log r). With
    # ~10,600 innovations both standard errors are about 3 % or less; 4 standard errors bound the
    # error (a 6e-5 two-sided tail per parameter), and a sloppy fit (wrong model, or an optimiser
    # stopping early) lands outside.
    x = jnp.log(jnp.array([fit.kf_q, fit.kf_r]))
    n = fit.n_innovations
    hess = np.asarray(jax.hessian(kn.mean_nll)(x, jnp.asarray(series.z), jnp.asarray(series.mask), p0, kalman_init))
    se = np.sqrt(np.diag(np.linalg.inv(n * hess)))
    assert np.all(se < 0.05), se
    err = np.log([fit.kf_q / q, fit.kf_r / r])
    assert np.all(np.abs(err) < 4 * se), (fit, se)


@pytest.mark.slow
@pytest.mark.parametrize("kalman_init", ["diffuse", "steady"])
def test_gradient_is_finite(kalman_init):
    z, mask = _random_series(np.random.default_rng(3), 20, 40)
    grad = jax.jit(jax.grad(kn.mean_nll), static_argnums=4)
    for x in [(0.0, 0.0), (-10.0, 10.0), (10.0, -10.0), (-12.0, -12.0)]:
        g = np.asarray(grad(jnp.array(x), jnp.asarray(z), jnp.asarray(mask), 100.0, kalman_init))
        assert np.all(np.isfinite(g)) and np.any(g != 0), (x, g)


LABELS = """\
0 0 Car 0 0 -1.5 100.0 150.0 200.0 220.0 1.5 1.6 4.0 1.0 2.0 10.0 0.1
0 2 Pedestrian 0 0 0.2 300.0 100.0 320.0 160.0 1.7 0.6 0.8 -3.0 1.8 12.0 0.0
0 -1 DontCare -1 -1 -10 500.0 100.0 600.0 150.0 -1 -1 -1 -1000 -1000 -1000 -10
1 0 Car 0 0 -1.5 102.0 151.0 203.0 221.0 1.5 1.6 4.0 1.1 2.0 9.5 0.1
1 2 Pedestrian 0 0 0.2 301.0 101.0 321.0 161.0 1.7 0.6 0.8 -3.0 1.8 11.9 0.0
2 1 Car 0 0 0.3 700.0 180.0 760.0 210.0 1.4 1.7 4.2 5.0 1.7 30.0 0.0
3 0 Car 0 0 -1.5 107.0 153.0 209.0 223.0 1.5 1.6 4.0 1.3 2.0 8.5 0.1
"""


@pytest.fixture
def label_root(tmp_path):
    (tmp_path / "label_02").mkdir()
    (tmp_path / "label_02" / "0003.txt").write_text(LABELS)
    return tmp_path


def test_gather_series_from_labels(label_root):
    s = kn.gather_series(label_root, "car")
    # car track 0 spans frames 0..3, unlabelled in frame 2; track 1 (one frame) gives no innovation
    np.testing.assert_array_equal(s["2d"].mask, np.tile([True, True, False, True], (4, 1)))
    np.testing.assert_array_equal(s["2d"].z, [[100, 102, 0, 107], [150, 151, 0, 153], [200, 203, 0, 209],
                                              [220, 221, 0, 223]])
    # legacy corners: min = (z, y, x), max = min + (l, w, h)
    want3 = [[10, 9.5, 0, 8.5], [2, 2, 0, 2], [1, 1.1, 0, 1.3], [14, 13.5, 0, 12.5], [3.6, 3.6, 0, 3.6],
             [2.5, 2.6, 0, 2.8]]
    np.testing.assert_allclose(s["3d"].z, want3, rtol=1e-6)
    assert s["3d"].mask.shape == (6, 4)
    p = kn.gather_series(label_root, "pedestrian", sequences=[3])
    np.testing.assert_array_equal(p["2d"].z, [[300, 301], [100, 101], [320, 321], [160, 161]])


def test_track_labelled_twice_in_a_frame_is_a_located_error(label_root):
    path = label_root / "label_02" / "0003.txt"
    path.write_text(LABELS + "3 0 Car 0 0 -1.5 108.0 153.0 209.0 223.0 1.5 1.6 4.0 1.3 2.0 8.5 0.1\n")
    with pytest.raises(KittiFormatError, match="labelled twice in frame 3") as e:
        kn.gather_series(label_root, "car")
    assert e.value.line == 8 and e.value.field == "track_id"


@pytest.mark.slow
def test_fit_kalman_noise_gives_tracker_params(tmp_path):
    root = make_scene(tmp_path, n_sequences=1, n_frames=60, n_cars=4, seed=2)
    out = kn.fit_kalman_noise(root, "car")
    assert out["2d"]["n_series"] % 4 == 0 and out["3d"]["n_series"] == out["2d"]["n_series"] // 4 * 6
    for g in ("2d", "3d"):
        assert out[g]["grad_norm"] < 1e-6 and np.isfinite(out[g]["loglik"])
    params = validate_params(Params(**out["params"]))
    assert (params.kf_q, params.kf_r, params.kf_q3, params.kf_r3) == (
        out["2d"]["kf_q"], out["2d"]["kf_r"], out["3d"]["kf_q"], out["3d"]["kf_r"])
