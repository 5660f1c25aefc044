"""Several classes at once: ``dfrmot eval --class car,pedestrian``, ``evaluate_files_classes`` /
``evaluate_classes`` and the class average (TrackEval's ``combine_classes_class_averaged``).

Two-class result files are built from the published car output (reference folder) and the
tracker's own pedestrian output (RRC + PointRCNN pedestrians, ``dfr2023``), merged per sequence
(frame order kept, pedestrian ids offset past the car ids).
"""

from __future__ import annotations

import csv

import numpy as np
import pytest

from dfrmot_jax.metrics import (CLASS_AVERAGED_FIELDS, CLASS_SUMMED_FIELDS, class_average, class_sequences,
                                classes_table, evaluate_classes, evaluate_files, evaluate_files_classes, prepare_gt)
from dfrmot_jax.metrics.kitti2d.evaluate import ALL_FIELDS, parse_classes
from dfrmot_jax.metrics.kitti2d.table import COUNT_FIELDS, PERCENT_FIELDS

REF = "reference/dfr_fastmot_rrc_pointrcnn"
TE_SEQS = ["0000", "0003", "0012", "0013", "0017"]  # 0003: no pedestrians, 0013: 'Person' distractors, 0017: no cars


def _rows(path):
    if not path.is_file():
        return []
    return [line.split() for line in path.read_text().splitlines() if line.strip()]


def merge_results(car_path, ped_path, out_path) -> None:
    """One file with the car rows and the pedestrian rows (ids offset past the car ids), sorted by frame."""
    car, ped = _rows(car_path), _rows(ped_path)
    off = max((int(r[1]) for r in car), default=-1) + 1
    ped = [[r[0], str(int(r[1]) + off)] + r[2:] for r in ped]
    rows = sorted(car + ped, key=lambda r: int(r[0]))  # stable: cars before pedestrians within a frame
    out_path.write_text("".join(" ".join(r) + "\n" for r in rows))


@pytest.fixture(scope="module")
def two_class(kitti_root, tmp_path_factory):
    import dfrmot_jax as dm
    from dfrmot_jax.trackers.dfr.results import write_lane

    tmp = tmp_path_factory.mktemp("classes")
    split = dm.load_split(kitti_root, "rrc", "pointrcnn", "pedestrian")
    params, options = dm.preset("dfr2023")
    res = dm.track(split, params, options)
    ped = tmp / "ped"
    write_lane(ped, split, res.frames, options, res.ids[0],
               None if options.output == "detections" else res.lane_boxes(0))
    car = kitti_root / REF
    both = tmp / "both"
    both.mkdir()
    seqs = sorted({p.stem for p in car.glob("*.txt")} | {p.stem for p in ped.glob("*.txt")})
    for s in seqs:
        merge_results(car / f"{s}.txt", ped / f"{s}.txt", both / f"{s}.txt")
    return {"car": car, "pedestrian": ped, "both": both, "tmp": tmp}


def _assert_same(a: dict, b: dict, tag: str = "", exact: bool = True) -> None:
    assert set(a) == set(b), (tag, sorted(set(a) ^ set(b)))
    for seq in a:
        assert set(a[seq]) == set(b[seq]), (tag, seq, set(a[seq]) ^ set(b[seq]))
        for f, v in a[seq].items():
            x, y = np.asarray(v, np.float64), np.asarray(b[seq][f], np.float64)
            ok = np.array_equal(x, y) if exact else np.allclose(x, y, atol=1e-9, rtol=0)
            assert x.shape == y.shape and ok, (tag, seq, f, v, b[seq][f])


def test_class_sequences_on_kitti(kitti_root):
    from dfrmot_jax.data import sequences_with_class

    car = class_sequences(kitti_root, "car")
    ped = class_sequences(kitti_root, "Pedestrian")
    assert len(car) == 20 and "0017" not in car
    assert len(ped) == 15 and "0017" in ped and "0003" not in ped
    assert list(car) == sequences_with_class(kitti_root, "car")
    assert list(ped) == sequences_with_class(kitti_root, "pedestrian")


def test_parse_classes():
    assert parse_classes("car,pedestrian") == ("car", "pedestrian")
    assert parse_classes(["Pedestrian", "car", "pedestrian"]) == ("pedestrian", "car")
    assert parse_classes(" car ") == ("car",)
    for bad in ("", "car,bike", ["van"]):
        with pytest.raises(ValueError):
            parse_classes(bad)


