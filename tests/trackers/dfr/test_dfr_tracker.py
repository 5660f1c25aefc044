"""The JAX tracker on the built-in synthetic scene: oracle parity, batching, recompiles, capacity."""

import warnings

import numpy as np
import pytest

from dfrmot_jax.trackers.dfr import run as tracker
from dfrmot_jax.devices import batch_devices
from dfrmot_jax.frames import Frames
from dfrmot_jax.trackers.dfr.track import default_capacity, track
from dfrmot_jax.data import load_sequences, pack
from dfrmot_jax.trackers.dfr.frames import prepare_frames
from dfrmot_jax.trackers.dfr.config import OBJECT_PARAMS, Options, Params, stack_params
from dfrmot_jax.testing.recompile import no_recompile
from dfrmot_jax.testing.parity import lane_mismatches, reference_rows
from dfrmot_jax.synthetic import make_scene
from dfrmot_jax.testing import random_params, random_settings


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    root = make_scene(tmp_path_factory.mktemp("scene"), n_sequences=2, n_frames=150, n_cars=7, seed=3)
    seqs = load_sequences(root, "synth2d", "synth3d", "car")
    return root, seqs, pack(seqs)


def _assert_parity(split, seqs, params, options):
    res = track(split, stack_params([params]), options)
    mm = lane_mismatches(split, res, 0, reference_rows(seqs, params, options))
    assert mm["lines"] > 0
    assert (mm["missing"], mm["extra"], mm["id"], mm["box"]) == (0, 0, 0, 0), (options, params, mm)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["dfr2023", "dfr_head"])
def test_presets_match_reference(scene, name):
    from dfrmot_jax.trackers.dfr.config import preset

    _, seqs, split = scene
    _assert_parity(split, seqs, *preset(name))


@pytest.mark.slow
def test_random_settings_match_reference(scene):
    """5 random settings (static options and parameters drawn), each id for id with the oracle on the
    synthetic scene (one compilation each; the KITTI parity test draws 16 more on 21 sequences)."""
    _, seqs, split = scene
    rng = np.random.default_rng(11)
    for params, options in random_settings(rng, 5):
        _assert_parity(split, seqs, params, options)


@pytest.mark.slow      # (the not-slow tier's 3-minute budget)
@pytest.mark.parametrize("options", [Options()] + [pytest.param(o, marks=pytest.mark.slow) for o in (
    Options(output="filtered", assign="hungarian"), Options(modality="3d"))])
def test_weak_detections_track_like_the_oracle(scene, options):
    """Weak detections (``weak_2d``, ``weak_3d``, ``a_weak``) continue tracks and never start one, as the
    oracle's independent rule; the setting is one where they change the output."""
    _, seqs, split = scene
    strict = Params(score_2d=0.6, score_3d=5.0)
    weak = strict._replace(weak_2d=0.3, weak_3d=3.0, a_weak=0.2)
    _assert_parity(split, seqs, weak, options)
    both = track(split, stack_params([strict, weak]), options)
    assert not np.array_equal(both.ids[0], both.ids[1]), "the weak detections changed nothing: the test proves nothing"


def _three_sizes(frames, options, min_frames=None, max_sizes=3):
    """A plan of three smaller steps for the scene (its own plan has one): frames in the first size
    that holds their detections (None without small frames, as ``small_frames``)."""
    if min_frames is None or options.assign == "hungarian":
        return None
    sizes = ((1, 1), (3, 2), (5, 4))
    last = [np.where(v.any(1), v.shape[1] - np.argmax(v[:, ::-1], axis=1), 0) for v in (frames.valid2, frames.valid3)]
    bucket = np.full(last[0].shape, len(sizes), np.int32)
    for k in reversed(range(len(sizes))):
        bucket[(last[0] <= sizes[k][0]) & (last[1] <= sizes[k][1])] = k
    return sizes, bucket


