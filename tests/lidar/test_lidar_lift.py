"""The authors' lifting rules on hand-made point sets (lidar.lift): voxel cells, crop bounds,
shrunk boxes with half-open edges, exclusive assignment, PCL's Euclidean clusters."""

import numpy as np
import pytest

from dfrmot_jax.io.kitti import Calib
from dfrmot_jax.lidar.lift import (LiftSettings, assign_points, crop_mask, detection_boxes, largest_clusters,
                                   project_pixels, shrunk_boxes, velo_to_image, voxel_grid)
from dfrmot_jax.lidar.prepare import lift_frames

F32 = np.float32


def simple_calib(f=100.0) -> Calib:
    """LiDAR (x fwd, y left, z up) -> camera (x = -y, y = -z, z = x); pixel u = f * -y / x, v = f * -z / x."""
    tr = np.array([[0, -1, 0, 0], [0, 0, -1, 0], [1, 0, 0, 0]], float)
    P2 = np.array([[f, 0, 0, 0], [0, f, 0, 0], [0, 0, 1, 0]], float)
    return Calib(P2=P2, R0_rect=np.eye(3), Tr_velo_to_cam=tr, P=np.zeros((4, 3, 4)), Tr_imu_to_velo=np.zeros((3, 4)))


# ---- voxel grid ---------------------------------------------------------------------------------

def test_voxel_cells_are_float32_floor_of_p_times_5_and_centroids_are_means():
    pts = np.array([[0.05, 0.05, 0.05], [0.15, 0.1, 0.1],      # cell (0, 0, 0): one centroid
                    [0.2, 0.0, 0.0],                            # float32(0.2) * 5.0f == 1.0: cell (1, 0, 0)
                    [np.nextafter(F32(0.2), F32(0)), 0.3, 0.0],  # just below 0.2: cell (0, 1, 0)
                    [-0.1, 0.0, 0.0]], F32)                     # cell (-1, 0, 0)
    cent, grp = voxel_grid(pts, np.zeros(5, int), 0.2)
    assert cent.dtype == np.float32 and list(grp) == [0, 0, 0, 0]
    expected = [[-0.1, 0, 0],                                   # ascending cells, x fastest
                [(F32(0.05) + F32(0.15)) / F32(2), (F32(0.05) + F32(0.1)) / F32(2), (F32(0.05) + F32(0.1)) / F32(2)],
                [0.2, 0, 0],
                [np.nextafter(F32(0.2), F32(0)), 0.3, 0]]
    np.testing.assert_array_equal(cent, np.array(expected, F32))


def test_voxel_order_is_x_fastest_then_y_then_z_per_group_and_no_point_kept():
    cells = [(0, 0, 1), (0, 1, 0), (1, 0, 0), (0, 0, 0), (5, 5, 0)]
    pts = (np.array(cells, F32) * F32(0.2) + F32(0.1))
    grp = np.array([0, 0, 0, 0, 1])
    cent, g = voxel_grid(pts, grp, 0.2)
    np.testing.assert_array_equal(g, [0, 0, 0, 0, 1])
    got = np.floor(cent * F32(5)).astype(int).tolist()
    assert got == [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [5, 5, 0]]
    # two points in one cell: their centroid, neither point itself
    cent, _ = voxel_grid(np.array([[0.01, 0, 0], [0.19, 0, 0]], F32), np.zeros(2, int), 0.2)
    assert cent.shape == (1, 3) and cent[0, 0] == (F32(0.01) + F32(0.19)) / F32(2)


# ---- crop and projection ------------------------------------------------------------------------

def test_crop_bounds_are_inclusive_in_float32():
    lo, hi = (0.5, -20.0, -1.2), (180.0, 20.0, 0.5)
    on = np.array([[0.5, 0, 0], [180, 0, 0], [1, -20, 0], [1, 20, 0], [1, 0, -1.2], [1, 0, 0.5]], F32)
    assert crop_mask(on, lo, hi).all()
    eps = [[np.nextafter(F32(0.5), F32(0)), 0, 0], [np.nextafter(F32(180), F32(200)), 0, 0],
           [1, np.nextafter(F32(-20), F32(-30)), 0], [1, np.nextafter(F32(20), F32(30)), 0],
           [1, 0, np.nextafter(F32(-1.2), F32(-2))], [1, 0, np.nextafter(F32(0.5), F32(1))]]
    assert not crop_mask(np.array(eps, F32), lo, hi).any()