@pytest.mark.slow
def test_both_classes_in_one_file_equal_single_class_runs(two_class, kitti_root):
    both = two_class["both"]
    texts = "".join(p.read_text() for p in both.glob("*.txt"))
    assert " Car " in texts and " Pedestrian " in texts
    res = evaluate_files_classes(both, kitti_root, ["car", "pedestrian"])
    assert list(res) == ["car", "pedestrian", "average"]
    for cls in ("car", "pedestrian"):
        seqs = class_sequences(kitti_root, cls)
        assert list(res[cls]) == list(seqs) + ["COMBINED"]
        single = evaluate_files(two_class[cls], kitti_root, cls, seqs)
        _assert_same(res[cls], single, tag=cls)  # bit for bit: the other class's rows change nothing
    c = res["car"]["COMBINED"]
    assert round(100 * float(np.mean(c["HOTA"])), 2) == 82.79 and c["IDSW"] == 177
    assert res["pedestrian"]["COMBINED"]["HOTA_TP"][0] > 0
    assert list(res["average"]) == ["COMBINED"]
    # explicit sequences: every class on exactly these (0017 has no cars: a car FP-free empty sequence)
    sub = evaluate_files_classes(both, kitti_root, "pedestrian,car", sequences=["0003", "0017"])
    assert list(sub) == ["pedestrian", "car", "average"]
    assert list(sub["car"]) == ["0003", "0017", "COMBINED"] and sub["pedestrian"]["0003"]["GT_Dets"] == 0
    # one class: no average
    assert list(evaluate_files_classes(both, kitti_root, "car")) == ["car"]


@pytest.mark.slow
def test_class_average_is_mean_of_ratios_and_sum_of_counts(two_class, kitti_root):
    res = evaluate_files_classes(two_class["both"], kitti_root)
    car, ped, avg = res["car"]["COMBINED"], res["pedestrian"]["COMBINED"], res["average"]["COMBINED"]
    assert set(CLASS_SUMMED_FIELDS) | set(CLASS_AVERAGED_FIELDS) == set(ALL_FIELDS)
    assert not set(CLASS_SUMMED_FIELDS) & set(CLASS_AVERAGED_FIELDS)
    assert set(avg) == set(ALL_FIELDS)
    for f in CLASS_SUMMED_FIELDS:
        np.testing.assert_array_equal(avg[f], np.asarray(car[f]) + np.asarray(ped[f]), err_msg=f)
    for f in CLASS_AVERAGED_FIELDS:
        np.testing.assert_allclose(avg[f], (np.asarray(car[f]) + np.asarray(ped[f])) / 2, rtol=0, atol=1e-15,
                                   err_msg=f)
    assert isinstance(avg["IDSW"], int) and isinstance(avg["MOTA"], float) and avg["HOTA"].shape == (19,)
    # the table view: class 'average' row = mean of the percent columns, sum of the count columns
    df = evaluate_classes(two_class["both"], kitti_root, "car,pedestrian", tracker="t")
    assert list(df.columns[:3]) == ["tracker", "class", "seq"]
    comb = df[df["seq"] == "COMBINED"].set_index("class")
    assert list(comb.index) == ["car", "pedestrian", "average"]
    assert (df["class"] == "average").sum() == 1
    for f in PERCENT_FIELDS:
        assert comb.loc["average", f] == pytest.approx((comb.loc["car", f] + comb.loc["pedestrian", f]) / 2,
                                                       abs=1e-9), f
    for f in COUNT_FIELDS:
        assert comb.loc["average", f] == comb.loc["car", f] + comb.loc["pedestrian", f], f
        assert df[f].dtype == np.int64
    assert comb.loc["car", "HOTA"] == pytest.approx(100 * np.mean(res["car"]["COMBINED"]["HOTA"]))


def test_class_average_rule_on_small_dicts():
    a = {"HOTA": np.full(19, 0.5), "HOTA_TP": np.full(19, 3.0), "MOTA": 0.2, "IDSW": 4, "Dets": 10, "MOTP_sum": 2.0}
    b = {"HOTA": np.full(19, 0.7), "HOTA_TP": np.full(19, 1.0), "MOTA": -0.4, "IDSW": 1, "Dets": 5, "MOTP_sum": 4.0}
    avg = class_average({"car": a, "pedestrian": b})
    np.testing.assert_allclose(avg["HOTA"], 0.6)
    np.testing.assert_array_equal(avg["HOTA_TP"], 4.0)
    assert avg["MOTA"] == pytest.approx(-0.1) and avg["IDSW"] == 5 and avg["Dets"] == 15
    assert avg["MOTP_sum"] == 3.0  # a float field: averaged, as TrackEval does
    with pytest.raises(ValueError):
        class_average({})


def test_classes_table_single_class_has_class_column(kitti_root):
    res = {"car": evaluate_files(kitti_root / REF, kitti_root, "car", ["0000", "0001"])}
    df = classes_table(res)
    assert list(df.columns[:2]) == ["class", "seq"] and list(df["seq"]) == ["0000", "0001", "COMBINED"]
    assert set(df["class"]) == {"car"}


