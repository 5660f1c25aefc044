"""LaneScorer: each distinct output of each sequence scored once, packed into virtual lanes; every
lane's fields equal scoring it alone (bit for bit), whatever its sequences share with other lanes."""

from __future__ import annotations

import numpy as np
import pytest

import dfrmot_jax as dm
from dfrmot_jax.trackers.dfr.config import Params
from dfrmot_jax.metrics import evaluate_arrays, evaluate_batch, prepare_gt
from dfrmot_jax.metrics.kitti2d.evaluate import result_dicts
from dfrmot_jax.metrics.kitti2d.padded import tracker_dets_from_arrays
from dfrmot_jax.metrics.kitti2d.lane_scorer import LaneScorer
from dfrmot_jax.synthetic import make_scene


@pytest.fixture(scope="module")
def outputs(tmp_path_factory):
    root = make_scene(tmp_path_factory.mktemp("lane_scorer"), n_sequences=3, n_frames=60, n_cars=5, seed=11)
    split = dm.load_split(root, "synth2d", "synth3d", "car")
    gt = prepare_gt(root, "car", split.names)
    params = dm.stack_params([Params(a_l=a, epsilon=e) for a in (2.0, 6.0, 12.0) for e in (1, 3, 30)])
    res = dm.track(split, params, dm.Options(output="filtered"))
    ids, boxes = np.asarray(res.ids), np.asarray(res.boxes, np.float64)
    # lanes that share some sequences with another lane and differ on others: lane 0 with lane 1's
    # first sequence, lane 2 emptied on its last sequence, a copy of lane 3
    a, e = int(split.offsets[0]), int(split.offsets[0] + split.lengths[0])
    mixed = ids[0].copy()
    mixed[a:e] = ids[1, a:e]
    mixed_boxes = boxes[0].copy()
    mixed_boxes[a:e] = boxes[1, a:e]
    emptied = ids[2].copy()
    emptied[int(split.offsets[-1]):] = -1
    ids = np.concatenate([ids, mixed[None], emptied[None], ids[3:4]])
    boxes = np.concatenate([boxes, mixed_boxes[None], boxes[2:3], boxes[3:4]])
    return gt, split, ids, boxes


def _scored(sc, ids, boxes, busy=frozenset()):
    per = sc.seq_digests(ids, boxes)
    items = sc.new_items(per, busy)
    if any(items):
        sc.store(per, items, sc.evaluate(sc.dets(ids, boxes, items)))
    return per, items


def _alone(gt, ids, boxes, offsets):
    """Every lane scored as it is (no memo, no virtual lanes)."""
    return result_dicts(gt, evaluate_batch(gt, tracker_dets_from_arrays(gt, ids, boxes, offsets)))


def _same(got, want, gt):
    for lane, w in enumerate(want):
        for name in ("COMBINED",) + tuple(gt.sequences):
            for f, v in w[name].items():
                np.testing.assert_array_equal(got[lane][name][f], v, err_msg=f"lane {lane} {name} {f}")


@pytest.mark.slow
def test_every_lane_equals_scoring_it_alone(outputs):
    gt, split, ids, boxes = outputs
    want = _alone(gt, ids, boxes, split.offsets)
    sc = LaneScorer(gt, split.offsets, lanes_per_batch=4)
    # two chunks: the second relies on the first's sequence outputs
    _scored(sc, ids[:5], boxes[:5])
    per, items = _scored(sc, ids, boxes)
    got = sc.gather(per)
    distinct = {(s, d[s]) for d in per for s in range(len(gt.sequences))}
    assert len(sc) == len(distinct) < ids.shape[0] * len(gt.sequences)
    # nothing scored twice: the second chunk's items are exactly what the first left
    assert sum(map(len, items)) == len(distinct) - len({(s, d[s]) for d in per[:5] for s in range(len(gt.sequences))})
    for lane in range(ids.shape[0]):
        w = want[lane]
        for f, v in w["COMBINED"].items():
            np.testing.assert_array_equal(got["comb"][f][lane], v, err_msg=f"lane {lane} {f}")
        for s, name in enumerate(gt.sequences):
            for f, v in w[name].items():
                np.testing.assert_array_equal(got["seq"][f][lane, s], v, err_msg=f"lane {lane} {name} {f}")


@pytest.mark.slow
def test_virtual_lanes_hold_each_sequences_new_outputs(outputs):
    gt, split, ids, boxes = outputs
    sc = LaneScorer(gt, split.offsets)
    per = sc.seq_digests(ids, boxes)
    items = sc.new_items(per)
    dets = sc.dets(ids, boxes, items)
    assert dets.n_lanes == max(len(lanes) for lanes in items)
    # the mixed lane's first sequence is lane 1's: not new there; its copy of lane 3 is new nowhere
    assert 9 not in items[0] and all(11 not in lanes for lanes in items)
    # in flight elsewhere: not scored here
    busy = sc.item_keys(per, [items[0], [], []])
    assert sc.new_items(per, busy)[0] == [] and sc.new_items(per, busy)[1:] == items[1:]


@pytest.mark.slow
def test_errors_name_the_lane_not_the_virtual_lane(outputs):
    """A problem in a lane's rows is named by the lane's own index, whichever virtual lane holds them."""
    from dfrmot_jax.metrics import DuplicateIdError

    gt, split, ids, boxes = outputs
    ids, boxes = ids[:6].copy(), boxes[:6].copy()
    ids[:, :] = ids[0]                           # six copies of lane 0 ...
    boxes[:, :] = boxes[0]
    s = 1
    a = int(split.offsets[s])
    t, k = np.argwhere(ids[4, a:a + int(split.lengths[s])] >= 0)[0]
    ids[4, a + t, (k + 1) % ids.shape[2]] = ids[4, a + t, k]       # ... lane 4 repeats an id in sequence 1
    boxes[4, a + t, (k + 1) % ids.shape[2]] = boxes[4, a + t, k] + 50
    sc = LaneScorer(gt, split.offsets)
    per = sc.seq_digests(ids, boxes)
    items = sc.new_items(per)
    assert items[s] == [0, 4] and items[0] == [0]
    with pytest.raises(DuplicateIdError, match="config 4:"):
        sc.evaluate(sc.dets(ids, boxes, items))
    boxes[4, a + t, k] = np.nan                   # not finite: named by lane 4 (dets of lanes 0 and 4 only)
    with pytest.raises(ValueError, match="non-finite box in config 4,"):
        sc.dets(ids, boxes, sc.new_items(sc.seq_digests(ids, boxes)))


@pytest.mark.slow
def test_evaluate_arrays_scores_repeated_outputs_once(outputs, monkeypatch):
    """evaluate_arrays packs repeated (config, sequence) outputs into virtual lanes: the same dicts as
    scoring every lane as it is, with fewer lanes scored."""
    from dfrmot_jax.metrics.kitti2d import evaluate

    gt, split, ids, boxes = outputs
    want = _alone(gt, ids, boxes, split.offsets)
    scored = []
    real = evaluate.evaluate_batch
    monkeypatch.setattr(evaluate, "evaluate_batch", lambda g, d, sim: scored.append(d.n_lanes) or real(g, d, sim))
    got = evaluate_arrays(gt, ids, boxes, split.offsets)
    _same(got, want, gt)
    assert sum(scored) < ids.shape[0]
    # nothing repeated: the lanes as they are
    scored.clear()
    _same(evaluate_arrays(gt, ids[:2], boxes[:2], split.offsets), want[:2], gt)
    assert sum(scored) == 2
