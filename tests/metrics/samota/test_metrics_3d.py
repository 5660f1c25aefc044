"""HOTA / CLEAR / Identity with 3D or bird's-eye-view similarity (metrics.kitti2d.evaluate, similarity=):
equal to the 2D scores where the boxes agree, hand-computed small cases, 2D-only rows unmatched in
3D, located errors, arrays equal to files, and a real KITTI output."""

import numpy as np
import pytest

from dfrmot_jax.io.kitti import KittiFormatError
from dfrmot_jax.metrics.kitti2d.boxes import pair_iou
from dfrmot_jax.metrics.kitti2d.evaluate import evaluate_classes, evaluate_files
from dfrmot_jax.metrics.kitti2d.kitti import prepare_gt
from dfrmot_jax.metrics.kitti2d.lane_scorer import evaluate_arrays
from dfrmot_jax.metrics.kitti2d.lane_scorer import LaneScorer
from dfrmot_jax.metrics.kitti2d.similarity import pair_similarity_3d
from dfrmot_jax.metrics.kitti2d.tracker_files import read_tracker_files
from dfrmot_jax.paths import default_data_root

PLACEHOLDER = (-1, -1, -1, -1000, -1000, -1000, -10)
VAL = ("0001", "0006", "0008", "0010", "0012", "0013", "0014", "0015", "0016", "0018", "0019")


def _car(x, z, l=4.0, w=4.0, h=1.0, y=1.0, s=8.0, typ="Car"):
    """A 3D box at rot_y 0 (length along x, width along z) and the image box that is its ground
    rectangle scaled by ``s``: image IoU and BEV IoU are the same number, and so is the 3D IoU of
    boxes with the same height range. Dyadic values keep every operation exact."""
    box2d = (s * (x - l / 2), s * (z - w / 2), s * (x + l / 2), s * (z + w / 2))
    return typ, box2d, (h, w, l, x, y, z, 0.0)


def _row(frame, tid, obj, score=None):
    typ, b2, b3 = obj
    f = [frame, tid, typ, 0, 0, -10, *b2, *b3]
    if score is not None:
        f.append(score)
    return " ".join(str(v) for v in f)


def _write(d, name, rows):
    """rows sorted by frame (stable), as the ground truth reader requires."""
    rows = sorted(rows, key=lambda r: int(r.split()[0]))
    d.mkdir(parents=True, exist_ok=True)
    (d / f"{name}.txt").write_text("\n".join(rows) + ("\n" if rows else ""))
    return d


# Three cars over five frames; a van (a distractor) and a DontCare region (2D rules in every mode).
GT_ROWS = ([_row(f, 1, _car(10 + f, 20)) for f in range(5)]
           + [_row(f, 2, _car(30, 40 - f, l=6.0)) for f in range(5)]
           + [_row(f, 3, _car(60, 10, w=5.0)) for f in range(1, 4)]
           + [_row(2, 4, _car(80, 80, typ="Van"))]
           + ["0 -1 DontCare -1 -1 -10 1000 1000 1200 1200 -1 -1 -1 -1000 -1000 -1000 -10"])
TRK_ROWS = ([_row(f, 7, _car(10 + f + d, 20 + e)) for f, d, e in ((0, 0, 0), (1, 1, 0), (2, 0, 1), (3, 2, 0))]
            + [_row(4, 8, _car(14.5, 20))]                                       # an id switch
            + [_row(f, 9, _car(30 + f % 2, 40 - f, l=6.0)) for f in range(5)]
            + [_row(f, 5, _car(60, 10.5, w=5.0)) for f in (1, 3)]
            + [_row(2, 6, _car(80.5, 80))]                                      # on the van: removed
            + [_row(1, 11, _car(130, 130, w=8.0))]                             # inside DontCare: removed
            + [_row(3, 12, _car(200, 200))])                                   # a false positive


@pytest.fixture
def scene(tmp_path):
    root = _write(tmp_path / "data" / "label_02", "0000", GT_ROWS).parent
    res = _write(tmp_path / "res", "0000", TRK_ROWS)
    return root, res


