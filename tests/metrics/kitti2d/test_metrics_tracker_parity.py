"""Metrics parity with ``trackeval`` on the project's own tracker output, for 10 random settings."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("trackeval")

from dfrmot_jax.trackers.dfr.track import track  # noqa: E402
from dfrmot_jax.data import load_split  # noqa: E402
from dfrmot_jax.metrics import evaluate_arrays, evaluate_files, prepare_gt  # noqa: E402
from dfrmot_jax.testing.trackeval_adapter import make_gt_folder, make_tracker_folder, run_trackeval  # noqa: E402
from dfrmot_jax.trackers.dfr.config import Options, stack_params  # noqa: E402
from dfrmot_jax.trackers.dfr.results import write_lane  # noqa: E402
from dfrmot_jax.testing import random_params  # noqa: E402

from test_metrics_parity import assert_same  # noqa: E402

SEQS = ["0000", "0011", "0014", "0017"]
GROUPS = [Options(), Options(filter="kalman", output="filtered", truncate=False)]


@pytest.mark.slow
def test_tracker_output_for_10_random_settings_scores_like_trackeval(kitti_root, tmp_path):
    split = load_split(kitti_root, "rrc", "pointrcnn", "car", SEQS)
    gt = prepare_gt(kitti_root, "car", SEQS)
    rng = np.random.default_rng(42)
    lanes = []  # (name, options, result, lane)
    for g, options in enumerate(GROUPS):
        settings = [random_params(rng, options.output) for _ in range(5)]
        res = track(split, stack_params(settings), options)
        for b in range(len(settings)):
            lanes.append((f"g{g}_{b}", options, res, b))
    for name, options, res, b in lanes:
        out = tmp_path / "ours" / name
        write_lane(out, split, res.frames, options, res.ids[b], None if options.output == "detections" else res.lane_boxes(b))
        make_tracker_folder(tmp_path / "trackers", name, {s: out / f"{s}.txt" for s in SEQS}, SEQS)
    make_gt_folder(tmp_path / "gt", kitti_root, gt.lengths_dict)
    te = run_trackeval(tmp_path / "gt", tmp_path / "trackers", "car")
    assert len(te) == 10
    for name, options, res, b in lanes:
        assert_same(te[name], evaluate_files(tmp_path / "ours" / name, gt), tag=name)
        if options.output == "detections":  # integer boxes: the files hold exactly the arrays' values
            ours = evaluate_arrays(gt, res.ids[b:b + 1], res.lane_boxes(b)[None], split.offsets)[0]
            assert_same(te[name], ours, tag=name + " (arrays)")
    hota = [float(np.mean(te[n]["COMBINED"]["HOTA"])) for n, *_ in lanes]
    assert len(set(np.round(hota, 6))) > 5  # the settings really differ
