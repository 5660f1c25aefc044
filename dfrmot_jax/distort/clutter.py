"""Clutter: false positives written into reserved empty slots, in free space.

Host side :func:`pad_for_clutter` reserves ``DistortSpec.clutter_slots`` empty slots at the end of
each modality's slot axis; in the scan :func:`clutter_2d` / :func:`clutter_3d` switch each one on
with probability ``clutter / clutter_slots`` and fill it with a box drawn from the spec's laws,
placed away from the frame's real detections and the earlier slots' boxes (the package docstring
gives the laws).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..boxes import iou, truncate_2d_box, truncate_3d_box
from ..frames import Frames
from ..geometry import box3d_extent
from .draws import absorb, uniform
from .exact import lin, project_box, widen
from .spec import (
    CAR_DIMS,
    CAR_Y,
    CLUTTER_XZ,
    CLUTTER_Z,
    FREE_DIST,
    FREE_IOU,
    N_QUANTILES,
    DistortSpec,
)

# ---- host side: the reserved slots ------------------------------------------------------------


def pad_slots(x: np.ndarray, n: int, value) -> np.ndarray:
    x = np.asarray(x)
    pad = [(0, 0)] * x.ndim
    pad[1] = (0, n)
    return np.pad(x, pad, constant_values=value)


def pad_for_clutter(frames: Frames, spec: DistortSpec) -> Frames:
    """Host side: ``spec.clutter_slots`` empty (invalid, zero) slots appended to the 2D and 3D slot
    axes of ``Frames [T, M, ...]`` -> ``[T, M + clutter_slots, ...]``. No-op for 0 slots."""
    n = int(spec.clutter_slots)
    if n == 0:
        return frames
    return Frames(
        reset=frames.reset,
        box2=pad_slots(frames.box2, n, 0), score2=pad_slots(frames.score2, n, 0),
        valid2=pad_slots(frames.valid2, n, False),
        box3=pad_slots(frames.box3, n, 0), score3=pad_slots(frames.score3, n, 0),
        valid3=pad_slots(frames.valid3, n, False),
        lo3=pad_slots(frames.lo3, n, 0), hi3=pad_slots(frames.hi3, n, 0),
    )



# ---- device side --------------------------------------------------------------------------------


def _free_iou(a, b, integer: bool):
    """``core.boxes.iou`` (areas clipped at 0) for the 2D free-space test: in float32 for integer
    (truncated) boxes, where every product of pixel sizes < 2^24 is exact already; else widened
    (float64 under x64: exact products, see ``exact.lin``)."""
    return iou(a, b) if integer else iou(widen(a), widen(b))


def ground_xz(lo3, hi3, centroid: str):
    """[..., 2] camera (x, z) of 3D boxes given as internal (lo3, hi3) in the ``centroid`` convention."""
    if centroid == "legacy":
        return jnp.stack([lo3[..., 2], lo3[..., 0]], -1)
    if centroid == "head":
        return jnp.stack([-lo3[..., 1], lo3[..., 0]], -1)
    return 0.5 * jnp.stack([lo3[..., 0] + hi3[..., 0], lo3[..., 2] + hi3[..., 2]], -1)


def _quantile_fn(u, q):
    """Piecewise-linear quantile function through the 17 quantiles ``q`` (at 0, 1/16, ..., 1) at
    u in [0, 1): q[i] + f (q[i+1] - q[i]) with x = 16 u = i + f; the two knots are selected by
    one-hot sums (exact, no gather)."""
    q = np.asarray(q, np.float32)
    x = u * jnp.float32(N_QUANTILES - 1)
    i = jnp.clip(jnp.floor(x), 0.0, N_QUANTILES - 2.0)
    f = x - i
    hot = i[..., None] == jnp.arange(N_QUANTILES - 1, dtype=jnp.float32)
    lo = jnp.sum(jnp.where(hot, jnp.asarray(q[:-1]), 0.0), axis=-1)
    step = jnp.sum(jnp.where(hot, jnp.asarray(np.diff(q)), 0.0), axis=-1)
    return lin(lo, (f, step))


def _dist(a, b):
    """Euclidean distance over the last axis (size 2) of float32 points (wide)."""
    d = widen(a) - widen(b)
    return jnp.sqrt(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1])


def _first(mask):
    """One-hot of the first True along the last axis (all False when none), by a plain
    min-reduction (jnp.argmax's two-operand reduction compiles slowly on CPU)."""
    k = jnp.arange(mask.shape[-1], dtype=jnp.int32)
    first = jnp.min(jnp.where(mask, k, mask.shape[-1]), axis=-1, keepdims=True)
    return k == first


def _place(conf_real, conf_pair, is_free, neutral):
    """Candidate of each clutter slot, slot after slot: the first free one, else the least in conflict.

    conf_real [S, K]: conflict of each candidate with the frame's real detections (max over them);
    conf_pair [S, K, S, K]: conflict between candidates of two slots; is_free(conflict) -> bool;
    neutral: conflict with nothing. Every earlier slot's choice counts as occupied whether or not
    that slot is switched on, so a slot's box does not depend on the clutter level (boxes are
    nested across levels like the on/off draws). Returns one-hot [S, K]; a fori_loop over slots.
    """
    S, K = conf_real.shape
    slots = jnp.arange(S)

    def body(j, hot):
        earlier = (slots < j)[:, None] & hot                                          # [S, K] placed
        pair = jnp.sum(jnp.where(slots[:, None, None, None] == j, conf_pair, 0.0), axis=0)   # [K, S, K] row j
        conf = jnp.sum(jnp.where(slots[:, None] == j, conf_real, 0.0), axis=0)         # [K]
        conf = jnp.maximum(conf, jnp.max(jnp.where(earlier[None], pair, neutral), axis=(1, 2)))
        free = is_free(conf)
        row = jnp.where(jnp.any(free), _first(free), _first(conf == jnp.min(conf)))
        return jnp.where((slots == j)[:, None], row[None, :], hot)

    return jax.lax.fori_loop(0, S, body, jnp.zeros((S, K), bool))


def _pick(cand, hot):
    """cand [S, K, ...], hot [S, K] one-hot -> [S, ...] (a masked sum: no gather)."""
    mask = hot.reshape(hot.shape + (1,) * (cand.ndim - 2))
    return jnp.sum(jnp.where(mask, cand, 0), axis=1).astype(cand.dtype)


# ---- the per-frame distortion -----------------------------------------------------------------


def _fill_tail(x, put, new):
    """x [M, ...] with its last S rows replaced by new [S, ...] where put [S] (no scatter)."""
    S = put.shape[0]
    tail = jnp.where(put.reshape((S,) + (1,) * (x.ndim - 1)), new.astype(x.dtype), x[x.shape[0] - S:])
    return jnp.concatenate([x[:x.shape[0] - S], tail], axis=0)


def clutter_2d(key, box, score, valid, real, rate, spec: DistortSpec, image_size):
    """Fill the last S 2D slots with clutter; ``real`` [M] the slots occupying image space."""
    S, K = int(spec.clutter_slots), int(spec.clutter_tries)
    W, H = float(image_size[0]), float(image_size[1])
    on = uniform(absorb(key, 0), (S,)) < rate / S
    u = uniform(absorb(key, 1), (S, K, 4))
    w = jnp.minimum(_quantile_fn(u[..., 0], spec.width2_q), W - 1.0)
    h = jnp.minimum(lin((w, _quantile_fn(u[..., 1], spec.aspect2_q))), H - 1.0)
    gap_w, gap_h = (W - 1.0) - w, (H - 1.0) - h
    cand = jnp.stack([lin((u[..., 2], gap_w)), lin((u[..., 3], gap_h)),
                      lin((u[..., 2], gap_w), w), lin((u[..., 3], gap_h), h)], -1)   # [S, K, 4]
    if spec.truncate:
        cand = truncate_2d_box(cand)
    sc = _quantile_fn(uniform(absorb(key, 2), (S,)), spec.score2_q)
    put = on & ~valid[valid.shape[0] - S:]
    integer = bool(spec.truncate)
    over_real = jnp.max(jnp.where(real, _free_iou(cand[:, :, None, :], box[None, None, :, :], integer), 0.0), -1)  # [S, K]
    over_pair = _free_iou(cand[:, :, None, None, :], cand[None, None, :, :, :], integer)                  # [S, K, S, K]
    hot = _place(over_real, over_pair, lambda c: c < FREE_IOU, 0.0)                             # [S, K]
    return (_fill_tail(box, put, _pick(cand, hot)), _fill_tail(score, put, sc),
            valid | _fill_tail(jnp.zeros_like(valid), put, put))


class Placement3D(NamedTuple):
    """Where a frame's 3D false positives stand (:func:`place_3d`), before any box convention: per
    reserved slot ``put`` [S] (switched on and empty), ``hot`` [S, K] the chosen candidate (one-hot),
    and per candidate ``loc`` [S, K, 3] (x, ``CAR_Y``, z; camera axes, bottom centre), ``rot`` [S, K]
    heading, ``box`` [S, K, 4] image box (truncated with ``spec.truncate``); ``score`` [S]. Every
    box is ``CAR_DIMS`` (h, w, l)."""

    put: jnp.ndarray
    hot: jnp.ndarray
    loc: jnp.ndarray
    rot: jnp.ndarray
    box: jnp.ndarray
    score: jnp.ndarray

    def pose(self) -> jnp.ndarray:
        """[S, 4] float32 x, y, z, heading of each slot's chosen candidate."""
        return jnp.concatenate([_pick(self.loc, self.hot), _pick(self.rot[..., None], self.hot)], axis=-1)


def place_3d(key, valid, lo3, hi3, real, rate, spec: DistortSpec, image_size) -> Placement3D:
    """The placement of the 3D false positives of the last S slots (the package docstring's law):
    ``valid`` [M] the slots holding a detection now, ``lo3`` / ``hi3`` [M, 3] the boxes in the
    ``spec.centroid`` convention (only their ground-plane position is read), ``real`` [M] the slots
    occupying space. Shared by every family: DFR-FastMOT's slots take :func:`clutter_3d`'s corners,
    AB3DMOT's the rotated box (``Placement3D.pose``)."""
    S, K = int(spec.clutter_slots), int(spec.clutter_tries)
    on = uniform(absorb(key, 0), (S,)) < rate / S
    u = uniform(absorb(key, 1), (S, K, 3))
    z = lin(CLUTTER_Z[0], (u[..., 0], CLUTTER_Z[1] - CLUTTER_Z[0]))
    x = lin((z, lin((2.0 * u[..., 1] - 1.0, CLUTTER_XZ))))
    rot = (2.0 * u[..., 2] - 1.0) * np.float32(math.pi)
    loc = jnp.stack([x, jnp.full_like(x, CAR_Y), z], -1)                 # [S, K, 3]
    dims = jnp.broadcast_to(jnp.asarray(CAR_DIMS, jnp.float32), loc.shape)
    c_box = project_box(dims, loc, rot, spec.p2, image_size)
    if spec.truncate:
        c_box = truncate_3d_box(c_box)
    sc = _quantile_fn(uniform(absorb(key, 2), (S,)), spec.score3_q)
    put = on & ~valid[valid.shape[0] - S:]
    xz = ground_xz(lo3, hi3, spec.centroid)                               # [M, 2]
    c_xz = jnp.stack([x, z], -1)                                          # [S, K, 2]
    # conflict = minus the ground-plane distance (higher = worse), free when the distance >= FREE_DIST
    near_real = jnp.max(jnp.where(real, -_dist(c_xz[:, :, None, :], xz[None, None, :, :]), -jnp.inf), axis=-1)
    near_pair = -_dist(c_xz[:, :, None, None, :], c_xz[None, None, :, :, :])                      # [S, K, S, K]
    hot = _place(near_real, near_pair, lambda c: c <= -FREE_DIST, -jnp.inf)
    return Placement3D(put, hot, loc, rot, c_box, sc)


def clutter_3d(key, box, score, valid, lo3, hi3, real, rate, spec: DistortSpec, image_size, pose: bool = False):
    """Fill the last S 3D slots with clutter (:func:`place_3d`), their ``lo3/hi3`` the corners of
    ``geometry.box3d_extent`` for ``spec.centroid``; ``real`` [M] the slots occupying space. With
    ``pose`` also the slots' [S, 4] x, y, z, heading (``Placement3D.pose``)."""
    p = place_3d(key, valid, lo3, hi3, real, rate, spec, image_size)
    put, hot = p.put, p.hot
    dims = jnp.broadcast_to(jnp.asarray(CAR_DIMS, jnp.float32), p.loc.shape)
    c_lo, c_hi = box3d_extent(dims, p.loc, spec.centroid)
    out = (_fill_tail(box, put, _pick(p.box, hot)), _fill_tail(score, put, p.score),
           valid | _fill_tail(jnp.zeros_like(valid), put, put),
           _fill_tail(lo3, put, _pick(c_lo, hot)), _fill_tail(hi3, put, _pick(c_hi, hot)))
    return out + (p.pose(),) if pose else out
