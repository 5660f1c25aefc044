"""Kalman noise by maximum likelihood: the tracker's ``kf_q`` and ``kf_r`` fitted to ground-truth tracks.

Every coordinate of a labelled track (``label_02``) is one scalar series: the four 2D corners
(pixels) and the six 3D corners of the tracker's default box convention (``Options().centroid``,
metres). The model is the tracker's own constant-acceleration Kalman filter (``core.filters``,
dt = 1 frame), run as the tracker runs it on a track:

* birth at the track's first labelled frame: p = z, v = a = 0, covariance diag(kf_r, kf_p0, kf_p0)
  ("diffuse") or the steady-state covariance of (kf_q, kf_r) ("steady"), and no prediction in
  that frame;
* every later frame: update when labelled (the innovation z - p, variance P00 + kf_r, enters the
  likelihood), then predict one frame. An unlabelled frame inside the track (a gap) only predicts,
  as the tracker does for an unmatched track.

The fit maximises the mean innovation log-likelihood over (log kf_q, log kf_r) with optax's L-BFGS,
in float64, separately for the 2D and the 3D corners of one class. Ground-truth boxes are not
detections: the fitted kf_r is the labels' own jitter, not a detector's error.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax

from .config import Options, Params
from . import filters
from ...data import CLASS_NAMES
from ...geometry import box3d_extent
from ...io.kitti import KittiFormatError, line_of_row, read_tracking_labels

GROUPS = ("2d", "3d")


class Series(NamedTuple):
    """Scalar coordinate series, one per (track, coordinate), padded to the longest track span.

    z [S, T] float64 the labelled value (0 where unlabelled); mask [S, T] bool labelled.
    Column 0 is each track's first labelled frame (mask[:, 0] is True); columns past a track's
    last labelled frame are padding (mask False), which adds nothing to the likelihood.
    """

    z: np.ndarray
    mask: np.ndarray


def _label_paths(root, sequences) -> list[Path]:
    label_dir = Path(root) / "label_02"
    if sequences is None:
        paths = sorted(label_dir.glob("*.txt"))
    else:
        paths = [label_dir / f"{int(s):04d}.txt" if str(s).isdigit() else label_dir / f"{s}.txt" for s in sequences]
    if not paths:
        raise KittiFormatError(str(label_dir), None, None, "no label files (label_02/*.txt)")
    return paths


def _track_series(path: Path, cls: str, centroid: str) -> dict[str, list[tuple[np.ndarray, np.ndarray]]]:
    """{group: [(frames [n] int, values [n, C]) per track]} of one label file, frames ascending."""
    labels = read_tracking_labels(path)
    rows = np.flatnonzero(labels.type == CLASS_NAMES[cls])
    lo, hi = box3d_extent(labels.dims[rows], labels.loc[rows], centroid)
    values = {"2d": labels.box[rows], "3d": np.concatenate([lo, hi], axis=1).astype(np.float64)}
    out: dict[str, list] = {g: [] for g in GROUPS}
    for tid in np.unique(labels.track_id[rows]):
        sel = np.flatnonzero(labels.track_id[rows] == tid)
        sel = sel[np.argsort(labels.frame[rows][sel], kind="stable")]
        frames = labels.frame[rows][sel]
        twice = np.flatnonzero(np.diff(frames) == 0)
        if twice.size:
            row = int(rows[sel[twice[0] + 1]])
            raise KittiFormatError(str(path), line_of_row(path, row), "track_id",
                                   f"track {int(tid)} of class {CLASS_NAMES[cls]} is labelled twice in frame "
                                   f"{int(frames[twice[0]])}")
        for g in GROUPS:
            out[g].append((frames, values[g][sel]))
    return out


def gather_series(root, cls: str = "car", sequences=None, centroid: str | None = None) -> dict[str, Series]:
    """The class's labelled tracks of ``root/label_02`` as coordinate series: {"2d": Series (4 per
    track, x1 y1 x2 y2, pixels), "3d": Series (6 per track, the tracker's min and max 3D corners,
    metres)}. Tracks labelled in a single frame give no innovation and are left out.

    sequences: names ("0001") or ints, default every label file; centroid: the 3D box convention
    (default ``Options().centroid``, the tracker's default).
    """
    if cls not in CLASS_NAMES:
        raise ValueError(f"unknown class {cls!r}: expected one of {list(CLASS_NAMES)}")
    centroid = Options().centroid if centroid is None else centroid
    tracks: dict[str, list] = {g: [] for g in GROUPS}
    for path in _label_paths(root, sequences):
        for g, items in _track_series(path, cls, centroid).items():
            tracks[g].extend(item for item in items if len(item[0]) > 1)
    out = {}
    for g in GROUPS:
        span = max((int(f[-1] - f[0]) + 1 for f, _ in tracks[g]), default=1)
        n_coords = 4 if g == "2d" else 6
        z = np.zeros((len(tracks[g]), n_coords, span))
        mask = np.zeros((len(tracks[g]), n_coords, span), bool)
        for i, (frames, vals) in enumerate(tracks[g]):
            z[i][:, frames - frames[0]] = vals.T
            mask[i][:, frames - frames[0]] = True
        out[g] = Series(z.reshape(-1, span), mask.reshape(-1, span))
    return out


def series_loglik(z, mask, kf_q, kf_r, kf_p0=100.0, kalman_init: str = "diffuse"):
    """Innovation log-likelihood [] of one series z [T], mask [T] (mask[0] True: the birth) under the
    tracker's filter with (kf_q, kf_r, kf_p0) and its ``kalman_init``; a ``lax.scan`` over T - 1 frames."""
    cov0 = filters.steady_cov(kf_q, kf_r) if kalman_init == "steady" else None
    s0 = filters.init(z[:1], "kalman", kf_r, kf_p0, cov0)

    def frame(s, zm):
        zt, seen = zm
        var = s.cov[0] + kf_r
        ll = -0.5 * (jnp.log(2 * jnp.pi * var) + (zt - s.p) ** 2 / var)
        s = filters.select(seen, filters.update(s, zt, "kalman", kf_r=kf_r), s)
        return filters.predict(s, "kalman", kf_q), jnp.where(seen, ll[0], 0.0)

    _, ll = jax.lax.scan(frame, s0, (z[1:, None], mask[1:, None]))
    return jnp.sum(ll)


#: log-likelihood [S] of many series z [S, T], mask [S, T] under one (kf_q, kf_r, kf_p0)
loglik = jax.vmap(series_loglik, in_axes=(0, 0, None, None, None, None))


def mean_nll(log_qr, z, mask, kf_p0=100.0, kalman_init: str = "diffuse"):
    """Negative mean log-likelihood per innovation [] at (log kf_q, log kf_r) = log_qr [2]."""
    q, r = jnp.exp(log_qr[0]), jnp.exp(log_qr[1])
    n = jnp.sum(mask[:, 1:])
    return -jnp.sum(loglik(z, mask, q, r, kf_p0, kalman_init)) / n


class Fit(NamedTuple):
    """One fit: kf_q, kf_r; loglik the mean log-likelihood per innovation; n_series, n_innovations;
    iterations run; grad_norm at the end (in log kf_q, log kf_r)."""

    kf_q: float
    kf_r: float
    loglik: float
    n_series: int
    n_innovations: int
    iterations: int
    grad_norm: float


def fit_series(series: Series, kf_p0: float = 100.0, kalman_init: str = "diffuse", start=(1.0, 1.0),
               max_iter: int = 200, tol: float = 1e-9) -> Fit:
    """Maximum-likelihood (kf_q, kf_r) of ``series``: L-BFGS (optax, zoom line search) on
    ``mean_nll`` over (log kf_q, log kf_r) from ``start``, in float64, until the gradient norm is below
    ``tol`` or ``max_iter`` iterations."""
    with jax.enable_x64(True):
        z, mask = jnp.asarray(series.z, jnp.float64), jnp.asarray(series.mask)
        x0 = jnp.log(jnp.asarray(start, jnp.float64))
        x, value, grad, it = _lbfgs(z, mask, jnp.float64(kf_p0), x0, jnp.float64(tol), kalman_init, max_iter)
        q, r = np.exp(np.asarray(x))
        return Fit(float(q), float(r), -float(value), int(series.z.shape[0]), int(np.sum(series.mask[:, 1:])),
                   int(it), float(jnp.linalg.norm(grad)))


@functools.partial(jax.jit, static_argnames=("kalman_init", "max_iter"))
def _lbfgs(z, mask, kf_p0, x0, tol, kalman_init: str, max_iter: int):
    """L-BFGS from x0 [2]: (x, value, grad at x, iterations)."""
    def objective(x):
        return mean_nll(x, z, mask, kf_p0, kalman_init)

    opt = optax.lbfgs()
    value_and_grad = optax.value_and_grad_from_state(objective)

    def body(carry):
        x, state, _, it = carry
        value, grad = value_and_grad(x, state=state)
        updates, state = opt.update(grad, state, x, value=value, grad=grad, value_fn=objective)
        return optax.apply_updates(x, updates), state, jnp.linalg.norm(grad), it + 1

    def more(carry):
        _, _, grad_norm, it = carry
        return (it < max_iter) & (grad_norm >= tol)

    x, _, _, it = jax.lax.while_loop(more, body, (x0, opt.init(x0), jnp.asarray(jnp.inf, x0.dtype), 0))
    value, grad = jax.value_and_grad(objective)(x)
    return x, value, grad, it


def fit_kalman_noise(root, cls: str = "car", sequences=None, kalman_init: str = "diffuse",
                     kf_p0: float | None = None) -> dict:
    """Fit (kf_q, kf_r) of the 2D corners and of the 3D corners to the class's ground truth in
    ``root/label_02`` (``sequences``: default all). kf_p0: default ``Params().kf_p0``.

    Returns {"class", "kalman_init", "kf_p0", "2d": Fit as a dict, "3d": Fit as a dict, "params":
    {"kf_q", "kf_r", "kf_q3", "kf_r3"}}: the last ready for ``Params(**...)`` (2D noise in kf_q / kf_r,
    3D noise in kf_q3 / kf_r3).
    """
    kf_p0 = Params().kf_p0 if kf_p0 is None else float(kf_p0)
    series = gather_series(root, cls, sequences)
    fits = {}
    for g in GROUPS:
        if not series[g].z.shape[0]:
            raise ValueError(f"no {CLASS_NAMES[cls]} track of {Path(root) / 'label_02'} is labelled in two frames")
        fits[g] = fit_series(series[g], kf_p0, kalman_init)
    return {"class": cls, "kalman_init": kalman_init, "kf_p0": kf_p0,
            **{g: f._asdict() for g, f in fits.items()},
            "params": {"kf_q": fits["2d"].kf_q, "kf_r": fits["2d"].kf_r,
                       "kf_q3": fits["3d"].kf_q, "kf_r3": fits["3d"].kf_r}}
