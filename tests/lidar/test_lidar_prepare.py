"""The lifting's first stage one scan at a time (lidar.prepare) gives bit for bit what the
whole-sequence computation it replaced gave (kept below as the reference), on simulated sequences;
the assignment in blocks of points what the one-array assignment gave; and no scan outlives its
frame when the scans come from a reader (lidar.prepare, lidar.source)."""

import weakref

import numpy as np
import pytest

import dfrmot_jax.lidar.source as source
from dfrmot_jax.io.kitti import read_calib, read_detections_2d, read_tracking_labels, sequence_lengths
from dfrmot_jax.lidar import LiftSettings, SimSettings, clear_cache, lift_sequence, prepare_points, simulate_sequence, \
    simulate_to_folder
from dfrmot_jax.lidar.lift import (Prepared, assign_points, crop_mask, detection_boxes, lift_prepared, project_pixels,
                                   shrunk_boxes, velo_to_image, voxel_grid)
from dfrmot_jax.synthetic import make_scene


# ---- the whole-sequence first stage as it was (commit b12dd6c), the reference --------------------

def old_frame_slots(det_frame):
    frames, f_idx = np.unique(det_frame, return_inverse=True)
    order = np.argsort(f_idx, kind="stable")
    counts = np.bincount(f_idx, minlength=frames.size)
    starts = np.cumsum(counts) - counts
    slot = np.empty(det_frame.size, np.int64)
    slot[order] = np.arange(det_frame.size) - np.repeat(starts, counts)
    return frames, f_idx.reshape(-1), slot, int(counts.max(initial=0))


def old_cells_in(scan, inv, clo, chi):
    a = scan[:, 2] * inv
    idx = np.flatnonzero((a >= clo[2]) & (a < chi[2]))
    pts = scan[idx, :3]
    ax, ay = pts[:, 0] * inv, pts[:, 1] * inv
    return pts[(ax >= clo[0]) & (ax < chi[0]) & (ay >= clo[1]) & (ay < chi[1])]


def old_prepare_points(scans, det_frame, det_box, det_score, calib, settings):
    """Every scan of the sequence in one array: one voxel grid, one [N, D_max, 4] box test."""
    s = settings.validate()
    det_frame = np.asarray(det_frame, np.int64).reshape(-1)
    keep, rect = detection_boxes(det_box, det_score, s.score_cut)
    rows = np.flatnonzero(keep)
    dframe, rect = det_frame[rows], rect[rows]
    frames, f_idx, slot, dmax = old_frame_slots(dframe)
    if not rows.size:
        return Prepared(rows, dframe, rect, np.zeros((0, 3), np.float32), np.zeros(0, np.int64),
                        np.zeros((0, 2), np.int64))
    inv = np.float32(1.0) / np.float32(s.leaf)
    lo32, hi32 = np.asarray(s.crop_lo, np.float32), np.asarray(s.crop_hi, np.float32)
    clo = np.floor(lo32 * inv) - np.float32(1)
    chi = np.floor(hi32 * inv) + np.float32(2)
    clouds = [old_cells_in(np.asarray(scans[int(f)], np.float32), inv, clo, chi) for f in frames]
    pts = np.concatenate(clouds) if clouds else np.zeros((0, 3), np.float32)
    fi = np.repeat(np.arange(frames.size), [c.shape[0] for c in clouds])
    cent, cfi = voxel_grid(pts, fi, s.leaf)
    ok = crop_mask(cent, s.crop_lo, s.crop_hi)
    cent, cfi = cent[ok], cfi[ok]
    pix = project_pixels(cent, velo_to_image(calib))
    rects = np.zeros((frames.size, max(dmax, 1), 4), np.int64)
    valid = np.zeros((frames.size, max(dmax, 1)), bool)
    rects[f_idx, slot] = rect
    valid[f_idx, slot] = True
    grown = rects + np.array([-1, -1, 2, 2])
    r = grown[cfi]
    px, py = pix[:, 0:1], pix[:, 1:2]
    in_any = np.any(valid[cfi] & (r[..., 0] <= px) & (px < r[..., 0] + r[..., 2]) & (r[..., 1] <= py)
                    & (py < r[..., 1] + r[..., 3]), axis=1)
    return Prepared(rows, dframe, rect, cent[in_any], frames[cfi[in_any]], pix[in_any])


def old_assign_points(pix, frame_of_point, rects, valid):
    r = np.asarray(rects)[frame_of_point]
    v = np.asarray(valid)[frame_of_point]
    px, py = pix[:, 0:1], pix[:, 1:2]
    inside = v & (r[..., 0] <= px) & (px < r[..., 0] + r[..., 2]) & (r[..., 1] <= py) & (py < r[..., 1] + r[..., 3])
    n_in = inside.sum(axis=1)
    return np.where(n_in == 1, np.argmax(inside, axis=1), -1)


# ---- comparisons ---------------------------------------------------------------------------------

def assert_same(new, old):
    for name in new._fields:
        a, b = getattr(new, name), getattr(old, name)
        assert a.dtype == b.dtype and a.shape == b.shape, name
        np.testing.assert_array_equal(a, b, err_msg=name)


