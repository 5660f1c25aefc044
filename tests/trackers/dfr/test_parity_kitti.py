"""On the KITTI training split: the published output line for line, and JAX == the NumPy oracle."""


import numpy as np
import pytest

from dfrmot_jax.trackers.dfr.track import track
from dfrmot_jax.cli import main
from dfrmot_jax.data import load_sequences, pack, sequences_with_class
from dfrmot_jax.io.kitti import read_tracking_labels
from dfrmot_jax.trackers.dfr.filters import steady_state
from dfrmot_jax.trackers.dfr.config import Options, Params, preset, stack_params
from dfrmot_jax.testing.parity import lane_mismatches, reference_pool, reference_rows
from dfrmot_jax.testing import random_options, random_params

REFERENCE = "reference/dfr_fastmot_rrc_pointrcnn"


def _lines(path):
    t = read_tracking_labels(path)
    return list(zip(t.frame.tolist(), t.track_id.tolist(), *(t.box[:, k].tolist() for k in range(4))))


@pytest.mark.slow
def test_dfr2023_reproduces_the_published_output_line_for_line(kitti_root, tmp_path):
    assert main(["track", "--data", str(kitti_root), "--det2d", "rrc", "--det3d", "pointrcnn",
                 "--preset", "dfr2023", "--class", "car", "--out", str(tmp_path)]) == 0
    seqs = sequences_with_class(kitti_root, "car")
    assert len(seqs) == 20 and "0017" not in seqs
    total = 0
    for s in seqs:
        ours, theirs = _lines(tmp_path / f"{s}.txt"), _lines(kitti_root / REFERENCE / f"{s}.txt")
        assert ours == theirs, f"sequence {s} differs"
        total += len(theirs)
    assert total == 28812


def test_dfr2023_authors_columns_are_byte_identical_to_the_published_files(kitti_root, tmp_path):
    assert main(["track", "--data", str(kitti_root), "--preset", "dfr2023", "--columns", "authors",
                 "--out", str(tmp_path)]) == 0
    seqs = sequences_with_class(kitti_root, "car")
    lines = 0
    for s in seqs:
        ours, theirs = (tmp_path / f"{s}.txt").read_bytes(), (kitti_root / REFERENCE / f"{s}.txt").read_bytes()
        assert ours == theirs, f"sequence {s} differs"
        lines += theirs.count(b"\n")
    assert (len(seqs), lines) == (20, 28812)


@pytest.mark.slow
def test_dfr2023_output_scores_the_published_figures_with_trackeval(kitti_root, tmp_path):
    compat = pytest.importorskip("dfrmot_jax.testing.trackeval_adapter")
    pytest.importorskip("trackeval")
    assert main(["track", "--data", str(kitti_root), "--preset", "dfr2023", "--out", str(tmp_path / "ours")]) == 0
    from dfrmot_jax.io.kitti import sequence_lengths

    seqs = sequences_with_class(kitti_root, "car")
    gt = compat.make_gt_folder(tmp_path / "gt", kitti_root, sequence_lengths(kitti_root, seqs))
    compat.make_tracker_folder(tmp_path / "trackers", "ours", {s: tmp_path / "ours" / f"{s}.txt" for s in seqs}, seqs)
    combined = compat.run_trackeval(gt, tmp_path / "trackers", "car")["ours"]["COMBINED"]
    assert round(100 * float(np.mean(combined["HOTA"])), 2) == 82.79
    assert round(100 * float(combined["MOTA"]), 2) == 90.73
    assert int(combined["IDSW"]) == 177


@pytest.fixture(scope="module")
def pool():
    with reference_pool(2) as p:
        yield p


@pytest.fixture(scope="module")
def all21(kitti_root):
    names = [f"{i:04d}" for i in range(21)]
    seqs = load_sequences(kitti_root, "rrc", "pointrcnn", "car", names)
    return seqs, pack(seqs)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["dfr2023", "dfr_head"])
def test_presets_match_the_reference_on_all_21_sequences(all21, pool, name):
    seqs, split = all21
    params, options = preset(name)
    res = track(split, stack_params([params]), options)
    mm = lane_mismatches(split, res, 0, reference_rows(seqs, params, options, pool))
    assert mm["lines"] > 28812  # 0017 has detections too
    assert (mm["missing"], mm["extra"], mm["id"], mm["box"]) == (0, 0, 0, 0), mm


@pytest.mark.slow
def test_random_settings_match_the_reference_on_all_21_sequences(all21, pool):
    """16 random settings: 4 random static option sets x 4 random parameter draws (one batch each),
    JAX tracking all 21 sequences in that one call. The NumPy oracle (most of the time) checks the
    k-th setting id for id on a rotating third of the sequences (those with index = k mod 3): each
    sequence is compared under >= 5 settings and under every one of the 4 option sets (4
    consecutive settings cover the 3 residues), so no sequence and no option set goes unchecked."""
    seqs, split = all21
    rng = np.random.default_rng(2023)
    seen = np.zeros((4, len(seqs)), int)                # (option set, sequence): settings compared
    for j in range(4):
        options = random_options(rng)
        settings = [random_params(rng, options.output) for _ in range(4)]
        res = track(split, stack_params(settings), options)
        for b, params in enumerate(settings):
            k = 4 * j + b
            third = [s for s in range(len(seqs)) if s % 3 == k % 3]
            ref = reference_rows([seqs[s] for s in third], params, options, pool)
            mm = lane_mismatches(split, res, b, ref, sequences=third)
            assert mm["lines"] > 0
            assert (mm["missing"], mm["extra"], mm["id"], mm["box"]) == (0, 0, 0, 0), (options, params, third, mm)
            seen[j, third] += 1
    assert (seen > 0).all() and seen.sum(0).min() >= 5, seen


def _links(split, ids):
    out = set()
    for s in range(len(split.names)):
        lane = ids[split.sequence_slice(s)]
        last = {}
        for t in range(lane.shape[0]):
            for k in np.flatnonzero(lane[t] >= 0):
                if lane[t, k] in last:
                    out.add((s, last[lane[t, k]], (t, k)))
                last[lane[t, k]] = (t, k)
    return out


@pytest.mark.slow
def test_steady_kalman_tracks_like_its_fixed_gain_twin(kitti_root):
    """With noise whose steady-state gains are (a, b, g), the Kalman filter links detections like the
    fixed-gain filter with gains (a, b, g) - more so than like other gains. Not identically: during
    occlusion gaps its covariance grows, so it re-acquires with a larger gain."""
    split = pack(load_sequences(kitti_root, "rrc", "pointrcnn", "car"))
    q, r = 0.1, 1.0
    (ga, gb, gg), _ = steady_state(q, r)
    kal = track(split, stack_params([Params(kf_q=q, kf_r=r)]), Options(filter="kalman", kalman_init="steady")).ids[0]
    fixed = track(split, stack_params([Params(gain_alpha=ga, gain_beta=gb, gain_gamma=gg), Params(),
                                       Params(gain_alpha=0.5, gain_beta=0.3, gain_gamma=0.05)]), Options()).ids
    k = _links(split, kal)
    jac = [len(k & f) / len(k | f) for f in (_links(split, fixed[i]) for i in range(3))]
    assert jac[0] >= 0.99 and jac[0] > jac[1] and jac[0] > jac[2], jac
