"""``dfrmot track --preset ab3dmot_...``: AB3DMOT, the second tracker family, through the command
line: the preset names the family, ``--set`` takes its settings, its 3D detections are read by the
tool's own readers (no ``--det2d``), and the files are AB3DMOT's lines: the NumPy oracle's on a
synthetic scene (fast), the reference runs' on KITTI (slow)."""

from __future__ import annotations

from pathlib import Path

import pytest

from dfrmot_jax.cli import main
from dfrmot_jax.io.kitti import sequence_lengths
from dfrmot_jax.synthetic import make_scene
from dfrmot_jax.testing import ab3dmot_oracle as ab

REF = "reference/ab3dmot_tracker/head61f3bd7_"


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    return make_scene(tmp_path_factory.mktemp("ab3dmot_scene"), n_sequences=2, n_frames=40, n_cars=4, seed=5)


def _oracle(root: Path, settings: ab.Settings, sequences, det: str = "synth3d") -> dict[str, list[str]]:
    """The oracle's lines of ``sequences`` in order, one id counter from 1 (every sequence has detections)."""
    lengths = sequence_lengths(root, list(sequences))
    out, next_id = {}, 1
    for s in sequences:
        dets = ab.read_detections(root / "detections" / det / settings.category.lower() / f"{s}.txt")
        out[s], next_id = ab.track_sequence(dets, lengths[s], settings, next_id)
    return out


def _lines(folder: Path) -> dict[str, list[str]]:
    return {p.stem: p.read_text().splitlines() for p in sorted(folder.glob("*.txt"))}


def test_an_ab3dmot_preset_tracks_with_its_settings_as_the_oracle(scene, tmp_path):
    """No --det2d is read (a folder that does not exist is not an error); the --set settings are
    AB3DMOT's; every line is the oracle's, ids included."""
    out = tmp_path / "mdis"
    args = ["track", "--data", str(scene), "--det2d", "no_such_detector", "--det3d", "synth3d", "--preset",
            "ab3dmot_car", "--set", "algorithm=greedy", "--set", "metric=dist_3d", "--set", "threshold=4",
            "--set", "min_hits=2", "--set", "max_age=3", "--out", str(out)]
    assert main(args) == 0
    want = _oracle(scene, ab.Settings("Car", "greedy", "dist_3d", 4.0, 2, 3), ["0000", "0001"])
    got = _lines(out)
    assert got == want and sum(map(len, got.values())) > 100


def test_bad_ab3dmot_settings_are_refused_readably(scene, tmp_path, capsys):
    base = ["track", "--data", str(scene), "--det3d", "synth3d", "--preset", "ab3dmot_car"]
    for extra, message in ((["--set", "metric=mdis"], "--set metric=mdis: expected one of ('iou_2d'"),
                           (["--set", "max_age=0"], "--set max_age=0: outside the valid range [1, 1e+06]"),
                           (["--set", "a_l=3"], "--set a_l: unknown; parameters are ['threshold', 'min_hits'"),
                           (["--set", "pedestrian.max_age=x"], "--set pedestrian.max_age: 'x' is not a number"),
                           (["--columns", "authors"], "AB3DMOT writes its own KITTI lines only"),
                           (["--class", "cyclist"], "--class 'cyclist': expected one or more of ['car', "
                                                    "'pedestrian']")):
        assert main(base + extra + ["--out", str(tmp_path / "bad")]) == 2
        err = capsys.readouterr().err
        assert message in err and "Traceback" not in err, err
    assert not list((tmp_path / "bad").glob("*.txt"))          # (nothing written; the folder may not exist)


@pytest.mark.slow
def test_the_car_preset_writes_the_reference_runs_lines(kitti_root, tmp_path):
    """All 21 sequences (also 0017, whose labels hold no car), as AB3DMOT ran them: every file
    byte for byte (the other six runs: tests/trackers/ab3dmot/test_ab3dmot_jax.py, through the package's own reader)."""
    seqs = ",".join(f"{i:04d}" for i in range(21))
    for run, sets in (("car_default", []),):
        out = tmp_path / run
        assert main(["track", "--data", str(kitti_root), "--preset", "ab3dmot_car", "--seqs", seqs, *sets,
                     "--out", str(out)]) == 0
        ref = kitti_root / (REF + run)
        names = sorted(p.name for p in ref.glob("*.txt"))
        assert len(names) == 21 and sorted(p.name for p in out.glob("*.txt")) == names
        for name in names:
            assert (out / name).read_bytes() == (ref / name).read_bytes(), f"{run} {name}"


@pytest.mark.slow
def test_two_classes_share_a_file_with_ids_apart(kitti_root, tmp_path):
    """--class car,pedestrian: each class with its own preset values, the pedestrians' ids offset past
    the cars' in each file; each class's lines are its own run's."""
    base = ["track", "--data", str(kitti_root), "--preset", "ab3dmot_pedestrian", "--seqs", "0004,0012"]
    assert main(base + ["--class", "car,pedestrian", "--out", str(tmp_path / "both")]) == 0
    assert main(base + ["--class", "pedestrian", "--out", str(tmp_path / "ped")]) == 0
    for name in ("0004.txt", "0012.txt"):
        both = (tmp_path / "both" / name).read_text().splitlines()
        ped = (tmp_path / "ped" / name).read_text().splitlines()
        cars = [s for s in both if s.split()[2] == "Car"]
        peds = [s for s in both if s.split()[2] == "Pedestrian"]
        assert cars and peds and len(ped) == len(peds)
        top = max(int(s.split()[1]) for s in cars)
        assert [s.split(" ", 2)[2] for s in peds] == [s.split(" ", 2)[2] for s in ped]
        assert [int(a.split()[1]) for a in peds] == [int(b.split()[1]) + top for b in ped]
        frames = [int(s.split()[0]) for s in both]
        assert frames == sorted(frames)
