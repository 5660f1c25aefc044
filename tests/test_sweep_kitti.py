"""On KITTI (skipped without the data): the sweep's baseline row is the published dfr2023 result."""

from __future__ import annotations

import pandas as pd
import pytest

from dfrmot_jax.sweep import COMBINED, run_sweep, sweep_report

# TrackEval's KITTI 2D box evaluation (car) of the authors' published RRC + PointRCNN files
PUBLISHED = {"HOTA": 82.79, "DetA": 83.12, "AssA": 82.59, "MOTA": 90.73, "MOTP": 90.57, "IDSW": 177,
             "IDF1": 91.36, "MT": 503, "ML": 8, "Frag": 238}


@pytest.mark.slow
def test_baseline_row_reproduces_dfr2023(kitti_root):
    spec = {"name": "kitti_baseline", "chunk": 2,
            "data": {"root": str(kitti_root), "det2d": "rrc", "det3d": "pointrcnn", "class": "car"},
            "baseline": {"preset": "dfr2023"}, "params": {"a_l": [8.0, 5.0]}}
    df = run_sweep(spec, progress=False, log=lambda m: None)
    comb = df[df["sequence"] == COMBINED]
    assert len(comb) == 2 and df["sequence"].nunique() == 21          # 20 sequences with cars + COMBINED
    base = comb[comb["baseline"]].iloc[0]
    for k, v in PUBLISHED.items():
        assert round(float(base[k]), 2) == v, k
    assert base["overflow"] == 0
    assert sweep_report(df).summary["baseline"] == pytest.approx(82.786, abs=5e-4)



@pytest.mark.slow
def test_compacted_detection_slots_change_nothing(kitti_root, monkeypatch):
    """Sweeps track each class on its split compacted to the table's loosest score thresholds
    (``data.compact_split``: 14 + 19 detection slots -> fewer): every column of every row equals the
    uncompacted run, for both output modes, on the car sequence with the most detections per
    frame, with the projected 3D boxes (some not finite); ``test_sweep`` covers the detector's boxes."""

    spec = {"name": "compact", "chunk": 8,
            "data": {"root": str(kitti_root), "det2d": "rrc", "det3d": "pointrcnn", "class": "car",
                     "sequences": ["0001"]},
            "baseline": {"preset": "dfr2023"},
            "params": {"score_2d": [0.3, 0.6], "score_3d": [4.0, 6.0], "merge_iou": [0.25, 0.5]},
            "options": {"output": ["detections", "filtered"], "merge": ["calib_projection"]}}
    compact = run_sweep(spec, progress=False, log=lambda m: None)
    full = run_sweep(spec, progress=False, log=lambda m: None, compact=False)
    pd.testing.assert_frame_equal(compact, full)
    assert compact["peak_tracks"].max() > 0