def test_projection_truncates_toward_zero():
    M = velo_to_image(simple_calib())
    pix = project_pixels(np.array([[10, -0.155, 0.255], [10, 0.155, -0.255]], F32), M)   # u = 1.55, v = -2.55 ...
    assert pix.tolist() == [[1, -2], [-1, 2]]


# ---- boxes and assignment ----------------------------------------------------------------------

def test_loader_boxes_truncate_like_stoi_and_drop_scores_below_the_cut():
    keep, rect = detection_boxes(np.array([[10.9, 20.2, 30.7, 41.99], [-1.5, 2, 5.5, 9]]), np.array([0.45, 0.4499]),
                                 0.45)
    assert rect.tolist() == [[10, 20, 20, 21], [-1, 2, 6, 7]]
    # stof("0.45") is 0.449999988f, below the double 0.45: the C++ drops it
    assert keep.tolist() == [False, False]
    assert detection_boxes(np.zeros((1, 4)), np.array([0.46]), 0.45)[0].tolist() == [True]


def test_shrunk_box_uses_float_arithmetic_and_truncation():
    assert shrunk_boxes([[100, 50, 41, 21]], 0.2).tolist() == [[104, 52, 32, 16]]
    # w * (1 - s) in float32: 90 * 0.7f = 63.0000009f -> 63 (double 90 * 0.7 = 62.99999... -> 62)
    assert shrunk_boxes([[0, 0, 90, 90]], 0.3)[0, 2] == 63
    assert shrunk_boxes([[7, 7, 10, 10]], 0.0).tolist() == [[7, 7, 10, 10]]


def test_box_edges_are_half_open():
    rects = np.array([[[10, 20, 5, 4]]])
    pix = np.array([[10, 20], [14, 23], [15, 20], [10, 24], [9, 21], [12, 19]])
    owner = assign_points(pix, np.zeros(6, int), rects, np.ones((1, 1), bool))
    assert owner.tolist() == [0, 0, -1, -1, -1, -1]


def test_a_point_in_two_shrunk_boxes_belongs_to_neither():
    rects = np.array([[[0, 0, 10, 10], [5, 5, 10, 10], [100, 100, 5, 5]]])
    valid = np.array([[True, True, False]])
    pix = np.array([[7, 7], [2, 2], [12, 12], [101, 101]])
    assert assign_points(pix, np.zeros(4, int), rects, valid).tolist() == [-1, 0, 1, -1]


# ---- Euclidean clusters --------------------------------------------------------------------------

def line(n, start, step=0.3, axis=0):
    p = np.zeros((n, 3), F32)
    p[:, axis] = F32(start) + F32(step) * np.arange(n, dtype=F32)
    return p


def test_two_clusters_give_the_larger():
    pts = np.concatenate([line(5, 0.0), line(7, 10.0)])
    found, lo, hi = largest_clusters(pts, np.zeros(12, int), 1, 0.5, 5)
    assert found.tolist() == [True]
    np.testing.assert_array_equal(lo[0], pts[5:].min(axis=0))
    np.testing.assert_array_equal(hi[0], pts[5:].max(axis=0))


def test_equal_clusters_go_to_the_earlier_found_and_order_inside_does_not_matter():
    a, b = line(6, 0.0), line(6, 10.0)
    pts = np.concatenate([b[:1], a, b[1:]])         # b's seed comes first
    found, lo, _ = largest_clusters(pts, np.zeros(12, int), 1, 0.5, 5)
    assert found[0] and lo[0, 0] == F32(10.0)


def test_a_four_point_cluster_gives_no_box():
    found, _, _ = largest_clusters(line(4, 0.0), np.zeros(4, int), 1, 0.5, 5)
    assert not found[0]
    found, _, _ = largest_clusters(line(4, 0.0), np.zeros(4, int), 1, 0.5, 4)
    assert found[0]


def test_points_exactly_half_a_metre_apart_are_not_neighbours():
    pts = line(6, 0.0, step=0.5)                    # (dx^2 + dy^2) + dz^2 == 0.25f, not < 0.25f
    assert not largest_clusters(pts, np.zeros(6, int), 1, 0.5, 2)[0][0]
    diag = np.array([[0, 0, 0], [0.3, 0.4, 0]], F32)  # 0.09f + 0.16f = 0.25f: not neighbours either
    assert not largest_clusters(diag, np.zeros(2, int), 1, 0.5, 2)[0][0]
    near = np.array([[0, 0, 0], [np.nextafter(F32(0.5), F32(0)), 0, 0]], F32)    # 0.24999997f < 0.25f
    assert largest_clusters(near, np.zeros(2, int), 1, 0.5, 2)[0][0]


