"""The Hungarian assignment option (``Options.assign = "hungarian"``): the optimal matching equals
SciPy's on gated matrices, the tracker equals the oracle id for id, and the option reaches the CLI,
the sweep files and the config hash (an old config keeps its hash)."""

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd
import pytest
from scipy.optimize import linear_sum_assignment

from dfrmot_jax.trackers.dfr.track import track
from dfrmot_jax.cli import main
from dfrmot_jax.trackers.dfr.config import ASSIGNS, Options, Params, parse_assignment, preset, stack_params
from dfrmot_jax.trackers.dfr import associate
from dfrmot_jax.data import load_sequences, pack
from dfrmot_jax.io.kitti import read_tracking_labels
from dfrmot_jax.sweep import SweepConfigError, config_hash, expand
from dfrmot_jax.synthetic import make_scene
from dfrmot_jax.testing import random_options, random_params, reference
from dfrmot_jax.testing.parity import lane_mismatches, reference_rows
from dfrmot_jax.testing.recompile import no_recompile

HUNGARIAN = Options(assign="hungarian")
hungarian_min = jax.jit(associate.hungarian_min)


# ---- the matching ----------------------------------------------------------------------------------


def _padded_problem(rng, n, m, shape=(8, 10), gated=0.3):
    """An n x m problem of continuous costs in the corner of a padded matrix (padding invalid)."""
    cost = np.ones(shape)
    valid = np.zeros(shape, bool)
    cost[:n, :m] = rng.random((n, m))
    valid[:n, :m] = rng.random((n, m)) >= gated
    return cost, valid


def _scipy_pairs(cost, valid, limit):
    """Pairs of the largest total margin limit - cost over pairs with cost < limit, straight from SciPy."""
    gain = np.where(valid & (cost < limit), limit - cost, 0.0)
    rows, cols = linear_sum_assignment(gain, maximize=True)
    return {(int(i), int(j)) for i, j in zip(rows, cols) if gain[i, j] > 0}


def _pairs(match):
    return {(int(i), int(j)) for i, j in zip(*np.nonzero(np.asarray(match)))}


@pytest.mark.parametrize("seed", range(6))
def test_hungarian_min_equals_scipy_on_gated_matrices(seed):
    rng = np.random.default_rng(seed)
    with jax.enable_x64(True):
        for n, m in [(8, 10), (3, 9), (8, 2), (5, 5), (1, 7), (0, 4), (6, 0)]:
            cost, valid = _padded_problem(rng, n, m)
            limit = float(rng.uniform(0.3, 1.0))
            got = _pairs(hungarian_min(jnp.asarray(cost), jnp.asarray(valid), limit))
            assert got == _scipy_pairs(cost[:n, :m], valid[:n, :m], limit), (n, m, limit)
            # the oracle's own matching (SciPy on the live rows and columns only) is the same
            ref = reference.hungarian_match(np.where(valid, cost, np.inf)[:n, :m], limit) if n and m else []
            assert set(ref) == got


def test_all_gated_matches_nothing():
    rng = np.random.default_rng(1)
    cost, valid = _padded_problem(rng, 8, 10, gated=0.0)
    with jax.enable_x64(True):
        assert not np.any(hungarian_min(jnp.asarray(cost), jnp.asarray(valid), 0.0))          # every cost >= 0
        assert not np.any(hungarian_min(jnp.asarray(cost), jnp.zeros_like(jnp.asarray(valid)), 2.0))
    assert reference.hungarian_match(cost, 0.0) == []


@pytest.mark.slow
def test_hungarian_takes_the_best_total_where_greedy_does_not():
    # greedy takes 0.9 first and leaves (1, 1) below the gate; the optimum pairs 0.8 + 0.7
    m_f = np.array([[0.9, 0.8], [0.7, 0.0]])
    valid = np.ones((2, 2), bool)
    with jax.enable_x64(True):
        greedy = associate.greedy_min(jnp.asarray(-m_f), jnp.asarray(valid), jnp.arange(2, dtype=jnp.int32), 0.0)
        best = hungarian_min(jnp.asarray(-m_f), jnp.asarray(valid), 0.0)
    assert _pairs(greedy) == {(0, 0)}
    assert _pairs(best) == {(0, 1), (1, 0)} == set(reference.hungarian_match(-m_f, 0.0))


