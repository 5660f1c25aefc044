"""Distortion studies on ByteTrack's 2D detections (``bytetrack.family.track(distortion=...)``): the
same seed and level give ByteTrack the 2D faults DFR-FastMOT's lanes get (the same ground-truth
objects' detections dropped, the same noise); each distorted lane of a batch equals its materialised
detections tracked alone; level 0 is the undistorted run, bit for bit; a ByteTrack sweep with a
``[distortion]`` table runs end to end on KITTI."""

from __future__ import annotations

import numpy as np
import pytest

from dfrmot_jax import distort
from dfrmot_jax.data import load_split
from dfrmot_jax.metrics import evaluate_files, metrics_table, prepare_gt
from dfrmot_jax.sweep import COMBINED, SweepConfigError, parse_spec, run_sweep
from dfrmot_jax.synthetic import make_scene
from dfrmot_jax.trackers.bytetrack import family as bf
from dfrmot_jax.trackers.bytetrack.config import Options, Params
from dfrmot_jax.trackers.dfr import track as api
from dfrmot_jax.trackers.dfr.config import Options as DOptions
from dfrmot_jax.trackers.dfr.frames import prepare_frames as dfr_frames

SLOTS = 2
#: lanes: undistorted (seed 5: still level 0), drops and bursts (3D levels too: ignored), every 2D fault
LANES = [distort.level_params("none", 0.0, seed=5),
         distort.level_params("drop", 0.3, seed=1, burst_rate=0.05, burst_len=4.0, jitter_3d=0.5),
         distort.level_params("clutter_2d", 1.5, seed=2, jitter_2d=3.0, score_noise_2d=0.1, drop_2d=0.1,
                              burst_rate=0.05, burst_len=4.0)]


@pytest.fixture(scope="module")
def split(tmp_path_factory):
    root = make_scene(tmp_path_factory.mktemp("bt_distort"), n_sequences=2, n_frames=40, n_cars=4, seed=11)
    return load_split(root, "synth2d", "synth3d", "car")


@pytest.mark.parametrize("truncate", [False, True])
def test_the_same_seed_and_level_give_both_families_the_same_2d_faults(split, truncate):
    """One lane distorted through DFR-FastMOT's path (its frames, its spec, the draws of its scan)
    and through ByteTrack's (:func:`bf.distorted_lanes`): the same surviving 2D detections (drops and
    bursts: the same ground-truth objects'), in slot order; untruncated, the same noisy boxes and
    scores; the real detections no noise touched carry the file's float64 values."""
    dps = distort.stack_distort(LANES)
    options = DOptions(truncate=truncate)
    frames = dfr_frames(split, options)
    dspec = distort.make_spec(options, clutter_slots=SLOTS, frames=frames, dps=dps)
    padded, (dspec, gid2, gid3) = api.prepare_distortion(split, frames, options, dps, dspec)
    prep = bf.prepare_frames(split)
    bspec = bf.distortion_spec(clutter_slots=SLOTS, frames=prep, dps=dps)
    assert not bspec.truncate and bspec.score2_q == dspec.score2_q
    assert bspec.enabled == ("burst", "drop", "jitter", "score", "clutter")
    lanes, ld = bf.distorted_lanes(split, prep, dps, bspec)
    np.testing.assert_array_equal(ld.gid2, gid2)                    # (the same ground-truth ids)
    assert ld.params.jitter_3d[1] == 0 and ld.params.drop_3d[1] == 0      # (3D levels ignored)
    m = split.valid2d.shape[1]
    for b, dp in enumerate(LANES):
        q = lanes.frames[lanes.of[b]]
        if b == 0:
            assert q is prep                                        # level 0: the undistorted frames themselves
            continue
        dfr = distort.distort_split(padded, gid2, gid3, dp, dspec)
        live = np.asarray(dfr.valid2)                               # DFR-FastMOT's surviving 2D slots [T, M + SLOTS]
        real = live & (np.arange(live.shape[1]) < m)
        assert real.sum() < split.valid2d.sum()                     # (something was dropped or occluded)
        valid = np.asarray(q.valid)
        np.testing.assert_array_equal(valid.sum(1), live.sum(1), err_msg=f"lane {b}: detections per frame")
        is_real = real[live]                                        # ByteTrack's packed slots: DFR's live slots in order
        dets = q.dets[valid]                                        # [N, 5] x1 y1 x2 y2 score
        assert (np.sum(~is_real) > 3) == (dp.clutter_2d > 0)
        # the kept real detections: the same ground-truth objects', the same slots
        np.testing.assert_array_equal(gid2[:, :m][real[:, :m]], ld.gid2[:, :m][real[:, :m]])
        if dp.score_noise_2d == 0:
            np.testing.assert_array_equal(dets[is_real, 4], split.score2d[real[:, :m]])
        else:
            np.testing.assert_array_equal(dets[:, 4].astype(np.float32), np.asarray(dfr.score2)[live])
        if dp.jitter_2d == 0:
            np.testing.assert_array_equal(dets[is_real, :4], split.box2d[real[:, :m]])
        elif not truncate:
            np.testing.assert_array_equal(dets[is_real, :4].astype(np.float32), np.asarray(dfr.box2)[real])
            assert np.abs(dets[is_real, :4] - split.box2d[real[:, :m]]).max() > 1.0


