"""Issue 28, item 1: ``dfrmot report DIR --html PAGE`` computes the report once and draws both the
printed text and the page from it, so they show the same numbers and the same sections (the
cross-validation in both or in neither), on a sweep whose file sets no folds (the case where the
page used to cross-validate and the printed report did not)."""

from __future__ import annotations

import html
import json
import re
import sys

import pytest

from dfrmot_jax.sweep import html_report, load_results, report_folds, run_sweep, sweep_report, write_html
from dfrmot_jax.report import report as report_module
from dfrmot_jax.synthetic import make_scene
from dfrmot_jax.testing.cli import run_cli

QUIET = dict(progress=False, workers=0, log=lambda m: None)


@pytest.fixture(scope="module")
def grid(tmp_path_factory):
    """A 2 x 2 grid sweep on three short synthetic sequences, with no folds in its file."""
    d = tmp_path_factory.mktemp("once")
    root = make_scene(d / "scene", n_sequences=3, n_frames=40, n_cars=4, seed=3)
    run_sweep({"name": "once", "chunk": 16, "data": {"root": str(root), "det2d": "synth2d", "det3d": "synth3d"},
               "params": {"a_l": [2.0, 8.0], "score_2d": [0.3, 0.5]}}, d / "grid", **QUIET)
    return d / "grid"


def _count_reports(monkeypatch) -> list:
    """Count every report computation, wherever the package calls ``sweep_report`` from."""
    calls = []
    original = report_module.sweep_report

    def counted(*args, **kwargs):
        calls.append(1)
        return original(*args, **kwargs)

    for name, mod in list(sys.modules.items()):
        if name.startswith("dfrmot_jax") and getattr(mod, "sweep_report", None) is original:
            monkeypatch.setattr(mod, "sweep_report", counted)
    return calls


def _printed_in_page(page: str) -> str:
    """The text report the page holds (its last, folded section)."""
    return html.unescape(re.search(r"<pre>([^<]*)</pre></details>\s*</body>", page).group(1))


def test_report_html_computes_the_report_once(grid, tmp_path, capsys, monkeypatch):
    calls = _count_reports(monkeypatch)
    status, _, err = run_cli(capsys, ["report", grid, "--html", tmp_path / "page.html"])
    assert status == 0, err
    assert len(calls) == 1, f"the report was computed {len(calls)} times"


@pytest.mark.parametrize("extra", [[], ["--folds", "2"], ["--objective", "IDSW", "--top", "2"]])
def test_the_page_and_the_printed_report_show_the_same_numbers(grid, tmp_path, capsys, extra):
    path = tmp_path / "page.html"
    status, out, err = run_cli(capsys, ["report", grid, "--html", path, *extra])
    assert status == 0, err
    printed, page = out.rstrip("\n"), path.read_text()
    assert _printed_in_page(page) == printed
    summary = json.loads(printed.splitlines()[-1])
    cv_printed = "cross-validation over sequences" in printed and "best_cross_validated" in summary
    assert cv_printed == ("<h2>Cross-validated</h2>" in page), "the cross-validation is in one of them only"
    assert cv_printed, "the page's default folds (min(5, sequences)) hold for the printed report too"
    objective = summary["objective"]
    assert f"Cross-validated {objective} {summary['best_cross_validated']:.3f}" in page
    assert f"Best {objective} {summary['best_in_sample']:.3f} (config {summary['best_config']['config']})" in page
    assert f"baseline {summary['baseline']:.3f}" in page


@pytest.mark.slow
def test_the_folds_the_report_chooses_are_said_in_both(grid):
    folds, note = report_folds(grid)
    assert folds == 3 and "min(5, sequences)" in note
    assert report_folds(grid, 2) == (2, "")
    rep = sweep_report(grid, folds=folds, folds_note=note)
    page = write_html(rep, grid.parent / "from_report.html").read_text()
    assert note in rep.text and html.escape(note) in page
    assert html_report(grid, grid.parent / "computed.html").read_text().split("<h2>The run</h2>")[0] == \
        page.split("<h2>The run</h2>")[0]