def test_ties_still_give_an_optimal_total():
    """With few distinct costs several matchings can be optimal: the two solvers may pick different
    ones (README), but both reach the same total."""
    rng = np.random.default_rng(7)
    with jax.enable_x64(True):
        for _ in range(40):
            cost, valid = _padded_problem(rng, 6, 7)
            cost[:6, :7] = rng.integers(0, 3, (6, 7)) / 3
            got = _pairs(hungarian_min(jnp.asarray(cost), jnp.asarray(valid), 0.9))
            want = _scipy_pairs(cost[:6, :7], valid[:6, :7], 0.9)
            assert sum(0.9 - cost[p] for p in got) == pytest.approx(sum(0.9 - cost[p] for p in want), abs=1e-12)


@pytest.mark.slow
def test_hungarian_min_under_vmap_matches_each_lane():
    rng = np.random.default_rng(3)
    probs = [_padded_problem(rng, int(rng.integers(0, 9)), int(rng.integers(0, 11))) for _ in range(5)]
    cost, valid = np.stack([p[0] for p in probs]), np.stack([p[1] for p in probs])
    limits = rng.uniform(0.3, 1.0, 5)
    with jax.enable_x64(True):
        batched = jax.vmap(associate.hungarian_min)(cost, valid, limits)
        for b in range(5):
            np.testing.assert_array_equal(batched[b], hungarian_min(cost[b], valid[b], limits[b]))


# ---- the tracker against the oracle ----------------------------------------------------------------


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """A crowded, noisy scene (on the default one the optimal matching is nearly always greedy's)."""
    root = make_scene(tmp_path_factory.mktemp("scene"), n_sequences=2, n_frames=100, n_cars=12, seed=3,
                      det2d_fp_rate=3.0, det3d_fp_rate=3.0, det2d_box_sigma=0.12, det3d_pos_sigma=0.6)
    seqs = load_sequences(root, "synth2d", "synth3d", "car")
    return root, seqs, pack(seqs)


def _assert_parity(split, seqs, settings, options) -> int:
    """Tracker == oracle id for id and box for box on every lane with assign="hungarian"; returns
    how many lanes the oracle tracks differently with greedy assignment (the option is not ignored)."""
    best = options._replace(assign="hungarian")
    res = track(split, stack_params(settings), best)
    differ = 0
    for b, params in enumerate(settings):
        ref = reference_rows(seqs, params, best)
        mm = lane_mismatches(split, res, b, ref)
        assert mm["lines"] > 0
        assert (mm["missing"], mm["extra"], mm["id"], mm["box"]) == (0, 0, 0, 0), (options, params, mm)
        greedy = reference_rows(seqs, params, options._replace(assign="greedy"))
        differ += [[r[:6] for r in rows] for rows in ref] != [[r[:6] for r in rows] for rows in greedy]
    return differ


def _untied(params: Params) -> Params:
    """a_f >= 0: with a_f < 0 every pair without evidence passes the gate with the same margin,
    and equal totals make the solvers' choices differ (README)."""
    return params._replace(a_f=abs(params.a_f))


@pytest.mark.slow
def test_tracker_with_hungarian_matches_the_oracle_and_does_not_recompile(scene):
    _, seqs, split = scene
    rng = np.random.default_rng(17)
    settings = [preset("dfr2023")[0]] + [_untied(random_params(rng))._replace(score_2d=0.45, score_3d=4.0)
                                         for _ in range(3)]
    assert _assert_parity(split, seqs, settings, Options()) >= 3
    with no_recompile():   # new values, same score thresholds: the same capacity and program
        track(split, stack_params([s._replace(a_l=s.a_l + 1.0, a_f=0.1) for s in settings]), HUNGARIAN)


@pytest.mark.slow
def test_random_options_with_hungarian_match_the_oracle(scene):
    _, seqs, split = scene
    rng = np.random.default_rng(4)
    options = random_options(rng)
    assert options != Options()._replace(kalman_init=options.kalman_init)
    assert _assert_parity(split, seqs, [_untied(random_params(rng, options.output)) for _ in range(3)], options) >= 2


#: two short sequences where the optimal matching differs from greedy's with dfr2023
KITTI_SEQS = ["0004", "0014"]


