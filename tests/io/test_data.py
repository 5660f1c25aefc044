import numpy as np
import pytest

from dfrmot_jax.data import box3d_extent, detection_dir, load_sequences, load_split, pack, sequences_with_class
from dfrmot_jax.trackers.dfr.frames import object_boxes, prepare_frames
from dfrmot_jax.boxes import truncate_2d_box, truncate_3d_box
from dfrmot_jax.io.kitti import KittiFormatError
from dfrmot_jax.trackers.dfr.config import Options
from dfrmot_jax.synthetic import make_scene


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    return make_scene(tmp_path_factory.mktemp("scene"), n_sequences=3, n_frames=60, n_cars=5, seed=1)


def test_pack_concatenates_sequences_with_resets(root):
    seqs = load_sequences(root, "synth2d", "synth3d", "car")
    split = pack(seqs)
    assert split.names == ("0000", "0001", "0002")
    assert split.n_frames == sum(s.n_frames for s in seqs) == 180
    np.testing.assert_array_equal(split.offsets, [0, 60, 120])
    assert split.reset.sum() == 3 and all(split.reset[o] for o in split.offsets)
    for k, s in enumerate(seqs):
        sl = split.sequence_slice(k)
        assert split.valid2d[sl].sum() == s.det2d.frame.size and split.valid3d[sl].sum() == s.det3d.frame.size
        t, m = np.nonzero(split.valid2d[sl])
        rows = split.row2d[sl][t, m]
        np.testing.assert_array_equal(split.box2d[sl][t, m], s.det2d.box[rows])
        np.testing.assert_array_equal(s.det2d.frame[rows], t)
    assert split.box2d.shape[1] == max(np.bincount(s.det2d.frame).max() for s in seqs)


def test_truncation_follows_the_cpp_loaders():
    b = np.array([[10.9, 20.2, 50.7, 80.99]])
    np.testing.assert_array_equal(truncate_2d_box(b), [[10, 20, 50, 80]])
    np.testing.assert_array_equal(truncate_3d_box(np.array([[10.9, 20.2, 50.7, 80.99]])), [[10, 20, 50, 80]])
    # 3D: w = trunc(|trunc(x1) - x2|) differs from the 2D rule when x1 is negative
    np.testing.assert_array_equal(truncate_2d_box(np.array([[-0.5, 0, 9.7, 5]]))[0, 2], 9)
    np.testing.assert_array_equal(truncate_3d_box(np.array([[-0.5, 0, 9.7, 5]]))[0, 2], 9)


def test_box3d_conventions():
    dims = np.array([1.5, 1.6, 3.9]); loc = np.array([2.0, 1.7, 20.0])
    lo, hi = box3d_extent(dims, loc, "legacy")
    np.testing.assert_allclose((lo + hi) / 2, [20 + 3.9 / 2, 1.7 + 1.6 / 2, 2 + 1.5 / 2], rtol=1e-6)
    lo, hi = box3d_extent(dims, loc, "head")
    np.testing.assert_allclose((lo + hi) / 2, [20 + 3.9 / 2, -2 + 1.5 / 2, -1.7 + 1.6 / 2], rtol=1e-6)
    lo, hi = box3d_extent(dims, loc, "kitti")
    np.testing.assert_allclose((lo + hi) / 2, [2.0, 1.7 - 0.75, 20.0], rtol=1e-6)
    assert lo.dtype == np.float32


def test_prepare_frames_choices(root):
    split = load_split(root, "synth2d", "synth3d", "car")
    code = prepare_frames(split, Options())
    paper = prepare_frames(split, Options(merge="calib_projection", truncate=False))
    v = split.valid3d
    assert np.all(code.box3[v] == np.trunc(code.box3[v]))
    assert not np.array_equal(code.box3[v], paper.box3[v])
    np.testing.assert_allclose(paper.box3[v], split.proj3d[v].astype(np.float32))
    assert object_boxes(code, Options()).shape[1] == split.box2d.shape[1] + split.box3d.shape[1]
    assert object_boxes(code, Options(modality="2d")).shape[1] == split.box2d.shape[1]


def test_detector_by_name_or_path_and_unknown_detector(root):
    assert detection_dir(root, "synth2d", "car") == root / "detections" / "synth2d" / "car"
    assert detection_dir(root, root / "detections" / "synth3d" / "car", "car").name == "car"
    with pytest.raises(KittiFormatError, match="unknown detector 'yolo'"):
        detection_dir(root, "yolo", "car")


def test_default_sequences_are_those_with_the_class(kitti_root):
    assert sequences_with_class(kitti_root, "car") == [f"{i:04d}" for i in range(21) if i != 17]


def test_whole_training_split_packs(kitti_root):
    split = load_split(kitti_root, "rrc", "pointrcnn", "car", [f"{i:04d}" for i in range(21)])
    assert split.n_frames == 8008 and split.box2d.shape[1] == 14 and split.box3d.shape[1] == 19


def _frames_equal(a, b):
    for name in a._fields:
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and x.shape == y.shape, name
        np.testing.assert_array_equal(x.view(np.uint8) if x.dtype != bool else x,
                                      y.view(np.uint8) if y.dtype != bool else y, err_msg=name)   # bit for bit


@pytest.mark.parametrize("options", [Options(), Options(truncate=False, merge="calib_projection", centroid="kitti"),
                                     Options(centroid="head", modality="3d")])
def test_compact_frames_equal_preparing_the_compacted_split(root, options):
    """``compact_frames`` (what ``track`` runs on) is ``prepare_frames(compact_split(...))`` bit for bit,
    empty slots and a kept 3D detection with a non-finite image box included, with the same slot orders."""
    from dfrmot_jax.trackers.dfr.frames import compact_frames
    from dfrmot_jax.data import compact_slots

    split = pack(load_sequences(root, "synth2d", "synth3d", "car"))
    t, j = np.argwhere(split.valid3d & (split.score3d >= 8.0))[3]
    split.proj3d[t, j, 2] = np.inf      # a kept detection whose projected box is not finite: invalid when prepared
    split.box3d[t, j, 0] = np.nan
    for s2, s3 in ((0.9, 8.0), (0.0, -5.0), (0.97, 0.2)):
        packed, order2, order3 = compact_slots(split, s2, s3)
        frames, o2, o3 = compact_frames(split, prepare_frames(split, options), options, s2, s3)
        assert packed.valid2d.shape[1] < split.valid2d.shape[1] or s2 == 0.0
        np.testing.assert_array_equal(o2, order2)
        np.testing.assert_array_equal(o3, order3)
        _frames_equal(frames, prepare_frames(packed, options))
        assert not frames.valid3[t][order3[t] == j].any()


def test_compact_frames_equal_on_kitti(kitti_root):
    """The same on KITTI car's two densest sequences at the grid's loosest thresholds."""
    from dfrmot_jax.trackers.dfr.frames import compact_frames
    from dfrmot_jax.data import compact_slots

    split = pack(load_sequences(kitti_root, "rrc", "pointrcnn", "car", ["0019", "0020"]))
    options = Options()
    packed, *_ = compact_slots(split, 0.25, 4.0)
    frames, *_ = compact_frames(split, prepare_frames(split, options), options, 0.25, 4.0)
    assert frames.valid3.shape[1] < split.valid3d.shape[1]
    _frames_equal(frames, prepare_frames(packed, options))
