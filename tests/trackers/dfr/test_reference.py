"""The oracle itself, on hand-made frames: the rules of the spec, one by one."""

import numpy as np

from dfrmot_jax.data import SequenceDets
from dfrmot_jax.io.kitti import Calib, Detections2D, Detections3D
from dfrmot_jax.trackers.dfr.config import Options, Params
from dfrmot_jax.testing.reference import greedy_match, iou, track_sequence


def _seq(frames2, boxes2, scores2, n_frames, frames3=(), boxes3=(), scores3=(), loc3=()):
    d2 = Detections2D(np.array(frames2, np.int64), np.array(boxes2, float).reshape(-1, 4), np.array(scores2, float))
    n3 = len(frames3)
    d3 = Detections3D(np.array(frames3, np.int64), np.array(["2"] * n3, object), np.array(boxes3, float).reshape(-1, 4),
                      np.array(scores3, float), np.tile([1.5, 1.6, 3.9], (n3, 1)), np.array(loc3, float).reshape(-1, 3),
                      np.zeros(n3), np.zeros(n3))
    P2 = np.array([[721.5, 0, 609.6, 44.9], [0, 721.5, 172.9, 0.2], [0, 0, 1, 0.003]])
    calib = Calib(P2, np.eye(3), np.zeros((3, 4)), np.stack([P2] * 4), np.zeros((3, 4)))
    return SequenceDets("0000", n_frames, d2, d3, calib)


def test_iou_on_integer_rects():
    assert iou(np.array([0, 0, 10, 10.0]), np.array([5, 0, 15, 10.0])) == 50 / 150
    assert iou(np.array([0, 0, 10, 10.0]), np.array([20, 20, 30, 30.0])) == 0


def test_ids_follow_overlap_and_memory_expires_after_epsilon():
    box = [100, 100, 200, 200]
    frames = [0, 1, 2, 40]
    seq = _seq(frames, [box] * 4, [0.9] * 4, 41)
    rows = track_sequence(seq, Params(), Options())
    assert [(r[0], r[1]) for r in rows] == [(0, 0), (1, 0), (2, 0), (40, 1)]  # gap of 38 > epsilon: new id
    rows = track_sequence(seq, Params(epsilon=40), Options())
    assert [r[1] for r in rows] == [0, 0, 0, 0]


def test_score_threshold_and_min_hits():
    seq = _seq([0, 1, 2], [[0, 0, 50, 50]] * 3, [0.9, 0.2, 0.9], 3)
    assert [r[0] for r in track_sequence(seq, Params(), Options())] == [0, 2]
    assert [r[0] for r in track_sequence(seq, Params(min_hits=2), Options())] == [2]


def test_2d_3d_duplicates_merge_and_lone_3d_is_an_object():
    seq = _seq([0], [[100, 100, 200, 200]], [0.9], 1, frames3=[0, 0], boxes3=[[102, 101, 201, 199], [400, 100, 500, 200]],
               scores3=[8.0, 8.0], loc3=[[0, 1.6, 20], [5, 1.6, 20]])
    rows = track_sequence(seq, Params(), Options())
    assert [(r[6], r[7]) for r in rows] == [("2d", 0), ("3d", 1)]


def test_greedy_takes_the_smallest_first_and_breaks_ties_by_track_id_then_row():
    cost = np.array([[0.2, 0.1], [0.1, 0.3]])
    assert greedy_match(cost, [5, 3], 1.0) == [(0, 1), (1, 0)]
    tie = np.array([[0.5, 0.5], [0.5, 0.5]])
    assert greedy_match(tie, [7, 2], 1.0) == [(0, 1), (1, 0)]
    assert greedy_match(np.array([[1.0]]), [0], 1.0) == []
