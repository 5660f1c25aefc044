from pathlib import Path

import numpy as np
import pytest

from dfrmot_jax.boxes import iou
from dfrmot_jax.geometry import project_box3d_to_image
from dfrmot_jax.synthetic import IMAGE_SIZE, NOISE_DEFAULTS, make_scene

W, H = IMAGE_SIZE
N_FRAMES = 80


# ---- hand parsers (independent of dfrmot_jax.io) -----------------------------------------------


def parse_labels(path):
    rows = [line.split() for line in Path(path).read_text().splitlines() if line.strip()]
    assert all(len(r) == 17 for r in rows)
    return {
        "frame": np.array([int(r[0]) for r in rows]),
        "track_id": np.array([int(r[1]) for r in rows]),
        "type": np.array([r[2] for r in rows]),
        "truncated": np.array([float(r[3]) for r in rows]),
        "occluded": np.array([float(r[4]) for r in rows]),
        "alpha": np.array([float(r[5]) for r in rows]),
        "box": np.array([[float(v) for v in r[6:10]] for r in rows]).reshape(-1, 4),
        "dims": np.array([[float(v) for v in r[10:13]] for r in rows]).reshape(-1, 3),
        "loc": np.array([[float(v) for v in r[13:16]] for r in rows]).reshape(-1, 3),
        "rot_y": np.array([float(r[16]) for r in rows]),
    }


def parse_csv(path, ncols):
    lines = [line for line in Path(path).read_text().splitlines() if line.strip()]
    rows = [line.split(",") for line in lines]
    assert all(len(r) == ncols for r in rows)
    return np.array([[float(v) for v in r] for r in rows]).reshape(-1, ncols)


def parse_p2(path):
    for line in Path(path).read_text().splitlines():
        name, _, values = line.partition(":")
        if name == "P2":
            return np.array(values.split(), dtype=float).reshape(3, 4)
    raise AssertionError("no P2")


def load(root, seq):
    root = Path(root)
    name = f"{seq:04d}.txt"
    return (
        parse_labels(root / "label_02" / name),
        parse_csv(root / "detections" / "synth2d" / "car" / name, 6),
        parse_csv(root / "detections" / "synth3d" / "car" / name, 15),
        parse_p2(root / "calib" / name),
    )


def wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    return make_scene(tmp_path_factory.mktemp("synth"), n_sequences=3, n_frames=N_FRAMES, seed=0)


# ---- tests ---------------------------------------------------------------------------------------


def test_layout_and_formats(scene):
    assert scene.is_dir()
    for seq in range(3):
        name = f"{seq:04d}.txt"
        for sub in ("label_02", "calib", "detections/synth2d/car", "detections/synth3d/car"):
            assert (scene / sub / name).is_file()
        lab, d2, d3, P2 = load(scene, seq)
        # every frame has a label row, so the sequence length is max frame + 1 = n_frames
        assert set(lab["frame"]) == set(range(N_FRAMES))
        assert set(lab["type"]) <= {"Car", "Van", "DontCare"}
        dc = lab["type"] == "DontCare"
        assert dc.any() and (lab["track_id"][dc] == -1).all()
        assert np.all(lab["dims"][dc] == -1000)
        cars = ~dc
        assert set(lab["truncated"][cars]) <= {0, 1, 2} and set(lab["occluded"][cars]) <= {0, 1, 2}
        ids = np.unique(lab["track_id"][cars])
        np.testing.assert_array_equal(ids, np.arange(len(ids)))  # 0.. in order of appearance
        first = [lab["frame"][cars][lab["track_id"][cars] == i].min() for i in ids]
        assert np.all(np.diff(first) >= 0)
        # each track appears at most once per frame
        pairs = set(zip(lab["frame"][cars], lab["track_id"][cars]))
        assert len(pairs) == cars.sum()
        # detection files
        assert len(d2) > 50 and len(d3) > 50
        assert np.all((d2[:, 5] >= 0.1) & (d2[:, 5] <= 1.0))
        assert np.all(d3[:, 1] == 2)
        assert np.all((d3[:, 6] >= -1) & (d3[:, 6] <= 16))
        for d, b in ((d2, d2[:, 1:5]), (d3, d3[:, 2:6])):
            assert np.all((d[:, 0] >= 0) & (d[:, 0] < N_FRAMES) & (d[:, 0] == np.round(d[:, 0])))
            assert np.all(np.diff(d[:, 0]) >= 0)  # sorted by frame
            assert np.all((b[:, 0] >= 0) & (b[:, 2] <= W - 1) & (b[:, 1] >= 0) & (b[:, 3] <= H - 1))
            assert np.all((b[:, 2] > b[:, 0]) & (b[:, 3] > b[:, 1]))
        assert P2.shape == (3, 4) and 700 < P2[0, 0] < 730


