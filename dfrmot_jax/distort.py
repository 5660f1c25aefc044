"""Controlled detection failures: pure, jittable distortions of the tracker's per-frame inputs.

The paper's claim is that long-term memory keeps identities through detection failures. This
module simulates failures at controlled levels, for many seeds, *inside* the vmapped batch: the
distortion is applied per frame inside the scanned step, per lane, statelessly from
``(seed, global frame index t)``, so no ``[B, T, ...]`` copy of the split is ever materialised.

Distortions (all keep shapes: they only clear ``valid``, move boxes, change scores, or fill
reserved empty slots), applied in this order to one frame:

1. **Burst occlusions** (``burst_rate``, ``burst_len``): every ground-truth object ``g`` (identity
   of a detection slot from :func:`gt_identity`: 2D IoU >= 0.5 with a ground-truth box) may start
   an occlusion burst at any global frame ``s`` with probability ``burst_rate``; the burst lasts
   ``L_s`` frames (``s .. s+L_s-1``), ``L_s`` drawn from ``DistortSpec.burst_dist`` with mean
   ``burst_len`` and capped at ``DistortSpec.burst_max``. While occluded, *all* detections of the
   object (every 2D and every 3D slot carrying its identity) are removed. Overlapping bursts merge.
   Detections matched to no ground truth (``gid = -1``) are never occluded.
2. **Independent drops** (``drop_2d``, ``drop_3d``): each remaining 2D (3D) detection is removed
   with probability ``drop_2d`` (``drop_3d``), independently per detection, frame and modality.
3. **Box jitter**: ``jitter_2d`` (pixels) is the std of independent Gaussian noise on each corner
   ``x1, y1, x2, y2`` of a 2D detector box; ``jitter_box3`` (pixels) the same for the image box
   of a 3D detection (``Frames.box3``); ``jitter_3d`` (metres) the per-axis std of an isotropic
   Gaussian shift of the 3D box (``lo3`` and ``hi3`` move together; the convention of
   ``Options.centroid`` is a signed permutation of camera axes, so the law is the same in all).
   With ``DistortSpec.truncate`` (``Options.truncate``) the stored boxes are integers, the
   truncated file values: the jittered file value is taken as ``box + 0.5 + noise`` (the centre of
   the truncation cell) and truncated again with the loaders' own formulas
   (``data.truncate_2d_box`` / ``data.truncate_3d_box``), so the integer boxes move by
   ``round(noise)`` (std ``sqrt(sigma^2 + 1/12)`` for ``sigma`` >~ 0.5) and a sub-pixel ``sigma``
   mostly leaves them unchanged. Without truncation the corners move by the noise exactly and are
   re-ordered (``x1 <= x2``, ``y1 <= y2``).
4. **Score noise**: ``score_noise_2d`` / ``score_noise_3d`` are the stds of Gaussian noise added to
   each detection's score, in the detector's own units (RRC 2D scores lie in ``[0, 1]``;
   PointRCNN 3D scores roughly in ``[-1, 16]``, threshold 4). Scores are not clipped.
5. **Clutter** (``clutter_2d``, ``clutter_3d``): expected false positives per frame in each
   modality, written into the ``DistortSpec.clutter_slots`` empty slots reserved at the end of the
   slot axis by :func:`pad_for_clutter`. Each reserved slot is switched on with probability
   ``clutter / clutter_slots`` (so the count is Binomial with mean ``clutter``, saturating at
   ``clutter_slots``); a slot already holding a detection is never overwritten. A 2D false
   positive is a box with the width and aspect distribution of real detections (quantiles in the
   spec) placed uniformly in the image, in free space: the first of ``clutter_tries`` candidates
   whose IoU with every real detection of the frame (and the boxes chosen for the earlier reserved
   slots) is below ``FREE_IOU`` (else the least overlapping). A 3D false positive is a car-sized
   box (``CAR_DIMS``) on the ground (``y = CAR_Y``) at depth ``z ~ U[CLUTTER_Z]`` m, lateral
   ``x = z * U[-CLUTTER_XZ, CLUTTER_XZ]`` (inside the camera's field of view), heading uniform, at
   least ``FREE_DIST`` m (in the ground plane) from every real 3D detection and the earlier slots'
   boxes when a candidate allows; its ``lo3/hi3`` follow ``DistortSpec.centroid`` exactly as ``data.box3d_extent``, its image box is
   its 8 corners projected with ``DistortSpec.p2`` and clipped (then truncated like the loader's).
   Clutter scores follow the quantile function of real scores (``score2_q``, ``score3_q``), so a
   false positive passes the tracker's score threshold about as often as a real detection does.

Randomness is counter-based and stateless: a 32-bit hash chain (``absorb(h, w) = mix(h ^
mix(w + golden))``, ``mix`` the bijective lowbias32 integer hash) of ``(seed, t, stream)`` for the
per-frame streams (``t`` the global frame index of the split, so different sequences differ),
with element ``i`` of a stream drawn from ``mix(h ^ mix(2 i + 1))``, and of ``(seed, BURST_TAG,
g, s)`` for the burst of object ``g`` starting at frame ``s`` (:func:`burst_draw`). It replaces
``jax.random`` keys because a frame needs ``slots x burst_max`` (~1000) burst draws: threefry keys
made the distortion ~10x slower and added seconds to every compile. Object ``g`` is occluded at
``t`` when some ``s in (t - burst_max, t]`` starts a burst (``u0 < burst_rate``) whose length
``L_s`` (from ``u1``) satisfies ``s + L_s > t``. Nothing is carried between frames. All
decisions are monotone in the level for fixed uniforms (``u < p``, ``sigma * n``, inverse-CDF
lengths), so the same seed at different levels gives *nested* distortions (common random numbers:
a drop set at p = 0.1 is a subset of the one at p = 0.2), which lowers the variance of
level-vs-metric curves.

Level 0 (every field 0) returns the frame bit-identical. Ground-truth ids restart per sequence
and bursts are hashed on the global frame index: the occlusion process is stationary, so an
object can enter a sequence already inside a burst.

Reproducibility: under ``jax.enable_x64`` (the tracker's step runs under it, and
:func:`distort_split` / :func:`distort_lanes` enable it) every sum of products is formed from
exact float64 products (:func:`_lin`), so the same ``(seed, t)`` gives the same bits in any
program: in the tracker's scan, in a vmap over frames, in one lane or in a batch (tested).
Without x64 the values can differ by an ulp between programs (XLA's fused multiply-add).

Cost (KITTI car split, 16 lanes, one CPU core, per lane-frame; the tracker step itself ~30 us):
drops ~0.05 us, bursts ~1-2 us, jitter ~4 us, score noise ~0.6 us, clutter (3 slots) ~4-5 us,
everything ~8-14 us. ``DistortSpec.enabled`` compiles only the groups a study uses
(``make_spec(dps=...)``).

Typical use (the lead wires this into the tracker's scan)::

    dps = distort.stack_distort([distort.level_params("drop", p, seed=s) for p in ps for s in seeds])
    spec = distort.make_spec(options, clutter_slots=0, frames=frames, dps=dps)   # checks dps too
    frames = distort.pad_for_clutter(frames, spec)
    gid2, gid3 = distort.pad_identity(*distort.gt_identity(split, root, options), spec)
    # scan xs = (frames, gid2, gid3, arange(T, int32)); per lane, per frame t:
    #     frame = distort.distort_frame(frame, gid2_t, gid3_t, t, dp, spec)   # then tracker.step
"""

