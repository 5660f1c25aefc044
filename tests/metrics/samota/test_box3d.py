"""Rotated 3D / BEV box IoU (dfrmot_jax.metrics.common.box3d) against an independent computation: Shapely
polygons for the ground rectangles times the overlap of the height ranges, on random boxes and the
special cases (identical, touching, nested, zero-volume, rotated by 90 degrees)."""

import math

import numpy as np
import pytest
from hypothesis import example, given, settings, strategies as st

from dfrmot_jax.metrics.common.box3d import bev_intersection, bev_iou, iou_3d

shapely = pytest.importorskip("shapely")
from shapely.geometry import Polygon  # noqa: E402


def _rect(b):
    """Ground rectangle of a KITTI box (h w l x y z ry) built here from its definition."""
    h, w, l, x, y, z, r = b
    out = []
    for sx, sz in ((1, 1), (1, -1), (-1, -1), (-1, 1)):
        dx, dz = sx * abs(l) / 2, sz * abs(w) / 2
        out.append((x + math.cos(r) * dx + math.sin(r) * dz, z - math.sin(r) * dx + math.cos(r) * dz))
    return Polygon(out)


def _ref(a, b, bev=False):
    inter = _rect(a).intersection(_rect(b)).area
    if bev:
        sa, sb = abs(a[1] * a[2]), abs(b[1] * b[2])
    else:
        hov = max(0.0, min(a[4], b[4]) - max(a[4] - abs(a[0]), b[4] - abs(b[0])))
        inter *= hov
        sa, sb = abs(a[0] * a[1] * a[2]), abs(b[0] * b[1] * b[2])
    union = sa + sb - inter
    return inter / union if union > 0 else 0.0


def _box(h=1.5, w=1.6, l=3.9, x=0.0, y=1.7, z=10.0, r=0.0):
    return np.array([h, w, l, x, y, z, r], dtype=np.float64)


def _pair(a, b):
    return np.asarray(a, dtype=np.float64)[None], np.asarray(b, dtype=np.float64)[None]


def _near_degenerate_bound(a, b) -> float:
    """How far the IoU may be from Shapely's when an edge or corner lies within the module's
    tolerance (1e-9 of the boxes' size) of the other box's boundary: a corner accepted as inside
    while outside by up to that tolerance adds a sliver of at most tolerance x the longest edge, so
    the IoU may move by 2 x sliver / union (1e-9 absolute besides)."""
    scale = max(abs(a[1]), abs(a[2]), abs(b[1]), abs(b[2]))
    union = abs(a[1] * a[2]) + abs(b[1] * b[2]) - _rect(a).intersection(_rect(b)).area
    return 1e-9 + (2 * 4 * 1e-9 * scale * scale / union if union > 0 else 0.0)


size = st.floats(0.2, 6.0)
coord = st.floats(-3.0, 3.0)
angle = st.floats(-2 * math.pi, 2 * math.pi)
box = st.tuples(size, size, size, coord, st.floats(-1.0, 1.0), coord, angle)


@settings(max_examples=300, deadline=None)
@given(box, box)
@example(a=(1.0, 0.25, 2.0, 0.0, 0.0, 0.0, 0.0), b=(1.0, 0.25, 2.0, 0.0, 0.0, 0.0, 4.3104640540947104e-10))
def test_random_boxes_match_shapely(a, b):
    """Any two boxes: Shapely's IoU within the module's tolerance (``_near_degenerate_bound``: 1e-9,
    more only where a corner lies within 1e-9 of the size of the other box's boundary, e.g. a box
    turned by 4e-10 rad, which Hypothesis found: IoU 1 against 0.9999999982), and the same either way
    round."""
    A, B = _pair(a, b)
    tol = _near_degenerate_bound(a, b)
    assert iou_3d(A, B)[0] == pytest.approx(_ref(a, b), abs=tol)
    assert bev_iou(A, B)[0] == pytest.approx(_ref(a, b, bev=True), abs=tol)
    assert iou_3d(B, A)[0] == pytest.approx(iou_3d(A, B)[0], abs=tol - 1e-9 + 1e-12)


@settings(max_examples=150, deadline=None)
@given(box, st.integers(0, 6), st.floats(-2.0, 2.0), st.sampled_from([0.0, math.pi / 2, math.pi, -math.pi / 2]))
def test_boxes_sharing_coordinates_match_shapely(a, field, shift, turn):
    """Degenerate geometry: one field changed (shared corners, collinear edges), right-angle turns."""
    b = list(a)
    b[field] = a[field] + shift if field >= 3 else max(0.2, a[field] + shift)
    b[6] += turn
    A, B = _pair(a, b)
    tol = _near_degenerate_bound(a, b)       # a tiny turn or shift leaves corners within the tolerance
    assert iou_3d(A, B)[0] == pytest.approx(_ref(a, b), abs=tol)
    assert bev_iou(A, B)[0] == pytest.approx(_ref(a, b, bev=True), abs=tol)


@settings(max_examples=100, deadline=None)
@given(box)
def test_identical_boxes_give_exactly_one(a):
    A, B = _pair(a, a)
    assert iou_3d(A, B)[0] == 1.0
    assert bev_iou(A, B)[0] == 1.0