def _materialised(res, lane: int) -> "bf.Frames":
    return res.frames.frames[res.frames.of[lane]]


@pytest.mark.slow           # (ByteTrack's batched and unbatched programs on two frame shapes)
def test_distorted_lanes_equal_each_alone_and_level0_the_undistorted(split, tmp_path):
    """Settings x distortion lanes in one ``track``: every lane's ids, boxes, scores, counters and
    written files == its materialised detections tracked alone (``track`` of its frames) and == the
    lane alone through ``track(distortion=...)``; the level-0 lanes == no distortion, bit for bit."""
    params = Params(np.array([0.5, 0.3]), np.array([0.8, 0.9]), np.array([30, 5], np.int32), np.array([0.1, 0.1]))
    nl = len(LANES)
    p = Params(*(np.repeat(v, nl) for v in params))              # lane i: setting i // nl, distortion i % nl
    dps = distort.stack_distort(LANES * 2)
    res = bf.track(split, p, Options(), distortion=dps, clutter_slots=SLOTS)
    clean = bf.track(split, params, Options())
    assert isinstance(res.distortion, distort.LaneDistortion) and len(res.frames.frames) == nl
    keys = bf.lane_keys(res, [b"x"] * len(dps.seed))
    assert len(set(keys)) == len(keys)
    for lane in range(2 * nl):
        one = Params(*(v[lane] for v in p))
        s, d = divmod(lane, nl)
        alone = bf.track(_materialised(res, lane), one, Options())
        by_dp = bf.track(split, one, Options(), distortion=distort.stack_distort([LANES[d]]), spec=res.distortion.spec)
        for other in (alone, by_dp):
            for f in ("ids", "boxes", "score", "overflow", "peak", "capacity"):
                a, o = np.asarray(getattr(res, f))[lane], np.asarray(getattr(other, f))[0]
                if f in ("ids", "boxes", "score"):
                    mine, own = np.asarray(res.ids)[lane] >= 0, np.asarray(other.ids)[0] >= 0
                    np.testing.assert_array_equal(a[mine], o[own], err_msg=f"lane {lane}: {f}")
                elif f != "capacity":
                    np.testing.assert_array_equal(a, o, err_msg=f"lane {lane}: {f}")
        mine = bf.write_runs(tmp_path / f"b{lane}", [bf.class_run(split, res, lane)])
        own = bf.write_runs(tmp_path / f"a{lane}", [bf.class_run(split, alone, 0)])
        assert [q.read_bytes() for q in mine] == [q.read_bytes() for q in own], lane
        if d == 0:              # level 0: the undistorted run, its rows bit for bit
            got, want = bf.rows(split, res, lanes=[lane]), bf.rows(split, clean, lanes=[s])
            for f in ("t", "ids", "box", "score", "box3d"):
                np.testing.assert_array_equal(getattr(got, f), getattr(want, f))
            assert keys[lane] != bf.lane_keys(clean, [b"x"] * 2)[s]       # (its levels and seed in the key)
    assert (np.asarray(res.ids)[1] >= 0).sum() != (np.asarray(res.ids)[0] >= 0).sum()