from __future__ import annotations

import functools
import math
from pathlib import Path
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .data import DEFAULT_IMAGE_SIZE, Frames, Split, image_box_3d
from .geometry import iou_2d
from .io.kitti import read_tracking_labels
from .config import Options

# ---------------------------------------------------------------------------------------------
# Parameters


class DistortParams(NamedTuple):
    """Dynamic distortion levels, one value per lane (vmappable: float32 leaves, ``seed`` int32).

    drop_2d:        probability that an individual 2D detection is removed (independent).
    drop_3d:        the same for 3D detections.
    burst_rate:     per (ground-truth object, frame): probability that an occlusion burst starts.
    burst_len:      mean burst length in frames (law: ``DistortSpec.burst_dist``); 0 = no bursts.
    jitter_2d:      std (pixels) of Gaussian noise on each corner of a 2D detector box.
    jitter_box3:    std (pixels) of Gaussian noise on each corner of a 3D detection's image box.
    jitter_3d:      per-axis std (metres) of a Gaussian shift of a 3D box (lo3 and hi3 together).
    score_noise_2d: std of Gaussian noise on 2D scores (detector units; RRC: [0, 1]).
    score_noise_3d: std of Gaussian noise on 3D scores (detector units; PointRCNN: ~[-1, 16]).
    clutter_2d:     expected 2D false positives per frame (<= DistortSpec.clutter_slots).
    clutter_3d:     expected 3D false positives per frame (<= DistortSpec.clutter_slots).
    seed:           the lane's seed (int32): root of all its draws (``lane_hash(seed)``).
    """

    drop_2d: Any = 0.0
    drop_3d: Any = 0.0
    burst_rate: Any = 0.0
    burst_len: Any = 0.0
    jitter_2d: Any = 0.0
    jitter_box3: Any = 0.0
    jitter_3d: Any = 0.0
    score_noise_2d: Any = 0.0
    score_noise_3d: Any = 0.0
    clutter_2d: Any = 0.0
    clutter_3d: Any = 0.0
    seed: Any = 0


BURST_DISTS = ("fixed", "geometric", "uniform")

#: Distortion groups and the DistortParams fields that drive them.
GROUPS = {
    "burst": ("burst_rate", "burst_len"),
    "drop": ("drop_2d", "drop_3d"),
    "jitter": ("jitter_2d", "jitter_box3", "jitter_3d"),
    "score": ("score_noise_2d", "score_noise_3d"),
    "clutter": ("clutter_2d", "clutter_3d"),
}

#: KITTI P2 of most tracking sequences (0000 and 13 others): projection of 3D clutter.
DEFAULT_P2 = (721.5377, 0.0, 609.5593, 44.85728,
              0.0, 721.5377, 172.854, 0.2163791,
              0.0, 0.0, 1.0, 0.002745884)

#: Quantiles (0, 1/16, ..., 1) of valid detections on the KITTI tracking training split, car
#: (20 sequences), RRC 2D and PointRCNN 3D: defaults of the clutter laws when no frames are given.
SCORE2_Q = (0.1003, 0.4934, 0.945, 0.9967, 0.9995, 0.9999, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0,
            1.0, 1.0, 1.0)
SCORE3_Q = (-0.8473, -0.5474, -0.215, 0.1695, 0.6219, 1.1606, 1.8532, 2.761, 3.9826, 5.3863, 6.7654,
            8.0462, 9.1963, 10.3928, 11.5325, 12.7273, 16.334)
WIDTH2_Q = (15.307, 27.215, 31.942, 36.4498, 42.11, 48.0858, 54.7225, 62.1135, 70.043, 80.1595, 94.2195,
            110.2475, 126.422, 153.597, 199.1645, 283.886, 498.277)
ASPECT2_Q = (0.253, 0.3948, 0.4382, 0.4755, 0.5183, 0.5665, 0.6025, 0.6394, 0.6762, 0.7123, 0.7439,
             0.7714, 0.8022, 0.8409, 0.896, 0.9569, 2.658)
N_QUANTILES = 17

#: 3D clutter: car dims (h, w, l) m (median PointRCNN car), bottom height y (m, camera 1.65 m above
#: the road), depth range (m), lateral extent |x| / z (field of view of camera 02: ~0.84).
CAR_DIMS = (1.50, 1.61, 3.91)
CAR_Y = 1.55
CLUTTER_Z = (5.0, 60.0)
CLUTTER_XZ = 0.8
#: Free space: a 2D candidate is free when its IoU with every occupied box is below FREE_IOU; a 3D
#: candidate when its ground-plane distance to every occupied 3D box is at least FREE_DIST metres.
FREE_IOU = 0.1
FREE_DIST = 4.0

#: Default start rate of ``level_params("burst", L)`` and default mean length of
#: ``level_params("burst_rate", r)``.
BURST_RATE = 0.02
BURST_LEN = 10.0
#: ``level_params("jitter", px)``: 3D shift std per image pixel, the size of a pixel at 30 m
#: (about the median car depth) for f = 721.5 px.
METRES_PER_PIXEL = 30.0 / 721.5377
#: ``level_params("score", s)``: 3D score noise per unit of 2D score noise (PointRCNN scores span
#: ~10x the [0, 1] range of RRC's).
SCORE3_PER_SCORE2 = 10.0

# Stream tags of the per-frame keys; bursts have their own root.
_DROP2, _DROP3, _JIT2, _JITB3, _JIT3, _SCORE2, _SCORE3, _CLUT2, _CLUT3 = range(1, 10)
BURST_TAG = 0x7FFFFFFF


