"""Lifted boxes as a 3D detection source (``det3d="lidar:DIR"``): packing, fusion by construction,
caching (lidar.source, data)."""

import os
import time

import numpy as np
import pytest

import dfrmot_jax as dm
from dfrmot_jax.data import load_split
from dfrmot_jax.boxes import truncate_2d_box
from dfrmot_jax.io.kitti import KittiFormatError, read_calib, read_detections_2d, read_detections_3d, \
    read_tracking_labels, sequence_lengths
from dfrmot_jax.lidar import LiftSettings, SimSettings, clear_cache, lift_sequence, scan_path, simulate_to_folder, \
    tie_scores, write_detections3d
from dfrmot_jax.synthetic import make_scene


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    root = make_scene(tmp_path_factory.mktemp("scene"), n_sequences=1, n_frames=40, n_cars=6, seed=3)
    scans = root / "scans"
    n = sequence_lengths(root, ["0000"])["0000"]
    simulate_to_folder(scans, read_tracking_labels(root / "label_02" / "0000.txt"),
                       read_calib(root / "calib" / "0000.txt"), n, "0000", SimSettings(beams=32), seed=0)
    # the files as a minute old: a memo trusts no file modified within RACY_NS of its stamp, and the
    # cache tests must not depend on how long the tests before them took
    old = time.time_ns() - 60 * 10**9
    for p in root.rglob("*"):
        if p.is_file():
            os.utime(p, ns=(old, old))
    return root, scans


def test_lifted_rows_carry_their_2d_box_as_both_image_boxes(scene):
    root, scans = scene
    split = load_split(root, "synth2d", f"lidar:{scans}", "car")
    assert split.valid3d.sum() > 40
    t, m = np.nonzero(split.valid3d)
    rows = split.row3d[t, m]
    # each lifted row: a 2D detection of the same frame with that very integer box and score
    for ti, mi in zip(t, m):
        same = split.valid2d[ti] & np.all(truncate_2d_box(split.box2d[ti]) == split.box3d[ti, mi], axis=1)
        assert same.any() and np.any(split.score2d[ti][same] == split.score3d[ti, mi])
    np.testing.assert_array_equal(split.proj3d[split.valid3d], split.box3d[split.valid3d])
    assert np.all(split.score3d[split.valid3d] >= 0.45) and rows.min() >= 0


@pytest.mark.slow
@pytest.mark.parametrize("merge", ["detector_box", "calib_projection"])
def test_every_lifted_box_fuses_with_its_own_2d_detection(scene, merge):
    root, scans = scene
    split = load_split(root, "synth2d", f"lidar:{scans}", "car")
    params, options = dm.preset("dfr2023")
    options = options._replace(merge=merge, centroid="kitti")
    res = dm.track(split, tie_scores(params), options, detail=True)
    m2 = split.box2d.shape[1]
    ids = res.ids[0]
    assert np.all(ids[:, m2:] == -1)                       # no lifted box is an object of its own
    kept2 = split.valid2d & (split.score2d.astype(np.float32) >= np.float32(0.45))
    assert np.all(ids[:, :m2][kept2] >= 0)
    # the objects with a 3D box are exactly as many as the lifted boxes
    assert int(res.own3[0][:, :m2].sum()) == int(split.valid3d.sum())
    # without tying the scores, dfr2023's score_3d = 4 drops every lifted box
    res4 = dm.track(split, params, options, detail=True)
    assert int(res4.own3[0].sum()) == 0


