"""The JAX tracker against the oracle (edge scenes, id for id) and the reference runs."""

import jax
import numpy as np
import pytest

from dfrmot_jax.testing import bytetrack_oracle as O
from dfrmot_jax.testing import bytetrack_scenes as S
from dfrmot_jax.testing.bytetrack_compare import compare_lines, reference_lines
from dfrmot_jax.trackers.bytetrack import batch, results
from dfrmot_jax.trackers.bytetrack.config import Options, Params

SEQS = [f"{i:04d}" for i in range(21)]
SETTINGS = [O.Settings(), O.Settings(mot20=True), O.Settings(track_thresh=0.3, track_buffer=60, match_thresh=0.9),
            O.Settings(frame_rate=30, track_buffer=10)]


def _params(s):
    return Params(s.track_thresh, s.match_thresh, s.track_buffer, s.det_thresh_margin), \
        Options(not s.mot20, s.frame_rate, s.demo_filter)


T_PAD, D_PAD = 48, 16     # every scene in one shape: one program per Options


def _pad(frames):
    return list(frames) + [np.zeros((0, 5))] * (T_PAD - len(frames))


def _jax_lines(frames, s, capacity=None):
    p, o = _params(s)
    out = batch.run(p, o, batch.pack_frames([_pad(frames)], D_PAD), capacity)
    return results.lane_lines(out, 0, "Car", s.demo_filter), out


@pytest.mark.parametrize("name", list(S.SCENES))
@pytest.mark.parametrize("si", range(len(SETTINGS)))
def test_scene_jax_equals_oracle(name, si):
    s = SETTINGS[si]
    got, out = _jax_lines(S.SCENES[name], s, capacity=48)
    want = O.run_sequence(_pad(S.SCENES[name]), s)
    assert sorted(got) == sorted(want)            # ids too: the same counter
    assert out.overflow[0] == 0


@pytest.mark.parametrize("seed", range(6))
def test_random_scene_jax_equals_oracle(seed):
    frames = S.random_scene(seed)
    for s in SETTINGS[:2]:
        got, _ = _jax_lines(frames, s, capacity=48)
        assert sorted(got) == sorted(O.run_sequence(_pad(frames), s))


def test_batch_lanes_equal_single_runs():
    frames = S.random_scene(11)
    lanes = SETTINGS[0], O.Settings(track_thresh=0.3, track_buffer=60, match_thresh=0.9), O.Settings(match_thresh=0.5)
    p = Params(*(np.array(v) for v in zip(*[_params(s)[0] for s in lanes])))
    out = batch.run(p, Options(), batch.pack_frames([_pad(frames)], D_PAD), 48)
    for i, s in enumerate(lanes):
        assert sorted(results.lane_lines(out, i)) == sorted(O.run_sequence(_pad(frames), s))


def test_capacity_overflow_counted():
    frames = S.SCENES["crowd"]
    got, out = _jax_lines(frames, O.Settings(), capacity=8)
    assert out.overflow[0] == 12                   # 12 detections, 8 slots: 4 births dropped in each of 3 frames
    got, out = _jax_lines(frames, O.Settings(), capacity=16)
    assert out.overflow[0] == 0 and sorted(got) == sorted(O.run_sequence(_pad(frames), O.Settings()))


def _run_reference(root, run, seqs):
    cls, s = O.PRESETS[run]
    frs = [O.load_frames(root, cls, q) for q in seqs]
    p, o = _params(s)
    out = batch.run(p, o, batch.pack_frames(frs))
    assert out.overflow[0] == 0
    per = results.sequence_lines(out, 0, [len(f) for f in frs], "Car" if cls == "car" else "Pedestrian", s.demo_filter)
    for q, lines in zip(seqs, per):
        c = compare_lines(lines, reference_lines(root, run, q))
        assert c.identical, (run, q, c)


def test_jax_reference_fast(kitti_root):
    _run_reference(kitti_root, "car_default", ["0003", "0012", "0017"])


@pytest.mark.slow
@pytest.mark.parametrize("run", list(O.PRESETS))
def test_jax_reference_all(kitti_root, run):
    _run_reference(kitti_root, run, SEQS)


def test_lanes_in_step_equal_lanes_one_by_one():
    """The vmapped step (``tracker.step_batch``, the path off CPU) equals the lanes one after the
    other (``lax.map``, the path on CPU), array for array."""
    frames = batch.pack_frames([_pad(S.random_scene(5))], D_PAD)
    lanes = SETTINGS[0], O.Settings(track_thresh=0.3, track_buffer=60, match_thresh=0.9), O.Settings(match_thresh=0.5)
    p = Params(*(np.array(v) for v in zip(*[_params(s)[0] for s in lanes])))
    with jax.enable_x64(True):
        p = Params(*(np.asarray(v, np.int32 if i == 2 else np.float64) for i, v in enumerate(p)))
        f = batch.Frames(*(jax.numpy.asarray(a) for a in frames))
        got = [jax.tree.map(np.asarray, batch._program(Options(), 48, True, s)(p, f)) for s in (False, True)]
    for a, b in zip(jax.tree.leaves(got[0]), jax.tree.leaves(got[1])):
        np.testing.assert_array_equal(a, b)
