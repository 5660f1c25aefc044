"""``dfrmot report DIR --html OUT.html`` (issue 23): one self-contained page for a grid sweep, a
robustness study and a tune, made quickly on a synthetic scene; its numbers are the text report's;
opened in headless Chromium (Debian's ``chromium`` + ``chromium-driver`` through selenium, nothing
downloaded), every figure renders (an SVG of non-zero size with drawn paths), the console has no
error, and a screenshot of each page is saved in the test's tmp dir. Only the browser test skips,
saying why, where Chromium or its driver is missing (``scripts/install_system_deps.sh`` installs
them)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from dfrmot_jax.sweep import run_sweep, sweep_report
from dfrmot_jax.synthetic import make_scene
from dfrmot_jax.testing.cli import run_cli
from dfrmot_jax.tuning import run_tune

QUIET = dict(progress=False, workers=0, log=lambda m: None)


@pytest.fixture(scope="module")
def folders(tmp_path_factory) -> dict[str, Path]:
    """A grid sweep (with folds), a robustness study (with a contrast) and a two-objective tune with
    nested cross-validation, on one small synthetic scene."""
    d = tmp_path_factory.mktemp("html")
    root = make_scene(d / "scene", n_sequences=3, n_frames=50, n_cars=4, seed=7)
    data = {"root": str(root), "det2d": "synth2d", "det3d": "synth3d"}
    run_sweep({"name": "grid", "chunk": 16, "data": data, "report": {"folds": 3},
               "params": {"a_l": [2.0, 4.0, 8.0], "score_2d": [0.3, 0.5], "alpha_c": {"grid": [0.3, 0.5]}},
               "options": {"output": ["detections", "filtered"]}}, d / "grid", **QUIET)
    run_sweep({"name": "robustness", "chunk": 16, "data": data, "params": {"epsilon": [1, 30]},
               "options": {"filter": ["fixed_gain", "kalman"]},
               "distortion": {"kind": ["drop", "burst"], "levels": {"drop": [0.0, 0.3], "burst": [0, 6]}, "seeds": 2},
               "report": {"contrast": {"axis": "epsilon", "high": [30], "low": [1], "by": ["filter"]}}},
              d / "robustness", **QUIET)
    run_tune({"name": "tune", "data": data,
              "params": {"a_l": {"uniform": [2.0, 10.0]}, "score_2d": {"uniform": [0.2, 0.6]}},
              "tune": {"budget": 8, "batch": 4, "objectives": ["HOTA", "IDSW"], "folds": 2}}, d / "tune",
             plots=False, **QUIET)
    return {k: d / k for k in ("grid", "robustness", "tune")}


#: per folder: sections its page must have (beside the identity, the top configs, sensitivity and
#: the per-sequence heatmap every page has) and its figures
EXPECT = {"grid": (["Cross-validated"], 3), "robustness": (["Cross-validated", "Robustness", "Contrast: epsilon in [30]"], 5),
          "tune": (["Nested cross-validation", "The tune", "Pareto front"], 5)}


@pytest.fixture(scope="module")
def pages(folders, tmp_path_factory) -> dict[str, Path]:
    """Where each folder's page goes (written by the tests)."""
    out = tmp_path_factory.mktemp("pages")
    return {k: out / f"{k}.html" for k in folders}


@pytest.mark.slow
def test_report_html_writes_one_self_contained_page_per_folder(folders, pages, capsys):
    for name, d in folders.items():
        status, stdout, err = run_cli(capsys, ["report", d, "--html", pages[name]])
        assert status == 0, err
        assert stdout.strip().splitlines()[-1].startswith("{")       # the text report is printed as before
        page = pages[name].read_text()
        assert page.startswith("<!DOCTYPE html>") and page.rstrip().endswith("</html>")
        assert not re.search(r"<script|<link|<img|<iframe|\bsrc=|@import", page, re.I), "not self-contained"
        assert set(re.findall(r"https?://[^\s\"'<>]+", page)) <= {   # (XML namespace names, never fetched)
            "http://www.w3.org/2000/svg", "http://www.w3.org/1999/xlink"}, "a network address"
        sections, n_figures = EXPECT[name]
        for s in ["The run", "Top configs by", "Sensitivity per axis", "Per sequence", "sweep file", "machine"] + sections:
            assert s in page, f"{name}: no {s!r}"
        assert page.count("<figure>") == n_figures and page.count("<svg") == n_figures, name
        ids = re.findall(r'\bid="([^"]+)"', page)
        assert len(ids) == len(set(ids)), "ids repeat across figures"