def _equal(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(
        a[s].keys() == b[s].keys() and all(np.array_equal(np.asarray(a[s][f]), np.asarray(b[s][f])) for f in a[s])
        for s in a)


def _pack(dets, gt):
    """One lane of TrackerDets (file rows) -> ids [1, T, K], boxes, box3d (file order = slot order)."""
    slot = np.arange(len(dets.frame)) - np.searchsorted(dets.frame, dets.frame)
    K = int(slot.max(initial=0)) + 1
    ids = np.full((1, gt.n_frames, K), -1, dtype=np.int64)
    boxes = np.zeros((1, gt.n_frames, K, 4))
    box3d = np.full((1, gt.n_frames, K, 7), np.nan)
    ids[0, dets.frame, slot] = dets.track_id
    boxes[0, dets.frame, slot] = dets.box
    box3d[0, dets.frame, slot] = np.where(dets.has3d[:, None], dets.box3d, np.nan)   # no box: all NaN
    return ids, boxes, box3d


def test_the_scene_is_what_it_says(scene):
    """Precondition of the next test: on every (object, row) pair the 2D, BEV and 3D IoU are equal
    bit for bit, and they take several values (partial overlaps, misses, exact matches)."""
    root, res = scene
    gt = prepare_gt(root, "car", ["0000"])
    dets = read_tracker_files(res, gt, need_3d=True)
    ia, ib = np.meshgrid(np.arange(len(gt.row_box)), np.arange(len(dets.box)), indexing="ij")
    ia, ib = ia.ravel(), ib.ravel()
    iou2 = pair_iou(gt.row_box[ia], dets.box[ib])
    for kind in ("3d", "bev"):
        assert np.array_equal(pair_similarity_3d(gt.row_box3d, gt.row_has3d, ia, dets.box3d, dets.has3d, ib, kind),
                              iou2)
    assert len(np.unique(iou2)) >= 6 and (iou2 == 1).any() and ((iou2 > 0) & (iou2 < 0.5)).any()


@pytest.mark.parametrize("similarity", ["3d", "bev"])
def test_3d_scores_equal_2d_where_the_boxes_agree(scene, similarity):
    root, res = scene
    two = evaluate_files(res, root, "car", ["0000"])
    three = evaluate_files(res, root, "car", ["0000"], similarity=similarity)
    assert _equal(two, three)
    c = two["COMBINED"]
    assert 0 < c["CLR_FP"] and 0 < c["CLR_FN"] and c["IDSW"] == 1 and 0 < np.mean(c["HOTA"]) < 1
    # arrays: the same rows as [1, T, K] arrays
    gt = prepare_gt(root, "car", ["0000"])
    ids, boxes, box3d = _pack(read_tracker_files(res, gt, need_3d=True), gt)
    assert _equal(evaluate_arrays(gt, ids, boxes, box3d=box3d, similarity=similarity)[0], three)


def _one(tmp_path, gt_obj, trk_obj=None, trk_line=None):
    root = _write(tmp_path / "data" / "label_02", "0000", [_row(0, 1, gt_obj)]).parent
    res = _write(tmp_path / "res", "0000", [trk_line or _row(0, 1, trk_obj)])
    return {s: evaluate_files(res, root, "car", ["0000"], similarity=s)["COMBINED"] for s in ("2d", "3d", "bev")}


ALPHAS = np.arange(0.05, 0.99, 0.05)


def test_a_box_shifted_along_its_length(tmp_path):
    """Same image box, the 3D box 1 m further along its 4 m length: IoU 3/5 in 3D and BEV. HOTA
    counts it at alpha <= 0.6 with LocA 0.6; the image boxes agree (LocA 1)."""
    _, b2, b3 = _car(10, 20)
    shifted = ("Car", b2, (b3[0], b3[1], b3[2], b3[3] + 1, *b3[4:]))
    r = _one(tmp_path, _car(10, 20), shifted)
    assert np.all(r["2d"]["LocA"] == 1) and np.all(r["2d"]["HOTA"] == 1) and r["2d"]["MOTP"] == 1
    hit = ALPHAS <= 0.6 + 1e-9
    assert hit.sum() == 12
    for s in ("3d", "bev"):
        assert np.allclose(r[s]["LocA"][hit], 0.6, rtol=0, atol=1e-15)
        assert np.all(r[s]["HOTA"][hit] == 1) and np.all(r[s]["HOTA"][~hit] == 0)
        assert np.all(r[s]["HOTA_FP"][~hit] == 1) and np.all(r[s]["HOTA_FN"][~hit] == 1)
        assert (r[s]["CLR_TP"], r[s]["MOTP"]) == (1, pytest.approx(0.6, abs=1e-15))   # CLEAR matches at 0.5


def test_a_box_raised_by_half_its_height(tmp_path):
    """Raised by half its height: the same ground rectangle (BEV IoU 1), half the height shared
    (3D IoU (A h / 2) / (2 A h - A h / 2) = 1/3): a CLEAR miss and false positive in 3D only."""
    _, b2, b3 = _car(10, 20)
    raised = ("Car", b2, (*b3[:4], b3[4] - 0.5, *b3[5:]))
    r = _one(tmp_path, _car(10, 20), raised)
    assert r["bev"]["CLR_TP"] == 1 and np.all(r["bev"]["LocA"] == 1)
    assert (r["3d"]["CLR_TP"], r["3d"]["CLR_FP"], r["3d"]["CLR_FN"]) == (0, 1, 1)
    hit = ALPHAS <= 1 / 3
    assert np.allclose(r["3d"]["LocA"][hit], 1 / 3, rtol=0, atol=1e-15)
    assert np.all(r["3d"]["HOTA_TP"] == hit)


def test_a_2d_only_row_is_a_false_positive_in_3d(tmp_path):
    typ, b2, _ = _car(10, 20)
    r = _one(tmp_path, _car(10, 20), (typ, b2, PLACEHOLDER))
    assert (r["2d"]["CLR_TP"], r["2d"]["CLR_FP"]) == (1, 0)
    for s in ("3d", "bev"):
        assert (r[s]["CLR_TP"], r[s]["CLR_FP"], r[s]["CLR_FN"], r[s]["IDTP"]) == (0, 1, 1, 0)
        assert np.all(r[s]["HOTA"] == 0) and np.all(r[s]["HOTA_FP"] == 1)


def test_3d_fields_of_result_files_are_located(scene, tmp_path):
    root, _ = scene
    good = TRK_ROWS[0].split()
    cases = [(10, "-2", "h", "not positive"), (12, "0", "l", "zero"), (14, "nan", "y", "not finite"),
             (11, "-4", "w", "differ in sign"), (15, "abc", "z", "not a number")]
    for col, val, field, text in cases:
        f = list(good)
        f[0], f[col] = "4", val                                  # frame 4: the file's third row
        res = _write(tmp_path / f"bad{col}", "0000", TRK_ROWS[1:3] + [" ".join(f)])
        if val != "abc":                     # TrackEval's reader refuses a non-number in any column, 2D too
            assert evaluate_files(res, root, "car", ["0000"])["COMBINED"]["Dets"] == 3   # 2D: not checked
        with pytest.raises(KittiFormatError) as e:
            evaluate_files(res, root, "car", ["0000"], similarity="3d")
        assert (e.value.line, e.value.field) == (3, field) and text in e.value.message, str(e.value)
    short = _write(tmp_path / "short", "0000", TRK_ROWS[:1] + [" ".join(["3"] + good[1:12])])
    with pytest.raises(KittiFormatError, match="3D fields") as e:
        evaluate_files(short, root, "car", ["0000"], similarity="bev")
    assert e.value.line == 2
    turned = list(good)
    turned[11], turned[12] = "-" + good[11], "-" + good[12]                      # h -w -l: the same box
    res = _write(tmp_path / "turned", "0000", [" ".join(turned)])
    same = _write(tmp_path / "same", "0000", TRK_ROWS[:1])
    assert _equal(evaluate_files(res, root, "car", ["0000"], similarity="3d"),
                  evaluate_files(same, root, "car", ["0000"], similarity="3d"))


def test_bad_arrays_and_arguments(scene):
    root, res = scene
    gt = prepare_gt(root, "car", ["0000"])
    ids, boxes, box3d = _pack(read_tracker_files(res, gt, need_3d=True), gt)
    with pytest.raises(ValueError, match="needs box3d"):
        evaluate_arrays(gt, ids, boxes, similarity="3d")
    with pytest.raises(ValueError, match="similarity '4d'"):
        evaluate_arrays(gt, ids, boxes, box3d=box3d, similarity="4d")
    with pytest.raises(ValueError, match="similarity"):
        evaluate_files(res, root, "car", ["0000"], similarity="iou")
    bad = box3d.copy()
    bad[0, 2, 0, 1] = 0.0
    with pytest.raises(ValueError, match=r"config 0, frame 2, slot 0, field w: width 0.0 is zero"):
        evaluate_arrays(gt, ids, boxes, box3d=bad, similarity="3d")
    half = box3d.copy()
    half[0, 2, 0, 3] = np.nan                                                    # NaN in one field only
    with pytest.raises(ValueError, match="field x: not finite"):
        evaluate_arrays(gt, ids, boxes, box3d=half, similarity="bev")
    assert _equal(evaluate_arrays(gt, ids, boxes, box3d=bad)[0], evaluate_files(res, root, "car", ["0000"]))


def test_lane_scorer_with_3d_similarity(scene):
    root, res = scene
    gt = prepare_gt(root, "car", ["0000"])
    ids, boxes, box3d = _pack(read_tracker_files(res, gt, need_3d=True), gt)
    moved = box3d.copy()
    moved[0, :, :, 3] += 1.0                                    # same ids and image boxes, other 3D boxes
    ids2, boxes2, b3 = np.concatenate([ids, ids]), np.concatenate([boxes, boxes]), np.concatenate([box3d, moved])
    sc = LaneScorer(gt, gt.offsets[:-1], similarity="3d")
    dig = sc.digests(ids2, boxes2, b3)
    assert dig[0] != dig[1] and LaneScorer.digests(ids2, boxes2)[0] == LaneScorer.digests(ids2, boxes2)[1]
    per = sc.seq_digests(ids2, boxes2, b3)
    assert per[0] != per[1] and sc.seq_digests(ids2, boxes2)[0] == sc.seq_digests(ids2, boxes2)[1]
    items = sc.new_items(per)
    sc.store(per, items, sc.evaluate(sc.dets(ids2, boxes2, items, b3)))
    got = sc.gather(per)
    want = evaluate_arrays(gt, ids2, boxes2, box3d=b3, similarity="3d")
    for lane in range(2):
        assert np.array_equal(got["comb"]["HOTA"][lane], want[lane]["COMBINED"]["HOTA"])
    assert not np.array_equal(got["comb"]["HOTA"][0], got["comb"]["HOTA"][1])


# ---------------------------------------------------------------- a real KITTI output

FIXTURES = default_data_root() / "reference" / "ab3dmot_eval"


def test_kitti_output_in_3d(kitti_root):
    """This project's dfr2023 output (kitti columns: placeholders on rows without a 3D detection) on
    AB3DMOT's validation sequences: 3D and BEV HOTA run, below 2D; arrays equal files."""
    folder = FIXTURES / "dfrmot_dfr2023_kitti_columns"
    if not folder.is_dir():
        pytest.skip(f"AB3DMOT fixtures not found at {FIXTURES}")
    gt = prepare_gt(kitti_root, "car", VAL)
    r = {s: evaluate_files(folder, gt, similarity=s) for s in ("2d", "3d", "bev")}
    hota = {s: float(np.mean(v["COMBINED"]["HOTA"])) for s, v in r.items()}
    assert 0.3 < hota["3d"] < hota["bev"] < hota["2d"]
    assert r["3d"]["COMBINED"]["Dets"] == r["2d"]["COMBINED"]["Dets"]          # the same rows, 2D preprocessing
    dets = read_tracker_files(folder, gt, need_3d=True)
    assert 0 < int((~dets.has3d).sum()) < len(dets.has3d)                      # placeholders among boxes
    ids, boxes, box3d = _pack(dets, gt)
    assert _equal(evaluate_arrays(gt, ids, boxes, box3d=box3d, similarity="3d")[0], r["3d"])
    table = evaluate_classes(folder, kitti_root, "car", VAL, similarity="bev")
    assert table.iloc[-1]["HOTA"] == pytest.approx(100 * hota["bev"], abs=1e-9)
