"""Distortion studies on AB3DMOT's 3D detections (``ab3dmot.family.track(distortion=...)``): the
same seed and level give AB3DMOT the 3D faults DFR-FastMOT's lanes get; each distorted lane of a
batch equals the lane alone and the NumPy oracle on the same distorted detections; level 0 is the
undistorted run, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from dfrmot_jax.trackers.dfr import track as api
from dfrmot_jax import distort
from dfrmot_jax.trackers.ab3dmot import family as af
from dfrmot_jax.trackers.ab3dmot.config import Options as AOptions
from dfrmot_jax.trackers.ab3dmot.config import Params as AParams
from dfrmot_jax.trackers.dfr.config import Options
from dfrmot_jax.data import load_split
from dfrmot_jax.trackers.dfr.frames import prepare_frames
from dfrmot_jax.rows import Rows
from dfrmot_jax.synthetic import make_scene
from dfrmot_jax.testing import ab3dmot_oracle as ab

SLOTS = 3
#: lanes: undistorted (seed 5: still level 0), drops and bursts, everything 3D at once
LANES = [distort.level_params("none", 0.0, seed=5),
         distort.level_params("drop", 0.3, seed=1, burst_rate=0.05, burst_len=4.0),
         distort.level_params("clutter", 1.5, seed=2, jitter_3d=0.4, jitter_box3=3.0, score_noise_3d=1.5,
                              drop_3d=0.1)]
#: the slow test's lanes: undistorted (seed 5), and every 3D fault in one lane (drops and bursts,
#: clutter, centre and box jitter, score noise): one distorted frame shape to compile, not two
ALL_3D = [LANES[0], distort.level_params("clutter", 1.5, seed=2, jitter_3d=0.4, jitter_box3=3.0, score_noise_3d=1.5,
                                         drop_3d=0.3, burst_rate=0.05, burst_len=4.0)]


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    return make_scene(tmp_path_factory.mktemp("ab3d_distort"), n_sequences=2, n_frames=40, n_cars=4, seed=11)


@pytest.fixture(scope="module")
def split(scene):
    return load_split(scene, "synth2d", "synth3d", "car")


def test_the_same_seed_and_level_give_both_families_the_same_3d_faults(split):
    """One lane distorted through DFR-FastMOT's path (its frames, its spec, the draws of its scan)
    and through AB3DMOT's (:func:`af.distorted_lanes`): the same surviving 3D detections (drops and
    bursts), the same scores, the same centre shifts and clutter at the same places."""
    dps = distort.stack_distort(LANES)
    options = Options()                     # DFR-FastMOT's default: centroid "legacy", the detector's image box
    frames = prepare_frames(split, options)
    dspec = distort.make_spec(options, clutter_slots=SLOTS, frames=frames, dps=dps)
    padded, (dspec, gid2, gid3) = api.prepare_distortion(split, frames, options, dps, dspec)
    prep = af.prepare_frames(split)
    aspec = af.distortion_spec(clutter_slots=SLOTS, frames=prep, dps=dps)
    assert aspec.score3_q == dspec.score3_q and aspec.centroid == dspec.centroid and not aspec.truncate
    lanes, _ = af.distorted_lanes(split, prep, dps, aspec)
    m = split.valid3d.shape[1]
    for b, dp in enumerate(LANES):
        dfr = distort.distort_split(padded, gid2, gid3, dp, dspec)
        dfr = type(dfr)(*(np.asarray(v) for v in dfr))
        q = lanes.preps[lanes.of[b]]
        if b == 0:
            assert q is prep                                        # level 0: the undistorted frames themselves
            continue
        # AB3DMOT's frames list each frame's detections packed in slot order (as a file would): its
        # valid slots, frame by frame, are DFR-FastMOT's valid slots in their order
        valid = np.asarray(q.frames.valid)
        np.testing.assert_array_equal(valid.sum(1), dfr.valid3.sum(1), err_msg=f"lane {b}: detections per frame")
        live = dfr.valid3                                           # DFR-FastMOT's surviving slots [T, M + SLOTS]
        real = live & (np.arange(live.shape[1]) < m)
        assert real.sum() < split.valid3d.sum()                     # (something was dropped or occluded)
        np.testing.assert_array_equal(q.frames.score[valid].astype(np.float32), dfr.score3[live])
        if dp.score_noise_3d == 0:
            np.testing.assert_array_equal(q.frames.score[valid][real[live]], split.score3d[real[:, :m]])
        box = q.frames.boxes[valid]                                 # [N, 7] x y z th l w h
        is_real = real[live]
        shift = box[is_real, :3] - np.asarray(split.loc3d, np.float64)[real[:, :m]]       # x y z
        d = dfr.lo3[real].astype(np.float64) - padded.lo3[real].astype(np.float64)   # legacy axes (z, y, x)
        np.testing.assert_allclose(shift, d[:, ::-1], rtol=0, atol=1e-12)     # (file value + shift, rounded)
        assert (np.abs(shift).max() > 0.05) == (dp.jitter_3d > 0)
        fake = box[~is_real]
        lo = dfr.lo3[live & ~real]                                  # legacy: lo = (z, y, x)
        assert (len(fake) > 5) == (dp.clutter_3d > 0)
        np.testing.assert_array_equal(fake[:, 0].astype(np.float32), lo[:, 2])
        np.testing.assert_array_equal(fake[:, 2].astype(np.float32), lo[:, 0])
        np.testing.assert_array_equal(fake[:, 1].astype(np.float32), np.float32(distort.CAR_Y))
        np.testing.assert_array_equal(fake[:, [6, 5, 4]], np.broadcast_to(np.float32(distort.CAR_DIMS), (len(fake), 3)))
        if len(fake):
            assert np.ptp(fake[:, 3]) > 1.0                          # rotated boxes, their headings drawn


def _oracle_lines(split, q: af.Prepared, params: AParams) -> dict[str, list[str]]:
    """The NumPy oracle on a lane's distorted detections, sequence after sequence, one id counter."""
    st = ab.Settings("Car", "hungar", "giou_3d", float(params.threshold), int(params.min_hits), int(params.max_age))
    out, next_id = {}, 1
    valid = np.asarray(q.frames.valid)
    for s, name in enumerate(split.names):
        sl = split.sequence_slice(s)
        dets = {}
        for f, t in enumerate(range(sl.start, sl.stop)):
            v = valid[t]
            if v.any():
                raw = q.frames.boxes[t][v][:, [6, 5, 4, 0, 1, 2, 3]]
                info = np.concatenate([q.alpha[t][v][:, None], np.full((v.sum(), 1), 2.0), q.image[t][v],
                                       q.frames.score[t][v][:, None]], axis=1)
                dets[f] = ab.FrameDets(raw, info)
        out[name], next_id = ab.track_sequence(dets, sl.stop - sl.start, st, next_id)
    return out


