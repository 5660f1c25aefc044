"""track(): distortion lanes inside the batch, lanes per compiled call, per-lane boxes."""

import numpy as np
import pytest

from dfrmot_jax import distort
from dfrmot_jax.trackers.dfr.track import track
from dfrmot_jax.data import load_split
from dfrmot_jax.trackers.dfr.config import Options, Params, stack_params
from dfrmot_jax.synthetic import make_scene


@pytest.fixture(scope="module")
def split(tmp_path_factory):
    root = make_scene(tmp_path_factory.mktemp("scene"), n_sequences=2, n_frames=100, n_cars=6, seed=7)
    return load_split(root, "synth2d", "synth3d", "car")


@pytest.mark.slow
def test_distortion_lanes_run_with_the_parameter_grid(split):
    params = stack_params([Params(), Params(a_l=4.0), Params(), Params()])
    dps = distort.stack_distort([distort.level_params("drop", 0.0, seed=0), distort.level_params("drop", 0.0, seed=0),
                                 distort.level_params("drop", 0.4, seed=1), distort.level_params("burst", 8, seed=2)])
    clean = track(split, params, Options())
    dist = track(split, params, Options(), distortion=dps, lanes_per_call=2)
    assert dist.boxes.ndim == 4 and dist.boxes.shape[0] == 4
    for b in (0, 1):  # level 0: bit-identical output, whatever the parameters
        np.testing.assert_array_equal(dist.ids[b], clean.ids[b])
        live = clean.ids[b] >= 0
        np.testing.assert_array_equal(dist.boxes[b][live], clean.lane_boxes(b)[live])
    for b in (2, 3):
        assert (dist.ids[b] >= 0).sum() < (clean.ids[b] >= 0).sum()
    again = track(split, params, Options(), distortion=dps)
    np.testing.assert_array_equal(again.ids, dist.ids)  # same seeds, same distortion, any lanes per call


@pytest.mark.slow
def test_clutter_adds_written_false_positives(split):
    dps = distort.stack_distort([distort.level_params("clutter", 0.0), distort.level_params("clutter", 1.5, seed=3)])
    res = track(split, stack_params([Params(), Params()]), Options(), distortion=dps, clutter_slots=3)
    assert (res.ids[1] >= 0).sum() > (res.ids[0] >= 0).sum()


def test_distortion_needs_a_split_and_matching_lanes(split):
    from dfrmot_jax.trackers.dfr.frames import prepare_frames

    dps = distort.stack_distort([distort.level_params("drop", 0.1)] * 3)
    with pytest.raises(ValueError, match="lanes"):
        track(split, stack_params([Params(), Params()]), Options(), distortion=dps)
    with pytest.raises(ValueError, match="Split"):
        track(prepare_frames(split, Options()), stack_params([Params()]), Options(),
              distortion=distort.level_params("drop", 0.1))


@pytest.mark.slow     # (the not-slow tier's 3-minute budget; the full suite runs it)
def test_the_old_keywords_chunk_still_work_with_a_deprecation_warning(split):
    """``track(chunk=)`` and ``evaluate_arrays(chunk=)`` were renamed (a sweep's chunk is its unit of
    configs): the old keyword still works for one release, the same as the new one, and warns."""
    from dfrmot_jax.metrics.kitti2d.evaluate import cached_gt
    from dfrmot_jax.metrics.kitti2d.lane_scorer import evaluate_arrays

    params = stack_params([Params(), Params(a_l=4.0), Params(score_2d=0.6)])
    new = track(split, params, Options(), lanes_per_call=2)
    with pytest.warns(DeprecationWarning, match="lanes_per_call"):
        old = track(split, params, Options(), chunk=2)
    np.testing.assert_array_equal(old.ids, new.ids)
    gt = cached_gt(split.root, "car", list(split.names))
    boxes = np.broadcast_to(new.boxes, new.ids.shape + (4,))      # (output "detections": shared boxes)
    want = evaluate_arrays(gt, new.ids, boxes, split.offsets, lanes_per_batch=2)
    with pytest.warns(DeprecationWarning, match="lanes_per_batch"):
        got = evaluate_arrays(gt, new.ids, boxes, split.offsets, chunk=2)
    np.testing.assert_equal(got, want)
