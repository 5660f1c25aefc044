"""Bad inputs to the metrics entry points: KittiFormatError naming file, line and field; array checks."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dfrmot_jax.io.kitti import KittiFormatError
from dfrmot_jax.metrics import DuplicateIdError, evaluate_arrays, evaluate_files, prepare_gt
from dfrmot_jax.metrics.common.sequences import class_sequences

ROW = "{f} {i} {t} -1 -1 -10 {x1} {y1} {x2} {y2} -1 -1 -1 -1000 -1000 -1000 -10 1\n"


def _row(f=0, i=1, t="Car", box=(100, 100, 200, 180)):
    return ROW.format(f=f, i=i, t=t, x1=box[0], y1=box[1], x2=box[2], y2=box[3])


@pytest.fixture(scope="module")
def gt0(kitti_root):
    return prepare_gt(kitti_root, "car", ["0000"])  # 154 frames


def _write(tmp_path: Path, text: str) -> Path:
    d = tmp_path / "res"
    d.mkdir(exist_ok=True)
    (d / "0000.txt").write_text(text)
    return d


def _raises(d, gt, field, line):
    with pytest.raises(KittiFormatError) as ei:
        evaluate_files(d, gt)
    e = ei.value
    assert e.field == field and e.line == line and e.path.endswith("0000.txt"), (e.field, e.line, e.path)
    return e


def test_wrong_column_count(tmp_path, gt0):
    # rows of one frame with 18 and 17 columns (TrackEval reads rows of different frames that differ)
    text = _row(0) + _row(1) + "1 2 Car -1 -1 -10 1 2 3 4 -1 -1 -1 -1000 -1000 -1000\n"
    _raises(_write(tmp_path, text), gt0, "columns", 3)


def test_frame_beyond_sequence(tmp_path, gt0):
    text = _row(0) + "\n" + _row(153) + _row(154)  # the blank line counts in line numbers
    e = _raises(_write(tmp_path, text), gt0, "frame", 4)
    assert "154" in str(e)


def test_non_numeric_id(tmp_path, gt0):
    text = _row(0) + _row(1, i="abc")
    _raises(_write(tmp_path, text), gt0, "track_id", 2)


def test_unknown_class(tmp_path, gt0):
    text = _row(0) + _row(1, t="Person_sitting")
    _raises(_write(tmp_path, text), gt0, "type", 2)


def test_unknown_classes_the_first_by_name_is_named_at_its_first_row(tmp_path, gt0):
    text = _row(0) + _row(1, t="Zebra") + _row(1, i=2, t="Bus") + _row(2, t="Bus")
    e = _raises(_write(tmp_path, text), gt0, "type", 3)
    assert "unknown class" in str(e) and "Bus" in str(e) and "Zebra" not in str(e), str(e)


def test_ground_truth_type_names_in_any_case(tmp_path):
    label = "{f} {i} {t} 0 0 -10 {x} 100 {x2} 180 1.5 1.6 4 1 1.8 20 0\n"
    rows = [(0, -1, "DontCare"), (0, -1, "dontcare"), (0, 1, "CAR"), (1, 2, "car"), (1, 3, "Van"),
            (1, 4, "DONTCARE"), (2, 5, "Pedestrian"), (2, -1, "Person_sitting")]
    (tmp_path / "label_02").mkdir()
    (tmp_path / "label_02" / "0000.txt").write_text("".join(label.format(f=f, i=i, t=t, x=100 + 10 * k, x2=200 + 10 * k)
                                                            for k, (f, i, t) in enumerate(rows)))
    gt = prepare_gt(tmp_path, "car", ["0000"])
    assert len(gt.dc_box) == 3 and gt.dc_box[:, 0].tolist() == [100, 110, 150]   # DontCare whatever its case or id
    assert int(gt.n_gt_dets.sum()) == 2 and gt.row_eval.tolist() == [True, True, False]   # CAR, car; the Van
    assert class_sequences(tmp_path, "car") == ("0000",) and class_sequences(tmp_path, "pedestrian") == ("0000",)
    (tmp_path / "label_02" / "0000.txt").write_text(label.format(f=0, i=1, t="Van", x=1, x2=2))
    assert class_sequences(tmp_path, "car") == ()



@pytest.mark.parametrize("rows, field, line", [
    ([(0, 1, "Car"), (1, 2, "Zebra"), (1, 3, "Bus"), (2, -1, "Unicorn")], "type", 3),   # first by name, its first row
    ([(0, 1, "Car"), (1, 2, "Car"), (1, 2, "car")], None, None),                      # one id twice in frame 1
])
def test_ground_truth_unknown_class_or_repeated_id(tmp_path, rows, field, line):
    """Ground truth refuses an unknown class name on a row TrackEval reads (not on negative ids) and an id
    twice in one frame, as TrackEval does."""
    label = "{f} {i} {t} 0 0 -10 {x} 100 {x2} 180 1.5 1.6 4 1 1.8 20 0\n"
    (tmp_path / "label_02").mkdir()
    (tmp_path / "label_02" / "0000.txt").write_text("".join(label.format(f=f, i=i, t=t, x=100 + 10 * k, x2=200 + 10 * k)
                                                            for k, (f, i, t) in enumerate(rows)))
    if field is None:
        with pytest.raises(ValueError, match="same id twice in one frame"):
            prepare_gt(tmp_path, "car", ["0000"])
        rows[-1] = (1, 3, "car")
        (tmp_path / "label_02" / "0000.txt").write_text("".join(
            label.format(f=f, i=i, t=t, x=100 + 10 * k, x2=200 + 10 * k) for k, (f, i, t) in enumerate(rows)))
        assert int(prepare_gt(tmp_path, "car", ["0000"]).n_gt_ids.sum()) == 3
        return
    with pytest.raises(KittiFormatError) as e:
        prepare_gt(tmp_path, "car", ["0000"])
    assert e.value.field == field and e.value.line == line and "Bus" in str(e.value), str(e.value)


def _gt_fields(gt) -> dict:
    return {f: getattr(gt, f) for f in gt.__dataclass_fields__ if f != "_cache"}


def test_ground_truth_of_all_sequences_at_once_equals_one_by_one(kitti_root, monkeypatch):
    """prepare_gt prepares the sequences read in one parse all at once; with that read switched off it
    takes them one by one (each file read alone): every array equal, bit for bit, dtypes too."""
    import dfrmot_jax.io.kitti as kio
    for cls, seqs in (("car", None), ("pedestrian", None), ("car", ["0017", "0001", "0005"])):
        joined = _gt_fields(prepare_gt(kitti_root, cls, seqs))
        with monkeypatch.context() as m:
            m.setattr(kio, "joined_tracking_labels", lambda paths: None)
            alone = _gt_fields(prepare_gt(kitti_root, cls, seqs))
        for f, v in joined.items():
            w = alone[f]
            same = (v.dtype == w.dtype and v.shape == w.shape and np.array_equal(v, w)) if isinstance(v, np.ndarray) \
                else v == w
            assert same, (cls, seqs, f)


@pytest.mark.parametrize("problems", [("dup", "type"), ("type", "dup"), ("ok", "dup"), ("ok", "type")])
def test_ground_truth_problem_of_the_first_sequence_that_has_one_is_raised(tmp_path, monkeypatch, problems):
    """Sequences prepared at once raise what they raise one by one: the first sequence's problem, by its file."""
    import dfrmot_jax.io.kitti as kio
    label = "{f} {i} {t} 0 0 -10 {x} 100 {x2} 180 1.5 1.6 4 1 1.8 20 0\n"
    rows = {"ok": [(0, 1, "Car"), (1, 2, "Van")], "dup": [(0, 1, "Car"), (1, 2, "Car"), (1, 2, "car")],
            "type": [(0, 1, "Car"), (1, 2, "Zebra")]}
    (tmp_path / "label_02").mkdir()
    for s, kind in enumerate(("ok",) + problems):
        (tmp_path / "label_02" / f"{s:04d}.txt").write_text("".join(
            label.format(f=f, i=i, t=t, x=100 + 10 * k, x2=200 + 10 * k) for k, (f, i, t) in enumerate(rows[kind])))
    assert kio.joined_tracking_labels(sorted((tmp_path / "label_02").glob("*.txt"))) is not None

    def outcome():
        try:
            prepare_gt(tmp_path, "car")
        except ValueError as e:
            return type(e), str(e)
    with monkeypatch.context() as m:
        m.setattr(kio, "joined_tracking_labels", lambda paths: None)
        alone = outcome()
    bad = 1 + next(i for i, k in enumerate(problems) if k != "ok")       # (sequence 0000 is fine)
    assert outcome() == alone and alone is not None and f"{bad:04d}.txt" in alone[1], (outcome(), alone)


