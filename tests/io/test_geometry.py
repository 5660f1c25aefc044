import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dfrmot_jax.boxes import iou
from dfrmot_jax.geometry import (
    box3d_corners,
    project_box3d_to_image,
    project_to_image,
)


def iou_2d(a, b):
    """The package's IoU (``core.boxes.iou``, areas clipped at 0) on float64 NumPy boxes."""
    return iou(np.asarray(a, np.float64), np.asarray(b, np.float64))

# A toy camera: f = 100 px, principal point (50, 50), no baseline.
P_TOY = np.array([[100.0, 0.0, 50.0, 0.0], [0.0, 100.0, 50.0, 0.0], [0.0, 0.0, 1.0, 0.0]])


def test_corners_follow_devkit_order_and_rotation():
    dims = np.array([2.0, 2.0, 4.0])  # h, w, l
    loc = np.array([1.0, 1.5, 10.0])
    c = box3d_corners(dims, loc, 0.0)
    assert c.shape == (8, 3)
    # computeBox3D: x = l/2*[1,1,-1,-1,1,1,-1,-1], y = -h*[0,0,0,0,1,1,1,1], z = w/2*[1,-1,-1,1,1,-1,-1,1]
    expected = np.stack(
        [
            1.0 + np.array([2, 2, -2, -2, 2, 2, -2, -2]),
            1.5 + np.array([0, 0, 0, 0, -2, -2, -2, -2]),
            10.0 + np.array([1, -1, -1, 1, 1, -1, -1, 1]),
        ],
        axis=-1,
    )
    np.testing.assert_allclose(c, expected)
    # rot_y = pi/2: x' = z_obj, z' = -x_obj  (length axis now points to -z)
    c90 = box3d_corners(dims, loc, np.pi / 2)
    np.testing.assert_allclose(c90[0], [1.0 + 1.0, 1.5, 10.0 - 2.0], atol=1e-12)
    np.testing.assert_allclose(c90[:, 0].min(), 0.0, atol=1e-12)  # x extent now w
    np.testing.assert_allclose(np.ptp(c90[:, 2]), 4.0)  # z extent now l


def test_corners_broadcast():
    dims = np.ones((5, 3))
    loc = np.zeros((5, 3))
    rot = np.linspace(0, 1, 5)
    assert box3d_corners(dims, loc, rot).shape == (5, 8, 3)
    assert box3d_corners(dims[None], loc[None], rot[None]).shape == (1, 5, 8, 3)


def test_project_to_image():
    pts = np.array([[0.0, 0.0, 10.0], [2.0, -1.0, 4.0]])
    uv = project_to_image(pts, P_TOY)
    np.testing.assert_allclose(uv, [[50.0, 50.0], [100.0, 25.0]])
    assert project_to_image(pts.reshape(1, 2, 3), P_TOY.ravel()).shape == (1, 2, 2)


def test_hand_computed_box():
    # h=2, w=2, l=4 at (0, 1, 10): x in [-2, 2], y in [-1, 1], z in [9, 11].
    box = project_box3d_to_image([2.0, 2.0, 4.0], [0.0, 1.0, 10.0], 0.0, P_TOY, image_size=(200, 200))
    np.testing.assert_allclose(box, [50 - 200 / 9, 50 - 100 / 9, 50 + 200 / 9, 50 + 100 / 9])
    # Rotated by 90 deg: x in [-1, 1], z in [8, 12].
    box = project_box3d_to_image([2.0, 2.0, 4.0], [0.0, 1.0, 10.0], np.pi / 2, P_TOY, image_size=(200, 200))
    np.testing.assert_allclose(box, [37.5, 37.5, 62.5, 62.5])
    # A rotation by pi maps the box onto itself.
    box_pi = project_box3d_to_image([2.0, 2.0, 4.0], [0.0, 1.0, 10.0], np.pi, P_TOY, image_size=(200, 200))
    np.testing.assert_allclose(box_pi, [50 - 200 / 9, 50 - 100 / 9, 50 + 200 / 9, 50 + 100 / 9])


