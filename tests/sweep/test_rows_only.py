"""Outputs kept at their rows only (``track(rows_only=True)``, :class:`dfrmot_jax.rows.Rows`): the same
values as the dense arrays at ``ids >= 0``, and every reader of the rows (the scorer's digests and
scores, AB3DMOT's rows and digests) gives the same as from the dense arrays."""

from __future__ import annotations

import numpy as np
import pytest

import dfrmot_jax as dm
from dfrmot_jax.trackers.dfr.config import Params
from dfrmot_jax.metrics import prepare_gt
from dfrmot_jax.metrics.kitti2d.evaluate import result_dicts
from dfrmot_jax.metrics.kitti2d.padded import tracker_dets_from_arrays
from dfrmot_jax.metrics.kitti2d.lane_scorer import LaneScorer
from dfrmot_jax.trackers.dfr.results import kitti_rows
from dfrmot_jax.rows import Rows, lane_values, row_starts
from dfrmot_jax.synthetic import make_scene


def test_rows_of_a_small_batch_by_hand():
    ids = np.array([[[0, -1, 1], [-1, -1, -1], [2, 3, -1]],
                    [[-1, -1, -1], [4, -1, -1], [-1, -1, 5]]])          # [B=2, T=3, K=3]
    dense = np.arange(2 * 3 * 3 * 2, dtype=np.float32).reshape(2, 3, 3, 2)
    r = Rows.of(ids, dense)
    np.testing.assert_array_equal(r.start, [0, 2, 2, 4, 4, 5, 6])
    np.testing.assert_array_equal(r.values, dense[ids >= 0])
    assert r.n_lanes == 2 and r.values.shape == (6, 2)
    np.testing.assert_array_equal(r.lane(0), dense[0][ids[0] >= 0])
    np.testing.assert_array_equal(r.lane(0, 1, 3), dense[0, 2, :2])
    np.testing.assert_array_equal(r.lane(1, 2), dense[1, 2, 2:])
    np.testing.assert_array_equal(lane_values(r, ids, 0, 1, 3), lane_values(dense, ids, 0, 1, 3))
    np.testing.assert_array_equal(lane_values(dense, ids, 1), dense[1][ids[1] >= 0])
    np.testing.assert_array_equal(r.lanes([1, 0]), np.concatenate([dense[1][ids[1] >= 0], dense[0][ids[0] >= 0]]))
    np.testing.assert_array_equal(r.lanes([1]), dense[1][ids[1] >= 0])
    back = r.dense(ids, fill=-7)
    np.testing.assert_array_equal(back[ids >= 0], dense[ids >= 0])
    assert (back[ids < 0] == -7).all()
    np.testing.assert_array_equal(r.lane_dense(1, ids[1], 0)[ids[1] >= 0], dense[1][ids[1] >= 0])


@pytest.fixture(scope="module")
def both(tmp_path_factory):
    root = make_scene(tmp_path_factory.mktemp("rows"), n_sequences=3, n_frames=50, n_cars=14, seed=5)
    split = dm.load_split(root, "synth2d", "synth3d", "car")
    params = dm.stack_params([Params(a_l=a, epsilon=e) for a in (2.0, 8.0) for e in (1, 3, 30)])
    # capacity 11 overflows some lanes, which run again with more slots: their rows replace the first run's
    opts = dm.Options(output="filtered", capacity=11)
    dense = dm.track(split, params, opts, detail=True, lanes_per_call=4)
    rows = dm.track(split, params, opts, detail=True, lanes_per_call=4, rows_only=True)
    return root, split, dense, rows


