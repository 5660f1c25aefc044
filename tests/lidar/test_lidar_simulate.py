"""The simulated LiDAR (lidar.simulate): geometry of the ray-cast, determinism, settings."""

import numpy as np
import pytest

from dfrmot_jax.io.kitti import TrackingLabels
from dfrmot_jax.lidar.simulate import SimSettings, sensor, simulate_sequence, simulate_to_folder, velo_boxes
from dfrmot_jax.lidar.scans import read_scan, scan_path
from test_lidar_lift import simple_calib

H, W, L, DIST = 1.5, 1.8, 4.0, 10.0       # a box straight ahead, its centre DIST m away


def labels(rows):
    """TrackingLabels from (frame, type, h, w, l, x, y, z, rot_y) in camera coordinates."""
    n = len(rows)
    col = lambda i: np.array([r[i] for r in rows], float)  # noqa: E731
    return TrackingLabels(frame=np.array([r[0] for r in rows], np.int64), track_id=np.arange(n),
                          type=np.array([r[1] for r in rows], object), truncated=np.zeros(n), occluded=np.zeros(n),
                          alpha=np.zeros(n), box=np.zeros((n, 4)), dims=np.stack([col(2), col(3), col(4)], 1),
                          loc=np.stack([col(5), col(6), col(7)], 1), rot_y=col(8), score=np.full(n, np.nan))


# camera: x = -y_lidar, y = -z_lidar, z = x_lidar; the box stands on the ground (LiDAR z = -1.73), length along x
AHEAD = (0, "Car", H, W, L, 0.0, 1.73, DIST, np.pi / 2)


def box_frame(points):
    """LiDAR points in the box's frame (x along its length) and its half extents."""
    return points[:, :3] - np.array([DIST, 0.0, -1.73 + H / 2]), np.array([L / 2, W / 2, H / 2])


@pytest.mark.slow
def test_a_box_at_known_range_returns_points_on_its_faces_and_none_behind():
    s = SimSettings(range_noise=0.0, fov=30)
    (_, pts), = simulate_sequence(labels([AHEAD]), simple_calib(), 1, "0000", s)
    assert pts.dtype == np.float32 and pts.shape[1] == 4
    q, half = box_frame(pts)
    on_box = pts[:, 3] == 0.5
    assert on_box.sum() > 500
    # every box return lies on a face: inside the box (to float32) with one coordinate on +-half
    qb = q[on_box]
    assert np.all(np.abs(qb) <= half + 1e-4)
    face = np.isclose(np.abs(qb), half, atol=1e-4)
    assert np.all(face.any(axis=1))
    # the faces seen from the sensor: the near end (x = -L/2) and the top, never the far end or the bottom
    assert np.isclose(qb[:, 0], -L / 2, atol=1e-4).sum() > 100 and np.isclose(qb[:, 2], H / 2, atol=1e-4).sum() > 50
    assert not np.isclose(qb[:, 0], L / 2, atol=1e-4).any() and not np.isclose(qb[:, 2], -H / 2, atol=1e-4).any()
    # the range of the near face is known
    near = qb[np.isclose(qb[:, 0], -L / 2, atol=1e-4)]
    np.testing.assert_allclose(near[:, 0] + DIST, DIST - L / 2, atol=1e-4)
    # no return behind it: no ray to a ground point passes through the box
    g = pts[~on_box, :3].astype(float)
    ts = np.linspace(0.0, 1.0, 400)[None, :, None]
    seg = g[:, None, :] * ts - np.array([DIST, 0.0, -1.73 + H / 2])
    inside = np.all(np.abs(seg) < half - 1e-3, axis=2).any(axis=1)
    assert not inside.any()
    # the ground is flat at -1.73 m
    np.testing.assert_allclose(g[:, 2], -1.73, atol=1e-4)


def test_dont_care_rows_and_empty_frames_have_no_box():
    rows = [AHEAD, (0, "DontCare", -1, -1, -1, -1000, -1000, -1000, -10)]
    frame, centre, _, half = velo_boxes(labels(rows), simple_calib())
    assert frame.tolist() == [0]
    np.testing.assert_allclose(centre[0], [DIST, 0, -1.73 + H / 2], atol=1e-9)
    np.testing.assert_allclose(half[0], [L / 2, H / 2, W / 2], atol=1e-9)
    (_, a), (_, b) = simulate_sequence(labels(rows), simple_calib(), 2, "0000", SimSettings(range_noise=0.0))
    assert (a[:, 3] == 0.5).any() and not (b[:, 3] == 0.5).any()


def test_deterministic_per_sequence_frame_and_seed(tmp_path):
    lab = labels([AHEAD, (1, "Pedestrian", 1.7, 0.6, 0.8, 2.0, 1.73, 15.0, 0.0)])
    s = SimSettings(beams=16, dropout=0.1, clutter=0.01)
    run = lambda seq, seed: [p for _, p in simulate_sequence(lab, simple_calib(), 2, seq, s, seed)]  # noqa: E731
    a, b, c, d = run("0000", 0), run("0000", 0), run("0000", 1), run("0001", 0)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not np.array_equal(a[0], c[0]) and not np.array_equal(a[0], d[0])
    # frame 1 alone is frame 1 of the whole run
    (_, only1), = simulate_sequence(lab, simple_calib(), 2, "0000", s, 0, frames=[1])
    np.testing.assert_array_equal(only1, a[1])
    n = simulate_to_folder(tmp_path, lab, simple_calib(), 2, "0000", s, seed=0)
    assert n == a[0].shape[0] + a[1].shape[0]
    np.testing.assert_array_equal(read_scan(scan_path(tmp_path, "0000", 1)), a[1])


def test_beams_dropout_and_clutter_settings():
    lab = labels([AHEAD])
    one = lambda **kw: next(simulate_sequence(lab, simple_calib(), 1, "0000", SimSettings(**kw)))[1]  # noqa: E731
    full, half_beams = one(range_noise=0.0), one(range_noise=0.0, beams=32)
    assert 0.4 < half_beams.shape[0] / full.shape[0] < 0.6
    el = sensor(SimSettings(beams=64)).elevation
    np.testing.assert_allclose(np.degrees([el[0], el[-1]]), [2.0, -24.9])
    dropped = one(range_noise=0.0, dropout=0.5)
    assert 0.45 < dropped.shape[0] / full.shape[0] < 0.55
    rain = one(range_noise=0.0, clutter=0.05)
    r = np.linalg.norm(rain[rain[:, 3] == np.float32(0.05), :3], axis=1)
    assert r.size > 100 and r.min() >= 1.0 - 1e-5 and r.max() <= 30.0 + 1e-4
    noisy = one(range_noise=0.05)
    q, half = box_frame(noisy[noisy[:, 3] == 0.5])
    assert np.abs(np.abs(q[:, 0]) - half[0]).max() > 0.01            # noise moves points off the face
    with pytest.raises(ValueError, match="dropout"):
        SimSettings(dropout=2).validate()