def test_duplicate_id_in_frame(tmp_path, gt0):
    text = _row(0) + _row(5, i=3) + _row(5, i=3, box=(400, 120, 500, 200))
    _raises(_write(tmp_path, text), gt0, "track_id", 3)


def test_duplicate_removed_by_preprocessing_is_fine(tmp_path, gt0):
    # the second box is 20 px tall and matches nothing: TrackEval drops it before checking ids
    text = _row(5, i=3) + _row(5, i=3, box=(1000, 10, 1010, 30))
    res = evaluate_files(_write(tmp_path, text), gt0)
    assert res["COMBINED"]["Dets"] == 1


def test_other_classes_and_negative_ids_ignored(tmp_path, gt0):
    text = _row(0, i=1) + _row(0, i=2, t="Pedestrian") + _row(0, i=-1) + _row(0, i=4, t="car_2", box=(600, 150, 700, 250))
    res = evaluate_files(_write(tmp_path, text), gt0)
    assert res["COMBINED"]["Dets"] == 2 and res["COMBINED"]["IDs"] == 2


def test_missing_file(tmp_path, gt0):
    d = tmp_path / "empty"
    d.mkdir()
    res = evaluate_files(d, gt0)
    assert res["COMBINED"]["CLR_TP"] == 0 and res["COMBINED"]["CLR_FN"] == int(gt0.n_gt_dets.sum())
    with pytest.raises(KittiFormatError) as ei:
        evaluate_files(d, gt0, missing="error")
    assert ei.value.path.endswith("0000.txt")


