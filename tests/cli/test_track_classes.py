"""``dfrmot track --class car,pedestrian``: each class with its own settings, one file per sequence."""

import numpy as np
import pytest

from dfrmot_jax.cli import main
from dfrmot_jax.io.kitti import read_tracking_labels
from dfrmot_jax.metrics import evaluate_classes
from dfrmot_jax.trackers.dfr.config import preset


@pytest.fixture(scope="module")
def runs(kitti_root, tmp_path_factory):
    out = tmp_path_factory.mktemp("classes")
    base = ["track", "--data", str(kitti_root), "--preset", "dfr2023"]
    assert main(base + ["--class", "car,pedestrian", "--set", "pedestrian.a_l=2", "--set", "epsilon=30",
                        "--out", str(out / "both")]) == 0
    assert main(base + ["--class", "car", "--out", str(out / "car")]) == 0
    assert main(base + ["--class", "pedestrian", "--set", "a_l=2", "--out", str(out / "ped")]) == 0
    return out


def _rows(path, type_name=None):
    t = read_tracking_labels(path)
    keep = np.ones(t.frame.size, bool) if type_name is None else t.type == type_name
    return t.frame[keep], t.track_id[keep], t.box[keep]


@pytest.mark.slow
def test_one_file_per_sequence_holds_both_classes_with_unique_ids(runs):
    both = sorted(p.name for p in (runs / "both").iterdir())
    car = sorted(p.name for p in (runs / "car").iterdir())
    ped = sorted(p.name for p in (runs / "ped").iterdir())
    assert both == sorted(set(car) | set(ped)) and len(car) == 20 and len(ped) == 15
    mixed = 0
    for name in both:
        frame = read_tracking_labels(runs / "both" / name).frame
        assert np.all(np.diff(frame) >= 0), f"{name}: rows not in frame order"
        fc, ic, bc = _rows(runs / "both" / name, "Car")
        fp, ip, bp = _rows(runs / "both" / name, "Pedestrian")
        assert not set(ic.tolist()) & set(ip.tolist()), f"{name}: a track id is used by both classes"
        if name in car:  # car rows: the car-only run, unchanged (car comes first, no offset)
            f, i, b = _rows(runs / "car" / name)
            assert (fc.tolist(), ic.tolist()) == (f.tolist(), i.tolist()) and np.array_equal(bc, b)
        if name in ped:  # pedestrian rows: the pedestrian-only run (a_l = 2), ids offset past the cars
            f, i, b = _rows(runs / "ped" / name)
            assert fp.tolist() == f.tolist() and np.array_equal(bp, b)
            offset = int(ic.max(initial=-1)) + 1
            assert ip.tolist() == (i + offset).tolist()
            mixed += bool(ic.size and ip.size)
    assert mixed >= 10


@pytest.mark.slow
def test_eval_of_the_two_class_files_scores_each_class_as_alone(runs, kitti_root):
    both = evaluate_classes(runs / "both", kitti_root, ["car", "pedestrian"])
    car = evaluate_classes(runs / "car", kitti_root, ["car"])
    ped = evaluate_classes(runs / "ped", kitti_root, ["pedestrian"])
    comb = both[both.seq == "COMBINED"].set_index("class")
    assert round(float(comb.loc["car", "HOTA"]), 2) == 82.79
    assert float(comb.loc["car", "HOTA"]) == float(car[car.seq == "COMBINED"].HOTA.iloc[0])
    assert float(comb.loc["pedestrian", "HOTA"]) == float(ped[ped.seq == "COMBINED"].HOTA.iloc[0])
    assert int(comb.loc["average", "IDSW"]) == int(comb.loc["car", "IDSW"]) + int(comb.loc["pedestrian", "IDSW"])


def test_per_class_settings_reach_only_their_class(kitti_root, tmp_path, capsys):
    from argparse import Namespace

    from dfrmot_jax.cli.track import class_settings

    args = Namespace(preset="dfr2023", set=["pedestrian.a_l=2", "car.score_2d=0.3", "epsilon=20"])
    car, ped = class_settings(args, "car")[0], class_settings(args, "pedestrian")[0]
    assert (car.a_l, car.score_2d, car.epsilon) == (preset("dfr2023")[0].a_l, 0.3, 20)
    assert (ped.a_l, ped.score_2d, ped.epsilon) == (2.0, preset("dfr2023", "pedestrian")[0].score_2d, 20)
    assert main(["track", "--data", str(kitti_root), "--class", "car", "--set", "bus.a_l=2",
                 "--out", str(tmp_path / "x")]) == 2
    assert "'bus' is not a class" in capsys.readouterr().err
    assert main(["track", "--data", str(kitti_root), "--class", "car,truck", "--out", str(tmp_path / "y")]) == 2
    assert "--class" in capsys.readouterr().err
