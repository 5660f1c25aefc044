"""KITTI velodyne scans: the reader's located errors and the writer's bytes (lidar.scans)."""

import numpy as np
import pytest

from dfrmot_jax.io.kitti import KittiFormatError
from dfrmot_jax.lidar.scans import check_frames, read_scan, scan_path, write_scan


def test_write_then_read_gives_the_same_float32_bytes(tmp_path):
    pts = np.array([[1.5, -2.25, 0.125, 0.5], [10.1, 0.2, -1.7, 0.0]], np.float32)
    p = scan_path(tmp_path, "0003", 7)
    assert p == tmp_path / "velodyne" / "0003" / "000007.bin"
    write_scan(p, pts)
    assert p.read_bytes() == pts.astype("<f4").tobytes()
    np.testing.assert_array_equal(read_scan(p), pts)
    write_scan(p, pts[:, :3])                               # no reflectance: written as 0
    np.testing.assert_array_equal(read_scan(p)[:, 3], [0, 0])
    assert scan_path(tmp_path / "velodyne", "0003", 7) == p


def test_size_not_a_multiple_of_16_bytes(tmp_path):
    p = tmp_path / "000000.bin"
    p.write_bytes(np.zeros(5, "<f4").tobytes())
    with pytest.raises(KittiFormatError, match="20 bytes is not a multiple of 16") as e:
        read_scan(p)
    assert e.value.path == str(p) and e.value.line is None


def test_non_finite_value_names_point_and_field(tmp_path):
    pts = np.zeros((3, 4), np.float32)
    pts[2, 1] = np.nan
    p = tmp_path / "000000.bin"
    pts.tofile(p)
    with pytest.raises(KittiFormatError) as e:
        read_scan(p)
    assert (e.value.line, e.value.field) == (3, "y") and "non-finite" in str(e.value)
    pts[2, 1] = 0
    pts[0, 3] = np.inf
    pts.tofile(p)
    with pytest.raises(KittiFormatError, match="field 'reflectance'"):
        read_scan(p)


def test_missing_frame(tmp_path):
    with pytest.raises(KittiFormatError, match="file not found"):
        read_scan(scan_path(tmp_path, "0000", 0))
    for f in (0, 1, 3):
        write_scan(scan_path(tmp_path, "0000", f), np.zeros((1, 4)))
    with pytest.raises(KittiFormatError, match="no scan for frame 2") as e:
        check_frames(tmp_path, "0000", 4)
    assert e.value.path.endswith("velodyne/0000/000002.bin")
    assert len(check_frames(tmp_path, "0000", 2)) == 2