def test_official_readers_agree(scene):
    kitti = pytest.importorskip("dfrmot_jax.io.kitti")
    for seq in range(3):
        name = f"{seq:04d}.txt"
        lab, d2, d3, P2 = load(scene, seq)
        L = kitti.read_tracking_labels(scene / "label_02" / name)
        np.testing.assert_array_equal(L.frame, lab["frame"])
        np.testing.assert_array_equal(L.track_id, lab["track_id"])
        np.testing.assert_array_equal(L.type.astype(str), lab["type"])
        np.testing.assert_allclose(L.box, lab["box"])
        np.testing.assert_allclose(L.loc, lab["loc"])
        D2 = kitti.read_detections_2d(scene / "detections" / "synth2d" / "car" / name)
        np.testing.assert_allclose(D2.box, d2[:, 1:5])
        np.testing.assert_allclose(D2.score, d2[:, 5])
        D3 = kitti.read_detections_3d(scene / "detections" / "synth3d" / "car" / name)
        np.testing.assert_allclose(D3.dims, d3[:, 7:10])
        np.testing.assert_allclose(D3.alpha, d3[:, 14])
        C = kitti.read_calib(scene / "calib" / name)
        np.testing.assert_allclose(C.P2, P2)
        assert C.R0_rect.shape == (3, 3)
    assert kitti.sequence_lengths(scene) == {f"{s:04d}": N_FRAMES for s in range(3)}


def _all_bytes(root):
    root = Path(root)
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*.txt"))}


def test_deterministic_and_seed_dependent(tmp_path):
    a = _all_bytes(make_scene(tmp_path / "a", seed=3))
    b = _all_bytes(make_scene(tmp_path / "b", seed=3))
    c = _all_bytes(make_scene(tmp_path / "c", seed=4))
    assert len(a) == 8 and a == b
    assert a.keys() == c.keys()
    for k in a:
        if "calib" not in k:
            assert a[k] != c[k], k
    # sequences within one scene differ too
    assert a["label_02/0000.txt"] != a["label_02/0001.txt"]


def test_gt_boxes_are_clipped_projections(scene):
    for seq in range(3):
        lab, _, _, P2 = load(scene, seq)
        cars = lab["type"] != "DontCare"
        box = lab["box"][cars]
        assert np.all((box[:, 0] >= 0) & (box[:, 1] >= 0) & (box[:, 2] <= W - 1) & (box[:, 3] <= H - 1))
        assert np.all((box[:, 2] - box[:, 0] >= 1.99) & (box[:, 3] - box[:, 1] >= 1.99))
        proj = project_box3d_to_image(lab["dims"][cars], lab["loc"][cars], lab["rot_y"][cars], P2)
        np.testing.assert_allclose(proj, box, atol=0.05)  # 6-decimal rounding, near corners
        alpha = lab["rot_y"][cars] - np.arctan2(lab["loc"][cars, 0], lab["loc"][cars, 2])
        assert np.max(np.abs(wrap(alpha - lab["alpha"][cars]))) < 1e-4
        dcbox = lab["box"][~cars]
        assert np.all((dcbox[:, 0] >= 0) & (dcbox[:, 2] <= W - 1) & (dcbox[:, 2] > dcbox[:, 0]))


def test_scene_physics(scene):
    n_entering = n_leaving = 0
    trunc, occ, car_dims = [], [], []
    for seq in range(3):
        lab, _, _, _ = load(scene, seq)
        cars = lab["type"] != "DontCare"
        loc, dims = lab["loc"][cars], lab["dims"][cars]
        assert np.all((loc[:, 2] > -10) & (loc[:, 2] < 70) & (np.abs(loc[:, 0]) < 17))
        assert np.all(np.abs(loc[:, 1] - 1.65) < 0.3)
        is_car = lab["type"][cars] == "Car"
        car_dims.append(np.unique(dims[is_car], axis=0))  # one row per car track (dims are fixed)
        trunc.append(lab["truncated"][cars])
        occ.append(lab["occluded"][cars])
        tid, frame = lab["track_id"][cars], lab["frame"][cars]
        for i in np.unique(tid):
            m = tid == i
            f, p, r = frame[m], loc[m], lab["rot_y"][cars][m]
            n_entering += f.min() > 0
            n_leaving += f.max() < N_FRAMES - 1
            step = np.diff(f) == 1
            if step.any():
                # smooth motion: at most ~26 m/s relative speed, small heading changes
                assert np.max(np.linalg.norm(np.diff(p, axis=0)[step], axis=1)) < 3.0
                assert np.max(np.abs(wrap(np.diff(r)[step]))) < 0.1
    trunc, occ = np.concatenate(trunc), np.concatenate(occ)
    car_dims = np.concatenate(car_dims)
    assert len(car_dims) >= 10
    np.testing.assert_allclose(np.median(car_dims, axis=0), [1.52, 1.63, 3.9], atol=0.3)
    assert n_entering >= 3 and n_leaving >= 3
    assert (occ == 0).mean() > 0.5 and (occ == 2).any() and (occ == 1).any()
    assert (trunc == 0).mean() > 0.7 and (trunc > 0).any()