def test_level0_alone_is_the_undistorted_run_bit_for_bit(split):
    """A batch of level-0 lanes (seeds differ): ids, boxes and scores == no distortion, no frames copied."""
    dps = distort.stack_distort([distort.level_params("none", 0.0, seed=s) for s in (0, 7)])
    p = Params(*(np.repeat(np.asarray(v)[None], 2) for v in Params()))
    res = bf.track(split, p, Options(), distortion=dps)
    clean = bf.track(split, p, Options())
    assert len(res.frames.frames) == 1 and res.frames.frames[0].dets.shape == clean.frames.dets.shape
    for f in ("ids", "boxes", "score", "overflow", "peak"):
        np.testing.assert_array_equal(np.asarray(getattr(res, f)), np.asarray(getattr(clean, f)))


def test_a_bytetrack_study_refuses_kinds_of_3d_detections_only(split):
    """ByteTrack reads 2D detections only: its sweeps refuse the 3D-only kinds, naming the key
    (AB3DMOT refuses the 2D-only ones); the kinds with a 2D part are taken."""
    doc = {"name": "bt", "data": {"root": str(split.root), "det2d": "synth2d"}, "options": {"family": "bytetrack"},
           "distortion": {"kind": ["drop", "jitter_3d"], "levels": {"drop": [0.1], "jitter_3d": [1.0]}}}
    for kind in distort.KINDS:
        if kind in ("none", "drop"):
            continue
        doc["distortion"]["kind"] = ["drop", kind]
        doc["distortion"]["levels"] = {"drop": [0.1], kind: [1.0] if kind not in ("drop_3d", "drop_2d") else [0.1]}
        if kind.startswith("clutter"):
            doc["distortion"]["clutter_slots"] = 2
        if kind in ("drop_3d", "jitter_box3", "jitter_3d", "score_3d", "clutter_3d"):
            with pytest.raises(SweepConfigError, match=r"3D detections only, which ByteTrack") as e:
                parse_spec(doc)
            assert e.value.key == "distortion.kind[1]"
        else:
            assert parse_spec(doc).distortion.kinds[1][0] == kind


@pytest.mark.slow           # (ByteTrack over two KITTI sequences, 5 lanes, then one lane alone)
def test_a_bytetrack_robustness_sweep_runs_on_kitti(kitti_root, tmp_path):
    """A ByteTrack sweep with a ``[distortion]`` table (drops, bursts, clutter) on 2 KITTI sequences:
    every lane scored; level 0 is the undistorted config's row; a drop lane's HOTA is its lane's."""
    spec = {"name": "bt_robust", "chunk": 8, "data": {"root": str(kitti_root), "det2d": "rrc",
                                                      "sequences": ["0012", "0017"]},
            "options": {"family": "bytetrack"}, "baseline": {"preset": "bytetrack_car"},
            "variants": [{"name": "bytetrack_car", "params": {"track_thresh": [0.5]}}],
            "distortion": {"kind": ["drop", "burst", "clutter"], "levels": {"drop": [0, 0.3], "burst": [5],
                                                                               "clutter": [1.0]},
                           "seeds": 1, "clutter_slots": 2}}
    table = run_sweep(spec, out=tmp_path / "out", progress=False, workers=0, log=lambda m: None)
    comb = table[table["sequence"] == COMBINED]
    assert len(comb) >= 4 and comb["HOTA"].notna().all()
    assert set(comb["distortion.kind"]) == {"none", "drop", "burst", "clutter"}
    by = comb.groupby("distortion.kind")["HOTA"].first()
    assert by["drop"] < by["none"] and len(set(by.round(12))) == 4
    split = load_split(kitti_root, "rrc", None, "car", ["0012", "0017"])
    res = bf.track(split, Params(), Options())              # bytetrack_car, undistorted, alone
    bf.write_runs(tmp_path / "plain", [bf.class_run(split, res, 0)])
    plain = metrics_table(evaluate_files(tmp_path / "plain", prepare_gt(kitti_root, "car", split.names)))
    assert plain.loc[COMBINED, "HOTA"] == by["none"]