@pytest.mark.slow
@pytest.mark.parametrize("plan", ["own", "three sizes"])
def test_small_frames_track_like_the_oracle_and_like_one_size(scene, plan, monkeypatch):
    """Frames with few detections run on smaller copies of the step (``trackers.dfr.run.small_frames``, on
    for long splits; forced here, with the scene's own plan and with three sizes): the oracle's tracks
    id for id, and the same arrays as one size, for random settings, the rows' 3D sources
    (``detail``) included (the KITTI parity tests run it on all 21 sequences, where it is on). Each
    plan: one random setting (its own draw) and the two default settings, both outputs."""
    _, seqs, split = scene
    frames = prepare_frames(split, Options())
    if plan == "three sizes":
        monkeypatch.setattr(tracker, "small_frames", _three_sizes)
    found = tracker.small_frames(frames, Options(), min_frames=0)
    assert found is not None and 0 < np.mean(found[1] < len(found[0])) < 1, "the scene has no small frames to run"
    assert plan == "own" or np.all(np.bincount(found[1], minlength=4) > 0), "a size holds no frame"
    rng = np.random.default_rng(31)
    carried = 0
    for params, options in (random_settings(rng, 1)
                            + [(Params(), Options()), (Params(), Options(output="filtered"))]):
        batch = stack_params([params, random_params(rng, options.output)])
        small = track(split, batch, options, small_frames_min=0, detail=True)
        mm = lane_mismatches(split, small, 0, reference_rows(seqs, params, options))
        assert (mm["missing"], mm["extra"], mm["id"], mm["box"]) == (0, 0, 0, 0), (options, params, mm)
        one = track(split, batch, options, small_frames_min=None, detail=True)
        carried += int(np.sum(one.src3 >= 0))
        for a, b in zip(small, one):
            if isinstance(a, np.ndarray):
                np.testing.assert_array_equal(a, b)
    assert carried > 0, "no row carries a 3D detection: the 3D sources were not compared"


@pytest.mark.slow
def test_vmap_batch_equals_loop_of_single_runs(scene):
    """32 random settings in one vmapped call; 6 of its lanes (the first, the last and 4 drawn with a
    fixed seed, so lanes from both ends and the middle of the batch) each equal a run of their own,
    ids and live boxes. Every lane runs through the same vmapped program, so a lane-mixing bug shows
    in any lane; comparing all 32 cost 32 single runs."""
    _, _, split = scene
    rng = np.random.default_rng(5)
    options = Options(filter="kalman", output="filtered", capacity=48)
    settings = [random_params(rng, "filtered") for _ in range(32)]
    batch = track(split, stack_params(settings), options, lanes_per_call=32)
    chosen = sorted({0, 31, *np.random.default_rng(7).choice(np.arange(1, 31), 4, replace=False).tolist()})
    assert len(chosen) == 6
    for b in chosen:
        p = settings[b]
        single = track(split, stack_params([p]), options)
        k = single.ids.shape[2]
        np.testing.assert_array_equal(batch.ids[b][:, :k], single.ids[0])
        assert np.all(batch.ids[b][:, k:] == -1)
        live = single.ids[0] >= 0
        np.testing.assert_array_equal(batch.boxes[b][:, :k][live], single.boxes[0][live])


@pytest.mark.slow
def test_second_call_with_new_values_does_not_recompile(scene):
    _, _, split = scene
    frames = prepare_frames(split, Options())
    cap = default_capacity(frames, Params(), Options())
    tracker.run_batch(stack_params([Params(), Params(a_l=5.0)]), frames, Options(), cap)
    small = tracker.small_frames(frames, Options())
    fn = tracker.compiled(Options(), cap, min(2, len(batch_devices())), None, False,
                          None if small is None else small[0])
    with no_recompile():
        out = tracker.run_batch(stack_params([Params(a_l=3.0, epsilon=5), Params(score_2d=0.7)]), frames, Options(),
                                cap)
    assert fn._cache_size() == 1
    assert out.ids.shape[0] == 2
    with pytest.raises(AssertionError, match="recompiled"), no_recompile():
        tracker.run_batch(stack_params([Params(a_l=3.0)] * 2), frames, Options(), cap + 8)


#: a_weak matters only with weak detections: it is changed from a base with weak_3d = 4 (its own base
#: lane in the Options() batch, so no program of its own is compiled)
WEAK_BASE = {"a_weak": Params(weak_3d=4.0)}
CHANGES = {
    "score_2d": (Options(), 0.8), "score_3d": (Options(), 9.0), "merge_iou": (Options(), 0.9),
    "a_c": (Options(modality="2d"), 0.6), "a_l": (Options(modality="3d"), 1.0), "alpha_c": (Options(), 0.95),
    "a_f": (Options(), 0.4), "epsilon": (Options(), 0), "gain_alpha": (Options(modality="2d"), 0.1),
    "gain_beta": (Options(modality="2d"), 0.0), "gain_gamma": (Options(modality="2d"), 0.9),
    "kf_q": (Options(filter="kalman", output="filtered"), 1e4), "kf_r": (Options(filter="kalman", output="filtered"), 1e4),
    "kf_p0": (Options(filter="kalman", output="filtered"), 1e-3),
    "kf_q3": (Options(filter="kalman", output="filtered"), 1e4), "kf_r3": (Options(filter="kalman", output="filtered"), 1e4),
    "keep_lost": (Options(output="filtered"), 5), "min_hits": (Options(), 4),
    "weak_2d": (Options(), 0.4), "weak_3d": (Options(), 4.0), "a_weak": (Options(), 0.9),
}


