"""The 2D side of ``distort.lanes`` (family-free): 2D-only frames (``frames_2d``), the 3D levels
zeroed (``only_2d``), a lane's 2D detections read back by the module's one rule (``read_back_2d``:
untouched values the file's float64, drawn values the distorted frame's float32), and the kinds a
family reading one modality refuses (``sweep.distortion.refused_kinds``)."""

from __future__ import annotations

import numpy as np
import pytest

from dfrmot_jax import distort
from dfrmot_jax.data import load_split
from dfrmot_jax.sweep.distortion import kinds_2d, kinds_3d, refused_kinds
from dfrmot_jax.synthetic import make_scene

SLOTS = 2


@pytest.fixture(scope="module")
def split(tmp_path_factory):
    root = make_scene(tmp_path_factory.mktemp("lanes2d"), n_sequences=2, n_frames=30, n_cars=4, seed=3)
    return load_split(root, "synth2d", None, "car")


def test_frames_2d_hold_the_2d_detections_only(split):
    dets = distort.split_detections_2d(split)
    f = distort.frames_2d(dets, split.reset)
    t, m = split.valid2d.shape
    assert f.box2.dtype == np.float32 and f.score2.dtype == np.float32 and f.valid2.dtype == bool
    np.testing.assert_array_equal(f.box2, split.box2d.astype(np.float32))          # untruncated
    np.testing.assert_array_equal(f.valid2, split.valid2d)
    assert f.box3.shape == (t, 0, 4) and f.valid3.shape == (t, 0) and f.lo3.shape == (t, 0, 3)
    assert dets.padded(m + 3).valid.shape == (t, m + 3) and not dets.padded(m + 3).valid[:, m:].any()
    packed = dets.packed()
    n = packed.valid.sum(1)
    assert np.all(packed.valid == (np.arange(m) < n[:, None]))
    np.testing.assert_array_equal(packed.box[packed.valid], dets.box[dets.valid])


def test_only_2d_and_only_3d_zero_the_other_modality():
    dp = distort.level_params("drop", 0.2, seed=4, jitter_2d=1.0, jitter_box3=2.0, jitter_3d=0.3, score_noise_2d=0.1,
                              score_noise_3d=1.0, clutter_2d=1.0, clutter_3d=1.0, burst_rate=0.1, burst_len=3.0)
    two, three = distort.only_2d(dp), distort.only_3d(dp)
    for n in distort.LEVELS_3D:
        assert getattr(two, n) == 0 and getattr(three, n) == getattr(dp, n)
    for n in distort.LEVELS_2D:
        assert getattr(three, n) == 0 and getattr(two, n) == getattr(dp, n)
    for n in ("burst_rate", "burst_len", "seed"):            # bursts occlude both modalities
        assert getattr(two, n) == getattr(dp, n) == getattr(three, n)
    assert set(kinds_2d()) & set(kinds_3d()) == set()
    assert set(refused_kinds(("2d",))) == set(kinds_3d()) and set(refused_kinds(("3d",))) == set(kinds_2d())
    assert refused_kinds(("2d", "3d")) == {}


def test_a_lanes_2d_detections_read_back_by_the_one_rule(split):
    """Drops and bursts only: every kept value the file's float64, bit for bit; jitter, score noise
    and clutter: those values the distorted frame's float32 ones; level 0: the file values."""
    dps = distort.stack_distort([distort.level_params("none", 0.0),
                                 distort.level_params("drop_2d", 0.3, seed=1, burst_rate=0.1, burst_len=3.0,
                                                      drop_3d=0.5, jitter_3d=1.0),
                                 distort.level_params("clutter_2d", 1.5, seed=2, jitter_2d=2.0, score_noise_2d=0.1)])
    spec = distort.make_spec(None, clutter_slots=SLOTS, truncate=False, dps=distort.only_2d(dps))
    ld = distort.distortion_2d(split, dps, spec)
    assert ld.frames.valid2.shape[1] == split.valid2d.shape[1] + SLOTS and ld.gid2.shape == ld.frames.valid2.shape
    assert float(ld.params.drop_3d[1]) == 0 and float(ld.params.jitter_3d[1]) == 0
    base = distort.split_detections_2d(split)
    m = split.valid2d.shape[1]
    got = ld.lanes(None, [0, 1, 2], base)
    assert [d.which.tolist() for d in got] == [[0], [1], [2]] and all(d.dets is None for d in got)
    zero, drop, noisy = (d.dets2 for d in got)
    for f in ("valid", "score", "box"):
        np.testing.assert_array_equal(getattr(zero, f)[:, :m], getattr(base, f))
    assert drop.valid.sum() < base.valid.sum() and not (drop.valid & ~zero.valid).any()
    np.testing.assert_array_equal(drop.box[drop.valid], zero.box[drop.valid])          # file values, float64
    np.testing.assert_array_equal(drop.score[drop.valid], zero.score[drop.valid])
    after = distort.distort_split(ld.frames, ld.gid2, ld.gid3, distort.lane_params(ld.params, 2), spec)
    v = noisy.valid
    np.testing.assert_array_equal(v, np.asarray(after.valid2))
    np.testing.assert_array_equal(noisy.box[v], np.asarray(after.box2)[v].astype(np.float64))
    np.testing.assert_array_equal(noisy.score[v], np.asarray(after.score2)[v].astype(np.float64))
    assert v[:, m:].sum() > 3                                   # clutter in the reserved slots
