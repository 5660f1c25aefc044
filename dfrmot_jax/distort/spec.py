"""Distortion levels (``DistortParams``, per lane) and static choices (``DistortSpec``, per
compilation): the constants of the distortion laws, validation, and the per-kind level helpers
(:func:`level_params`, :func:`stack_distort`). Host side; no device work."""

from __future__ import annotations

from typing import Any, NamedTuple

import jax.numpy as jnp
import numpy as np

from ..frames import Frames


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
    seed:           the lane's seed (int32): root of all its draws (``draws.lane_hash(seed)``).
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

class DistortSpec(NamedTuple):
    """Static choices (each distinct value is its own compilation; all fields hashable).

    clutter_slots:  empty slots per frame and modality reserved for clutter at the end of the
                    slot axis (``clutter.pad_for_clutter``); 0 = no clutter possible.
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

    def validate(self) -> DistortSpec:
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


def make_spec(options=None, clutter_slots: int = 0, burst_max: int = 30,
              burst_dist: str = "fixed", frames: Frames | None = None, dps: DistortParams | None = None,
              **kw) -> DistortSpec:
    """A ``DistortSpec`` matching the frames' ``options``: any record with ``truncate`` and ``centroid``
    fields (DFR-FastMOT's ``Options``); a field it lacks, or None, takes ``DistortSpec``'s default.

    With ``frames`` (host ``Frames [T, ...]``), the clutter laws (score, width and aspect quantiles)
    are measured on their valid detections; otherwise the KITTI RRC/PointRCNN car defaults.
    With ``dps`` (the batch that will run), only the groups it uses are compiled in (``enabled``):
    a drop-only study then pays for drops only. ``kw`` sets any other field (``clutter_tries``, ...).
    """
    defaults = DistortSpec._field_defaults
    fields: dict[str, Any] = dict(clutter_slots=int(clutter_slots), burst_max=int(burst_max),
                                  burst_dist=burst_dist, truncate=bool(getattr(options, "truncate", defaults["truncate"])),
                                  centroid=getattr(options, "centroid", defaults["centroid"]))
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


def cast_params(dp: DistortParams) -> DistortParams:
    """``dp`` as jnp leaves: float32 levels, int32 seed (scalars or a batch)."""
    return DistortParams(*(jnp.asarray(v, jnp.int32 if name == "seed" else jnp.float32)
                           for name, v in zip(DistortParams._fields, dp)))