class DistortSpec(NamedTuple):
    """Static choices (each distinct value is its own compilation; all fields hashable).

    clutter_slots:  empty slots per frame and modality reserved for clutter at the end of the
                    slot axis (:func:`pad_for_clutter`); 0 = no clutter possible.
    burst_max:      longest burst (frames): lengths are capped at it, and the stateless burst test
                    looks back this many frames (cost per frame ~ slots x burst_max hashes).
    burst_dist:     law of a burst's length L with mean mu = burst_len:
                    "fixed"     L = floor(mu + u): mu when mu is an integer, else floor/ceil with mean mu;
                    "geometric" P(L = k) = q (1-q)^(k-1), k >= 1, q = 1/max(mu, 1) (memoryless);
                    "uniform"   L uniform on {1, ..., n}, n = max(round(2 mu - 1), 1) (mean (n+1)/2).
                    Then L = min(L, burst_max) (the geometric mean becomes (1-(1-q)^burst_max)/q).
    truncate:       ``Options.truncate`` of the frames (integer boxes; jitter and clutter re-truncate).
    centroid:       ``Options.centroid`` of the frames (3D clutter lo3/hi3 convention).
    clutter_tries:  candidates per clutter slot for the free-space test.
    enabled:        the distortion groups compiled in ("burst", "drop", "jitter", "score", "clutter");
                    a group left out costs nothing and its levels are ignored (:func:`check_params`
                    refuses such levels; ``make_spec(dps=...)`` keeps exactly the groups used).
    p2:             12 values of the projection matrix for 3D clutter image boxes.
    score2_q, score3_q, width2_q, aspect2_q: 17 quantiles (0, 1/16, ..., 1) of real 2D scores,
                    3D scores, 2D box widths (px) and heights/widths: the clutter laws.
    """

    clutter_slots: int = 0
    burst_max: int = 30
    burst_dist: str = "fixed"
    truncate: bool = True
    centroid: str = "legacy"
    clutter_tries: int = 4
    enabled: tuple = ("burst", "drop", "jitter", "score", "clutter")
    p2: tuple = DEFAULT_P2
    score2_q: tuple = SCORE2_Q
    score3_q: tuple = SCORE3_Q
    width2_q: tuple = WIDTH2_Q
    aspect2_q: tuple = ASPECT2_Q

    def validate(self) -> "DistortSpec":
        if self.burst_dist not in BURST_DISTS:
            raise ValueError(f"burst_dist={self.burst_dist!r}: expected one of {BURST_DISTS}")
        if self.centroid not in ("legacy", "head", "kitti"):
            raise ValueError(f"centroid={self.centroid!r}")
        if int(self.clutter_slots) < 0 or int(self.burst_max) < 1 or int(self.clutter_tries) < 1:
            raise ValueError("clutter_slots >= 0, burst_max >= 1 and clutter_tries >= 1 expected")
        for name in ("score2_q", "score3_q", "width2_q", "aspect2_q"):
            if len(getattr(self, name)) != N_QUANTILES:
                raise ValueError(f"{name}: expected {N_QUANTILES} quantiles")
        if len(self.p2) != 12:
            raise ValueError("p2: expected 12 values")
        unknown = set(self.enabled) - set(GROUPS)
        if unknown:
            raise ValueError(f"enabled: unknown groups {sorted(unknown)}; expected some of {GROUPS}")
        return self


def _quantiles(x: np.ndarray) -> tuple:
    x = np.asarray(x, np.float64)
    return tuple(float(v) for v in np.quantile(x, np.linspace(0.0, 1.0, N_QUANTILES)))


def used_groups(dp: DistortParams) -> tuple:
    """The groups (``GROUPS``) with a nonzero level in ``dp`` (scalars or a batch ``[B]``)."""
    return tuple(g for g, names in GROUPS.items()
                 if any(np.any(np.asarray(getattr(dp, n)) != 0) for n in names))


def check_params(dp: DistortParams, spec: DistortSpec) -> DistortParams:
    """Host side: refuse levels the spec cannot apply (a disabled group, clutter without slots,
    a negative level, a probability above 1). Returns ``dp``."""
    off = set(used_groups(dp)) - set(spec.enabled)
    if off:
        raise ValueError(f"distortion levels set for groups not compiled in the spec: {sorted(off)} "
                         f"(spec.enabled = {spec.enabled})")
    if "clutter" in used_groups(dp) and spec.clutter_slots == 0:
        raise ValueError("clutter levels need DistortSpec.clutter_slots > 0 (and pad_for_clutter frames)")
    for name in DistortParams._fields[:-1]:
        v = np.asarray(getattr(dp, name), np.float64)
        if np.any(~np.isfinite(v)) or np.any(v < 0):
            raise ValueError(f"{name}: levels must be finite and >= 0")
        if name in ("drop_2d", "drop_3d", "burst_rate") and np.any(v > 1):
            raise ValueError(f"{name}: a probability, expected <= 1")
    return dp


def make_spec(options: Options | None = None, clutter_slots: int = 0, burst_max: int = 30,
              burst_dist: str = "fixed", frames: Frames | None = None, dps: DistortParams | None = None,
              **kw) -> DistortSpec:
    """A ``DistortSpec`` matching the frames' ``Options`` (truncate, centroid).

    With ``frames`` (host ``Frames [T, ...]``), the clutter laws (score, width and aspect quantiles)
    are measured on their valid detections; otherwise the KITTI RRC/PointRCNN car defaults.
    With ``dps`` (the batch that will run), only the groups it uses are compiled in (``enabled``):
    a drop-only study then pays for drops only. ``kw`` sets any other field (``clutter_tries``, ...).
    """
    options = Options() if options is None else options
    fields: dict[str, Any] = dict(clutter_slots=int(clutter_slots), burst_max=int(burst_max),
                                  burst_dist=burst_dist, truncate=bool(options.truncate),
                                  centroid=options.centroid)
    if dps is not None:
        fields["enabled"] = used_groups(dps)
    if frames is not None:
        v2 = np.asarray(frames.valid2, bool)
        v3 = np.asarray(frames.valid3, bool)
        b2 = np.asarray(frames.box2)[v2]
        w = b2[:, 2] - b2[:, 0]
        h = b2[:, 3] - b2[:, 1]
        ok = w > 0
        if ok.any():
            fields.update(width2_q=_quantiles(w[ok]), aspect2_q=_quantiles(h[ok] / w[ok]))
        if v2.any():
            fields["score2_q"] = _quantiles(np.asarray(frames.score2)[v2])
        if v3.any():
            fields["score3_q"] = _quantiles(np.asarray(frames.score3)[v3])
    fields.update(kw)
    if "p2" in fields:
        fields["p2"] = tuple(float(v) for v in np.asarray(fields["p2"], np.float64).reshape(-1))
    spec = DistortSpec(**fields).validate()
    spec = spec._replace(enabled=tuple(g for g in GROUPS if g in set(spec.enabled)))     # canonical order
    if dps is not None:
        check_params(dps, spec)
    return spec