def iou_2d(a, b):
    return iou(np.asarray(a, np.float64), np.asarray(b, np.float64))


def _best_match(frames, boxes, gt):
    """IoU of each detection with its best GT box of the same frame (Car or Van)."""
    out = np.zeros(len(boxes))
    for k, (f, b) in enumerate(zip(frames, boxes)):
        g = gt["box"][(gt["frame"] == f) & (gt["type"] != "DontCare")]
        out[k] = iou_2d(b, g).max() if len(g) else 0.0
    return out


def test_detections_overlap_ground_truth(scene):
    hits = []
    for seq in range(3):
        lab, d2, d3, P2 = load(scene, seq)
        best2 = _best_match(d2[:, 0], d2[:, 1:5], lab)
        confident = d2[:, 5] > 0.5
        assert confident.sum() > 50
        assert (best2[confident] > 0.5).mean() > 0.95
        assert np.median(best2[confident]) > 0.8
        assert (best2[d2[:, 5] < 0.45] < 0.5).any()  # some false positives
        # recall of clearly visible cars by the 2D detector
        cars = (lab["type"] == "Car") & (lab["occluded"] == 0) & (lab["box"][:, 3] - lab["box"][:, 1] > 25)
        hit = [
            len(d2[d2[:, 0] == f]) and iou_2d(b, d2[d2[:, 0] == f, 1:5]).max() > 0.5
            for f, b in zip(lab["frame"][cars], lab["box"][cars])
        ]
        hits += hit
        # 3D: real vehicles score high, false positives low
        best3 = _best_match(d3[:, 0], d3[:, 2:6], lab)
        real = best3 > 0.5
        assert 4.0 < np.median(d3[real, 6]) < 10.0
        assert np.percentile(d3[real, 6], 90) > 7.0
        fp = best3 == 0
        assert fp.any() and np.all(d3[fp, 6] <= 3.0)
    assert len(hits) > 100
    assert 0.8 < np.mean(hits) < 0.98  # misses exist


def test_3d_detection_image_boxes_are_projections(scene):
    for seq in range(3):
        _, _, d3, P2 = load(scene, seq)
        proj = project_box3d_to_image(d3[:, 7:10], d3[:, 10:13], d3[:, 13], P2)
        np.testing.assert_allclose(proj, d3[:, 2:6], atol=1e-3)
        alpha = d3[:, 13] - np.arctan2(d3[:, 10], d3[:, 12])
        assert np.max(np.abs(wrap(alpha - d3[:, 14]))) < 2e-4


def test_noise_knobs(tmp_path):
    exact = dict(
        det2d_miss_rate=0.0, det2d_box_sigma=0.0, det2d_fp_rate=0.0, det2d_min_height=0.0,
        det3d_miss_rate=0.0, det3d_pos_sigma=0.0, det3d_dim_sigma=0.0, det3d_rot_sigma=0.0,
        det3d_flip_rate=0.0, det3d_fp_rate=0.0, det3d_max_range=1000.0, occlusion_miss=1.0,
        van_detect_prob=1.0,
    )
    assert set(exact) == set(NOISE_DEFAULTS)
    root = make_scene(tmp_path / "exact", n_sequences=1, seed=1, **exact)
    lab, d2, d3, _ = load(root, 0)
    best2 = _best_match(d2[:, 0], d2[:, 1:5], lab)
    assert np.all(best2 > 0.999)
    best3 = _best_match(d3[:, 0], d3[:, 2:6], lab)
    assert np.all(best3 > 0.99)
    # noisier settings give worse boxes and more false positives
    noisy = make_scene(tmp_path / "noisy", n_sequences=1, seed=1, det2d_box_sigma=0.15, det2d_fp_rate=3.0)
    _, n2, _, _ = load(noisy, 0)
    default = make_scene(tmp_path / "default", n_sequences=1, seed=1)
    _, dd2, _, _ = load(default, 0)
    assert len(n2) > len(dd2) + 100
    with pytest.raises(TypeError, match="unknown noise"):
        make_scene(tmp_path / "bad", det2d_mis_rate=0.1)


def test_scales_to_long_and_to_empty_scenes(tmp_path):
    """A long, crowded sequence and one with no car (its speed: benchmarks, never a timed test)."""
    root = make_scene(tmp_path / "big", n_sequences=1, n_frames=300, n_cars=12, seed=7)
    lab, _, _, _ = load(root, 0)
    assert lab["frame"].max() == 299
    root = make_scene(tmp_path / "empty", n_sequences=1, n_frames=5, n_cars=0)
    lab, d2, d3, _ = load(root, 0)
    assert set(lab["frame"]) == set(range(5)) and set(lab["type"]) == {"DontCare"}