@pytest.mark.slow
def test_the_pages_numbers_are_the_reports(folders, pages, capsys):
    for name, d in folders.items():          # (each test writes the pages it reads when they are not there)
        if not pages[name].is_file():
            assert run_cli(capsys, ["report", d, "--html", pages[name]])[0] == 0
    grid = sweep_report(folders["grid"], folds=3)
    page = pages["grid"].read_text()
    assert f"Cross-validated HOTA {grid.cv['cross_validated']:.3f}" in page
    assert f"Best HOTA {grid.top.iloc[0]['HOTA']:.3f} (config {int(grid.top.iloc[0]['config'])})" in page
    tune = pages["tune"].read_text()
    nested = sweep_report(folders["tune"]).summary["tune"]
    assert f"HOTA cross-validated {nested['cross_validated']:.3f}" in tune
    rob = sweep_report(folders["robustness"])
    for row in rob.contrast:
        assert f"<td>{row['kind']}</td>" in pages["robustness"].read_text()


def _chromium():
    """(browser binary, driver) of Debian's chromium / chromium-driver, or a pytest.skip saying what is missing."""
    browser = next((p for p in (shutil.which("chromium"), shutil.which("chromium-browser")) if p), None)
    driver = next((p for p in ("/usr/bin/chromedriver", shutil.which("chromedriver")) if p and Path(p).is_file()), None)
    if browser is None or driver is None:
        pytest.skip("Chromium or its WebDriver is not installed (scripts/install_system_deps.sh installs Debian's "
                    "chromium and chromium-driver; it could not here): the HTML report was not opened in a browser")
    return browser, driver


@pytest.mark.slow
def test_every_figure_renders_in_headless_chromium(folders, pages, tmp_path, capsys):
    webdriver = pytest.importorskip("selenium.webdriver", reason="selenium is a dev dependency: pip install -e .[dev]")
    from selenium.webdriver.chrome.service import Service

    browser, driver_path = _chromium()
    for name, d in folders.items():
        if not pages[name].is_file():
            assert run_cli(capsys, ["report", d, "--html", pages[name]])[0] == 0
    opts = webdriver.ChromeOptions()
    opts.binary_location = browser
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
              "--disable-background-networking", "--disable-component-update", "--disable-sync",
              f"--user-data-dir={tmp_path / 'profile'}", "--window-size=1280,900"):
        opts.add_argument(a)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    drv = webdriver.Chrome(service=Service(executable_path=driver_path), options=opts)
    try:
        drv.set_page_load_timeout(60)
        for name in folders:
            drv.get(pages[name].resolve().as_uri())
            figs = drv.execute_script("""
                return Array.from(document.querySelectorAll('figure > svg')).map(s => {
                    const r = s.getBoundingClientRect();
                    const drawn = Array.from(s.querySelectorAll('path')).filter(p => {
                        const b = p.getBBox(); return (b.width > 0 || b.height > 0) && p.getAttribute('d'); });
                    return {w: r.width, h: r.height, paths: drawn.length, uses: s.querySelectorAll('use').length};
                });""")
            assert len(figs) == EXPECT[name][1], (name, figs)
            for i, f in enumerate(figs):
                assert f["w"] > 100 and f["h"] > 50 and f["paths"] >= 10 and f["uses"] > 0, (name, i, f)
            errors = [e for e in drv.get_log("browser") if e["level"] in ("SEVERE", "ERROR")]
            assert not errors, (name, errors)
            height = drv.execute_script("return document.documentElement.scrollHeight")
            drv.set_window_size(1280, min(int(height) + 40, 12000))
            shot = tmp_path / f"{name}.png"
            assert drv.save_screenshot(str(shot)) and shot.stat().st_size > 20_000, name
            drv.set_window_size(1280, 900)
    finally:
        drv.quit()


def test_the_readme_shows_the_current_report_help():
    """README, "The HTML report": ``dfrmot report --help`` as printed 100 columns wide."""
    repo = Path(__file__).resolve().parents[2]
    env = {**os.environ, "COLUMNS": "100", "PYTHONPATH": str(repo)}
    text = subprocess.run([sys.executable, "-m", "dfrmot_jax.cli", "report", "--help"], env=env, capture_output=True,
                          text=True, timeout=120, check=True).stdout
    assert f"```text\n{text}```" in (repo / "README.md").read_text()


def test_a_global_matplotlib_style_does_not_change_the_report_figures():
    """Optuna's plots (a tune's history.png) set the ggplot style for the whole process: a report
    page drawn after them in the same process differed from one drawn in a fresh one (ids, grid
    lines). The figures start from Matplotlib's defaults, whatever was set before."""
    import matplotlib
    import pandas as pd

    from dfrmot_jax.report.figures import heatmap_figure

    values = pd.DataFrame([[1.0, 2.0], [3.0, 4.5]], index=pd.Index([0.1, 0.2], name="a_f"),
                          columns=pd.Index([2.0, 4.0], name="a_l"))
    before = heatmap_figure(values, "HOTA")
    with matplotlib.rc_context():
        matplotlib.style.use("ggplot")
        during = heatmap_figure(values, "HOTA")
    assert during == before and "<svg" in before
