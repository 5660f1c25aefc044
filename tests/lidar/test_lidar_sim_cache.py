"""The simulated-scan cache (lidar.sim_cache): its marker names the simulator's version and the
inputs, so a cache written by another version, or from other labels, is simulated again."""

import json

import pytest

import dfrmot_jax.lidar.sim_cache as sim_cache
from dfrmot_jax.io.kitti import sequence_lengths
from dfrmot_jax.lidar import SIM_VERSION, SimSettings, simulate_cached
from dfrmot_jax.synthetic import make_scene

SETTINGS = SimSettings(beams=8, az_step=1.0)


@pytest.fixture
def scene(tmp_path):
    root = make_scene(tmp_path / "scene", n_sequences=1, n_frames=4, n_cars=2, seed=5)
    return root, sequence_lengths(root, ["0000"])["0000"]


@pytest.fixture
def runs(monkeypatch):
    """The sequences simulated, one entry per call of the simulator."""
    calls = []
    real = sim_cache.simulate_to_folder
    monkeypatch.setattr(sim_cache, "simulate_to_folder", lambda *a, **k: calls.append(a[4]) or real(*a, **k))
    return calls


def test_a_cache_of_another_simulator_version_is_simulated_again(scene, tmp_path, runs, monkeypatch):
    root, n = scene
    folder = simulate_cached(tmp_path / "c", root, ["0000"], [n], SETTINGS)
    marker = folder / "done" / "0000.json"
    assert json.loads(marker.read_text())["version"] == SIM_VERSION and runs == ["0000"]
    simulate_cached(tmp_path / "c", root, ["0000"], [n], SETTINGS)
    assert runs == ["0000"]                                      # the same version: reused
    monkeypatch.setattr(sim_cache, "SIM_VERSION", SIM_VERSION + 1)
    assert simulate_cached(tmp_path / "c", root, ["0000"], [n], SETTINGS) == folder
    assert runs == ["0000"] * 2 and json.loads(marker.read_text())["version"] == SIM_VERSION + 1
    # a marker without a version (written before versions existed) is not reused either
    doc = json.loads(marker.read_text())
    del doc["version"]
    marker.write_text(json.dumps(doc, sort_keys=True))
    simulate_cached(tmp_path / "c", root, ["0000"], [n], SETTINGS)
    assert runs == ["0000"] * 3


def test_changed_labels_or_calibration_are_simulated_again_but_not_a_touched_file(scene, tmp_path, runs):
    root, n = scene
    simulate_cached(tmp_path / "c", root, ["0000"], [n], SETTINGS)
    label = root / "label_02" / "0000.txt"
    label.write_bytes(label.read_bytes())                        # new mtime, same bytes: reused
    simulate_cached(tmp_path / "c", root, ["0000"], [n], SETTINGS)
    assert runs == ["0000"]
    lines = label.read_text().splitlines(keepends=True)
    label.write_text("".join(lines[:-1]))                        # a label row fewer
    simulate_cached(tmp_path / "c", root, ["0000"], [n], SETTINGS)
    calib = root / "calib" / "0000.txt"
    calib.write_text(calib.read_text() + "\n")
    simulate_cached(tmp_path / "c", root, ["0000"], [n], SETTINGS)
    assert runs == ["0000"] * 3


def test_equal_settings_spelled_differently_share_the_cache(scene, tmp_path, runs):
    root, n = scene
    a = simulate_cached(tmp_path / "c", root, ["0000"], [n], SETTINGS._replace(fov=45))
    b = simulate_cached(tmp_path / "c", root, ["0000"], [n], SETTINGS._replace(fov=45.0))
    assert a == b and runs == ["0000"]