KINDS = ("none", "drop", "drop_2d", "drop_3d", "burst", "burst_rate", "jitter", "jitter_2d", "jitter_box3",
         "jitter_3d", "score", "score_2d", "score_3d", "clutter", "clutter_2d", "clutter_3d")


def level_params(kind: str, level: float, seed: int = 0, **kw) -> DistortParams:
    """The ``DistortParams`` of one distortion kind at one level (every other field 0).

    kind          level                     fields set
    ------------  ------------------------  -----------------------------------------------------
    "none"        ignored                   nothing
    "drop"        probability p             drop_2d = drop_3d = p (independently per modality)
    "drop_2d"     probability p             drop_2d = p
    "drop_3d"     probability p             drop_3d = p
    "burst"       mean length L (frames)    burst_len = L, burst_rate = kw burst_rate (BURST_RATE)
    "burst_rate"  start rate r              burst_rate = r, burst_len = kw burst_len (BURST_LEN)
    "jitter"      sigma (pixels)            jitter_2d = jitter_box3 = sigma,
                                            jitter_3d = sigma * kw metres_per_pixel (METRES_PER_PIXEL)
    "jitter_2d"   sigma (pixels)            jitter_2d = sigma (2D detector boxes only)
    "jitter_box3" sigma (pixels)            jitter_box3 = sigma (image boxes of 3D detections only)
    "jitter_3d"   sigma (metres)            jitter_3d = sigma
    "score"       sigma (2D score units)    score_noise_2d = sigma,
                                            score_noise_3d = sigma * kw score3_per_score2 (SCORE3_PER_SCORE2)
    "score_2d"    sigma                     score_noise_2d = sigma
    "score_3d"    sigma                     score_noise_3d = sigma
    "clutter"     false positives / frame   clutter_2d = clutter_3d = level (per modality)
    "clutter_2d"  false positives / frame   clutter_2d = level
    "clutter_3d"  false positives / frame   clutter_3d = level

    Level 0 is the identity for every kind (for "burst_rate" and "burst" either zero disables
    bursts). Any ``DistortParams`` field can be given in ``kw`` to combine distortions, e.g.
    ``level_params("drop", 0.2, seed=3, jitter_2d=2.0)``.
    """
    level = float(level)
    kw = dict(kw)
    extra = {k: kw.pop(k) for k in ("metres_per_pixel", "score3_per_score2") if k in kw}
    f: dict[str, float] = {}
    if kind == "none":
        pass
    elif kind == "drop":
        f.update(drop_2d=level, drop_3d=level)
    elif kind in ("drop_2d", "drop_3d", "jitter_2d", "jitter_box3", "jitter_3d", "clutter_2d", "clutter_3d"):
        f[kind] = level
    elif kind == "burst":
        f.update(burst_len=level, burst_rate=BURST_RATE)        # kw burst_rate overrides
    elif kind == "burst_rate":
        f.update(burst_rate=level, burst_len=BURST_LEN)         # kw burst_len overrides
    elif kind == "jitter":
        mpp = float(extra.get("metres_per_pixel", METRES_PER_PIXEL))
        f.update(jitter_2d=level, jitter_box3=level, jitter_3d=level * mpp)
    elif kind == "score":
        r = float(extra.get("score3_per_score2", SCORE3_PER_SCORE2))
        f.update(score_noise_2d=level, score_noise_3d=level * r)
    elif kind in ("score_2d", "score_3d"):
        f["score_noise_" + kind[-2:]] = level
    elif kind == "clutter":
        f.update(clutter_2d=level, clutter_3d=level)
    else:
        raise ValueError(f"distortion kind {kind!r}: expected one of {KINDS}")
    unknown = set(kw) - set(DistortParams._fields)
    if unknown:
        raise ValueError(f"unknown DistortParams fields {sorted(unknown)}")
    f.update({k: v for k, v in kw.items()})
    f["seed"] = int(f.get("seed", seed))
    return DistortParams(**f)


def stack_distort(items) -> DistortParams:
    """A batch ``DistortParams [B]`` (numpy float32 leaves, int32 seed) from a list of settings."""
    items = list(items)
    if not items:
        raise ValueError("empty batch")
    cols = zip(*items)
    return DistortParams(*(np.asarray(c, np.int32 if name == "seed" else np.float32)
                           for name, c in zip(DistortParams._fields, cols)))


def _cast(dp: DistortParams) -> DistortParams:
    return DistortParams(*(jnp.asarray(v, jnp.int32 if name == "seed" else jnp.float32)
                           for name, v in zip(DistortParams._fields, dp)))


# ---------------------------------------------------------------------------------------------
# Host side: clutter slots and ground-truth identities


def _pad_slots(x: np.ndarray, n: int, value) -> np.ndarray:
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
        box2=_pad_slots(frames.box2, n, 0), score2=_pad_slots(frames.score2, n, 0),
        valid2=_pad_slots(frames.valid2, n, False),
        box3=_pad_slots(frames.box3, n, 0), score3=_pad_slots(frames.score3, n, 0),
        valid3=_pad_slots(frames.valid3, n, False),
        lo3=_pad_slots(frames.lo3, n, 0), hi3=_pad_slots(frames.hi3, n, 0),
    )


def pad_identity(gid2: np.ndarray, gid3: np.ndarray, spec: DistortSpec) -> tuple[np.ndarray, np.ndarray]:
    """Host side: ``gid2 [T, M2]``, ``gid3 [T, M3]`` padded with -1 like :func:`pad_for_clutter`."""
    n = int(spec.clutter_slots)
    return (_pad_slots(gid2, n, -1).astype(np.int32), _pad_slots(gid3, n, -1).astype(np.int32))


def _match_ids(det_box: np.ndarray, det_valid: np.ndarray, gt_box: np.ndarray, gt_id: np.ndarray,
               min_iou: float) -> np.ndarray:
    out = np.full(det_box.shape[0], -1, np.int32)
    if gt_box.shape[0] == 0 or not det_valid.any():
        return out
    iou = iou_2d(det_box[:, None, :], gt_box[None, :, :])                  # [M, G]
    best = np.argmax(iou, axis=1)
    ok = det_valid & (iou[np.arange(det_box.shape[0]), best] >= min_iou)
    out[ok] = gt_id[best[ok]]
    return out


