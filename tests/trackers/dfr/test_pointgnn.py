"""PointGNN 3D detections (``detections/pointgnn/car``): the files, the loader and RRC + PointGNN tracking.

The DFR-FastMOT authors' published RRC + PointGNN run used a_l = 4 (all else as ``dfr2023``); the
paper reports HOTA 82.2 / MOTA 90.2 / IDSW 189 for it (car, 20 sequences).
"""

from __future__ import annotations

import numpy as np
import pytest

from dfrmot_jax.io.kitti import KittiFormatError, read_detections_3d, sequence_lengths

SEQS = [f"{i:04d}" for i in range(21)]


@pytest.fixture(scope="module")
def pgnn_dir(kitti_root):
    d = kitti_root / "detections" / "pointgnn" / "car"
    if not d.is_dir():
        pytest.skip(f"PointGNN detections not found at {d}")
    return d


def test_pointgnn_files(pgnn_dir, kitti_root):
    lengths = sequence_lengths(kitti_root, SEQS)
    rows = {}
    for s in SEQS:
        path = pgnn_dir / f"{s}.txt"
        assert path.is_file(), path
        assert "," not in path.read_text().splitlines()[0]  # space-separated, 15 columns
        d = read_detections_3d(path)
        rows[s] = d.frame.size
        assert set(d.type) == {"2"}  # AB3DMOT code 2 = car, like the PointRCNN car files
        assert np.all(d.alpha == -1)
        assert np.all(np.isfinite(d.score)) and d.score.min() >= 0.25  # PointGNN's own scale, not [0, 1]
        assert np.all(d.frame < lengths[s])
        assert np.all(d.dims > 0)
    assert sum(rows.values()) == 28340
    assert rows["0017"] == 7  # 0017 has no cars in the ground truth, a few detections anyway
    scores = np.concatenate([read_detections_3d(pgnn_dir / f"{s}.txt").score for s in ("0000", "0020")])
    assert scores.max() > 100


def test_load_split_pointgnn(pgnn_dir, kitti_root):
    from dfrmot_jax.data import load_split

    split = load_split(kitti_root, "rrc", "pointgnn", "car")
    assert len(split.names) == 20 and "0017" not in split.names  # default: sequences with cars
    assert int(split.valid3d.sum()) == 28340 - 7
    assert np.all(split.alpha3d[split.valid3d] == -1)
    one = load_split(kitti_root, "rrc", "pointgnn", "car", ["0017"])  # explicitly: loads fine
    assert int(one.valid3d.sum()) == 7


def test_missing_detection_file_is_an_error(pgnn_dir, kitti_root, tmp_path):
    """As for PointRCNN (the same loader): a missing file is an error, not an empty sequence."""
    from dfrmot_jax.data import load_sequences

    det = tmp_path / "pgnn"
    det.mkdir()
    for s in SEQS:
        if s != "0003":
            (det / f"{s}.txt").symlink_to(pgnn_dir / f"{s}.txt")
    with pytest.raises(KittiFormatError, match="0003.txt: file not found"):
        load_sequences(kitti_root, "rrc", det, "car")
    (det / "0003.txt").write_text("")  # an empty file is a sequence without 3D detections
    seqs = load_sequences(kitti_root, "rrc", det, "car", ["0003"])
    assert seqs[0].det3d.frame.size == 0


def test_3d_rows_of_another_type_are_dropped(pgnn_dir, kitti_root, tmp_path):
    from dfrmot_jax.data import load_sequences

    det = tmp_path / "typed"
    det.mkdir()
    lines = (pgnn_dir / "0000.txt").read_text().splitlines()
    edited = list(lines)
    edited[1] = edited[1].replace(" 2 ", " 3 ", 1)   # a cyclist (AB3DMOT code 3)
    edited[2] = edited[2].replace(" 2 ", " 1 ", 1)   # a pedestrian
    (det / "0000.txt").write_text("\n".join(edited) + "\n")
    seq = load_sequences(kitti_root, "rrc", det, "car", ["0000"])[0]
    assert seq.det3d.frame.size == len(lines) - 2
    full = read_detections_3d(pgnn_dir / "0000.txt")
    np.testing.assert_array_equal(seq.det3d.box, np.delete(full.box, [1, 2], axis=0))
    edited[3] = edited[3].replace(" 2 ", " 7 ", 1)   # not a known type: an error, not a guess
    (det / "0000.txt").write_text("\n".join(edited) + "\n")
    with pytest.raises(KittiFormatError, match=r"0000.txt:4: field 'type'"):
        load_sequences(kitti_root, "rrc", det, "car", ["0000"])


@pytest.mark.slow
def test_track_and_eval_two_sequences_cli(pgnn_dir, kitti_root, tmp_path, capsys):
    from dfrmot_jax.cli import main

    out = tmp_path / "pgnn"
    assert main(["track", "--data", str(kitti_root), "--det3d", "pointgnn", "--set", "a_l=4",
                 "--seqs", "0000,0002", "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["0000.txt", "0002.txt"]
    capsys.readouterr()
    csv = tmp_path / "m.csv"
    assert main(["eval", str(out), "--data", str(kitti_root), "--seqs", "0000,0002", "--csv", str(csv)]) == 0
    import pandas as pd

    df = pd.read_csv(csv)
    comb = df[df["seq"] == "COMBINED"].iloc[0]
    assert comb["class"] == "car" and comb["HOTA"] > 65 and comb["MOTA"] > 70  # 71.0 / 79.8


@pytest.mark.slow
def test_rrc_pointgnn_a_l_4_reproduces_the_paper(pgnn_dir, kitti_root, tmp_path):
    import dfrmot_jax as dm
    from dfrmot_jax.metrics import evaluate_files
    from dfrmot_jax.trackers.dfr.results import write_lane

    split = dm.load_split(kitti_root, "rrc", "pointgnn", "car")
    params, options = dm.preset("dfr2023")
    params = params._replace(a_l=4.0)
    res = dm.track(split, params, options)
    assert int(res.overflow[0]) == 0
    write_lane(tmp_path / "out", split, res.frames, options, res.ids[0],
               None if options.output == "detections" else res.lane_boxes(0))
    c = evaluate_files(tmp_path / "out", kitti_root, "car", split.names)["COMBINED"]
    hota, mota = 100 * float(np.mean(c["HOTA"])), 100 * c["MOTA"]
    assert (round(hota, 1), round(mota, 1), c["IDSW"]) == (82.2, 90.2, 189)  # the paper's figures
