"""Detection-failure distortions (dfrmot_jax.distort): identity at level 0, calibrated levels,
determinism, bursts, jitter, clutter, and use under jit(vmap) and lax.scan under x64."""


import jax
import jax.numpy as jnp
import numpy as np
import pytest

import dfrmot_jax as dm
from dfrmot_jax import boxes as dm_boxes, distort as D
from dfrmot_jax.frames import Frames
from dfrmot_jax.data import box3d_extent
from dfrmot_jax.trackers.dfr.frames import image_box_3d

W, H = 1242, 375


# ---- synthetic frames -----------------------------------------------------------------------


def synth(T=300, M2=8, M3=10, n_obj=6, seed=0, truncate=True, centroid="legacy"):
    """Frames [T, ...] with n_obj ground-truth objects (present ~80% of frames, one 2D and one 3D
    detection each), a few unmatched detections and empty slots; gid2 [T, M2], gid3 [T, M3]."""
    rng = np.random.default_rng(seed)
    box2 = np.zeros((T, M2, 4), np.float32); score2 = np.zeros((T, M2), np.float32)
    valid2 = np.zeros((T, M2), bool); gid2 = np.full((T, M2), -1, np.int32)
    box3 = np.zeros((T, M3, 4), np.float32); score3 = np.zeros((T, M3), np.float32)
    valid3 = np.zeros((T, M3), bool); gid3 = np.full((T, M3), -1, np.int32)
    dims = np.ones((T, M3, 3)); loc = np.zeros((T, M3, 3)); loc[..., 2] = 10.0
    for t in range(T):
        present = np.flatnonzero(rng.random(n_obj) < 0.8)
        n2 = min(M2, present.size + 1)
        n3 = min(M3, present.size + 2)
        for i in range(n2):
            x1, y1 = rng.uniform(0, W - 200), rng.uniform(0, H - 100)
            b = np.array([x1, y1, x1 + rng.uniform(20, 200), y1 + rng.uniform(20, 100)])
            box2[t, i] = np.trunc(b) if truncate else b
            score2[t, i] = rng.uniform(0.1, 1.0)
            valid2[t, i] = True
            gid2[t, i] = present[i] if i < present.size else -1
        for i in range(n3):
            x1, y1 = rng.uniform(0, W - 200), rng.uniform(0, H - 100)
            b = np.array([x1, y1, x1 + rng.uniform(20, 200), y1 + rng.uniform(20, 100)])
            box3[t, i] = np.trunc(b) if truncate else b
            score3[t, i] = rng.uniform(-1.0, 15.0)
            valid3[t, i] = True
            gid3[t, i] = present[i] if i < present.size else -1
            dims[t, i] = (1.5, 1.6, 3.9)
            loc[t, i] = (rng.uniform(-15, 15), 1.6, rng.uniform(5, 60))
    lo3, hi3 = box3d_extent(dims, loc, centroid)
    reset = np.zeros(T, bool); reset[0] = True; reset[T // 2] = True
    frames = Frames(reset=reset, box2=box2, score2=score2, valid2=valid2, box3=box3, score3=score3,
                    valid3=valid3, lo3=lo3, hi3=hi3)
    return frames, gid2, gid3


def np_frames(fr):
    return Frames(*(np.asarray(x) for x in fr))


def assert_identical(a, b):
    for name, x, y in zip(Frames._fields, a, b):
        x, y = np.asarray(x), np.asarray(y)
        assert x.dtype == y.dtype, name
        assert x.shape == y.shape, name
        assert np.array_equal(x, y), name
        # bit-identical, including the sign of zeros
        assert x.tobytes() == y.tobytes(), name


NB = 20   # every batch is padded to NB lanes: one compilation per (frames shape, spec)


def batch(frames, gid2, gid3, dps, spec):
    """jit(vmap) over a DistortParams batch [B <= NB] -> Frames [B, T, ...] (numpy)."""
    dps = list(dps)
    assert len(dps) <= NB
    out = D.distort_lanes(frames, gid2, gid3, D.stack_distort(dps + [dps[-1]] * (NB - len(dps))), spec)
    return Frames(*(np.asarray(x)[:len(dps)] for x in out))


def lane(out, b):
    return Frames(*(x[b] for x in out))


def _padded(options, **kw):
    spec = D.make_spec(options, clutter_slots=3)
    frames, gid2, gid3 = synth(truncate=options.truncate, centroid=options.centroid, **kw)
    return D.pad_for_clutter(frames, spec), *D.pad_identity(gid2, gid3, spec), spec


@pytest.fixture(scope="module")
def synthetic():
    """Truncated integer boxes, legacy 3D convention, 3 clutter slots."""
    return _padded(dm.Options())


@pytest.fixture(scope="module")
def synthetic_float():
    """Float boxes (no truncation), kitti 3D convention, 3 clutter slots."""
    return _padded(dm.Options(truncate=False, centroid="kitti"), seed=1)


@pytest.fixture(scope="module")
def kitti(kitti_root):
    split = dm.load_split(kitti_root, "rrc", "pointrcnn", "car", ["0000", "0001"])
    options = dm.Options()
    frames = dm.prepare_frames(split, options)
    gid2, gid3 = D.gt_identity(split, kitti_root, image_box_3d(split.box3d, split.proj3d, options))
    spec = D.make_spec(options, clutter_slots=3, frames=frames)
    return split, D.pad_for_clutter(frames, spec), *D.pad_identity(gid2, gid3, spec), spec


# ---- level 0, determinism, batching ---------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("which", ["synthetic", "synthetic_float"])
def test_level_zero_is_bit_identical_synthetic(which, request):
    frames, gid2, gid3, spec = request.getfixturevalue(which)
    dps = [D.level_params(kind, 0.0, seed=3) for kind in D.KINDS] + [D.DistortParams()]
    out = batch(frames, gid2, gid3, dps, spec)
    for b in range(len(dps)):
        assert_identical(lane(out, b), frames)


def test_level_zero_without_clutter_slots():
    frames, gid2, gid3 = synth(T=40)
    out = batch(frames, gid2, gid3, [D.level_params(k, 0.0, seed=2) for k in ("drop", "burst", "jitter")],
                D.make_spec(clutter_slots=0))
    for b in range(3):
        assert_identical(lane(out, b), frames)


@pytest.mark.slow
def test_level_zero_is_bit_identical_kitti(kitti):
    _, frames, gid2, gid3, spec = kitti
    dps = [D.level_params(kind, 0.0, seed=11) for kind in D.KINDS]
    out = batch(frames, gid2, gid3, dps, spec)
    for b in range(len(dps)):
        assert_identical(lane(out, b), frames)


MIX = dict(drop_3d=0.2, burst_rate=0.05, burst_len=4, jitter_2d=2.0, jitter_box3=1.0, jitter_3d=0.3,
           score_noise_2d=0.1, score_noise_3d=1.0, clutter_2d=1.0, clutter_3d=1.0)


@pytest.mark.slow      # (the not-slow tier's 3-minute budget)
def test_same_key_same_distortion_and_seeds_differ(synthetic):
    frames, gid2, gid3, spec = synthetic
    out = batch(frames, gid2, gid3, [D.level_params("drop_2d", 0.3, seed=s, **MIX) for s in (5, 5, 6)], spec)
    assert_identical(lane(out, 0), lane(out, 1))
    for name in Frames._fields[1:]:
        assert not np.array_equal(getattr(out, name)[0], getattr(out, name)[2]), name
    # the global frame index seeds the frame: an offset split differs
    shifted = D.distort_lanes(frames, gid2, gid3, D.stack_distort([D.level_params("drop_2d", 0.3, seed=5, **MIX)] * NB),
                              spec, t0=1000)
    assert not np.array_equal(np.asarray(shifted.valid2)[0], out.valid2[0])


@pytest.mark.slow          # the fast tier's budget: one of its costliest tests
def test_jit_vmap_batch_equals_single_lanes(synthetic):
    frames, gid2, gid3, spec = synthetic
    dps = [D.level_params("drop", 0.2, seed=1), D.level_params("burst", 5, seed=2),
           D.level_params("jitter", 2.0, seed=3), D.level_params("clutter", 1.5, seed=4),
           D.level_params("score", 0.1, seed=5), D.level_params("drop_2d", 0.3, seed=6, **MIX)]
    out = batch(frames, gid2, gid3, dps, spec)
    for b, dp in enumerate(dps):
        assert_identical(lane(out, b), D.distort_split(frames, gid2, gid3, dp, spec))


@pytest.mark.slow          # the fast tier's budget: one of its costliest tests
def test_inside_scan_under_x64_matches(synthetic):
    """The tracker's pattern: lax.scan over frames (xs = frames, gid2, gid3, t), vmap over lanes,
    under jax.enable_x64: the same bits as distort_split; float32 stays float32."""
    frames, gid2, gid3, spec = synthetic
    dps = [D.level_params("drop_2d", 0.3, seed=7, **MIX), D.level_params("none", 0, seed=8)]
    T = frames.reset.shape[0]

    def run_lane(dp, fr, g2, g3):
        def body(carry, xs):
            f, a, b, t = xs
            out = D.distort_frame(f, a, b, t, dp, spec)
            return carry + jnp.sum(out.valid2, dtype=jnp.int32), out
        return jax.lax.scan(body, jnp.int32(0), (fr, g2, g3, jnp.arange(T, dtype=jnp.int32)))

    with jax.enable_x64(True):
        fr = Frames(*(jnp.asarray(x) for x in frames))
        dpb = D.DistortParams(*(jnp.asarray(v) for v in D.stack_distort(dps)))
        count, out = jax.jit(jax.vmap(run_lane, in_axes=(0, None, None, None)))(dpb, fr, jnp.asarray(gid2),
                                                                                  jnp.asarray(gid3))
        out = np_frames(out)
    for b, dp in enumerate(dps):
        ref = D.distort_split(frames, gid2, gid3, dp, spec)
        assert_identical(lane(out, b), ref)
        assert int(count[b]) == int(np.asarray(ref.valid2).sum())
    assert_identical(lane(out, 1), frames)


# ---- independent drops ----------------------------------------------------------------------


def _drop_fractions(frames, gid2, gid3, spec, kind, p, seeds):
    out = batch(frames, gid2, gid3, [D.level_params(kind, p, seed=s) for s in seeds], spec)
    f2 = [(frames.valid2 & ~out.valid2[b]).sum() / frames.valid2.sum() for b in range(len(seeds))]
    f3 = [(frames.valid3 & ~out.valid3[b]).sum() / frames.valid3.sum() for b in range(len(seeds))]
    assert not np.any(out.valid2 & ~frames.valid2[None])          # drops never add detections
    return np.array(f2), np.array(f3)


def _within_3se(fracs, p):
    se = fracs.std(ddof=1) / np.sqrt(fracs.size)
    assert se > 0
    assert abs(fracs.mean() - p) <= 3 * se, (fracs.mean(), p, se)


@pytest.mark.slow
@pytest.mark.parametrize("p", [0.05, 0.3, 0.7])
def test_drop_fraction_within_3se_synthetic(synthetic, p):
    frames, gid2, gid3, spec = synthetic
    f2, f3 = _drop_fractions(frames, gid2, gid3, spec, "drop", p, range(20))
    _within_3se(f2, p)
    _within_3se(f3, p)
    f2, f3 = _drop_fractions(frames, gid2, gid3, spec, "drop_3d", p, range(20))
    assert np.all(f2 == 0)
    _within_3se(f3, p)


@pytest.mark.slow      # (the not-slow tier's 3-minute budget)
@pytest.mark.parametrize("p", [0.1, 0.5])
def test_drop_fraction_within_3se_kitti(kitti, p):
    _, frames, gid2, gid3, spec = kitti
    f2, f3 = _drop_fractions(frames, gid2, gid3, spec, "drop", p, range(100, 120))
    _within_3se(f2, p)
    _within_3se(f3, p)
    f2, f3 = _drop_fractions(frames, gid2, gid3, spec, "drop_2d", p, range(100, 120))
    _within_3se(f2, p)
    assert np.all(f3 == 0)


def test_drops_are_nested_across_levels(synthetic):
    frames, gid2, gid3, spec = synthetic
    out = batch(frames, gid2, gid3, [D.level_params("drop", p, seed=4) for p in (0.1, 0.3, 0.6)], spec)
    assert np.all(out.valid2[1] <= out.valid2[0]) and np.all(out.valid2[2] <= out.valid2[1])
    assert np.all(out.valid3[1] <= out.valid3[0]) and np.all(out.valid3[2] <= out.valid3[1])


# ---- bursts -----------------------------------------------------------------------------------


def _occlusion_oracle(seed, dp, spec, gids, T):
    """Host reconstruction from burst_draw: occ[g][t] for t in 0..T-1."""
    W_ = spec.burst_max
    s = np.arange(-W_, T)
    occ = {}
    for g in gids:
        start, length = D.burst_draw(seed, np.full(s.shape, g), s, dp, spec)
        row = np.zeros(T, bool)
        for si, st, L in zip(s, np.asarray(start), np.asarray(length)):
            if st:
                row[max(si, 0):max(min(si + L, T), 0)] = True
        occ[g] = row
    return occ


def test_burst_removes_all_detections_of_the_object(synthetic):
    frames, gid2, gid3, spec = synthetic
    dp = D.level_params("burst", 6, seed=9, burst_rate=0.03)
    out = lane(batch(frames, gid2, gid3, [dp], spec), 0)
    T = frames.reset.shape[0]
    occ = _occlusion_oracle(9, dp, spec, range(6), T)
    assert sum(o.sum() for o in occ.values()) > 20                # some bursts happened
    for valid, g, new in ((frames.valid2, gid2, out.valid2), (frames.valid3, gid3, out.valid3)):
        removed = valid & ~new
        expect = np.zeros_like(valid)
        for obj, row in occ.items():
            expect |= valid & (g == obj) & row[:, None]
        assert np.array_equal(removed, expect)
        assert not np.any(removed & (g < 0))                         # unmatched detections stay


@pytest.mark.slow        # (bursts on the synthetic scene stay in the fast tier)
def test_burst_on_kitti_hits_both_modalities(kitti):
    _, frames, gid2, gid3, spec = kitti
    out = lane(batch(frames, gid2, gid3, [D.level_params("burst", 8, seed=1, burst_rate=0.05)], spec), 0)
    rem2 = frames.valid2 & ~out.valid2
    rem3 = frames.valid3 & ~out.valid3
    assert rem2.sum() > 50 and rem3.sum() > 50
    for t in range(frames.reset.shape[0]):
        gone = set(gid2[t][rem2[t]]) | set(gid3[t][rem3[t]])
        for g in gone:                                                 # every detection of g vanished
            assert not np.any(out.valid2[t] & (gid2[t] == g))
            assert not np.any(out.valid3[t] & (gid3[t] == g))
        kept = set(gid2[t][out.valid2[t]]) | set(gid3[t][out.valid3[t]])
        assert not (gone & kept)


def _truncated_geometric_mean(mu, w):
    q = 1.0 / mu
    return (1 - (1 - q) ** w) / q


@pytest.mark.parametrize("dist,mu,expected", [
    ("fixed", 5.0, 5.0), ("fixed", 2.5, 2.5), ("geometric", 6.0, _truncated_geometric_mean(6.0, 30)),
    ("geometric", 20.0, _truncated_geometric_mean(20.0, 30)), ("uniform", 4.0, 4.0)])
def test_burst_length_distribution(dist, mu, expected):
    spec = D.make_spec(burst_dist=dist, burst_max=30)
    dp = D.DistortParams(burst_rate=1.0, burst_len=mu, seed=2)
    g, s = np.meshgrid(np.arange(100), np.arange(200), indexing="ij")
    start, length = D.burst_draw(2, g, s, dp, spec)
    L = np.asarray(length).ravel().astype(float)
    assert np.all(np.asarray(start))
    assert L.min() >= 1 and L.max() <= 30
    if dist == "fixed" and mu == int(mu):
        assert np.all(L == mu)
    elif dist == "fixed":
        assert set(np.unique(L)) == {2.0, 3.0}
    elif dist == "uniform":
        assert set(np.unique(L)) == set(range(1, 8))
    se = L.std() / np.sqrt(L.size)
    assert abs(L.mean() - expected) <= 3 * max(se, 1e-9), (L.mean(), expected, se)


def test_occluded_fraction_matches_rate_and_length():
    """Fixed length L, start rate r: an object-frame is occluded w.p. 1 - (1 - r)^L."""
    spec = D.make_spec(burst_dist="fixed", burst_max=30)
    r, L = 0.03, 7
    dp = D.DistortParams(burst_rate=r, burst_len=float(L), seed=13)
    G, T = 300, 400
    occ = jax.jit(jax.vmap(lambda t: D.occluded(jnp.arange(G, dtype=jnp.int32), t, dp, spec)))(
        jnp.arange(T, dtype=jnp.int32))
    per_obj = np.asarray(occ).mean(axis=0)                                       # [G]
    expected = 1 - (1 - r) ** L
    se = per_obj.std(ddof=1) / np.sqrt(G)
    assert abs(per_obj.mean() - expected) <= 3 * se, (per_obj.mean(), expected, se)
    assert not np.any(np.asarray(D.occluded(jnp.full(5, -1, jnp.int32), 10, dp, spec)))


# ---- jitter and score noise ---------------------------------------------------------------------


@pytest.mark.slow      # (the not-slow tier's 3-minute budget)
def test_jitter_std_untruncated(synthetic_float):
    frames, gid2, gid3, spec = synthetic_float
    sig2, sigb3, sig3 = 3.0, 2.0, 0.4
    dps = [D.DistortParams(jitter_2d=sig2, jitter_box3=sigb3, jitter_3d=sig3, seed=s) for s in range(5)]
    out = batch(frames, gid2, gid3, dps, spec)
    v2, v3 = frames.valid2, frames.valid3
    d2 = (out.box2 - frames.box2[None])[:, v2]          # [B, n, 4] (corners re-ordered: rare for these sizes)
    db3 = (out.box3 - frames.box3[None])[:, v3]
    d3 = (out.lo3 - frames.lo3[None])[:, v3]
    for d, sig in ((d2, sig2), (db3, sigb3), (d3, sig3)):
        n = d.size
        assert abs(d.mean()) <= 3 * sig / np.sqrt(n)
        assert abs(d.std() - sig) <= 3 * sig / np.sqrt(2 * n) + 0.01 * sig, (d.std(), sig)
    # the 3D box moves as a whole; empty slots never move
    np.testing.assert_allclose(out.hi3 - out.lo3, np.broadcast_to(frames.hi3 - frames.lo3, out.hi3.shape),
                               atol=1e-4)
    assert np.array_equal(out.box2[:, ~v2], np.broadcast_to(frames.box2[~v2], out.box2[:, ~v2].shape))
    assert np.array_equal(out.lo3[:, ~v3], np.broadcast_to(frames.lo3[~v3], out.lo3[:, ~v3].shape))


def test_jitter_truncated_boxes_stay_integer_with_rounded_noise(synthetic):
    frames, gid2, gid3, spec = synthetic
    sig = 3.0
    out = batch(frames, gid2, gid3, [D.level_params("jitter_2d", sig, seed=s) for s in range(5)], spec)
    v2 = frames.valid2
    assert np.all(out.box2 == np.trunc(out.box2))
    d = (out.box2 - frames.box2[None])[:, v2]                  # round(noise): std sqrt(sig^2 + 1/12)
    expected = np.sqrt(sig ** 2 + 1 / 12)
    assert abs(d.std() - expected) <= 3 * expected / np.sqrt(2 * d.size) + 0.01 * expected, (d.std(), expected)
    # sub-pixel jitter mostly leaves a truncated box unchanged
    small = batch(frames, gid2, gid3, [D.level_params("jitter_2d", 0.05, seed=1)], spec)
    assert np.mean(small.box2[0][v2] == frames.box2[v2]) > 0.99


def test_score_noise_std(synthetic):
    frames, gid2, gid3, spec = synthetic
    out = batch(frames, gid2, gid3, [D.level_params("score", 0.1, seed=s) for s in range(5)], spec)
    d2 = (out.score2 - frames.score2[None])[:, frames.valid2]
    d3 = (out.score3 - frames.score3[None])[:, frames.valid3]
    for d, sig in ((d2, 0.1), (d3, 0.1 * D.SCORE3_PER_SCORE2)):
        assert abs(d.std() - sig) <= 3 * sig / np.sqrt(2 * d.size) + 1e-3 * sig, (d.std(), sig)
    assert np.array_equal(out.valid2, np.broadcast_to(frames.valid2, out.valid2.shape))


# ---- clutter ------------------------------------------------------------------------------------


@pytest.mark.parametrize("which", ["synthetic", pytest.param("synthetic_float", marks=pytest.mark.slow)])
def test_clutter_count_and_geometry(which, request):
    frames, gid2, gid3, spec = request.getfixturevalue(which)
    S = spec.clutter_slots
    M2, M3 = frames.valid2.shape[1] - S, frames.valid3.shape[1] - S
    assert np.all(gid2[:, M2:] == -1) and np.all(gid3[:, M3:] == -1)
    assert not frames.valid2[:, M2:].any() and not frames.valid3[:, M3:].any()
    lam = 1.5
    out = batch(frames, gid2, gid3, [D.level_params("clutter", lam, seed=s) for s in range(NB)], spec)
    # real slots untouched
    for name in Frames._fields[1:]:
        m = M2 if name in ("box2", "score2", "valid2") else M3
        real = getattr(out, name)[:, :, :m]
        assert np.array_equal(real, np.broadcast_to(getattr(frames, name)[:, :m], real.shape)), name
    for valid in (out.valid2[:, :, M2:], out.valid3[:, :, M3:]):
        count = valid.sum(-1).ravel().astype(float)                   # per (seed, frame): independent
        se = count.std(ddof=1) / np.sqrt(count.size)
        assert abs(count.mean() - lam) <= 3 * se, (count.mean(), lam, se)
    # 2D clutter: inside the image, plausible sizes, integer when truncating, mostly in free space
    on2 = out.valid2[:, :, M2:]
    b2 = out.box2[:, :, M2:][on2]
    assert np.all(b2[:, 0] >= 0) and np.all(b2[:, 2] <= W - 1) and np.all(b2[:, 1] >= 0) and np.all(b2[:, 3] <= H - 1)
    assert np.all(b2[:, 2] > b2[:, 0]) and np.all(b2[:, 3] > b2[:, 1])
    assert np.all(b2 == np.trunc(b2)) == spec.truncate
    width = b2[:, 2] - b2[:, 0]
    assert D.WIDTH2_Q[0] - 1 <= width.min() and width.max() <= D.WIDTH2_Q[-1] + 1
    free = []
    for b, t, j in zip(*np.nonzero(on2)):
        rb = frames.box2[t][frames.valid2[t]]
        if rb.size:
            free.append(dm_boxes.iou(np.float64(out.box2[b, t, M2 + j][None]), np.float64(rb)).max() < D.FREE_IOU)
    assert np.mean(free) > 0.9
    s2 = out.score2[:, :, M2:][on2]
    assert s2.min() >= D.SCORE2_Q[0] - 1e-6 and s2.max() <= D.SCORE2_Q[-1] + 1e-6
    # 3D clutter: car-sized boxes in the frames' convention, in front of the camera, apart from others
    on3 = out.valid3[:, :, M3:]
    lo, hi = out.lo3[:, :, M3:][on3], out.hi3[:, :, M3:][on3]
    h, w, l = D.CAR_DIMS
    ref_lo, ref_hi = box3d_extent(np.array([[h, w, l]]), np.array([[0.0, D.CAR_Y, 20.0]]), spec.centroid)
    np.testing.assert_allclose(hi - lo, np.broadcast_to(ref_hi - ref_lo, lo.shape), atol=1e-5)
    xz = np.asarray(D.ground_xz(lo, hi, spec.centroid))
    assert np.all(xz[:, 1] >= D.CLUTTER_Z[0]) and np.all(xz[:, 1] <= D.CLUTTER_Z[1])
    assert np.all(np.abs(xz[:, 0]) <= D.CLUTTER_XZ * xz[:, 1] + 1e-4)
    real_xz = np.asarray(D.ground_xz(frames.lo3, frames.hi3, spec.centroid))          # [T, M3 + S, 2]
    apart = [np.min(np.linalg.norm(real_xz[t][frames.valid3[t]] - xz_i, axis=-1)) >= D.FREE_DIST
             for xz_i, (b, t, j) in zip(xz, zip(*np.nonzero(on3))) if frames.valid3[t].any()]
    assert np.mean(apart) > 0.9
    b3 = out.box3[:, :, M3:][on3]
    assert np.all(b3[:, 2] >= b3[:, 0]) and np.all(b3[:, 3] > b3[:, 1])
    s3 = out.score3[:, :, M3:][on3]
    assert s3.min() >= D.SCORE3_Q[0] - 1e-5 and s3.max() <= D.SCORE3_Q[-1] + 1e-5


def test_clutter_never_overwrites_a_detection(synthetic):
    frames, gid2, gid3, spec = synthetic
    S = spec.clutter_slots
    # real detections sitting in the reserved slots (frames not padded for clutter)
    frames = frames._replace(valid2=frames.valid2.copy(), valid3=frames.valid3.copy())
    frames.valid2[::2, -S:] = True
    frames.valid3[::2, -S:] = True
    out = lane(batch(frames, gid2, gid3, [D.level_params("clutter", 3.0, seed=1)], spec), 0)
    for name in ("box2", "score2"):
        assert np.array_equal(getattr(out, name)[frames.valid2], getattr(frames, name)[frames.valid2])
    for name in ("box3", "score3", "lo3", "hi3"):
        assert np.array_equal(getattr(out, name)[frames.valid3], getattr(frames, name)[frames.valid3])
    assert out.valid2[1::2, -S:].all() and out.valid3[1::2, -S:].all()       # clutter 3.0 = every slot


# ---- host side and API ------------------------------------------------------------------------


def test_level_params_mapping():
    assert D.level_params("drop", 0.2, seed=4) == D.DistortParams(drop_2d=0.2, drop_3d=0.2, seed=4)
    b = D.level_params("burst", 8)
    assert b.burst_len == 8 and b.burst_rate == D.BURST_RATE
    assert D.level_params("burst", 8, burst_rate=0.1).burst_rate == 0.1
    r = D.level_params("burst_rate", 0.05)
    assert r.burst_rate == 0.05 and r.burst_len == D.BURST_LEN
    j = D.level_params("jitter", 2.0, metres_per_pixel=0.1)
    assert (j.jitter_2d, j.jitter_box3, j.jitter_3d) == (2.0, 2.0, pytest.approx(0.2))
    s = D.level_params("score", 0.1)
    assert s.score_noise_2d == 0.1 and s.score_noise_3d == pytest.approx(0.1 * D.SCORE3_PER_SCORE2)
    c = D.level_params("clutter_3d", 1.0, seed=2, drop_2d=0.1)
    assert (c.clutter_2d, c.clutter_3d, c.drop_2d, c.seed) == (0.0, 1.0, 0.1, 2)
    with pytest.raises(ValueError):
        D.level_params("occlusion", 0.1)
    with pytest.raises(ValueError):
        D.level_params("drop", 0.1, dropout=0.2)
    with pytest.raises(ValueError):
        D.make_spec(burst_dist="poisson")
    st = D.stack_distort([D.level_params("drop", p, seed=i) for i, p in enumerate((0.1, 0.2))])
    assert st.drop_2d.dtype == np.float32 and st.seed.dtype == np.int32 and st.drop_2d.shape == (2,)


def test_gt_identity_kitti(kitti, kitti_root):
    split, frames, gid2, gid3, spec = kitti
    M2, M3 = split.valid2d.shape[1], split.valid3d.shape[1]
    assert gid2.shape == (split.n_frames, M2 + spec.clutter_slots) and gid2.dtype == np.int32
    g2, g3 = gid2[:, :M2], gid3[:, :M3]
    assert np.all(g2[~split.valid2d] == -1) and np.all(g3[~split.valid3d] == -1)
    assert (g2[split.valid2d] >= 0).mean() > 0.8                    # RRC cars mostly match a GT box
    assert (g3[split.valid3d] >= 0).mean() > 0.4
    labels = dm.io.kitti.read_tracking_labels(kitti_root / "label_02" / "0000.txt")
    t = 10
    ids = set(labels.track_id[(labels.frame == t) & (labels.type != "DontCare")])
    assert set(g2[t][g2[t] >= 0]) <= ids


def test_spec_groups_and_param_checks(synthetic):
    frames, gid2, gid3, spec = synthetic
    drops = D.stack_distort([D.level_params("drop", 0.2, seed=s) for s in range(3)])
    assert D.used_groups(drops) == ("drop",)
    only = D.make_spec(dm.Options(), clutter_slots=3, dps=drops)
    assert only.enabled == ("drop",)
    with pytest.raises(ValueError, match="not compiled"):
        D.check_params(D.level_params("jitter", 1.0), only)
    with pytest.raises(ValueError, match="clutter_slots"):
        D.make_spec(dps=D.level_params("clutter", 1.0))
    with pytest.raises(ValueError, match="probability"):
        D.check_params(D.level_params("drop", 1.5), spec)
    with pytest.raises(ValueError, match=">= 0"):
        D.check_params(D.level_params("jitter", -1.0), spec)
    with pytest.raises(ValueError, match="unknown groups"):
        D.make_spec(enabled=("drop", "blur"))
    # a spec compiling only drops gives the same drops as the full spec, and ignores other levels
    dps = [D.level_params("drop", 0.3, seed=s) for s in range(3)]
    full = batch(frames, gid2, gid3, dps, spec)
    part = batch(frames, gid2, gid3, dps, only)
    for b in range(3):
        assert_identical(lane(part, b), lane(full, b))


def test_clutter_and_bursts_are_nested_across_levels(synthetic):
    frames, gid2, gid3, spec = synthetic
    S = spec.clutter_slots
    out = batch(frames, gid2, gid3, [D.level_params("clutter", lam, seed=3) for lam in (0.5, 1.5, 2.5)], spec)
    on = out.valid2[:, :, -S:]
    assert np.all(on[0] <= on[1]) and np.all(on[1] <= on[2])
    same = on[0]                                   # a clutter box present at both levels is the same box
    assert np.array_equal(out.box2[0][:, -S:][same], out.box2[1][:, -S:][same])
    out = batch(frames, gid2, gid3, [D.level_params("burst", L, seed=3, burst_rate=0.03) for L in (2, 5, 9)],
                spec)
    assert np.all(out.valid2[2] <= out.valid2[1]) and np.all(out.valid2[1] <= out.valid2[0])
    assert np.all(out.valid3[2] <= out.valid3[1]) and np.all(out.valid3[1] <= out.valid3[0])


# ---- one geometry: the distortions trace the loaders' own functions ---------------------------


def _random_boxes(rng, n):
    b = rng.uniform(-20, 1300, (n, 4))
    b[: n // 4, 2:] = b[: n // 4, :2] - rng.uniform(0, 30, (n // 4, 2))      # some inverted boxes
    return b


# (x1, y1, x2, y2) -> the 2D loader's box, the 3D loader's box, by hand with C++ (int) (towards
# zero): 2D x = (int) x1, w = |x - (int) x2|; 3D x = (int) x1, w = (int) |x - x2|; out (x, y, x + w, y + h).
_TRUNCATION_CASES = [
    ([10.9, 20.2, 50.7, 80.99], [10, 20, 50, 80], [10, 20, 50, 80]),
    ([-0.5, -1.5, 2.5, 3.5], [0, -1, 2, 3], [0, -1, 2, 3]),          # (int) -0.5 = 0, (int) -1.5 = -1
    ([-3.7, 0.5, -1.2, 0.5], [-3, 0, -1, 0], [-3, 0, -2, 0]),        # 2D |-3 - -1| = 2; 3D (int) 1.8 = 1
    ([5.0, 7.0, 2.5, 1.5], [5, 7, 8, 13], [5, 7, 7, 12]),            # inverted: 2D |5 - 2| = 3; 3D (int) 2.5 = 2
    ([1241.5, 374.5, 1241.9, 374.99], [1241, 374, 1241, 374], [1241, 374, 1241, 374]),
    ([100.5, 50.5, 200.5, 150.5], [100, 50, 200, 150], [100, 50, 200, 150]),
]


def test_truncation_by_hand_in_numpy_and_jax():
    from dfrmot_jax.boxes import truncate_2d_box, truncate_3d_box
    box = np.array([c[0] for c in _TRUNCATION_CASES])
    for fn, col in ((truncate_2d_box, 1), (truncate_3d_box, 2)):
        want = np.array([c[col] for c in _TRUNCATION_CASES], np.float64)
        np.testing.assert_array_equal(fn(box), want)
        np.testing.assert_array_equal(np.asarray(jax.jit(fn)(jnp.asarray(box, jnp.float32))), want)
        with jax.enable_x64(True):
            np.testing.assert_array_equal(np.asarray(jax.jit(fn)(jnp.asarray(box))), want)
        # NaN stays in its coordinates (a projected box behind the camera)
        out = fn(np.array([[np.nan, 1.0, 2.0, 3.0]]))[0]
        assert np.isnan(out[[0, 2]]).all() and out[1] == 1 and out[3] == 3
        # the traced function (the distortions' re-truncation in the scan) gives the NumPy bits
        rnd = _random_boxes(np.random.default_rng(0), 64).astype(np.float32)
        assert np.asarray(jax.jit(fn)(jnp.asarray(rnd))).tobytes() == fn(rnd).tobytes()


def test_box3d_extent_by_hand_and_against_the_corners():
    # dyadic values, exact in float32: (h, w, l) = (1.5, 1.75, 4), (x, y, z) = (2, 1.25, 20.5)
    dims, loc = np.array([[1.5, 1.75, 4.0]]), np.array([[2.0, 1.25, 20.5]])
    by_hand = {"legacy": ([20.5, 1.25, 2.0], [24.5, 3.0, 3.5]),      # (z, y, x) + (l, w, h)
               "head": ([20.5, -2.0, -1.25], [24.5, -0.5, 0.5]),     # (z, -x, -y) + (l, h, w)
               "kitti": ([0.0, -0.25, 19.625], [4.0, 1.25, 21.375])}  # (x -+ l/2, y - h .. y, z -+ w/2)
    for centroid, (lo, hi) in by_hand.items():
        got = box3d_extent(dims, loc, centroid)
        with jax.enable_x64(True):
            got_j = jax.jit(box3d_extent, static_argnums=2)(jnp.asarray(dims, jnp.float32),
                                                             jnp.asarray(loc, jnp.float32), centroid)
        for g, gj, want in zip(got, got_j, (lo, hi)):
            assert g.dtype == np.float32
            np.testing.assert_array_equal(g[0], want)
            np.testing.assert_array_equal(np.asarray(gj)[0], want)
    # "kitti" is the axis-aligned hull of the box's 8 corners at rot_y = 0 (geometry.box3d_corners)
    rng = np.random.default_rng(0)
    dims = rng.uniform(0.5, 5.0, (32, 3)); loc = rng.uniform(-30, 60, (32, 3))
    corners = dm.geometry.box3d_corners(dims, loc, np.zeros(32))
    lo, hi = box3d_extent(dims, loc, "kitti")
    np.testing.assert_allclose(lo, corners.min(axis=1), rtol=1e-6, atol=1e-5)
    np.testing.assert_allclose(hi, corners.max(axis=1), rtol=1e-6, atol=1e-5)


def _iou_by_formula(a, b) -> float:
    """IoU of two boxes written out: overlap rectangle over the sum of areas minus the overlap."""
    ax1, ay1, ax2, ay2 = (float(v) for v in a)
    bx1, by1, bx2, by2 = (float(v) for v in b)
    if any(v != v for v in (ax1, ay1, ax2, ay2, bx1, by1, bx2, by2)):
        return 0.0
    w = min(ax2, bx2) - max(ax1, bx1)
    h = min(ay2, by2) - max(ay1, by1)
    if w <= 0 or h <= 0:
        return 0.0
    inter = w * h
    union = (ax2 - ax1) * (ay2 - ay1) + (bx2 - bx1) * (by2 - by1) - inter
    return inter / union if union > 0 else 0.0


def test_iou_against_the_formula():
    from dfrmot_jax import boxes
    a0 = [0.0, 0.0, 10.0, 10.0]
    hand = [(a0, a0, 1.0), (a0, [5.0, 5.0, 15.0, 15.0], 25 / 175), (a0, [5.0, 0.0, 15.0, 10.0], 50 / 150),
            (a0, [2.0, 2.0, 4.0, 4.0], 4 / 100),                                    # contained
            ([-4.0, -4.0, 4.0, 4.0], [0.0, -8.0, 8.0, 0.0], 16 / 112),              # negative coordinates
            (a0, [10.0, 0.0, 20.0, 10.0], 0.0), (a0, [20.0, 20.0, 30.0, 30.0], 0.0),  # touching, apart
            ([1.0, 1.0, 1.0, 1.0], [1.0, 1.0, 1.0, 1.0], 0.0),                      # empty union
            (a0, [8.0, 8.0, 2.0, 2.0], 0.0), (a0, [2.0, 8.0, 8.0, 2.0], 0.0),       # inverted
            (a0, [np.nan] * 4, 0.0)]
    for a, b, want in hand:
        assert _iou_by_formula(a, b) == pytest.approx(want, abs=0)
        for clip in (True, False):
            assert float(boxes.iou(np.array(a), np.array(b), clip_areas=clip)) == pytest.approx(want, rel=1e-15)
    rng = np.random.default_rng(1)

    def near(n):                                   # boxes in a 200 px square, every tenth inverted
        xy = rng.uniform(-50, 150, (n, 2)); wh = rng.uniform(5, 120, (n, 2))
        wh[::10] *= -1
        return np.concatenate([xy, xy + wh], axis=1)

    a, b = near(24), near(20)
    a[3] = np.nan
    want = np.array([[_iou_by_formula(x, y) for y in b] for x in a])
    assert (want > 0).sum() > 100                                                 # some overlap
    np.testing.assert_allclose(boxes.iou(a[:, None], b[None]), want, rtol=1e-13, atol=0)
    np.testing.assert_allclose(boxes.iou(a[:, None], b[None], clip_areas=False), want, rtol=1e-13, atol=0)
    # the tracker's matrix (float32 inputs, as the step's boxes outside x64), and the clutter's jax path
    af, bf = jnp.asarray(a, jnp.float32), jnp.asarray(b, jnp.float32)
    np.testing.assert_allclose(np.asarray(boxes.iou_matrix(af, bf)), want, atol=1e-5)
    np.testing.assert_allclose(np.asarray(boxes.iou(af[:, None], bf[None])), want, atol=1e-5)


def test_clutter_projection_has_the_loaders_behind_the_camera_rule():
    from dfrmot_jax.distort.exact import project_box
    P2 = np.array(D.DEFAULT_P2).reshape(3, 4)
    dims = np.array([[1.5, 1.6, 3.9]] * 4)
    loc = np.array([[2.0, 1.6, 20.0],       # in front
                    [1.0, 1.6, 1.0],        # straddles the camera plane: corners behind are ignored
                    [0.0, 1.6, -10.0],      # behind: NaN
                    [-3.0, 1.6, 0.5]])
    rot = np.array([0.3, 1.2, 0.0, -0.7])
    ref = dm.geometry.project_box3d_to_image(dims, loc, rot, P2, (W, H))
    with jax.enable_x64(True):
        got = np.asarray(project_box(jnp.asarray(dims, jnp.float32), jnp.asarray(loc, jnp.float32),
                                     jnp.asarray(rot, jnp.float32), D.DEFAULT_P2, (W, H)))
    assert got.dtype == np.float32
    np.testing.assert_array_equal(np.isnan(got), np.isnan(ref))
    assert np.all(np.isnan(got[2]))
    np.testing.assert_allclose(got[~np.isnan(ref)], ref[~np.isnan(ref)], rtol=0, atol=2e-3)
    # the 3D clutter never gets there: its nearest corner is ~2.9 m in front with a KITTI P2
    half_diag = 0.5 * np.hypot(D.CAR_DIMS[1], D.CAR_DIMS[2])
    assert D.CLUTTER_Z[0] - half_diag + P2[2, 3] > 10 * dm.geometry.MIN_DEPTH