@pytest.mark.slow
def test_kitti_sequences_with_hungarian_match_the_oracle(kitti_root):
    seqs = load_sequences(kitti_root, "rrc", "pointrcnn", "car", KITTI_SEQS)
    split = pack(seqs)
    params, options = preset("dfr2023")
    rng = np.random.default_rng(5)
    settings = [params, params._replace(a_l=5.0, score_2d=0.3, a_f=0.1), _untied(random_params(rng))]
    assert _assert_parity(split, seqs, settings, options) >= 2


# ---- the option: validation, CLI, sweep files, config hash -----------------------------------------


def test_option_defaults_to_greedy_and_is_validated():
    assert Options().assign == "greedy" and ASSIGNS == ("greedy", "hungarian")
    assert parse_assignment("assign=hungarian", Params(), Options())[1] == HUNGARIAN
    with pytest.raises(ValueError, match="assign"):
        Options(assign="optimal").validate()


@pytest.mark.slow
def test_cli_track_with_hungarian(tmp_path, capsys):
    root = make_scene(tmp_path / "scene", n_sequences=1, n_frames=60, seed=4)
    base = ["track", "--data", str(root), "--det2d", "synth2d", "--det3d", "synth3d"]
    assert main(base + ["--set", "assign=hungarian", "--out", str(tmp_path / "h")]) == 0
    assert read_tracking_labels(tmp_path / "h" / "0000.txt").frame.size > 0
    capsys.readouterr()
    assert main(base + ["--set", "assign=optimal", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("dfrmot track: error: ") and "Traceback" not in err[0]
    assert "assign" in err[0] and "hungarian" in err[0]


def test_track_help_lists_the_option(capsys):
    with pytest.raises(SystemExit) as e:
        main(["track", "--help"])
    assert e.value.code == 0
    line = next(s for s in capsys.readouterr().out.splitlines() if s.strip().startswith("assign "))
    assert "greedy | hungarian" in line


def test_sweep_axis_and_hash():
    plain = expand({"params": {"a_l": [4.0, 8.0]}})
    both = expand({"params": {"a_l": [4.0, 8.0]}, "options": {"assign": ["greedy", "hungarian"]}})
    assert len(both) == 4 and both["config_hash"].is_unique
    greedy = both[both["assign"] == "greedy"]
    assert greedy["config_hash"].tolist() == plain["config_hash"].tolist()   # the default leaves the hash as it was
    row = plain.iloc[0].to_dict()
    assert config_hash({**row, "assign": "hungarian"}) != config_hash(row)
    assert config_hash({k: v for k, v in row.items() if k != "assign"}) == config_hash(row)
    with pytest.raises(SweepConfigError, match=r"options\.assign\[1\]"):
        expand({"options": {"assign": ["greedy", "optimal"]}})


@pytest.mark.slow
def test_sweep_over_assign_and_chunks_written_before_the_option(tmp_path):
    """A sweep over both assignments runs them as two option groups; chunks written before the option
    existed (no ``assign`` column, same hashes and chunk ids) read back as greedy."""
    from dfrmot_jax.sweep import run_sweep
    from dfrmot_jax.report.stored import finish_table

    root = make_scene(tmp_path / "scene", n_sequences=1, n_frames=40, n_cars=6, seed=2, det2d_fp_rate=2.0)
    spec = {"name": "assign", "chunk": 2, "data": {"root": str(root), "det2d": "synth2d", "det3d": "synth3d"},
            "params": {"a_l": [4.0, 8.0]}, "options": {"assign": ["greedy", "hungarian"]}}
    out = tmp_path / "out"
    df = run_sweep(spec, out=out, progress=False, workers=0, log=lambda m: None)
    assert sorted(df.loc[df["sequence"] == "COMBINED", "assign"]) == ["greedy", "greedy", "hungarian", "hungarian"]
    chunks = [pd.read_parquet(p) for p in sorted((out / "chunks").glob("*.parquet"))]
    old = [c.drop(columns="assign") if (c["assign"] == "greedy").all() else c for c in chunks]
    assert sum("assign" not in c.columns for c in old) == 1
    pd.testing.assert_frame_equal(finish_table(pd.concat(old, ignore_index=True))[df.columns], df)