@pytest.mark.slow
def test_every_parameter_changes_the_output(scene):
    """A guard against settings that are silently ignored: every parameter, changed from its base
    lane (``Params()``, or ``WEAK_BASE``) in one batch per static option set, changes the output."""
    _, _, split = scene
    assert set(CHANGES) == set(Params._fields)
    by_options = {}
    for name, (options, value) in CHANGES.items():
        by_options.setdefault(options, []).append((name, value, WEAK_BASE.get(name, Params())))
    for options, changes in by_options.items():
        bases = list(dict.fromkeys(base for _, _, base in changes))
        lanes = bases + [base._replace(**{n: v}) for n, v, base in changes]
        res = track(split, stack_params(lanes), options)
        for b, (name, value, base) in enumerate(changes, start=len(bases)):
            a = bases.index(base)
            assert lanes[b] != lanes[a]
            same = np.array_equal(res.ids[b], res.ids[a]) and (
                options.output == "detections" or np.array_equal(res.boxes[b], res.boxes[a]))
            assert not same, f"changing {name} to {value} under {options} (from {base}) changed nothing"


@pytest.mark.slow
def test_overflow_is_detected_counted_per_lane_and_reported(scene):
    _, _, split = scene
    params = stack_params([Params(), Params(epsilon=0), Params(epsilon=60)])
    with pytest.warns(RuntimeWarning, match="overflow"):
        small = track(split, params, Options(capacity=4), grow=False)
    assert np.all(small.overflow >= 0) and small.overflow[2] > 0
    assert small.overflow[2] >= small.overflow[1]
    np.testing.assert_array_equal(small.dropped.sum(axis=1), small.overflow)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        grown = track(split, params, Options(capacity=4), grow=True)
    assert np.all(grown.overflow == 0) and np.all(grown.capacity > 4)
    big = track(split, params, Options(capacity=256))
    assert np.all(big.overflow == 0)
    np.testing.assert_array_equal(grown.ids, big.ids)


def test_default_capacity_comes_from_the_data(scene):
    _, _, split = scene
    frames = prepare_frames(split, Options())
    most = int((frames.valid2 & (frames.score2 >= 0.45)).sum(1).max() + (frames.valid3 & (frames.score3 >= 4.0)).sum(1).max())
    cap = default_capacity(frames, Params(), Options())
    assert cap % 8 == 0 and most <= cap <= 3 * most + 16
    loose = default_capacity(frames, Params(score_2d=0.0, score_3d=-10.0), Options())
    assert loose >= cap


def _frame_ids(ids: np.ndarray) -> list[tuple[int, int]]:
    """(frame, id) of every output box of ids [T, K], sorted."""
    t, k = np.nonzero(ids >= 0)
    return sorted(zip(t.tolist(), ids[t, k].tolist()))


@pytest.mark.slow
def test_ids_restart_at_each_sequence(scene):
    """The id rule (``core.memory``): each birth takes the next id, in slot order, and the counter
    restarts at 0 on a sequence's first frame. With every birth output (min_hits 1) each sequence's
    ids are therefore 0..n-1, first seen in that order; with the default min_hits (births that never
    reach it leave gaps) the ids are the oracle's, which tracks each sequence on its own; and a
    sequence tracked alone gets the same ids as inside the split."""
    _, seqs, split = scene
    assert len(seqs) >= 2
    for params in (Params(min_hits=1), Params()):
        res = track(split, stack_params([params]), Options())
        ref = reference_rows(seqs, params, Options())
        for s in range(len(seqs)):
            mine = _frame_ids(res.ids[0][split.sequence_slice(s)])
            assert mine == sorted({(row[0], row[1]) for row in ref[s]})
            if params.min_hits == 1:
                first = {}
                for t, i in mine:
                    first.setdefault(i, t)
                assert sorted(first) == list(range(len(first))) and len(first) > 10
                assert all(first[i] <= first[i + 1] for i in range(len(first) - 1)), first
        alone = track(pack([seqs[1]]), stack_params([params]), Options())
        assert _frame_ids(alone.ids[0]) == _frame_ids(res.ids[0][split.sequence_slice(1)])


def test_keep_lost_needs_filtered_output(scene):
    _, _, split = scene
    with pytest.raises(ValueError, match="keep_lost"):
        track(split, stack_params([Params(keep_lost=2)]), Options())