def test_cache_per_setting_and_scan_stamps(scene, monkeypatch):
    root, scans = scene
    clear_cache()
    det2 = read_detections_2d(root / "detections" / "synth2d" / "car" / "0000.txt")
    calib = read_calib(root / "calib" / "0000.txt")
    a = lift_sequence(scans, "0000", 40, det2, calib, LiftSettings())
    calls = []
    import dfrmot_jax.lidar.source as src
    real = src.prepare_points
    monkeypatch.setattr(src, "prepare_points", lambda *a, **k: calls.append(1) or real(*a, **k))
    b = lift_sequence(scans, "0000", 40, det2, calib, LiftSettings())
    assert b is a and not calls                            # the same setting: from the cache
    c = lift_sequence(scans, "0000", 40, det2, calib, LiftSettings(shrink=0.4))
    assert not calls and c.frame.size != a.frame.size      # another shrink reuses the first stage
    p = scan_path(scans, "0000", 5)
    st = p.stat()
    os.utime(p, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    d = lift_sequence(scans, "0000", 40, det2, calib, LiftSettings())
    assert calls == [1] and d is not a                     # a changed scan: lifted again
    np.testing.assert_array_equal(d.loc, a.loc)


def test_missing_scan_and_folder_are_located_errors(scene, tmp_path):
    root, scans = scene
    with pytest.raises(KittiFormatError, match="LiDAR scan folder not found"):
        load_split(root, "synth2d", f"lidar:{tmp_path / 'none'}", "car")
    (tmp_path / "velodyne" / "0000").mkdir(parents=True)
    for f in range(39):
        (tmp_path / "velodyne" / "0000" / f"{f:06d}.bin").write_bytes(scan_path(scans, "0000", f).read_bytes())
    with pytest.raises(KittiFormatError, match="no scan for frame 39"):
        load_split(root, "synth2d", f"lidar:{tmp_path}", "car")


def test_written_detection_folder_reads_back_the_same(scene, tmp_path):
    root, scans = scene
    det2 = read_detections_2d(root / "detections" / "synth2d" / "car" / "0000.txt")
    det = lift_sequence(scans, "0000", 40, det2, read_calib(root / "calib" / "0000.txt"))
    write_detections3d(tmp_path / "0000.txt", det)
    back = read_detections_3d(tmp_path / "0000.txt")
    for name in ("frame", "box", "score", "dims", "loc", "rot_y", "alpha"):
        np.testing.assert_array_equal(getattr(back, name), getattr(det, name))
    assert set(back.type) == {"Car"}
    # KITTI camera box: bottom centre below the geometric centre, heading along the camera's z
    assert np.all(det.dims > 0) and np.allclose(det.rot_y, -np.pi / 2, atol=0.05)


def same_detections(a, b) -> bool:
    return all(np.array_equal(getattr(a, n), getattr(b, n)) for n in ("frame", "box", "score", "dims", "loc",
                                                                       "rot_y", "alpha"))


def test_cache_sees_changed_detections_and_calibration(scene):
    """The cache keys on the 2D detections and the calibration themselves: a direct caller passing
    other values for the same scans gets them lifted, not the cached lifting of the first."""
    root, scans = scene
    clear_cache()
    det2 = read_detections_2d(root / "detections" / "synth2d" / "car" / "0000.txt")
    calib = read_calib(root / "calib" / "0000.txt")
    a = lift_sequence(scans, "0000", 40, det2, calib)
    copy = det2._replace(box=det2.box.copy())
    assert lift_sequence(scans, "0000", 40, copy, calib._replace(P2=calib.P2.copy())) is a   # equal values: cached
    moved = det2._replace(box=det2.box + 7.0)
    tilted = calib._replace(Tr_velo_to_cam=calib.Tr_velo_to_cam + np.array([[0, 0, 0, 0.3], [0, 0, 0, 0],
                                                                             [0, 0, 0, 0]]))
    changed = [lift_sequence(scans, "0000", 40, moved, calib), lift_sequence(scans, "0000", 40, det2, tilted)]
    clear_cache()
    fresh = [lift_sequence(scans, "0000", 40, moved, calib), lift_sequence(scans, "0000", 40, det2, tilted)]
    for got, want in zip(changed, fresh):
        assert got is not a and same_detections(got, want) and not same_detections(got, a)