def test_groups_never_join():
    pts = np.concatenate([line(3, 0.0), line(3, 0.9)])   # one chain in space, two groups
    found, _, _ = largest_clusters(pts, np.array([0, 0, 0, 1, 1, 1]), 2, 0.5, 4)
    assert found.tolist() == [False, False]
    found, _, _ = largest_clusters(pts, np.zeros(6, int), 1, 0.5, 4)
    assert found.tolist() == [True]


# ---- the whole path on a hand-made scan ---------------------------------------------------------

def wall(x, y0, y1, z0, z1, step=0.2):
    ys, zs = np.meshgrid(np.arange(y0, y1 + 1e-9, step), np.arange(z0, z1 + 1e-9, step))
    return np.stack([np.full(ys.size, x), ys.ravel(), zs.ravel()], 1).astype(F32) + F32(0.01)


def test_lift_frames_end_to_end():
    calib = simple_calib(100.0)
    car = wall(10.0, -1.0, 1.0, -1.0, 0.4)                  # in front, pixels u in [-10, 10], v in [-4, 10]
    ground = wall(10.0, -1.0, 1.0, -1.8, -1.6)               # below the crop
    far = wall(30.0, -1.0, 1.0, -0.5, -0.1)                  # a smaller object behind, the same pixels
    scan = np.concatenate([ground, far, car])
    det_box = np.array([[-12.0, -6.0, 12.0, 12.0], [300.0, 300.0, 310.0, 310.0]])
    out = lift_frames({0: scan}, np.array([0, 0]), det_box, np.array([0.9, 0.9]), calib, LiftSettings(shrink=0.0))
    assert out.rows.tolist() == [0]
    cent, _ = voxel_grid(car, np.zeros(len(car), int), 0.2)
    cent = cent[crop_mask(cent, (0.5, -20, -1.2), (180, 20, 0.5))]
    np.testing.assert_array_equal(out.lo[0], cent.min(axis=0))
    np.testing.assert_array_equal(out.hi[0], cent.max(axis=0))
    # a second box covering the car's left half: those points belong to neither; the right half remains
    det2 = np.array([[-12.0, -6.0, 12.0, 12.0], [-12.0, -6.0, 0.0, 12.0]])
    out2 = lift_frames({0: scan}, np.array([0, 0]), det2, np.array([0.9, 0.9]), calib, LiftSettings(shrink=0.0))
    # (y = 0.01 projects to u = -0.1, truncated to 0: outside [-12, 0), so it stays the first box's)
    assert out2.rows.tolist() == [0] and out2.hi[0, 1] == F32(0.01) and out2.lo[0, 1] == out.lo[0, 1]
    # a score below the cut: nothing lifted; a frame without detections needs no scan
    none = lift_frames({}, np.array([0]), det_box[:1], np.array([0.3]), calib, LiftSettings())
    assert none.rows.size == 0


def test_settings_are_checked():
    with pytest.raises(ValueError, match="shrink"):
        LiftSettings(shrink=1.0).validate()
    with pytest.raises(ValueError, match="crop"):
        LiftSettings(crop_lo=(1, 0, 0), crop_hi=(0, 1, 1)).validate()
    with pytest.raises(ValueError, match="min_cluster"):
        LiftSettings(min_cluster=2.5).validate()


@pytest.mark.parametrize("value", [float("inf"), float("-inf"), float("nan"), 1e300, True])
def test_a_non_finite_or_huge_count_is_a_value_error_naming_the_setting(value):
    """int(inf) is an OverflowError (an internal error, exit 1), int(nan) a ValueError naming no
    setting: every count of the LiDAR settings is checked as a finite whole number in its range."""
    from dfrmot_jax.lidar import SimSettings, with_setting

    with pytest.raises(ValueError, match="lift min_cluster .*expected an integer in"):
        LiftSettings(min_cluster=value).validate()
    if not isinstance(value, bool):                       # (as --set and sweep files give it)
        with pytest.raises(ValueError, match="lift min_cluster .*expected an integer in"):
            with_setting(LiftSettings(), "min_cluster", str(value))
    with pytest.raises(ValueError, match="simulate beams .*expected an integer in"):
        SimSettings(beams=value).validate()