@pytest.mark.slow
def test_more_than_64_objects_in_a_frame_track_like_the_oracle(tmp_path):
    """100 detections in one frame (2D + 3D rows past the old 64-row limit): tracker == oracle."""
    from dfrmot_jax.io.kitti import Calib, Detections2D, Detections3D
    from dfrmot_jax.data import SequenceDets

    rng = np.random.default_rng(5)
    n, frames = 60, 4
    x = np.repeat(rng.uniform(0, 1100, n)[None], frames, 0) + np.arange(frames)[:, None] * 3.0
    y = np.repeat(rng.uniform(0, 300, n)[None], frames, 0)
    box2 = np.stack([x, y, x + 40, y + 30], -1).reshape(-1, 4)
    f2 = np.repeat(np.arange(frames), n)
    d2 = Detections2D(f2, box2, np.full(f2.size, 0.9))
    m = 45
    f3 = np.repeat(np.arange(frames), m)
    b3 = box2.reshape(frames, n, 4)[:, :m].reshape(-1, 4) + 1.0
    loc = np.stack([rng.uniform(-20, 20, f3.size), np.full(f3.size, 1.5), rng.uniform(5, 60, f3.size)], -1)
    d3 = Detections3D(f3, np.array(["2"] * f3.size, object), b3, np.full(f3.size, 9.0),
                      np.tile([1.5, 1.6, 3.9], (f3.size, 1)), loc, np.zeros(f3.size), np.zeros(f3.size))
    P2 = np.array([[721.5, 0, 609.6, 44.9], [0, 721.5, 172.9, 0.2], [0, 0, 1, 0.003]])
    seq = SequenceDets("0000", frames, d2, d3, Calib(P2, np.eye(3), np.zeros((3, 4)), np.stack([P2] * 4),
                                                     np.zeros((3, 4))))
    split = pack([seq])
    assert split.box2d.shape[1] + split.box3d.shape[1] > 64
    res = track(split, stack_params([Params()]), Options())
    bad = lane_mismatches(split, res, 0, reference_rows([seq], Params(), Options()), tol=0.0)
    assert bad["lines"] >= frames * n and (bad["missing"], bad["extra"], bad["id"], bad["box"]) == (0, 0, 0, 0), bad


def test_too_many_objects_per_frame_is_refused_up_front():
    from dfrmot_jax.trackers.dfr.track import MAX_OBJECTS

    from dfrmot_jax.frames import Frames

    T, m2, m3 = 2, MAX_OBJECTS, 8
    fr = Frames(np.zeros(T, bool), np.zeros((T, m2, 4), np.float32), np.zeros((T, m2), np.float32),
                np.zeros((T, m2), bool), np.zeros((T, m3, 4), np.float32), np.zeros((T, m3), np.float32),
                np.zeros((T, m3), bool), np.zeros((T, m3, 3), np.float32), np.zeros((T, m3, 3), np.float32))
    with pytest.raises(ValueError, match=f"at most {MAX_OBJECTS} objects per frame"):
        track(fr, stack_params([Params()]), Options())


@pytest.mark.slow      # (the not-slow tier's 3-minute budget; the full suite runs every variant)
@pytest.mark.parametrize("options", [Options()] + [pytest.param(o, marks=pytest.mark.slow) for o in (
    Options(output="filtered", filter="kalman"), Options(modality="3d"), Options(merge="calib_projection", modality="2d"))])
def test_lanes_sharing_merge_settings_share_objects_made_outside_the_scan(scene, options, monkeypatch):
    """Lanes with the same ``trackers.dfr.config.OBJECT_PARAMS`` (score_2d, score_3d, merge_iou, weak_2d, weak_3d) share their objects, made once outside the
    scan (``trackers.dfr.run.split_objects``): the same arrays as each step making its own, detail included.
    8 lanes, 4 per setting of those parameters, with the batch's threshold for sharing
    (``SHARED_OBJECTS_MIN_LANES`` lanes per setting, 8) lowered to 4: the same shared path as 16
    lanes at the default, on half the lanes."""
    from dfrmot_jax.trackers.dfr import track as api

    _, _, split = scene
    monkeypatch.setattr(api, "SHARED_OBJECTS_MIN_LANES", 4)
    rng = np.random.default_rng(17)
    triples = [random_params(rng) for _ in range(2)]
    lanes = []
    for i in range(8):
        p = random_params(rng, options.output)
        t = triples[i % 2]
        lanes.append(p._replace(**{name: getattr(t, name) for name in OBJECT_PARAMS}))
    batch = stack_params(lanes)
    assert api.merge_keys(batch) is not None
    shared = track(split, batch, options, detail=True, small_frames_min=0)
    monkeypatch.setattr(api, "SHARED_OBJECTS_MIN_LANES", 10**6)
    assert api.merge_keys(batch) is None
    in_scan = track(split, batch, options, detail=True, small_frames_min=0)
    assert np.any(shared.ids >= 0)
    for a, b in zip(shared, in_scan):
        if isinstance(a, np.ndarray):
            np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("options", [Options()] + [pytest.param(o, marks=pytest.mark.slow) for o in (
    Options(output="filtered"), Options(modality="3d"), Options(modality="2d"))])
