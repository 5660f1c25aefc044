"""Issue 28, item 2: ``dfrmot demo`` shows the main job, a sweep: on its synthetic scene (written in
KITTI layout) it runs a grid through ``run_sweep`` into a results folder, prints the top configs
beside the baseline, and writes the HTML report next to the results. Small scenes keep it fast."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from dfrmot_jax.cli.demo import GRID, GRIDS, sweep_file
from dfrmot_jax.trackers.dfr.config import preset
from dfrmot_jax.sweep import COMBINED, load_results
from dfrmot_jax.report.stored import read_manifest
from dfrmot_jax.testing.cli import error_line, run_cli

SMALL = ["--sequences", "2", "--frames", "40"]


def _best_printed(out: str) -> tuple[int, float]:
    """(config, HOTA) of the printed table's rank-1 row."""
    header = next(s for s in out.splitlines() if s.startswith("rank "))
    row = next(s for s in out.splitlines() if re.match(r"\s*1\s", s))
    cols = dict(zip(header.split(), row.split()))
    return int(cols["config"]), float(cols["HOTA"])


def _stored(sweep):
    """The stored table's COMBINED rows: config and HOTA."""
    comb = load_results(sweep)
    return comb.loc[comb["sequence"] == COMBINED, ["config", "HOTA"]]


@pytest.mark.slow
def test_the_demo_sweeps_its_scene_and_writes_its_report(tmp_path, capsys):
    out = tmp_path / "demo"
    status, text, err = run_cli(capsys, ["demo", "--out", out, *SMALL])
    assert status == 0 and not err, err
    sweep = out / "sweep"
    for f in ("scene/label_02/0000.txt", "scene/calib/0001.txt", "scene/detections/synth2d/car/0000.txt",
              "scene/detections/synth3d/car/0001.txt", "demo.toml", "sweep/manifest.json", "sweep/results.parquet"):
        assert (out / f).is_file(), f
    assert list((sweep / "chunks").glob("*.parquet")), "no chunk file"
    page = sweep / "report.html"
    assert page.read_text().startswith("<!DOCTYPE html>") and f"HTML report: {page}" in text
    stored = _stored(sweep)
    n_grid = len(GRID["score_2d"]) * len(GRID["gain_beta"]) * len(GRID["gain_gamma"])
    assert n_grid <= len(stored) <= n_grid + 1                         # the grid, and the baseline if not on it
    assert "1 chunks of" in text, "not one vmapped call"
    config, hota = _best_printed(text)
    best = stored["HOTA"].max()
    assert hota == pytest.approx(best, abs=0.005)
    assert stored.set_index("config").loc[config, "HOTA"] == best
    base = re.search(r"^base\s+(\d+)\s+([\d.]+)", text, re.M)
    assert base and f"vs {float(base.group(2)):.2f}" in text
    assert "cross-validated HOTA" in text and "Cross-validated" in page.read_text()


def test_the_demos_sweep_file_is_a_sweep_file(tmp_path):
    doc = tomllib.loads(sweep_file(tmp_path / "scene", ["0000", "0001", "0002"]))
    assert list(doc["params"]) == list(GRID) and doc["baseline"]["preset"] == "dfr2023"
    for k, values in GRID.items():          # the preset's values as its exact (float32) constants
        assert np.float32(doc["params"][k]).tolist() == np.float32(values).tolist()
    base = preset("dfr2023")[0]
    assert all(float(getattr(base, k)) in doc["params"][k] for k in GRID), "the baseline is no point of the grid"
    assert doc["data"]["sequences"] == ["0000", "0001", "0002"] and doc["report"]["folds"] == 3
    assert "report" not in tomllib.loads(sweep_file(tmp_path, ["0000"]))


def test_the_ab3dmot_demos_sweep_file_sweeps_its_family(tmp_path):
    doc = tomllib.loads(sweep_file(tmp_path / "scene", ["0000", "0001"], "ab3dmot"))
    assert doc["options"]["family"] == "ab3dmot" and doc["baseline"]["preset"] == "ab3dmot_car"
    assert doc["params"] == GRIDS["ab3dmot"] and "det2d" not in doc["data"]
    assert -0.2 in doc["params"]["threshold"] and 3 in doc["params"]["min_hits"] and 2 in doc["params"]["max_age"]