@pytest.mark.slow
def test_cli_eval_two_classes(two_class, kitti_root, tmp_path, capsys):
    from dfrmot_jax.cli import main

    out_csv = tmp_path / "m.csv"
    assert main(["eval", str(two_class["both"]), str(two_class["pedestrian"]), "--data", str(kitti_root),
                 "--class", "car,pedestrian", "--csv", str(out_csv), "--allow-missing"]) == 0   # ped: no car files
    text = capsys.readouterr().out
    assert "car, 20 sequences, 7863 frames" in text and "pedestrian, 15 sequences" in text
    assert "average" in text and "both" in text
    rows = list(csv.DictReader(out_csv.open()))
    assert list(rows[0])[:3] == ["tracker", "class", "seq"]
    keys = [(r["tracker"], r["class"], r["seq"]) for r in rows]
    car_seqs, ped_seqs = class_sequences(kitti_root, "car"), class_sequences(kitti_root, "pedestrian")
    want = []
    for tr in ("both", "ped"):
        want += [(tr, "car", s) for s in car_seqs + ("COMBINED",)]
        want += [(tr, "pedestrian", s) for s in ped_seqs + ("COMBINED",)]
        want += [(tr, "average", "COMBINED")]
    assert keys == want
    df = evaluate_classes(two_class["both"], kitti_root, "car,pedestrian", tracker="both")
    for r, (_, d) in zip(rows, df.iterrows()):
        assert (r["class"], r["seq"]) == (d["class"], d["seq"])
        assert float(r["HOTA"]) == pytest.approx(d["HOTA"], abs=1e-9) and int(r["IDSW"]) == d["IDSW"]
    # the pedestrian-only folder has no car rows: its car rows are all misses
    ped_car = [r for r in rows if r["tracker"] == "ped" and r["class"] == "car" and r["seq"] == "COMBINED"][0]
    assert int(ped_car["CLR_TP"]) == 0 and int(ped_car["Dets"]) == 0
    # --per-seq prints every sequence of every class
    assert main(["eval", str(two_class["both"]), "--data", str(kitti_root), "--class", "pedestrian,car",
                 "--per-seq"]) == 0
    text = capsys.readouterr().out
    assert "0017" in text and text.index("pedestrian") < text.index(" car ")


@pytest.mark.slow
def test_cli_eval_single_class_csv_has_class_column(two_class, kitti_root, tmp_path, capsys):
    from dfrmot_jax.cli import main

    out_csv = tmp_path / "one.csv"
    assert main(["eval", str(two_class["both"]), "--data", str(kitti_root), "--class", "pedestrian",
                 "--seqs", "0000,0017", "--csv", str(out_csv)]) == 0
    text = capsys.readouterr().out
    assert "pedestrian, 2 sequences" in text and "average" not in text
    rows = list(csv.DictReader(out_csv.open()))
    assert [(r["tracker"], r["class"], r["seq"]) for r in rows] == [
        ("both", "pedestrian", "0000"), ("both", "pedestrian", "0017"), ("both", "pedestrian", "COMBINED")]
    # default class is car, on the 20 sequences with cars
    assert main(["eval", str(two_class["both"]), "--data", str(kitti_root), "--csv", str(out_csv)]) == 0
    assert "car, 20 sequences, 7863 frames" in capsys.readouterr().out
    rows = list(csv.DictReader(out_csv.open()))
    assert {r["class"] for r in rows} == {"car"} and len(rows) == 21
    assert float(rows[-1]["HOTA"]) == pytest.approx(82.79, abs=0.005)


def test_cli_eval_rejects_unknown_class(kitti_root, tmp_path, capsys):
    from dfrmot_jax.cli import main

    with pytest.raises(SystemExit) as e:
        main(["eval", str(tmp_path), "--data", str(kitti_root), "--class", "car,cyclist"])
    assert e.value.code == 2 and "cyclist" in capsys.readouterr().err


@pytest.mark.slow
def test_two_classes_vs_trackeval(two_class, kitti_root):
    """TrackEval's Kitti2DBox with CLASSES_TO_EVAL = [car, pedestrian] on the merged files (one seqmap)."""
    pytest.importorskip("trackeval")
    from dfrmot_jax.testing.trackeval_adapter import make_gt_folder, make_tracker_folder, run_trackeval_classes

    tmp = two_class["tmp"] / "te"
    gt = prepare_gt(kitti_root, "car", TE_SEQS)
    make_gt_folder(tmp / "gt", kitti_root, gt.lengths_dict)
    both = two_class["both"]
    make_tracker_folder(tmp / "trackers", "both", {s: both / f"{s}.txt" for s in TE_SEQS}, TE_SEQS)
    te = run_trackeval_classes(tmp / "gt", tmp / "trackers", ["car", "pedestrian"])["both"]
    ours = evaluate_files_classes(both, kitti_root, ["car", "pedestrian"], sequences=TE_SEQS)
    assert set(te) == set(ours) == {"car", "pedestrian", "average"}
    for cls in ("car", "pedestrian"):
        _assert_same(te[cls], ours[cls], tag=cls, exact=False)
        assert te[cls]["COMBINED"]["HOTA_TP"][0] > 0
    _assert_same(te["average"], ours["average"], tag="average", exact=False)