def test_a_page_needs_a_directorys_report(grid):
    with pytest.raises(ValueError, match="sweep or tune directory"):
        write_html(sweep_report(load_results(grid)), grid.parent / "no.html")


def test_a_page_is_a_function_of_its_report(grid):
    """The same report drawn twice in one process gives the same page (but its time stamp): the
    figures' SVG ids once came from a process-wide counter."""
    from dfrmot_jax.sweep import render_html

    rep = sweep_report(grid, folds=3)

    def page():
        return [line for line in render_html(rep).splitlines() if " UTC<" not in line]

    first = page()
    assert 'id="f' in "\n".join(first) and page() == first


def test_the_page_shows_the_held_out_gain_over_the_baseline(grid, tmp_path, capsys):
    """Issue 41, item 17: the page's cross-validation says the held-out gain over the baseline (mean ± sd,
    folds better) as the printed report does."""
    path = tmp_path / "page.html"
    status, out, err = run_cli(capsys, ["report", grid, "--html", path, "--folds", "3"])
    assert status == 0, err
    m = re.search(r"held-out gain over the baseline ([+-][0-9.]+) \+- ([0-9.]+) \(sd over (\d+) folds; (\d+) of \d+ "
                  r"folds better\)", out)
    assert m, out
    section = html.unescape(re.search(r"<h2>Cross-validated</h2>(.*?)</p>", path.read_text(), re.S).group(1))
    assert (f"held-out gain over the baseline {m.group(1)} ± {m.group(2)} (sd over {m.group(3)} folds; "
            f"{m.group(4)} of {m.group(3)} folds better)") in section


@pytest.fixture(scope="module")
def gains(tmp_path_factory):
    """A sweep shaped as sweeps/kitti_dfr_grid.toml: the dfr2023 baseline (the C++'s float32 gains,
    0.89999997615814209, ...) and two [[variants]] of gains, the first the file's 0.9, 0.9, 0.1."""
    d = tmp_path_factory.mktemp("gains")
    root = make_scene(d / "scene", n_sequences=3, n_frames=40, n_cars=4, seed=3)
    run_sweep({"name": "gains", "chunk": 16, "data": {"root": str(root), "det2d": "synth2d", "det3d": "synth3d"},
               "baseline": {"preset": "dfr2023"}, "params": {"a_l": [8.0, 2.0]}, "options": {"output": ["filtered"]},
               "variants": [{"name": "gains_code", "params": {"gain_alpha": 0.9, "gain_beta": 0.9, "gain_gamma": 0.1}},
                            {"name": "gains_low", "params": {"gain_alpha": 1.0, "gain_beta": 0.4, "gain_gamma": 0.03}}]},
              d / "sweep", **QUIET)
    return d / "sweep"


def test_a_setting_the_hash_treats_as_one_is_one_value_in_the_report(gains):
    """Issue 41, item 16: the baseline's float32 gains and the file's 0.9 are one setting (one config
    hash), so the report's sensitivity and plots count two values of the gains, not three; the stored
    table keeps the values each config was tracked with."""
    from dfrmot_jax.report import axis_profiles

    stored = load_results(gains)
    assert stored["gain_alpha"].nunique() == 3        # 0.89999997615814209 (baseline), 0.9, 1.0: as tracked
    rep = sweep_report(gains, objective="HOTA")
    row = rep.sensitivity.set_index("axis").loc["gain_alpha+gain_beta+gain_gamma"]
    assert row["values"] == 2
    prof = axis_profiles(rep.view)["gain_alpha+gain_beta+gain_gamma"]
    assert list(prof["label"]) == ["0.9/0.9/0.1", "1/0.4/0.03"]
    assert sorted(rep.data["gain_alpha"].unique()) == [0.9, 1.0]
