"""KITTI velodyne scans: the reader's located errors and the writer's bytes (lidar.scans)."""

import os

import numpy as np
import pytest

from dfrmot_jax.io.kitti import KittiFormatError
from dfrmot_jax.lidar.scans import check_frames, read_scan, scan_path, write_scan
from dfrmot_jax.testing.cli import deadline


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


@pytest.mark.parametrize("extra", [1, 2, 3, 15, -1, -13])
def test_a_partial_last_point_is_an_error_naming_the_true_size(tmp_path, extra):
    """Bytes appended to a scan, or a scan cut inside a point: 16k+1 .. 16k+3 bytes were read as k
    points (the partial one dropped, no error), and other bad sizes were reported rounded down to
    whole float32s (915596 for a 915599-byte file)."""
    p = tmp_path / "000000.bin"
    data = np.arange(2 * 4, dtype="<f4").tobytes()          # two points, 32 bytes
    p.write_bytes(data + bytes(range(extra)) if extra > 0 else data[:extra])
    size = len(p.read_bytes())
    with pytest.raises(KittiFormatError, match=f"size {size} bytes is not a multiple of 16") as e:
        read_scan(p)
    assert e.value.path == str(p)
    p.write_bytes(np.zeros(57224 * 4, "<f4").tobytes() + bytes(15))      # the tester's 915599-byte file
    with pytest.raises(KittiFormatError, match="size 915599 bytes"):
        read_scan(p)


def test_a_fifo_for_a_scan_is_refused_without_blocking(tmp_path):
    """A FIFO where a scan should be: reading it waited forever for a writer."""
    write_scan(scan_path(tmp_path, "0000", 0), np.zeros((1, 4)))
    fifo = scan_path(tmp_path, "0000", 1)
    os.mkfifo(fifo)
    with deadline(5):
        with pytest.raises(KittiFormatError, match="is a FIFO"):
            read_scan(fifo)
        with pytest.raises(KittiFormatError, match="is a FIFO") as e:
            check_frames(tmp_path, "0000", 2)
        assert e.value.path == str(fifo) and "frame 1" in str(e.value)


def test_an_unreachable_sequence_folder_says_why_not_not_found(tmp_path):
    """A sequence folder that cannot be read (here a symlink loop, which fails for root too) was
    reported as "file not found ... no scan for frame 0": the system's reason, not "not found"."""
    base = tmp_path / "velodyne"
    base.mkdir()
    (base / "0000").symlink_to("0000")                      # velodyne/0000 -> itself
    with pytest.raises(KittiFormatError, match="Too many levels of symbolic links") as e:
        check_frames(tmp_path, "0000", 3)
    assert "not found" not in str(e.value) and e.value.path.endswith("velodyne/0000/000000.bin")
    with pytest.raises(KittiFormatError, match="cannot read the scan: Too many levels of symbolic links"):
        read_scan(scan_path(tmp_path, "0000", 0))