@pytest.mark.slow
def test_track_compacts_the_split_and_gives_the_output_back_in_its_own_layout(scene, options):
    """``track(split)`` runs on the split compacted to the batch's loosest thresholds and moves the
    output back to the split's own slots: every array equal to tracking the split as it is."""
    from dfrmot_jax.trackers.dfr import track as api

    _, _, split = scene
    rng = np.random.default_rng(23)
    batch = stack_params([random_params(rng, options.output)._replace(score_2d=0.6, score_3d=5.0)
                          for _ in range(3)])
    assert api._compacted(split, prepare_frames(split, options), batch, options) is not None, "nothing to compact: the test would prove nothing"
    packed = track(split, batch, options, detail=True)
    plain = track(split, batch, options, detail=True, compact=False)
    assert np.any(packed.ids >= 0) and packed.ids.shape == plain.ids.shape
    if options.modality != "2d":
        assert np.any(packed.src3 >= 0)
    for name in ("ids", "boxes", "src3", "own3", "box3", "dropped", "overflow", "peak"):
        a, b = getattr(packed, name), getattr(plain, name)
        if a is not None:
            np.testing.assert_array_equal(a, b, err_msg=name)


def test_small_frame_plan_nests_its_sizes_and_puts_each_frame_in_the_first_that_holds_it():
    """``small_frames``: nested sizes (each larger in one count, smaller in none), every frame in the
    first size holding its last valid 2D and 3D slots (or the full step), a further size only when it
    lowers the expected slots per step; one size is the best single size found by brute force."""
    rng = np.random.default_rng(4)
    T, m2, m3 = 4000, 14, 13
    # KITTI-like: most frames hold at most 1, 4 or 8 detections of each kind, a tenth up to all slots
    most = np.array([1, 4, 8, 14])[rng.choice(4, T, p=[0.35, 0.35, 0.2, 0.1])]
    n2, n3 = np.minimum(rng.integers(0, most + 1), m2), np.minimum(rng.integers(0, most + 1), m3)
    valid2 = np.arange(m2)[None, :] < n2[:, None]
    valid3 = np.arange(m3)[None, :] < n3[:, None]
    frames = Frames(np.zeros(T, bool), np.zeros((T, m2, 4), np.float32), np.zeros((T, m2), np.float32), valid2,
                    np.zeros((T, m3, 4), np.float32), np.zeros((T, m3), np.float32), valid3,
                    np.zeros((T, m3, 3), np.float32), np.zeros((T, m3, 3), np.float32))
    expected = []
    for k in (1, 2, 3):
        sizes, bucket = tracker.small_frames(frames, Options(), min_frames=0, max_sizes=k)
        assert len(sizes) == k
        for (a2, a3), (b2, b3) in zip(sizes, sizes[1:]):
            assert a2 <= b2 and a3 <= b3 and (a2, a3) != (b2, b3)
        fits = np.array([(n2 <= a2) & (n3 <= a3) for a2, a3 in sizes] + [np.ones(T, bool)])
        np.testing.assert_array_equal(bucket, np.argmax(fits, axis=0))
        expected.append(np.array([a + b for a, b in sizes] + [m2 + m3])[bucket].mean())
    assert expected[0] > expected[1] > expected[2], expected
    brute = min(np.mean(np.where((n2 <= a2) & (n3 <= a3), a2 + a3, m2 + m3))
                for a2 in range(1, m2 + 1) for a3 in range(1, m3 + 1))
    assert np.isclose(expected[0], brute)
    assert tracker.small_frames(frames, Options(assign="hungarian"), min_frames=0) is None
    one = frames._replace(valid2=valid2[:, :1], valid3=valid3[:, :1])       # one slot of each: nothing smaller
    assert tracker.small_frames(one, Options(), min_frames=0) is None
    assert tracker.small_frames(frames, Options(), min_frames=T + 1) is None