def test_identical_and_equivalent_boxes():
    a = _box(r=0.3)
    turned = _box(w=-1.6, l=-3.9, r=0.3)                 # h -w -l: the same box turned by 180 degrees
    by_pi = _box(r=0.3 + math.pi)
    swapped = _box(w=3.9, l=1.6, r=0.3 + math.pi / 2)    # length and width swapped, turned by 90 degrees
    for b in (a, turned, by_pi, swapped):
        assert iou_3d(*_pair(a, b))[0] == pytest.approx(1.0, abs=1e-12)
    assert iou_3d(*_pair(a, turned))[0] == 1.0


def test_a_tiny_turn_of_a_long_thin_box_stays_within_the_tolerance_bound():
    """Hypothesis found it: a 6 x 0.2 box turned by 6e-8 rad is 0.99999911014 by exact arithmetic
    (and Shapely) and 0.99999911214 here: corners within 1e-9 x size of the other box are inside."""
    a = (1.0, 6.0, 0.201171875, 0.0, 0.0, 0.0, 0.0)
    b = (1.0, 6.0, 0.201171875, 0.0, 0.0, 0.0, 5.960464477539063e-08)
    exact = 0.99999911013966917983655354372878          # mpmath polygon clipping at 50 digits
    got = iou_3d(*_pair(a, b))[0]
    assert _ref(a, b) == pytest.approx(exact, abs=1e-13)
    assert abs(got - exact) <= _near_degenerate_bound(a, b)
    assert abs(got - exact) > 1e-9                  # the bound is needed: beyond the plain 1e-9


def test_touching_boxes_give_zero():
    a = _box(l=4.0, x=0.0)
    assert iou_3d(*_pair(a, _box(l=4.0, x=4.0)))[0] == 0.0          # face to face along the length
    assert iou_3d(*_pair(a, _box(l=4.0, z=10.0 + 1.6)))[0] == 0.0   # side by side
    assert iou_3d(*_pair(a, _box(l=4.0, y=1.7 - 1.5)))[0] == 0.0    # stacked: heights touch
    assert iou_3d(*_pair(a, _box(l=4.0, x=4.0, z=11.6)))[0] == 0.0  # corner to corner
    assert bev_intersection(*_pair(a, _box(l=4.0, x=4.0)))[0] == 0.0


def test_nested_boxes():
    big = _box(h=2.0, w=2.0, l=5.0, r=0.7)
    small = _box(h=1.0, w=1.0, l=2.0, y=1.5, r=0.7 + 0.4)
    expect = (1.0 * 1.0 * 2.0) / (2.0 * 2.0 * 5.0)
    assert iou_3d(*_pair(big, small))[0] == pytest.approx(expect, rel=1e-12)
    assert iou_3d(*_pair(small, big))[0] == pytest.approx(expect, rel=1e-12)
    assert bev_iou(*_pair(big, small))[0] == pytest.approx(2.0 / 10.0, rel=1e-12)


def test_rotated_by_90_degrees():
    a = _box(h=1.0, w=2.0, l=4.0, r=0.0)
    b = _box(h=1.0, w=2.0, l=4.0, r=math.pi / 2)          # a cross: the overlap is the 2 x 2 square
    assert iou_3d(*_pair(a, b))[0] == pytest.approx(4.0 / (8.0 + 8.0 - 4.0), rel=1e-12)
    sq = _box(w=2.0, l=2.0, r=0.0)
    assert iou_3d(*_pair(sq, _box(w=2.0, l=2.0, r=math.pi / 2)))[0] == 1.0


def test_zero_volume_boxes_give_zero_not_nan():
    a = _box()
    for flat in (_box(h=0.0), _box(w=0.0), _box(l=0.0), _box(h=0.0, w=0.0, l=0.0)):
        for p in (_pair(a, flat), _pair(flat, flat)):
            assert iou_3d(*p)[0] == 0.0
            assert np.isfinite(bev_iou(*p)[0])
    assert bev_iou(*_pair(_box(h=0.0), _box(h=0.0)))[0] == 1.0   # a flat box still has its ground rectangle


def test_far_apart_and_batched():
    rng = np.random.default_rng(3)
    a = np.column_stack([rng.uniform(1, 2, 200), rng.uniform(1, 2, 200), rng.uniform(3, 5, 200),
                         rng.uniform(-20, 20, 200), rng.uniform(1, 2, 200), rng.uniform(5, 50, 200),
                         rng.uniform(-3, 3, 200)])
    b = a.copy()
    b[:, 3] += rng.normal(0, 1, 200)
    b[:, 6] += rng.normal(0, 0.3, 200)
    got = iou_3d(a, b)
    assert np.allclose(got, [_ref(x, y) for x, y in zip(a, b)], atol=1e-9, rtol=0)
    far = b.copy()
    far[:, 5] += 100.0
    assert not iou_3d(a, far).any()
    assert iou_3d(np.zeros((0, 7)), np.zeros((0, 7))).shape == (0,)
    with pytest.raises(ValueError):
        iou_3d(a[:, :6], b[:, :6])