def _lines(split, res, lane: int, out) -> dict[str, list[str]]:
    paths = af.write_runs(out, [af.class_run(split, res, lane)])
    return {p.stem: p.read_text().splitlines() for p in paths}


@pytest.mark.slow          # (three compilations of AB3DMOT's batch)
def test_distorted_lanes_equal_each_alone_the_oracle_and_level0_the_undistorted(split, tmp_path):
    """A batch of settings x distortion lanes (``ALL_3D``: undistorted at level 0, and one lane with
    every 3D fault: drops, bursts, clutter, jitter, score noise): every lane's lines == the lane
    tracked alone, == the NumPy oracle on its distorted detections, id for id; the level-0 lane == no
    distortion. (Each distinct distortion lane costs two compilations, batched and alone: the faults
    share one lane rather than a lane each.)"""
    params = AParams(np.array([-0.2, 0.01]), np.array([1, 2]), np.array([2, 3]), np.array([-1e4, -1e4]))
    b = len(ALL_3D) * 2
    p = AParams(*(np.tile(v, len(ALL_3D)) for v in params))
    dps = distort.stack_distort([d for d in ALL_3D for _ in range(2)])
    options = AOptions(metric="giou_3d", algorithm="hungarian")
    res = af.track(split, p, options, distortion=dps, clutter_slots=SLOTS)
    clean = af.track(split, params, options)
    for lane in range(b):
        one = AParams(*(v[lane] for v in p))
        dp = distort.stack_distort([ALL_3D[lane // 2]])
        mine = _lines(split, res, lane, tmp_path / f"batch{lane}")
        alone = af.track(split, one, options, distortion=dp, spec=res.distortion.spec)
        assert mine == _lines(split, alone, 0, tmp_path / f"alone{lane}"), lane
        q = res.frames.preps[res.frames.of[lane]]
        oracle = _oracle_lines(split, q, one)
        assert {k: v for k, v in mine.items()} == {k: v for k, v in oracle.items() if v or k in mine}, lane
        if lane < 2:            # level 0: the undistorted run, its rows and files bit for bit
            assert mine == _lines(split, clean, lane, tmp_path / f"clean{lane}")
            got, want = af.rows(split, res, lanes=[lane]), af.rows(split, clean, lanes=[lane])
            for f in ("t", "ids", "box", "score", "box3d"):
                np.testing.assert_array_equal(getattr(got, f), getattr(want, f))
    assert sum(len(v) for v in _lines(split, res, 2, tmp_path / "x").values()) != sum(
        len(v) for v in _lines(split, res, 0, tmp_path / "y").values())


@pytest.mark.slow          # (two compilations: the shared call's lanes, and one lane alone)
def test_distinct_distortions_batched_in_one_call_equal_each_alone(split):
    """Several distinct distortions of one frame shape (level 0, drops, bursts) and two settings,
    batched into shared calls (``batch.run(frame_of=...)``: each tracking lane on its own frames,
    calls padded to one lane count) from too few track slots (the calls grow): every lane's ids,
    rows (``rows_only`` too), counters and capacity == the lane tracked alone."""
    lanes = [distort.level_params("none", 0.0, seed=0), distort.level_params("drop", 0.2, seed=0),
             distort.level_params("drop", 0.5, seed=0), distort.level_params("burst", 4.0, seed=2, burst_rate=0.1)]
    b = len(lanes)
    p = AParams(np.r_[np.full(b, -0.2), np.full(b, 0.01)], np.r_[np.full(b, 3), np.full(b, 1)],
                np.full(2 * b, 2), np.full(2 * b, -1e4))
    dps = distort.stack_distort(lanes + lanes)
    options = AOptions(metric="giou_3d", algorithm="greedy", capacity=4)
    res = af.track(split, p, options, distortion=dps, lanes_per_call=3)
    rows = af.track(split, p, options, distortion=dps, lanes_per_call=3, rows_only=True, spec=res.distortion.spec)
    assert len(set(res.capacity.tolist())) > 1                 # (lanes grew apart)
    for f in ("boxes", "box3"):
        want = Rows.of(res.ids, getattr(res, f))
        np.testing.assert_array_equal(getattr(rows, f).values, want.values)
        np.testing.assert_array_equal(getattr(rows, f).start, want.start)
    for lane in range(2 * b):
        one = AParams(*(v[lane] for v in p))
        alone = af.track(split, one, options, distortion=distort.stack_distort([lanes[lane % b]]),
                         spec=res.distortion.spec)
        for f in ("peak", "overflow", "capacity", "dropped"):
            np.testing.assert_array_equal(np.asarray(getattr(res, f))[lane], np.asarray(getattr(alone, f))[0])
        mine, own = np.asarray(res.ids)[lane], np.asarray(alone.ids)[0]
        for f in ("ids", "src3", "box3", "boxes"):
            np.testing.assert_array_equal(np.asarray(getattr(res, f))[lane][mine >= 0],
                                          np.asarray(getattr(alone, f))[0][own >= 0])
        got, want = af.rows(split, res, lanes=[lane]), af.rows(split, alone)
        for f in ("t", "ids", "box", "score", "box3d"):
            np.testing.assert_array_equal(getattr(got, f), getattr(want, f))