def gt_identity(split: Split, root, options: Options | None = None,
                min_iou: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Host side: the ground-truth track id of every detection slot.

    Returns ``gid2 [T, M2]`` and ``gid3 [T, M3]`` int32: the ``track_id`` (as in
    ``root/label_02/SSSS.txt``, every class except ``DontCare``) of the ground-truth box of the same
    frame with the highest 2D IoU with the detection's image box, when that IoU >= ``min_iou``;
    -1 otherwise (and for empty slots). 2D detections use their raw (untruncated) box; 3D
    detections their image box under ``options`` (``data.image_box_3d``: the detector's box by
    default, the calib projection with ``merge="calib_projection"`` or ``modality="3d"``).
    Each detection takes its best ground truth independently (several detections may share one
    identity: an occluded object's duplicates vanish with it). Ids restart per sequence.
    """
    options = Options() if options is None else options
    root = Path(root)
    box3 = image_box_3d(split.box3d, split.proj3d, options)
    gid2 = np.full(split.valid2d.shape, -1, np.int32)
    gid3 = np.full(split.valid3d.shape, -1, np.int32)
    for k, name in enumerate(split.names):
        labels = read_tracking_labels(root / "label_02" / f"{name}.txt")
        keep = labels.type != "DontCare"
        frame, tid, gbox = labels.frame[keep], labels.track_id[keep], labels.box[keep]
        o = int(split.offsets[k])
        for f in range(int(split.lengths[k])):
            sel = frame == f
            t = o + f
            gid2[t] = _match_ids(split.box2d[t], split.valid2d[t], gbox[sel], tid[sel], min_iou)
            gid3[t] = _match_ids(box3[t], split.valid3d[t], gbox[sel], tid[sel], min_iou)
    return gid2, gid3


# ---------------------------------------------------------------------------------------------
# Device side


_GOLDEN = 0x9E3779B9
_SALT = 0x2545F491


def _mix32(x: jnp.ndarray) -> jnp.ndarray:
    """A bijective 32-bit integer hash (``lowbias32``: xor-shift-multiply, full avalanche)."""
    x = x ^ (x >> jnp.uint32(16))
    x = x * jnp.uint32(0x7FEB352D)
    x = x ^ (x >> jnp.uint32(15))
    x = x * jnp.uint32(0x846CA68B)
    return x ^ (x >> jnp.uint32(16))


def _u32(x) -> jnp.ndarray:
    """int32 (two's complement) -> uint32 bits."""
    return jax.lax.bitcast_convert_type(jnp.asarray(x).astype(jnp.int32), jnp.uint32)


def _absorb(h: jnp.ndarray, w) -> jnp.ndarray:
    """Chain one int32 word into a 32-bit hash state: ``mix(h ^ mix(w + golden))``."""
    return _mix32(h ^ _mix32(_u32(w) + jnp.uint32(_GOLDEN)))


def lane_hash(seed) -> jnp.ndarray:
    """uint32 root of a lane: ``absorb(SALT, seed)``."""
    return _absorb(jnp.uint32(_SALT), seed)


def stream_hash(seed, t, stream: int) -> jnp.ndarray:
    """uint32 state of one per-frame stream: ``absorb(absorb(lane_hash(seed), t), stream)``."""
    return _absorb(_absorb(lane_hash(seed), t), stream)


def _unit(x: jnp.ndarray) -> jnp.ndarray:
    """uint32 -> float32 uniform in [0, 1) (top 24 bits, exact)."""
    return (x >> jnp.uint32(8)).astype(jnp.float32) * jnp.float32(2.0 ** -24)


def _np_mix32(x: np.ndarray) -> np.ndarray:
    x = x.astype(np.uint32)
    x ^= x >> np.uint32(16)
    x *= np.uint32(0x7FEB352D)
    x ^= x >> np.uint32(15)
    x *= np.uint32(0x846CA68B)
    x ^= x >> np.uint32(16)
    return x


@functools.lru_cache(maxsize=None)
def _counters(n: int) -> np.ndarray:
    """``mix(2 i + 1)`` for i < n, precomputed (a constant of the program)."""
    with np.errstate(over="ignore"):
        return _np_mix32(np.arange(n, dtype=np.uint32) * np.uint32(2) + np.uint32(1))


def uniform(h: jnp.ndarray, shape) -> jnp.ndarray:
    """float32 uniforms in [0, 1) of ``shape`` from a stream state: element i (row-major) is
    ``unit(mix(h ^ mix(2 i + 1)))`` (counter-based: element i never depends on the shape)."""
    n = int(np.prod(shape))
    return _unit(_mix32(h ^ jnp.asarray(_counters(n).reshape(shape))))


def normal(h: jnp.ndarray, shape) -> jnp.ndarray:
    """float32 standard normals of ``shape``: Box-Muller on uniform pairs (u_2k, u_2k+1) of the
    stream, element 2k = r cos(theta), element 2k+1 = r sin(theta) (row-major)."""
    n = int(np.prod(shape))
    u = uniform(h, ((n + 1) // 2, 2))
    r = jnp.sqrt(jnp.float32(-2.0) * jnp.log(jnp.float32(1.0) - u[:, 0]))      # 1 - u in (0, 1]
    theta = jnp.float32(2.0 * math.pi) * u[:, 1]
    z = jnp.stack([r * jnp.cos(theta), r * jnp.sin(theta)], axis=-1).reshape(-1)
    return z[:n].reshape(shape)


def _burst_length(u: jnp.ndarray, mean: jnp.ndarray, spec: DistortSpec) -> jnp.ndarray:
    """Burst length (float32, integer-valued, in [0, burst_max]) from a uniform u in [0, 1)."""
    mean = jnp.asarray(mean, jnp.float32)
    if spec.burst_dist == "fixed":
        n = jnp.floor(mean + u)
    elif spec.burst_dist == "geometric":
        q = 1.0 / jnp.maximum(mean, 1.0)
        safe_q = jnp.where(q < 1.0, q, 0.5)
        n = jnp.where(q < 1.0, 1.0 + jnp.floor(jnp.log1p(-u) / jnp.log1p(-safe_q)), 1.0)
    else:  # uniform
        m = jnp.maximum(jnp.round(2.0 * mean - 1.0), 1.0)
        n = 1.0 + jnp.floor(u * m)
    n = jnp.minimum(n, jnp.float32(spec.burst_max))
    return jnp.where(mean > 0, n, 0.0).astype(jnp.float32)


def burst_draw(seed, g, s, dp: DistortParams, spec: DistortSpec):
    """Whether object ``g`` starts a burst at global frame ``s``, and its length.

    ``g``, ``s`` int arrays (broadcast together). Returns ``(start bool, length int32)`` of their
    shape; ``length`` is drawn whether or not the burst starts. The two uniforms of ``(g, s)``
    come from the state ``b = absorb(absorb(absorb(lane_hash(seed), BURST_TAG), g), s)``:
    ``u0 = unit(b)`` (start when ``u0 < burst_rate``), ``u1 = unit(mix(b ^ golden))`` (length).
    """
    dp = _cast(dp)
    g, s = jnp.broadcast_arrays(jnp.asarray(g, jnp.int32), jnp.asarray(s, jnp.int32))
    b = _absorb(_absorb(_absorb(lane_hash(seed), BURST_TAG), g), s)
    start = _unit(b) < dp.burst_rate
    length = _burst_length(_unit(_mix32(b ^ jnp.uint32(_GOLDEN))), dp.burst_len, spec)
    return start, length.astype(jnp.int32)


def occluded(gid: jnp.ndarray, t, dp: DistortParams, spec: DistortSpec) -> jnp.ndarray:
    """[M] bool: the slot's ground-truth object (``gid >= 0``) is inside an occlusion burst at ``t``."""
    dp = _cast(dp)
    gid = jnp.asarray(gid, jnp.int32)
    lag = jnp.arange(spec.burst_max, dtype=jnp.int32)                     # t - s
    s = jnp.asarray(t, jnp.int32) - lag
    start, length = burst_draw(dp.seed, jnp.maximum(gid, 0)[:, None], s[None, :], dp, spec)
    covers = start & (length > lag[None, :])
    return jnp.any(covers, axis=1) & (gid >= 0)


def _wide():
    """float64 under ``jax.enable_x64`` (the tracker's step, :func:`distort_split`), else float32."""
    return jax.dtypes.canonicalize_dtype(np.float64)


def _w(x) -> jnp.ndarray:
    """A float32 value widened (exactly) for sums of products, see :func:`_lin`."""
    return jnp.asarray(x, jnp.float32).astype(_wide())


def _f32(x) -> jnp.ndarray:
    return jnp.asarray(x).astype(jnp.float32)


def _lin(*terms) -> jnp.ndarray:
    """``sum(terms)`` rounded to float32, each term a float32 value or a ``(a, b)`` product of two.

    XLA on CPU lets LLVM contract a multiply feeding an add (even through a float32 -> float64
    conversion) into one fused multiply-add, and whether it does depends on the surrounding
    program (fusion decisions differ between a scan step, a vmap, a single jit). Here every
    product is formed in float64 from float32 operands, so it is exact and fused and unfused
    evaluation agree: the same (seed, t) gives the same bits in the tracker and in
    :func:`distort_split` (both run under x64). Without x64 this is plain float32 arithmetic.
    """
    acc = None
    for term in terms:
        v = _w(term[0]) * _w(term[1]) if isinstance(term, tuple) else _w(term)
        acc = v if acc is None else acc + v
    return _f32(acc)


# ---- geometry helpers (jnp, float32) --------------------------------------------------------


def _trunc_2d(box):
    x = jnp.trunc(box[..., 0]); y = jnp.trunc(box[..., 1])
    w = jnp.abs(x - jnp.trunc(box[..., 2])); h = jnp.abs(y - jnp.trunc(box[..., 3]))
    return jnp.stack([x, y, x + w, y + h], axis=-1)


def _trunc_3d(box):
    x = jnp.trunc(box[..., 0]); y = jnp.trunc(box[..., 1])
    w = jnp.trunc(jnp.abs(x - box[..., 2])); h = jnp.trunc(jnp.abs(y - box[..., 3]))
    return jnp.stack([x, y, x + w, y + h], axis=-1)


def _ordered(box):
    return jnp.stack([jnp.minimum(box[..., 0], box[..., 2]), jnp.minimum(box[..., 1], box[..., 3]),
                      jnp.maximum(box[..., 0], box[..., 2]), jnp.maximum(box[..., 1], box[..., 3])], -1)


def _iou(a, b, integer: bool = False):
    """IoU of float32 boxes a [..., 4] and b [..., 4] (broadcast), 0 for empty unions. In float64
    under x64 (exact products), or in float32 for ``integer`` boxes (truncated: every product of
    pixel sizes < 2^24 is exact in float32 already)."""
    if not integer:
        a, b = _w(a), _w(b)
    iw = jnp.minimum(a[..., 2], b[..., 2]) - jnp.maximum(a[..., 0], b[..., 0])
    ih = jnp.minimum(a[..., 3], b[..., 3]) - jnp.maximum(a[..., 1], b[..., 1])
    inter = jnp.maximum(iw, 0.0) * jnp.maximum(ih, 0.0)
    area = lambda x: jnp.maximum(x[..., 2] - x[..., 0], 0.0) * jnp.maximum(x[..., 3] - x[..., 1], 0.0)
    union = area(a) + area(b) - inter
    return jnp.where(union > 0, inter / jnp.where(union > 0, union, 1.0), 0.0)


def extent_3d(dims, loc, centroid: str):
    """jnp ``data.box3d_extent``: (lo, hi) [..., 3] float32 from dims (h, w, l) and loc (x, y, z)."""
    h, w, l = (jnp.asarray(dims[..., i], jnp.float32) for i in range(3))
    x, y, z = (jnp.asarray(loc[..., i], jnp.float32) for i in range(3))
    if centroid == "legacy":
        lo = jnp.stack([z, y, x], -1)
        return lo, lo + jnp.stack([l, w, h], -1)
    if centroid == "head":
        lo = jnp.stack([z, -x, -y], -1)
        return lo, lo + jnp.stack([l, h, w], -1)
    half = jnp.float32(0.5)            # half * l is exact: no contraction issue
    return (jnp.stack([x - half * l, y - h, z - half * w], -1), jnp.stack([x + half * l, y, z + half * w], -1))


def ground_xz(lo3, hi3, centroid: str):
    """[..., 2] camera (x, z) of 3D boxes given as internal (lo3, hi3) in the ``centroid`` convention."""
    if centroid == "legacy":
        return jnp.stack([lo3[..., 2], lo3[..., 0]], -1)
    if centroid == "head":
        return jnp.stack([-lo3[..., 1], lo3[..., 0]], -1)
    return 0.5 * jnp.stack([lo3[..., 0] + hi3[..., 0], lo3[..., 2] + hi3[..., 2]], -1)


_XP = np.array([0.5, 0.5, -0.5, -0.5, 0.5, 0.5, -0.5, -0.5], np.float32)
_YP = np.array([0.0, 0.0, 0.0, 0.0, -1.0, -1.0, -1.0, -1.0], np.float32)
_ZP = np.array([0.5, -0.5, -0.5, 0.5, 0.5, -0.5, -0.5, 0.5], np.float32)


def project_box(dims, loc, rot_y, p2, image_size):
    """[..., 4] float32 image box of KITTI 3D boxes in front of the camera (corners projected with
    p2, clipped to [0, W-1] x [0, H-1], as ``geometry.project_box3d_to_image``)."""
    P = np.asarray(p2, np.float32).reshape(3, 4)
    h, w, l = dims[..., 0:1], dims[..., 1:2], dims[..., 2:3]
    xo, yo, zo = l * _XP, h * _YP, w * _ZP                                # exact (halves, signs)
    c, s = jnp.cos(rot_y)[..., None], jnp.sin(rot_y)[..., None]
    pts = (_lin((c, xo), (s, zo), loc[..., 0:1]), yo + loc[..., 1:2], _lin((-s, xo), (c, zo), loc[..., 2:3]))
    hom = [_lin((P[i, 0], pts[0]), (P[i, 1], pts[1]), (P[i, 2], pts[2]), P[i, 3]) for i in range(3)]
    depth = jnp.maximum(hom[2], jnp.float32(0.1))
    u, v = hom[0] / depth, hom[1] / depth                                  # float32, correctly rounded
    W, H = image_size
    box = jnp.stack([u.min(-1), v.min(-1), u.max(-1), v.max(-1)], -1)
    return jnp.clip(box, 0.0, jnp.asarray([W - 1.0, H - 1.0, W - 1.0, H - 1.0], jnp.float32))


def _qf(u, q):
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
    return _lin(lo, (f, step))


def _dist(a, b):
    """Euclidean distance over the last axis (size 2) of float32 points (wide)."""
    d = _w(a) - _w(b)
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


def _clutter_2d(key, box, score, valid, real, rate, spec: DistortSpec, image_size):
    """Fill the last S 2D slots with clutter; ``real`` [M] the slots occupying image space."""
    S, K = int(spec.clutter_slots), int(spec.clutter_tries)
    W, H = float(image_size[0]), float(image_size[1])
    on = uniform(_absorb(key, 0), (S,)) < rate / S
    u = uniform(_absorb(key, 1), (S, K, 4))
    w = jnp.minimum(_qf(u[..., 0], spec.width2_q), W - 1.0)
    h = jnp.minimum(_lin((w, _qf(u[..., 1], spec.aspect2_q))), H - 1.0)
    gap_w, gap_h = (W - 1.0) - w, (H - 1.0) - h
    cand = jnp.stack([_lin((u[..., 2], gap_w)), _lin((u[..., 3], gap_h)),
                      _lin((u[..., 2], gap_w), w), _lin((u[..., 3], gap_h), h)], -1)   # [S, K, 4]
    if spec.truncate:
        cand = _trunc_2d(cand)
    sc = _qf(uniform(_absorb(key, 2), (S,)), spec.score2_q)
    put = on & ~valid[valid.shape[0] - S:]
    exact = bool(spec.truncate)
    over_real = jnp.max(jnp.where(real, _iou(cand[:, :, None, :], box[None, None, :, :], exact), 0.0), -1)  # [S, K]
    over_pair = _iou(cand[:, :, None, None, :], cand[None, None, :, :, :], exact)                   # [S, K, S, K]
    hot = _place(over_real, over_pair, lambda c: c < FREE_IOU, 0.0)                             # [S, K]
    return (_fill_tail(box, put, _pick(cand, hot)), _fill_tail(score, put, sc),
            valid | _fill_tail(jnp.zeros_like(valid), put, put))


def _clutter_3d(key, box, score, valid, lo3, hi3, real, rate, spec: DistortSpec, image_size):
    """Fill the last S 3D slots with clutter; ``real`` [M] the slots occupying space."""
    S, K = int(spec.clutter_slots), int(spec.clutter_tries)
    on = uniform(_absorb(key, 0), (S,)) < rate / S
    u = uniform(_absorb(key, 1), (S, K, 3))
    z = _lin(CLUTTER_Z[0], (u[..., 0], CLUTTER_Z[1] - CLUTTER_Z[0]))
    x = _lin((z, _lin((2.0 * u[..., 1] - 1.0, CLUTTER_XZ))))
    rot = (2.0 * u[..., 2] - 1.0) * np.float32(math.pi)
    loc = jnp.stack([x, jnp.full_like(x, CAR_Y), z], -1)                 # [S, K, 3]
    dims = jnp.broadcast_to(jnp.asarray(CAR_DIMS, jnp.float32), loc.shape)
    c_lo, c_hi = extent_3d(dims, loc, spec.centroid)
    c_box = project_box(dims, loc, rot, spec.p2, image_size)
    if spec.truncate:
        c_box = _trunc_3d(c_box)
    sc = _qf(uniform(_absorb(key, 2), (S,)), spec.score3_q)
    put = on & ~valid[valid.shape[0] - S:]
    xz = ground_xz(lo3, hi3, spec.centroid)                               # [M, 2]
    c_xz = jnp.stack([x, z], -1)                                          # [S, K, 2]
    # conflict = minus the ground-plane distance (higher = worse), free when the distance >= FREE_DIST
    near_real = jnp.max(jnp.where(real, -_dist(c_xz[:, :, None, :], xz[None, None, :, :]), -jnp.inf), axis=-1)
    near_pair = -_dist(c_xz[:, :, None, None, :], c_xz[None, None, :, :, :])                      # [S, K, S, K]
    hot = _place(near_real, near_pair, lambda c: c <= -FREE_DIST, -jnp.inf)
    return (_fill_tail(box, put, _pick(c_box, hot)), _fill_tail(score, put, sc),
            valid | _fill_tail(jnp.zeros_like(valid), put, put),
            _fill_tail(lo3, put, _pick(c_lo, hot)), _fill_tail(hi3, put, _pick(c_hi, hot)))


def _jitter_box(box, valid, sigma, key, truncate_fn):
    n = normal(key, box.shape)
    if truncate_fn is None:
        out = _ordered(_lin(box, (sigma, n)))
    else:
        out = truncate_fn(_lin(box + 0.5, (sigma, n)))        # box + 0.5 is exact
    return jnp.where((sigma > 0) & valid[:, None], out, box).astype(box.dtype)


class FrameDistortion(NamedTuple):
    """The tracker's per-frame hook (``core.run.FrameHook.fn``) of a distortion study: hashable by
    its static spec; the hook's lane values are ``DistortParams``, its xs the (gid2, gid3) arrays."""

    spec: DistortSpec

    def __call__(self, frame: Frames, dp: DistortParams, gids, t) -> Frames:
        return distort_frame(frame, gids[0], gids[1], t, dp, self.spec)


def distort_frame(frame: Frames, gid2, gid3, t, dp: DistortParams, spec: DistortSpec,
                  image_size=DEFAULT_IMAGE_SIZE) -> Frames:
    """One frame's inputs distorted for one lane (pure, jittable, vmappable over ``dp``).

    frame:  one frame of ``Frames`` (reset [], box2 [M2, 4], score2 [M2], valid2 [M2], box3 [M3, 4],
            score3 [M3], valid3 [M3], lo3 / hi3 [M3, 3]); with clutter, slots from
            :func:`pad_for_clutter` (the last ``spec.clutter_slots`` of each modality).
    gid2:   [M2] int32 ground-truth id of each 2D slot (:func:`gt_identity`, -1 = none).
    gid3:   [M3] int32 the same for 3D slots.
    t:      int32 scalar, the frame's global index in the split (seeds the per-frame streams).
    dp:     ``DistortParams`` of this lane (scalars); ``spec`` static; ``image_size`` (W, H) static.

    Returns a ``Frames`` slice of the same shapes and dtypes (float32 boxes and scores, bool
    masks); with every level 0 it is bit-identical to ``frame``. Groups not in ``spec.enabled``
    are not computed. Call it under ``jax.enable_x64`` (as the tracker's step runs) for values
    bit-identical to :func:`distort_split`. See the module docstring for the meaning of each
    level and the order of the steps.
    """
    dp = _cast(dp)
    t = jnp.asarray(t, jnp.int32)
    gid2 = jnp.asarray(gid2, jnp.int32)
    gid3 = jnp.asarray(gid3, jnp.int32)
    m2 = frame.valid2.shape[0]
    key = functools.partial(stream_hash, dp.seed, t)

    valid2, valid3 = frame.valid2, frame.valid3
    box2, box3, lo3, hi3 = frame.box2, frame.box3, frame.lo3, frame.hi3
    score2, score3 = frame.score2, frame.score3
    on = set(spec.enabled)
    # 1. occlusion bursts (one test for the 2D and 3D slots together: same object, same answer)
    if "burst" in on:
        occ = occluded(jnp.concatenate([gid2, gid3]), t, dp, spec)
        valid2 = valid2 & ~occ[:m2]
        valid3 = valid3 & ~occ[m2:]
    # 2. independent drops
    if "drop" in on:
        valid2 = valid2 & ~(uniform(key(_DROP2), valid2.shape) < dp.drop_2d)
        valid3 = valid3 & ~(uniform(key(_DROP3), valid3.shape) < dp.drop_3d)
    # 3. jitter (only slots holding a detection move: empty slots stay as they are)
    if "jitter" in on:
        box2 = _jitter_box(box2, frame.valid2, dp.jitter_2d, key(_JIT2), _trunc_2d if spec.truncate else None)
        box3 = _jitter_box(box3, frame.valid3, dp.jitter_box3, key(_JITB3), _trunc_3d if spec.truncate else None)
        shift = normal(key(_JIT3), lo3.shape)
        move3 = ((dp.jitter_3d > 0) & frame.valid3)[:, None]
        lo3 = jnp.where(move3, _lin(lo3, (dp.jitter_3d, shift)), lo3).astype(frame.lo3.dtype)
        hi3 = jnp.where(move3, _lin(hi3, (dp.jitter_3d, shift)), hi3).astype(frame.hi3.dtype)
    # 4. score noise
    if "score" in on:
        n2 = normal(key(_SCORE2), score2.shape)
        n3 = normal(key(_SCORE3), score3.shape)
        score2 = jnp.where((dp.score_noise_2d > 0) & frame.valid2, _lin(score2, (dp.score_noise_2d, n2)),
                           score2).astype(frame.score2.dtype)
        score3 = jnp.where((dp.score_noise_3d > 0) & frame.valid3, _lin(score3, (dp.score_noise_3d, n3)),
                           score3).astype(frame.score3.dtype)
    # 5. clutter in the reserved slots (free space judged against the frame's real detections)
    if spec.clutter_slots > 0 and "clutter" in on:
        box2, score2, valid2 = _clutter_2d(key(_CLUT2), box2, score2, valid2, frame.valid2, dp.clutter_2d,
                                           spec, image_size)
        box3, score3, valid3, lo3, hi3 = _clutter_3d(key(_CLUT3), box3, score3, valid3, lo3, hi3,
                                                     frame.valid3, dp.clutter_3d, spec, image_size)
    return Frames(reset=frame.reset, box2=box2, score2=score2, valid2=valid2, box3=box3, score3=score3,
                  valid3=valid3, lo3=lo3, hi3=hi3)


@functools.partial(jax.jit, static_argnames=("spec", "image_size"))
def _distort_all(frames, gid2, gid3, t, dp, spec, image_size):
    return jax.vmap(lambda fr, g2, g3, tt: distort_frame(fr, g2, g3, tt, dp, spec, image_size))(
        frames, gid2, gid3, t)


@functools.partial(jax.jit, static_argnames=("spec", "image_size"))
def _distort_lanes(frames, gid2, gid3, t, dp, spec, image_size):
    return jax.vmap(lambda d: _distort_all(frames, gid2, gid3, t, d, spec, image_size))(dp)


def distort_lanes(frames: Frames, gid2, gid3, dp: DistortParams, spec: DistortSpec,
                  image_size=DEFAULT_IMAGE_SIZE, t0: int = 0) -> Frames:
    """:func:`distort_split` for a batch ``dp [B]`` (e.g. from :func:`stack_distort`): Frames
    ``[B, T, ...]``, one jit(vmap) call. Materialises B copies: for evaluation and tests."""
    with jax.enable_x64(True):
        frames = Frames(*(jnp.asarray(x) for x in frames))
        t = jnp.arange(frames.reset.shape[0], dtype=jnp.int32) + jnp.int32(t0)
        return _distort_lanes(frames, jnp.asarray(gid2, jnp.int32), jnp.asarray(gid3, jnp.int32), t,
                              _cast(dp), spec, tuple(image_size))


def distort_split(frames: Frames, gid2, gid3, dp: DistortParams, spec: DistortSpec,
                  image_size=DEFAULT_IMAGE_SIZE, t0: int = 0) -> Frames:
    """All frames ``[T, ...]`` of one lane distorted (global frame index ``t0 + arange(T)``).

    The same bits the scanned step sees frame by frame when the step runs under ``jax.enable_x64``
    as the tracker's does (see :func:`_lin`); runs under x64 itself. For evaluation, plots and
    tests: materialises one lane's ``[T, ...]`` copy. ``dp`` scalars (:func:`distort_lanes` for a batch).
    """
    with jax.enable_x64(True):
        frames = Frames(*(jnp.asarray(x) for x in frames))
        t = jnp.arange(frames.reset.shape[0], dtype=jnp.int32) + jnp.int32(t0)
        return _distort_all(frames, jnp.asarray(gid2, jnp.int32), jnp.asarray(gid3, jnp.int32), t, _cast(dp),
                            spec, tuple(image_size))