def check_sequence(scans, det2, calib, settings_list):
    """Both first stages on every setting; the assignment of each shrink against the old one."""
    points = 0
    for s in settings_list:
        new = prepare_points(scans, det2.frame, det2.box, det2.score, calib, s)
        assert_same(new, old_prepare_points(scans, det2.frame, det2.box, det2.score, calib, s))
        points += new.points.shape[0]
        frames, pf = np.unique(new.point_frame, return_inverse=True)
        slots = np.unique(new.det_frame, return_counts=True)[1].max(initial=1)
        for shrink in (0.0, 0.2, 0.5):
            rects = np.zeros((frames.size, slots, 4), np.int64)
            valid = np.zeros((frames.size, slots), bool)
            for i, f in enumerate(frames):                      # a frame's detections, in row order
                mine = new.det_frame == f
                rects[i, :mine.sum()] = shrunk_boxes(new.rect[mine], shrink)
                valid[i, :mine.sum()] = True
            want = old_assign_points(new.pix, pf, rects, valid)
            for block in (1, 7, 1 << 20):
                np.testing.assert_array_equal(assign_points(new.pix, pf, rects, valid, block=block), want)
    return points


SETTINGS = [LiftSettings(), LiftSettings(leaf=0.3, score_cut=0.2), LiftSettings(crop_lo=(-40.0, -30.0, -2.0),
                                                                                  crop_hi=(60.0, 30.0, 2.0))]


@pytest.mark.slow
@pytest.mark.parametrize("sim", [SimSettings(beams=32), SimSettings(beams=32, fov=180.0, az_step=0.3, clutter=0.05,
                                                                    dropout=0.1)])
def test_one_scan_at_a_time_equals_the_whole_sequence_on_simulated_scenes(tmp_path, sim):
    root = make_scene(tmp_path / "scene", n_sequences=3, n_frames=20, n_cars=7, seed=11)
    lengths = sequence_lengths(root)
    points = 0
    for seq, n in lengths.items():
        scans = dict(simulate_sequence(read_tracking_labels(root / "label_02" / f"{seq}.txt"),
                                       read_calib(root / "calib" / f"{seq}.txt"), n, seq, sim, seed=2))
        det2 = read_detections_2d(root / "detections" / "synth2d" / "car" / f"{seq}.txt")
        points += check_sequence(scans, det2, read_calib(root / "calib" / f"{seq}.txt"), SETTINGS)
    assert points > 1000


@pytest.mark.slow
def test_one_scan_at_a_time_equals_the_whole_sequence_on_kitti_sequences(kitti_root):
    """Simulated full-turn scans of KITTI's labels at real density, RRC's detections, 40 frames each."""
    points = 0
    for seq in ("0001", "0019"):
        calib = read_calib(kitti_root / "calib" / f"{seq}.txt")
        scans = dict(simulate_sequence(read_tracking_labels(kitti_root / "label_02" / f"{seq}.txt"), calib, 40, seq,
                                       SimSettings(fov=180.0, az_step=0.17), seed=0))
        det2 = read_detections_2d(kitti_root / "detections" / "rrc" / "car" / f"{seq}.txt")
        inside = det2.frame < 40
        det2 = det2._replace(frame=det2.frame[inside], box=det2.box[inside], score=det2.score[inside])
        points += check_sequence(scans, det2, calib, SETTINGS[:2])
    assert points > 1000


# ---- bounded memory: no scan outlives its frame ----------------------------------------------------

class Reader:
    """``load`` (a fresh array per call) recording how many earlier scans were still alive at each call."""

    def __init__(self, load):
        self.load, self.alive, self.refs = load, [], []

    def __call__(self, key):
        self.alive.append(sum(r() is not None for r in self.refs))
        scan = self.load(key)
        self.refs.append(weakref.ref(scan))
        return scan


def test_a_reader_is_called_once_per_frame_and_no_scan_outlives_its_frame(tmp_path):
    root = make_scene(tmp_path / "scene", n_sequences=1, n_frames=15, n_cars=5, seed=2)
    calib = read_calib(root / "calib" / "0000.txt")
    scans = dict(simulate_sequence(read_tracking_labels(root / "label_02" / "0000.txt"), calib, 15, "0000",
                                   SimSettings(beams=16)))
    det2 = read_detections_2d(root / "detections" / "synth2d" / "car" / "0000.txt")
    reader = Reader(lambda f: scans[f].copy())
    got = prepare_points(reader, det2.frame, det2.box, det2.score, calib, LiftSettings())
    assert_same(got, prepare_points(scans, det2.frame, det2.box, det2.score, calib, LiftSettings()))
    assert len(reader.alive) == np.unique(det2.frame[det2.score >= 0.45]).size > 5
    assert max(reader.alive) == 0
    lifted = lift_prepared(got, LiftSettings())
    assert lifted.rows.size > 5


def test_lift_sequence_reads_one_scan_at_a_time(tmp_path, monkeypatch):
    root = make_scene(tmp_path / "scene", n_sequences=1, n_frames=15, n_cars=5, seed=2)
    calib = read_calib(root / "calib" / "0000.txt")
    simulate_to_folder(tmp_path / "scans", read_tracking_labels(root / "label_02" / "0000.txt"), calib, 15, "0000",
                       SimSettings(beams=16))
    det2 = read_detections_2d(root / "detections" / "synth2d" / "car" / "0000.txt")
    reader = Reader(source.read_scan)
    monkeypatch.setattr(source, "read_scan", reader)
    clear_cache()
    lifted = lift_sequence(tmp_path / "scans", "0000", 15, det2, calib)
    clear_cache()
    assert lifted.frame.size > 5 and len(reader.alive) > 5 and max(reader.alive) == 0
