"""Result-file 3D fields: the JAX tracker names, row for row, the 3D detection the oracle names
(its own, or its track's stale one) and, for filtered output, the same filtered 3D corners."""

import numpy as np
import pytest

from dfrmot_jax.trackers.dfr.track import track
from dfrmot_jax.data import load_sequences, pack
from dfrmot_jax.trackers.dfr.config import preset, stack_params
from dfrmot_jax.testing.parity import reference_lane, reference_rows
from dfrmot_jax.testing import random_settings


def _by_key(ids, *values):
    """{(t, id): tuple of the values at that row} for the written rows of one lane."""
    t, k = np.nonzero(ids >= 0)
    return {(int(a), int(ids[a, b])): tuple(np.asarray(v[a, b]).tolist() for v in values) for a, b in zip(t, k)}


def _compare(split, seqs, params, options, res, lane):
    ref = reference_lane(split, seqs, reference_rows(seqs, params, options), options)
    ids = res.ids[lane]
    assert _by_key(ids) == _by_key(ref.ids), "rows differ"
    mine = _by_key(ids, res.src3[lane], res.own3[lane])
    theirs = _by_key(ref.ids, ref.src3, ref.own3)
    assert mine == theirs
    if options.output == "filtered":
        t, k = np.nonzero(ids >= 0)
        has = res.src3[lane][t, k] >= 0
        got = {(int(a), int(ids[a, b])): res.box3[lane][a, b] for a, b, h in zip(t, k, has) if h}
        rt, rk = np.nonzero(ref.ids >= 0)
        want = {(int(a), int(ref.ids[a, b])): ref.box3[a, b] for a, b in zip(rt, rk) if ref.src3[a, b] >= 0}
        assert got.keys() == want.keys()
        for key in got:
            np.testing.assert_allclose(got[key], want[key].astype(np.float32), rtol=0, atol=0)
    return len(mine), sum(not v[1] and v[0] >= 0 for v in mine.values())


@pytest.fixture(scope="module")
def kitti_car(kitti_root):
    seqs = load_sequences(kitti_root, "rrc", "pointrcnn", "car")
    return seqs, pack(seqs, "car")


@pytest.mark.slow
def test_dfr2023_rows_carry_the_oracles_3d_detections(kitti_car):
    seqs, split = kitti_car
    params, options = preset("dfr2023")
    res = track(split, params, options, detail=True)
    rows, stale = _compare(split, seqs, params, options, res, 0)
    assert rows == 28812 and stale == 2033          # the published files hold 2,033 stale 3D boxes


@pytest.mark.slow
def test_random_settings_rows_carry_the_oracles_3d_detections(kitti_car):
    seqs, split = kitti_car
    few = [0, 4, 11]
    seqs = [seqs[i] for i in few]
    split = pack(seqs, "car")
    rng = np.random.default_rng(7)
    checked = {"detections": 0, "filtered": 0}
    for params, options in random_settings(rng, 4):
        res = track(split, stack_params([params]), options, detail=True)
        rows, _ = _compare(split, seqs, params, options, res, 0)
        checked[options.output] += rows
    assert min(checked.values()) > 1000, checked