def test_bad_class_name(kitti_root):
    with pytest.raises(ValueError):
        prepare_gt(kitti_root, "cyclist", ["0000"])


def test_array_checks(gt0):
    T = gt0.n_frames
    ids = np.full((2, T, 3), -1, np.int32)
    boxes = np.zeros((2, T, 3, 4), np.float32)
    with pytest.raises(ValueError):
        evaluate_arrays(gt0, ids[0], boxes[0], [0])
    with pytest.raises(ValueError):
        evaluate_arrays(gt0, ids, boxes[:, :, :2], [0])
    with pytest.raises(ValueError):
        evaluate_arrays(gt0, ids, boxes, [1])  # sequence would run past T
    ids[1, 4, 0] = 7
    boxes[1, 4, 0] = [np.nan, 0, 10, 10]
    with pytest.raises(ValueError, match="non-finite"):
        evaluate_arrays(gt0, ids, boxes, [0])
    boxes[1, 4, 0] = [100, 100, 200, 180]
    ids[1, 4, 1] = 7
    boxes[1, 4, 1] = [300, 100, 400, 180]
    with pytest.raises(DuplicateIdError, match="config 1"):
        evaluate_arrays(gt0, ids, boxes, [0])
    ids[1, 4, 1] = 8
    res = evaluate_arrays(gt0, ids, boxes, [0])
    assert [r["COMBINED"]["Dets"] for r in res] == [0, 2]
    # in a later chunk of lanes (4 per chunk): still named by its own index
    many_ids, many_boxes = np.repeat(ids, 4, axis=0), np.repeat(boxes, 4, axis=0)
    many_ids[6, 4, 1] = 7
    with pytest.raises(DuplicateIdError, match="config 6:"):
        evaluate_arrays(gt0, many_ids, many_boxes, [0])


def test_missing_results_folder(tmp_path, gt0):
    with pytest.raises(FileNotFoundError):
        evaluate_files(tmp_path / "does_not_exist", gt0)


def test_lenient_rows_like_trackeval(tmp_path, gt0, kitti_root):
    """Rows TrackEval skips before any check (negative ids: any class, any frame) and a duplicate id
    removed by preprocessing must not raise, and must give TrackEval's numbers."""
    pytest.importorskip("trackeval")
    from dfrmot_jax.testing.trackeval_adapter import make_gt_folder, make_tracker_folder, run_trackeval

    text = (_row(0, i=1, box=(296, 160, 452, 288)) + _row(0, i=-1, t="Whatever") + _row(3, i=2)
            + _row(5, i=3) + _row(5, i=3, box=(1000, 10, 1010, 30))
            + _row(7, i=8, t="DontCare", box=(10, 10, 20, 20)) + _row(999, i=-5))
    d = _write(tmp_path, text)
    make_gt_folder(tmp_path / "gt", kitti_root, gt0.lengths_dict)
    make_tracker_folder(tmp_path / "trk", "t", {"0000": text}, ["0000"])
    te = run_trackeval(tmp_path / "gt", tmp_path / "trk", "car")["t"]
    ours = evaluate_files(d, gt0)
    for seq in te:
        for f, v in te[seq].items():
            assert np.allclose(np.asarray(ours[seq][f], float), np.asarray(v, float), atol=1e-9, rtol=0), (seq, f)