def test_clipping_and_behind_camera():
    # Same box, small image: clipped to [0, W-1] x [0, H-1].
    box = project_box3d_to_image([2.0, 2.0, 4.0], [0.0, 1.0, 10.0], 0.0, P_TOY, image_size=(60, 55))
    np.testing.assert_allclose(box, [50 - 200 / 9, 50 - 100 / 9, 59.0, 54.0])
    unclipped = project_box3d_to_image([2.0, 2.0, 4.0], [0.0, 1.0, 10.0], 0.0, P_TOY, (60, 55), clip=False)
    np.testing.assert_allclose(unclipped[2], 50 + 200 / 9)
    # Straddling the camera plane: z in [-1, 3]; only corners with z = 3 count.
    box = project_box3d_to_image([2.0, 2.0, 4.0], [0.0, 1.0, 1.0], np.pi / 2, P_TOY, image_size=(1000, 1000), clip=False)
    np.testing.assert_allclose(box, [50 - 100 / 3, 50 - 100 / 3, 50 + 100 / 3, 50 + 100 / 3])
    # Completely behind: NaN box, also after clipping.
    boxes = project_box3d_to_image([[2.0, 2.0, 4.0]] * 2, [[0.0, 1.0, -10.0], [0.0, 1.0, 10.0]], [0.0, 0.0], P_TOY)
    assert boxes.shape == (2, 4)
    assert np.all(np.isnan(boxes[0])) and np.all(np.isfinite(boxes[1]))


def test_iou_values():
    a = np.array([0.0, 0.0, 10.0, 10.0])
    assert iou_2d(a, a) == pytest.approx(1.0)
    assert iou_2d(a, [5.0, 0.0, 15.0, 10.0]) == pytest.approx(50 / 150)
    assert iou_2d(a, [10.0, 0.0, 20.0, 10.0]) == 0.0  # touching
    assert iou_2d(a, [20.0, 20.0, 30.0, 30.0]) == 0.0
    assert iou_2d([1.0, 1.0, 1.0, 1.0], [1.0, 1.0, 1.0, 1.0]) == 0.0  # empty union
    assert iou_2d(a, [np.nan] * 4) == 0.0
    m = iou_2d(np.array([a, a + 5])[:, None], np.array([a, a + 5, a + 100])[None])
    assert m.shape == (2, 3)
    np.testing.assert_allclose(m, [[1, 25 / 175, 0], [25 / 175, 1, 0]])


_coord = st.floats(-100, 100, allow_nan=False)


@settings(max_examples=100, deadline=None)
@given(st.lists(_coord, min_size=8, max_size=8))
def test_iou_properties(v):
    a = np.array([min(v[0], v[2]), min(v[1], v[3]), max(v[0], v[2]), max(v[1], v[3])])
    b = np.array([min(v[4], v[6]), min(v[5], v[7]), max(v[4], v[6]), max(v[5], v[7])])
    iou = iou_2d(a, b)
    assert 0.0 <= iou <= 1.0 + 1e-12
    assert iou == pytest.approx(iou_2d(b, a))


def _read_p2(path):
    for line in open(path):
        if line.startswith("P2:"):
            return np.array(line.split()[1:], dtype=float).reshape(3, 4)
    raise ValueError(path)


def test_reproduces_pointrcnn_image_boxes(kitti_root):
    """PointRCNN's image box is its 3D box projected with P2 and clipped to the image.

    Measured on sequence 0000 (1054 boxes, 936 not touching the border): median IoU 0.99993,
    median absolute coordinate difference 0.0008 px, max 0.013 px (the files have 4 decimals);
    clipped boxes agree as closely.
    """
    P2 = _read_p2(kitti_root / "calib" / "0000.txt")
    d = np.loadtxt(kitti_root / "detections" / "pointrcnn" / "car" / "0000.txt", delimiter=",", ndmin=2)
    det_box, dims, loc, rot = d[:, 2:6], d[:, 7:10], d[:, 10:13], d[:, 13]
    W, H = 1242, 375
    unclipped = project_box3d_to_image(dims, loc, rot, P2, (W, H), clip=False)
    inside = (unclipped[:, 0] >= 0) & (unclipped[:, 1] >= 0) & (unclipped[:, 2] <= W - 1) & (unclipped[:, 3] <= H - 1)
    assert inside.sum() > 100
    ours = project_box3d_to_image(dims, loc, rot, P2, (W, H))
    iou = iou_2d(ours[inside], det_box[inside])
    assert np.median(iou) >= 0.9
    assert np.median(np.abs(ours[inside] - det_box[inside])) < 0.5
    # The clipping convention ([0, W-1] x [0, H-1]) matches as well.
    assert np.median(iou_2d(ours, det_box)) >= 0.9
    # And the detector's alpha is rot_y - arctan2(x, z).
    alpha = rot - np.arctan2(loc[:, 0], loc[:, 2])
    diff = (d[:, 14] - alpha + np.pi) % (2 * np.pi) - np.pi
    assert np.max(np.abs(diff)) < 1e-3
