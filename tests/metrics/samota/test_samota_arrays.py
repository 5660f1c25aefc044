"""AB3DMOT's metrics from padded arrays (dfrmot_jax.metrics.samota.arrays) equal scoring the same rows
as result files: the two fixture outputs packed into [B, T, K] arrays, 2D and 3D."""

import numpy as np
import pytest

from dfrmot_jax.metrics.samota.arrays import evaluate_ab3dmot_arrays
from dfrmot_jax.metrics.samota.evaluate import evaluate_ab3dmot_files
from dfrmot_jax.metrics.samota.prep import prepare_ab3dmot_gt
from dfrmot_jax.paths import default_data_root

FIXTURES = default_data_root() / "reference" / "ab3dmot_eval"
VAL = ("0001", "0006", "0008", "0010", "0012", "0013", "0014", "0015", "0016", "0018", "0019")


def _pack(folders, gt):
    """Result files -> ids [B, T, K], boxes, scores, box3d (file order within a frame = slot order)."""
    per = []
    for d in folders:
        rows = []
        for s, name in enumerate(gt.sequences):
            path = d / f"{name}.txt"
            if not path.is_file():
                continue
            for line in path.read_text().splitlines():
                f = line.split()
                if f and f[2] == "Car":
                    rows.append((int(gt.offsets[s]) + int(f[0]), int(f[1]), [float(v) for v in f[6:10]],
                                 [float(v) for v in f[10:17]], float(f[17])))
        per.append(rows)
    T = gt.n_frames
    K = max(np.bincount([r[0] for rows in per for r in rows]).max(), 1)
    B = len(folders)
    ids = np.full((B, T, K), -1, dtype=np.int64)
    boxes = np.zeros((B, T, K, 4))
    box3d = np.full((B, T, K, 7), np.nan)
    scores = np.zeros((B, T, K))
    for b, rows in enumerate(per):
        used = np.zeros(T, dtype=np.int64)
        for t, tid, box, b3, sc in rows:
            k = used[t]
            used[t] += 1
            ids[b, t, k], boxes[b, t, k], box3d[b, t, k], scores[b, t, k] = tid, box, b3, sc
    return ids, boxes, scores, box3d


@pytest.mark.slow
@pytest.mark.parametrize("iou", ["3d:0.25", "2d:0.5"])
def test_arrays_equal_files(kitti_root, iou):
    if not FIXTURES.is_dir():
        pytest.skip(f"AB3DMOT fixtures not found at {FIXTURES}")
    folders = [kitti_root / "reference" / "dfr_fastmot_rrc_pointrcnn", FIXTURES / "dfrmot_dfr2023_kitti_columns"]
    gt = prepare_ab3dmot_gt(kitti_root, "car", VAL)
    ids, boxes, scores, box3d = _pack(folders, gt)
    got = evaluate_ab3dmot_arrays(gt, ids, boxes, scores, box3d, iou=iou)
    want = [evaluate_ab3dmot_files(d, gt, iou=iou) for d in folders]
    assert got == want
    # the same outputs with padding frames between the sequences
    pad = 3
    offs = gt.offsets[:-1] + pad * np.arange(len(VAL))
    T2 = gt.n_frames + pad * len(VAL)
    spread = [np.full((2, T2) + a.shape[2:], fill, dtype=a.dtype) for a, fill in
              ((ids, -1), (boxes, 0.0), (scores, 0.0), (box3d, np.nan))]
    for s in range(len(VAL)):
        a, n = int(gt.offsets[s]), int(gt.lengths[s])
        for dst, src in zip(spread, (ids, boxes, scores, box3d)):
            dst[:, offs[s]:offs[s] + n] = src[:, a:a + n]
    spread[0][:, offs[1] - 1, 0] = 5                      # rows in a padding frame are not scored
    assert evaluate_ab3dmot_arrays(gt, *spread, seq_offsets=offs, iou=iou) == want


def test_array_errors(tmp_path):
    root = tmp_path / "data"
    (root / "label_02").mkdir(parents=True)
    (root / "label_02" / "0000.txt").write_text("0 1 Car 0 0 -1 100 150 180 220 1.5 1.6 3.9 0 1.7 10 0.2\n"
                                                "1 1 Car 0 0 -1 100 150 180 220 1.5 1.6 3.9 0 1.7 11 0.2\n")
    gt = prepare_ab3dmot_gt(root, "car", ["0000"])
    ids = np.array([[[3, -1], [3, -1]]])
    boxes = np.tile(np.array([100.0, 150, 180, 220]), (1, 2, 2, 1))
    scores = np.ones((1, 2, 2))
    b3 = np.tile(np.array([1.5, 1.6, 3.9, 0, 1.7, 10, 0.2]), (1, 2, 2, 1))
    r = evaluate_ab3dmot_arrays(gt, ids, boxes, scores, b3)[0]
    assert (r["TP"], r["FN"], r["FP"]) == (1, 1, 1)        # frame 1: 1 m off across its 1.6 m width, IoU 0.23
    bad = b3.copy()
    bad[0, 1, 0, 2] = -3.9
    with pytest.raises(ValueError, match="config 0, sequence 0000, frame 1, slot 0: 3D box"):
        evaluate_ab3dmot_arrays(gt, ids, boxes, scores, bad)
    dup = np.array([[[3, 3], [3, -1]]])
    with pytest.raises(ValueError, match="id 3 occurs twice"):
        evaluate_ab3dmot_arrays(gt, dup, boxes, scores, b3)
    with pytest.raises(ValueError, match="needs box3d"):
        evaluate_ab3dmot_arrays(gt, ids, boxes, scores)
    assert evaluate_ab3dmot_arrays(gt, ids[:0], boxes[:0], scores[:0], b3[:0]) == []


@pytest.mark.parametrize("iou", ["3d:0.25", "2d:0.5"])
def test_many_outputs_at_once_equal_one_by_one(kitti_root, iou):
    """Outputs scored together (distinct boxes, pairs and ignore rules shared) equal each scored
    alone (which equals its file, above): rows dropped, ids merged, boxes moved, scores changed."""
    folder = kitti_root / "reference" / "dfr_fastmot_rrc_pointrcnn"
    if not folder.is_dir():
        pytest.skip(f"published output not found at {folder}")
    gt = prepare_ab3dmot_gt(kitti_root, "car", VAL[:6])
    ids, boxes, scores, box3d = _pack([folder] * 6, gt)
    rng = np.random.default_rng(3)
    ids[1:][rng.random(ids[1:].shape) < 0.1] = -1
    ids[2] = np.where(ids[2] >= 0, ids[2] // 2, -1)                 # merged tracks: id switches
    first = np.argmax(ids[2][..., :, None] == ids[2][..., None, :], axis=-1)
    ids[2][first != np.arange(ids.shape[2])] = -1                    # one row per id and frame
    boxes[3] += rng.normal(0, 8, boxes[3].shape)
    real = box3d[4, ..., 0] > 0                                       # boxes, not placeholders
    box3d[4, ..., 3] += np.where(real, rng.normal(0, 0.6, real.shape), 0.0)
    scores[5] = np.round(rng.random(scores[5].shape), 2)
    together = evaluate_ab3dmot_arrays(gt, ids, boxes, scores, box3d, iou=iou)
    alone = [evaluate_ab3dmot_arrays(gt, *(a[b:b + 1] for a in (ids, boxes, scores, box3d)), iou=iou)[0]
             for b in range(6)]
    assert together == alone
    assert len({r["FP"] for r in together}) >= 4                      # the outputs do differ