@pytest.mark.slow      # (tracks: the not-slow tier's 3-minute budget; the full suite runs it)
def test_rows_equal_the_dense_arrays_at_their_rows(both):
    _, _, dense, rows = both
    assert isinstance(rows.boxes, Rows) and isinstance(rows.box3, Rows)
    assert len(set(dense.capacity.tolist())) > 1          # some lanes ran again with more slots
    np.testing.assert_array_equal(rows.ids, dense.ids)
    np.testing.assert_array_equal(rows.src3, dense.src3)
    live = dense.ids >= 0
    assert rows.boxes.values.dtype == dense.boxes.dtype
    np.testing.assert_array_equal(rows.boxes.values, dense.boxes[live])
    np.testing.assert_array_equal(rows.box3.values, dense.box3[live])
    np.testing.assert_array_equal(rows.boxes.start, row_starts(dense.ids))
    for b in (0, 3):
        np.testing.assert_array_equal(lane_values(rows.box3, rows.ids, b, 5, 70), lane_values(dense.box3, dense.ids, b, 5, 70))
    for b in range(dense.ids.shape[0]):
        np.testing.assert_array_equal(rows.boxes.lane(b, 10, 60), dense.boxes[b, 10:60][live[b, 10:60]])
        np.testing.assert_array_equal(rows.lane_boxes(b)[live[b]], dense.lane_boxes(b)[live[b]])
    pick = [4, 0, 2]
    np.testing.assert_array_equal(rows.box3.lanes(pick), np.concatenate([dense.box3[b][live[b]] for b in pick]))
    back = rows.boxes.dense(rows.ids)
    np.testing.assert_array_equal(back[live], dense.boxes[live])
    assert np.isnan(back[~live]).all()


@pytest.mark.slow
def test_the_scorer_reads_rows_as_the_dense_arrays(both):
    root, split, dense, rows = both
    gt = prepare_gt(root, "car", split.names)
    sc_dense, sc_rows = (LaneScorer(gt, split.offsets, as_written=True) for _ in range(2))
    per_dense = sc_dense.seq_digests(dense.ids, dense.boxes)
    per_rows = sc_rows.seq_digests(rows.ids, rows.boxes)
    assert per_rows == per_dense
    assert LaneScorer.digests(rows.ids, rows.boxes) == LaneScorer.digests(dense.ids, dense.boxes)
    items = sc_dense.new_items(per_dense)
    got = sc_rows.evaluate(sc_rows.dets(rows.ids, rows.boxes, items))
    want = sc_dense.evaluate(sc_dense.dets(dense.ids, dense.boxes, items))
    _same(got, want)
    # frames taken apart from the rows (offsets other than the ground truth's): the padded form
    shifted = np.concatenate([np.full_like(rows.ids[:, :2], -1), rows.ids], axis=1)
    moved = Rows.of(shifted, np.concatenate([np.zeros_like(dense.boxes[:, :2]), dense.boxes], axis=1))
    a = result_dicts(gt, dm.metrics.evaluate_batch(gt, tracker_dets_from_arrays(gt, shifted, moved, split.offsets + 2)))
    b = result_dicts(gt, dm.metrics.evaluate_batch(gt, tracker_dets_from_arrays(gt, dense.ids, dense.boxes, split.offsets)))
    for lane in range(len(b)):
        for f, v in b[lane]["COMBINED"].items():
            np.testing.assert_array_equal(a[lane]["COMBINED"][f], v, err_msg=f)
    with pytest.raises(ValueError, match="rows of ids"):
        tracker_dets_from_arrays(gt, rows.ids[:, :-1], rows.boxes, split.offsets)


def _same(got, want, where=""):
    if isinstance(want, dict):
        assert set(got) == set(want), where
        for k in want:
            _same(got[k], want[k], f"{where}/{k}")
    else:
        np.testing.assert_array_equal(got, want, err_msg=where)


@pytest.mark.slow
def test_result_rows_and_ab3dmot_digests_from_rows(both):
    from dfrmot_jax.metrics.samota.prep import Ab3dGT  # noqa: F401  (AB3DMOT's family importable)
    from dfrmot_jax.sweep.samota_lanes import Ab3dmotLanes

    _, split, dense, rows = both
    for lanes in (None, [3, 1]):
        a, b = kitti_rows(split, dense, lanes=lanes), kitti_rows(split, rows, lanes=lanes)
        for f in a._fields:
            va, vb = getattr(a, f), getattr(b, f)
            if isinstance(va, np.ndarray):
                np.testing.assert_array_equal(vb, va, err_msg=f)
            else:
                assert vb == va, f

    class _GT:
        sequences = split.names

    lanes = Ab3dmotLanes(_GT(), split, "3d:0.25")
    assert lanes.digests(rows) == lanes.digests(dense)
