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
   (``core.boxes.truncate_2d_box`` / ``core.boxes.truncate_3d_box``), so the integer boxes move by
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
   boxes when a candidate allows; its ``lo3/hi3`` are ``geometry.box3d_extent`` for
   ``DistortSpec.centroid`` (the loader's rule), its image box is its 8 corners projected with
   ``DistortSpec.p2`` and clipped, with ``geometry.project_box3d_to_image``'s rule (corners at depth
   <= 0.1 m ignored; :func:`exact.project_box`), then truncated like the loader's.
   Clutter scores follow the quantile function of real scores (``score2_q``, ``score3_q``), so a
   false positive passes the tracker's score threshold about as often as a real detection does.

Randomness is counter-based and stateless: a 32-bit hash chain (``absorb(h, w) = mix(h ^
mix(w + golden))``, ``mix`` the bijective lowbias32 integer hash) of ``(seed, t, stream)`` for the
per-frame streams (``t`` the global frame index of the split, so different sequences differ),
with element ``i`` of a stream drawn from ``mix(h ^ mix(2 i + 1))``, and of ``(seed, BURST_TAG,
g, s)`` for the burst of object ``g`` starting at frame ``s`` (:func:`burst_draw`). Why not
``jax.random``: see ``draws`` (measured: keys are slower inside the scanned step, and the
published robustness study is a function of these exact draws). Object ``g`` is occluded at
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
exact float64 products (:func:`exact.lin`), so the same ``(seed, t)`` gives the same bits in any
program: in the tracker's scan, in a vmap over frames, in one lane or in a batch (tested).
Without x64 the values can differ by an ulp between programs (XLA's fused multiply-add).

Cost (KITTI car split, 16 lanes, one CPU core, per lane-frame; the tracker step itself ~30 us):
drops ~0.05 us, bursts ~1-2 us, jitter ~4 us, score noise ~0.6 us, clutter (3 slots) ~4-5 us,
everything ~8-14 us. ``DistortSpec.enabled`` compiles only the groups a study uses
(``make_spec(dps=...)``).

Both tracker families, the same faults. The draws depend on ``(seed, t)``, the slot and the
ground-truth identity only, so DFR-FastMOT (inside its scan, on its ``Frames``) and AB3DMOT (which
reads 3D detections alone) get the same faults on the 3D detections from one seed and level:
AB3DMOT's lanes (``ab3dmot.family.track(distortion=...)``) run :func:`apply_draws` on a ``Frames``
holding the split's 3D detections only (:func:`frames_3d`: the detector's untruncated image box as
``box3``, ``lo3/hi3`` in ``DistortSpec.centroid``'s convention, ``"legacy"`` by default), each
distinct lane materialised on the host (:func:`distort_split`, with the clutter's poses), and read
the result back as result files carry it (:func:`read_back`, ``lanes``): the same drops and bursts
(``gid3`` from :func:`gt_identity` with the detector's image box), the same score noise, the same
physical shift of the box centre (``jitter_3d``: DFR-FastMOT's ``lo3`` shift in its convention,
mapped to camera x y z), ``jitter_box3`` on the image box AB3DMOT writes (untruncated), and the same
3D clutter (:func:`place_3d`: position, heading, score; AB3DMOT tracks the rotated ``CAR_DIMS`` box,
DFR-FastMOT its axis-aligned ``lo3/hi3``). ByteTrack, reading 2D detections alone, is the mirror image
(``bytetrack.family.track(distortion=...)``): its lanes run the draws on a ``Frames`` holding the
split's 2D detections only (:func:`frames_2d`: the detector's untruncated box, ``gid2`` as
DFR-FastMOT's), read back by :func:`read_back_2d`; the 3D levels (:data:`LEVELS_3D`) change nothing of
a 2D detection: it ignores them (:func:`only_2d`), and its sweeps refuse the kinds that set only them.
The 2D levels (``drop_2d``, ``jitter_2d``,
``score_noise_2d``, ``clutter_2d``) change nothing of a 3D detection: AB3DMOT ignores them
(:func:`only_3d`), and its sweeps refuse the kinds that set only them. DFR-FastMOT's rows of a
distorted lane (its sAMOTA) read that lane's 3D detections back by the same rule
(``results.lane_detections`` through the ``TrackResult``'s :class:`LaneDistortion`).

Typical use: ``dfrmot_jax.track(split, params, options, distortion=dps)`` does all of this
(``trackers.dfr.track.prepare_distortion``, then a ``trackers.dfr.run.FrameHook`` of :class:`FrameDistortion`); by hand::

    dps = distort.stack_distort([distort.level_params("drop", p, seed=s) for p in ps for s in seeds])
    spec = distort.make_spec(options, clutter_slots=0, frames=frames, dps=dps)   # checks dps too
    frames = distort.pad_for_clutter(frames, spec)
    gid2, gid3 = distort.pad_identity(*distort.gt_identity(split, root), spec)
    # scan xs = (frames, gid2, gid3, arange(T, int32)); per lane, per frame t:
    #     frame = distort.distort_frame(frame, gid2_t, gid3_t, t, dp, spec)   # then the tracker's step

Modules: ``spec`` (levels, static spec, constants, level helpers), ``draws`` (the counter-based
random draws), ``bursts``, ``noise`` (jitter, score noise), ``clutter`` (reserved slots, false
positives), ``exact`` (float32 arithmetic with exact products, the clutter's projection),
``hook`` (:func:`distort_frame`, :class:`FrameDistortion`, :func:`distort_split`,
:func:`distort_lanes`), ``identity`` (host side: ground-truth ids from the label files), ``lanes``
(host side: a lane's detections read back, :class:`Detections3D` / :class:`Detections2D`,
:class:`LaneDistortion`, :func:`frames_3d` / :func:`frames_2d`, :func:`distortion_3d` /
:func:`distortion_2d`). Every name below is importable from
``dfrmot_jax.distort`` itself.
"""

from __future__ import annotations

from .bursts import burst_draw, burst_length, occluded
from .clutter import Placement3D, ground_xz, pad_for_clutter, place_3d
from .draws import BURST_TAG, lane_hash, normal, stream_hash, uniform
from .exact import project_box
from .hook import FrameDistortion, distort_frame, distort_lanes, distort_split
from .identity import gt_identity, pad_identity
from .lanes import (
                    LEVELS_2D,
                    LEVELS_3D,
                    Detections2D,
                    Detections3D,
                    DistortedLane,
                    LaneDistortion,
                    distinct_lanes,
                    distortion_2d,
                    distortion_3d,
                    frames_2d,
                    frames_3d,
                    is_zero,
                    lane_params,
                    only_2d,
                    only_3d,
                    packed_slots,
                    padded_slots,
                    read_back,
                    read_back_2d,
                    split_detections,
                    split_detections_2d,
)
from .spec import (
                   ASPECT2_Q,
                   BURST_DISTS,
                   BURST_LEN,
                   BURST_RATE,
                   CAR_DIMS,
                   CAR_Y,
                   CLUTTER_XZ,
                   CLUTTER_Z,
                   DEFAULT_P2,
                   FREE_DIST,
                   FREE_IOU,
                   GROUPS,
                   KINDS,
                   METRES_PER_PIXEL,
                   N_QUANTILES,
                   SCORE2_Q,
                   SCORE3_PER_SCORE2,
                   SCORE3_Q,
                   WIDTH2_Q,
                   DistortParams,
                   DistortSpec,
                   cast_params,
                   check_params,
                   level_params,
                   make_spec,
                   stack_distort,
                   used_groups,
)

__all__ = [
    "ASPECT2_Q", "BURST_DISTS", "BURST_LEN", "BURST_RATE", "BURST_TAG", "CAR_DIMS", "CAR_Y", "CLUTTER_XZ",
    "CLUTTER_Z", "DEFAULT_P2", "FREE_DIST", "FREE_IOU", "GROUPS", "KINDS", "METRES_PER_PIXEL", "N_QUANTILES",
    "SCORE2_Q", "SCORE3_PER_SCORE2", "SCORE3_Q", "WIDTH2_Q",
    "LEVELS_2D", "LEVELS_3D", "Detections2D", "Detections3D", "DistortParams", "DistortSpec", "FrameDistortion", "DistortedLane", "LaneDistortion", "Placement3D",
    "burst_draw", "burst_length", "cast_params", "check_params", "distort_frame", "distort_lanes", "distort_split",
    "distinct_lanes", "distortion_2d", "distortion_3d", "frames_2d", "frames_3d", "is_zero", "lane_params", "only_2d",
    "only_3d", "packed_slots", "padded_slots", "place_3d", "read_back", "read_back_2d", "split_detections",
    "split_detections_2d",
    "ground_xz", "gt_identity", "lane_hash", "level_params", "make_spec", "normal", "occluded", "pad_for_clutter",
    "pad_identity", "project_box", "stack_distort", "stream_hash", "uniform", "used_groups",
]
