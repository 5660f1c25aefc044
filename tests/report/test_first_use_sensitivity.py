"""Issue 51, item 18: AB3DMOT's ``threshold`` is an IoU for some metrics and metres for others; the
sweep report's sensitivity shows it once per metric (one row, one panel each), never one axis binning
IoUs and metres together (the fact is the family's: ``FamilyConfig.unit_of``)."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="module")
def two_metric_sweep(tmp_path_factory):
    from dfrmot_jax import run_sweep
    from dfrmot_jax.synthetic import make_scene

    tmp = tmp_path_factory.mktemp("sens")
    root = make_scene(tmp / "scene", n_sequences=2, n_frames=20, seed=3)
    spec = {"name": "sens", "chunk": 8, "data": {"root": str(root), "det3d": "synth3d"},
            "baseline": {"preset": "ab3dmot_car"}, "options": {"family": "ab3dmot"},
            "params": {"min_hits": [1, 2]},
            "variants": [{"name": "giou", "options": {"metric": "giou_3d"}, "params": {"threshold": [-0.4, -0.2, 0.0]}},
                         {"name": "dist", "options": {"metric": "dist_3d"}, "params": {"threshold": [2.0, 4.0]}}]}
    return run_sweep(spec, tmp / "out", progress=False), tmp / "out"


def test_threshold_sensitivity_is_per_metric(two_metric_sweep):
    from dfrmot_jax.report.analysis import axis_profiles, sensitivity

    df, _ = two_metric_sweep
    sens = sensitivity(df, "HOTA")
    axes = set(sens["axis"])
    assert "threshold [metric=giou_3d]" in axes and "threshold [metric=dist_3d]" in axes
    assert "threshold" not in axes
    prof = axis_profiles(df, "HOTA")
    assert sorted(prof["threshold [metric=giou_3d]"]["value"]) == [-0.4, -0.2, 0.0]
    assert sorted(prof["threshold [metric=dist_3d]"]["value"]) == [2.0, 4.0]


def test_report_and_page_show_one_threshold_panel_per_metric(two_metric_sweep, tmp_path):
    from dfrmot_jax.report import sweep_report, write_html

    _, folder = two_metric_sweep
    rep = sweep_report(folder)
    assert "threshold [metric=giou_3d]" in rep.text and "threshold [metric=dist_3d]" in rep.text
    page = write_html(rep, tmp_path / "r.html")
    html = page.read_text()
    assert "threshold [metric=dist_3d]" in html and "threshold [metric=giou_3d]" in html and "<svg" in html


def test_families_declare_the_units_of_their_parameters():
    from dfrmot_jax.trackers.registry import CONFIGS

    assert CONFIGS["ab3dmot"].unit_of == {"threshold": "metric"} and not CONFIGS["dfr"].unit_of