@pytest.mark.slow
def test_the_demo_sweeps_ab3dmot_with_family_ab3dmot(tmp_path, capsys):
    """``--family ab3dmot``: the same scene, AB3DMOT's grid around its car preset, one vmapped call
    (lanes that track alike tracked once), its report."""
    out = tmp_path / "demo"
    status, text, err = run_cli(capsys, ["demo", "--out", out, *SMALL, "--family", "ab3dmot"])
    assert status == 0 and not err, err
    assert "AB3DMOT, the ab3dmot_car preset as baseline + a 3 x 3 x 3 grid of threshold, min_hits, max_age" in text
    stored = _stored(out / "sweep")
    assert len(stored) == 27 and "baseline (preset ab3dmot_car)" in text
    assert read_manifest(out / "sweep")["family"] == "ab3dmot"
    config, hota = _best_printed(text)
    assert stored.set_index("config").loc[config, "HOTA"] == stored["HOTA"].max()
    assert (out / "sweep" / "report.html").read_text().startswith("<!DOCTYPE html>")


@pytest.mark.slow
def test_a_rerun_in_the_same_folder_sweeps_the_new_scene(tmp_path, capsys):
    """Another seed in the same --out: the demo's old chunks are stale and are not reused."""
    assert run_cli(capsys, ["demo", "--out", tmp_path / "a", *SMALL])[0] == 0
    status, again, _ = run_cli(capsys, ["demo", "--out", tmp_path / "a", *SMALL, "--seed", "3"])
    assert status == 0 and "; 0 done)" in again
    assert run_cli(capsys, ["demo", "--out", tmp_path / "b", *SMALL, "--seed", "3"])[0] == 0
    a, b = _stored(tmp_path / "a" / "sweep"), _stored(tmp_path / "b" / "sweep")
    assert a.reset_index(drop=True).equals(b.reset_index(drop=True))
    assert read_manifest(tmp_path / "a" / "sweep")["name"] == "demo"


def test_the_demo_refuses_bad_input_and_another_sweeps_folder(tmp_path, capsys):
    status, _, err = run_cli(capsys, ["demo", "--out", tmp_path / "x", "--top", "0"])
    assert status == 2 and "--top 0" in error_line(err, "demo", alone=True)
    status, _, err = run_cli(capsys, ["demo", "--out", tmp_path / "x", "--sequences", "0"])
    assert status == 2 and "--sequences 0" in error_line(err, "demo", alone=True)
    other = tmp_path / "other" / "sweep"
    other.mkdir(parents=True)
    (other / "manifest.json").write_text('{"name": "mine", "kind": "sweep"}')
    status, _, err = run_cli(capsys, ["demo", "--out", tmp_path / "other", *SMALL])
    assert status == 2 and "mine" in error_line(err, "demo")
    assert (other / "manifest.json").read_text() == '{"name": "mine", "kind": "sweep"}'


def _stable(text: str) -> list[str]:
    """The demo's output without its timing paragraph (``... tracked and scored in 3.0 s ...``)."""
    out, skip = [], False
    for line in text.splitlines():
        skip = (line.startswith("sweep demo: ") and " tracked and scored in " in line) or (skip and line.startswith("  "))
        if not skip:
            out.append(line)
    return out


@pytest.mark.slow
def test_the_readme_shows_the_demos_output(tmp_path, monkeypatch, capsys):
    """README, "The demo": ``dfrmot demo`` as printed, run as the README runs it (default settings,
    from the repository root: paths under results/demo), but for its timings."""
    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    shown = re.search(r"```text\n\$ dfrmot demo\n(.*?)```", readme, re.S).group(1)
    monkeypatch.chdir(tmp_path)
    status, text, err = run_cli(capsys, ["demo"])
    assert status == 0 and not err, err
    assert _stable(text) == _stable(shown)
