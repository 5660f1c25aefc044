"""``dfrmot tune``: batched ask/tell on a real Optuna study, resume after kill -9, nested
cross-validation that never sees the held-out sequences, multi-objective Pareto fronts, the CLI."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import dfrmot_jax.tuning.study as study
from dfrmot_jax.cli import main
from dfrmot_jax.sweep import SweepConfigError, load_results, sweep_report
from dfrmot_jax.synthetic import make_scene
from dfrmot_jax.testing.cli import kill_when
from dfrmot_jax.tuning import load_tune, run_tune
from dfrmot_jax.tuning.plots import pareto_front


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    return make_scene(tmp_path_factory.mktemp("tune") / "scene", n_sequences=4, n_frames=120, n_cars=6, seed=5)


def _tune_text(root: Path, budget=12, batch=4, extra="", sampler="tpe", objectives='["HOTA"]') -> str:
    return f"""
name = "tune_test"
[data]
root = "{root}"
det2d = "synth2d"
det3d = "synth3d"
[params]
a_l = {{loguniform = [2.0, 12.0]}}
score_2d = {{uniform = [0.2, 0.7]}}
epsilon = {{randint = [2, 31]}}
[options]
output = ["detections", "filtered"]
[tune]
sampler = "{sampler}"
budget = {budget}
batch = {batch}
seed = 3
objectives = {objectives}
{extra}
"""


def _write(tmp_path: Path, text: str, name="tune.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def _quiet(**kw):
    return dict(progress=False, workers=0, log=lambda m: None, **kw)


@pytest.mark.slow
def test_each_batch_is_one_call_and_the_baseline_is_trial_0(scene, tmp_path, monkeypatch):
    calls = []
    real = study.run_sweep

    def counting(spec, out=None, **kw):
        calls.append(len(kw["table"]))
        return real(spec, out, **kw)

    monkeypatch.setattr(study, "run_sweep", counting)          # the tune's one call per batch
    res = run_tune(_write(tmp_path, _tune_text(scene)), tmp_path / "out", **_quiet())
    assert calls == [4, 4, 4]                         # budget 12 in batches of 4: three batched calls
    assert len(res.trials) == 12 and list(res.trials["batch"]) == [0] * 4 + [1] * 4 + [2] * 4
    first = res.trials.iloc[0]
    assert first["baseline"] and first["a_l"] == 8.0 and first["output"] == "detections"
    comb = res.table[res.table["sequence"] == "COMBINED"]
    assert len(comb) == comb["config_hash"].nunique() == 12
    assert comb.iloc[0]["baseline"] and comb.iloc[0]["trial"] == 0
    assert res.best_value == comb["HOTA"].max()
    assert res.summary()["in_sample"] >= res.summary()["baseline"]
    # the tidy store: per sequence + COMBINED, config and versions in every row; report reads it
    assert set(res.table["sequence"]) == {"0000", "0001", "0002", "0003", "COMBINED"}
    assert {"trial", "batch", "sampler", "dfrmot_jax_version", "jax_version", "a_l"} <= set(res.table.columns)
    pd.testing.assert_frame_equal(load_results(tmp_path / "out"), pd.read_parquet(tmp_path / "out" / "results.parquet"))
    rep = sweep_report(tmp_path / "out")
    assert f"{res.best_value:.2f}" in rep.text
    assert rep.text.startswith("tune ")             # a tune directory's report is headed so (was "sweep ...")
    assert (tmp_path / "out" / "plots" / "history.png").is_file()


@pytest.mark.slow
def test_an_interrupted_batch_is_asked_again_and_the_table_is_unchanged(scene, tmp_path):
    """A kill while a batch was being asked (trials RUNNING, no batch record): they are failed and the
    batch re-asked with the same seeded sampler; the final table equals an uninterrupted run's."""
    import optuna
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend

    path = _write(tmp_path, _tune_text(scene, budget=8, batch=4))
    clean = run_tune(path, tmp_path / "clean", **_quiet())
    out = tmp_path / "cut"
    run_tune(path, out, budget=4, **_quiet())              # the first batch only of the same tune
    study = optuna.load_study(study_name="tune", storage=JournalStorage(JournalFileBackend(str(out / "journal.log"))))
    from dfrmot_jax.tuning.space import search_space

    spec, _ = load_tune(path)
    for i in range(2):                                     # a batch killed half-asked
        t = study.ask(search_space(spec).distributions())
        t.set_user_attr("batch", 1)
        t.set_user_attr("slot", i)
        t.set_user_attr("phase", "search")
    resumed = run_tune(path, out, **_quiet())
    pd.testing.assert_frame_equal(resumed.table, clean.table)
    pd.testing.assert_frame_equal(resumed.trials, clean.trials)
    states = [t.state.name for t in resumed.study.get_trials()]
    assert states.count("FAIL") == 2 and states.count("RUNNING") == 0


@pytest.mark.slow
@pytest.mark.skipif(sys.platform == "win32", reason="SIGKILL")
def test_kill_9_during_a_tune_then_rerun_gives_the_same_table(scene, tmp_path):
    path = _write(tmp_path, _tune_text(scene, budget=16, batch=4))
    out = tmp_path / "killed"
    cmd = [sys.executable, "-m", "dfrmot_jax.cli", "tune", str(path), "--out", str(out), "--workers", "0",
           "--no-progress"]
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    kill_when(proc, (out / "batches" / "0001.json").is_file, timeout=300)    # batch 1 asked, being evaluated
    proc.wait(timeout=60)
    log = proc.stdout.read().decode()
    assert proc.returncode == -signal.SIGKILL, f"not killed mid-run (rc {proc.returncode}):\n{log}"
    assert not (out / "results.parquet").exists()
    rerun = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)
    assert rerun.returncode == 0, rerun.stdout + rerun.stderr
    clean = run_tune(path, tmp_path / "clean", **_quiet())
    pd.testing.assert_frame_equal(pd.read_parquet(out / "results.parquet"), clean.table)
    pd.testing.assert_frame_equal(pd.read_parquet(out / "trials.parquet"), clean.trials)
    summary = json.loads(rerun.stdout.strip().splitlines()[-1])
    assert summary["evaluated_configs"] == clean.table["config"].nunique()


@pytest.mark.slow
def test_nested_cv_tunes_without_the_held_out_sequences(scene, tmp_path):
    res = run_tune(_write(tmp_path, _tune_text(scene, budget=6, batch=3)), tmp_path / "n", folds=2, **_quiet())
    n = res.nested
    assert n["folds"] == 2 and sorted(s for f in n["fold_sequences"] for s in f) == ["0000", "0001", "0002", "0003"]
    for f, test in enumerate(n["fold_sequences"]):
        seen = set(pd.read_parquet(tmp_path / "n" / f"fold_{f}" / "results.parquet")["sequence"]) - {"COMBINED"}
        assert seen and not seen & set(test), (f, seen, test)    # the inner tune never saw its held-out fold
    held = pd.read_parquet(tmp_path / "n" / "heldout" / "results.parquet") if \
        (tmp_path / "n" / "heldout" / "results.parquet").is_file() else None
    assert held is None or set(held["sequence"]) >= {"0000", "0003"}
    assert 0 < n["cross_validated"] <= 100 and 0 < n["baseline"] <= 100
    assert json.loads((tmp_path / "n" / "nested.json").read_text())["cross_validated"] == n["cross_validated"]
    # the pooled figure lies between the folds' held-out figures' extremes (it combines them)
    lo, hi = min(p["held_out"] for p in n["per_fold"]), max(p["held_out"] for p in n["per_fold"])
    assert lo - 1e-9 <= n["cross_validated"] <= hi + 1e-9


@pytest.mark.slow
def test_two_objectives_give_a_pareto_front(scene, tmp_path):
    res = run_tune(_write(tmp_path, _tune_text(scene, budget=8, batch=4, sampler="nsga2",
                                               objectives='["HOTA", "IDSW"]')), tmp_path / "mo", **_quiet())
    assert res.settings.directions == ("maximize", "minimize")
    front = res.pareto
    v = res.trials[["HOTA", "IDSW"]].to_numpy()
    for h, s in front[["HOTA", "IDSW"]].to_numpy():
        assert not np.any((v[:, 0] >= h) & (v[:, 1] <= s) & ((v[:, 0] > h) | (v[:, 1] < s)))
    dominated = res.trials[~res.trials["trial"].isin(front["trial"])]
    for h, s in dominated[["HOTA", "IDSW"]].to_numpy():
        assert np.any((front["HOTA"] >= h) & (front["IDSW"] <= s))
    assert (tmp_path / "mo" / "plots" / "pareto.png").is_file()


def test_pareto_front_unit():
    from dfrmot_jax.tuning.settings import TuneSettings

    t = pd.DataFrame({"trial": [0, 1, 2, 3], "HOTA": [80.0, 82.0, 81.0, 82.0], "IDSW": [10, 20, 30, 15]})
    front = pareto_front(t, TuneSettings(objectives=("HOTA", "IDSW")))
    assert list(front["trial"]) == [3, 0]


@pytest.mark.slow
def test_refinement_runs_as_batched_steps_and_is_recorded(scene, tmp_path):
    extra = "[tune.refine]\nsteps = 2\npairs = 2\npatience = 2\n"
    res = run_tune(_write(tmp_path, _tune_text(scene, budget=4, batch=4, extra=extra)), tmp_path / "r", **_quiet())
    assert res.refinement is not None and 1 <= len(res.refinement.steps) <= 2
    refine_rows = res.trials[res.trials["phase"] == "refine"]
    assert len(refine_rows) == 5 * len(res.refinement.steps)      # centre + 2 x 2 samples per step
    assert res.best_value >= res.trials.loc[res.trials["phase"] == "search", "HOTA"].max()


@pytest.mark.parametrize("tune_table, key", [
    ('sampler = "annealing"', "tune.sampler"),
    ('objectives = ["HOTAA"]', "tune.objectives"),
    ('budget = 1', "tune.budget"),
    ('bogus = 1', "tune.bogus"),
    ('objectives = ["HOTA", "IDSW"]\n[tune.refine]\nsteps = 2', "tune.refine"),
    ('[tune.transfer]\nbaseline = {a_l = 4.0}', "tune.transfer"),
    ('[tune.transfer]\ndet3d = "synth3d"\nbaseline = {a_ll = 4.0}', "tune.transfer.baseline.a_ll"),
])
def test_bad_tune_tables_name_the_key(scene, tmp_path, capsys, tune_table, key):
    text = _tune_text(scene).split("[tune]")[0] + "[tune]\n" + tune_table + "\n"
    path = _write(tmp_path, text)
    with pytest.raises(SweepConfigError) as e:
        load_tune(path)
    assert e.value.key == key
    assert main(["tune", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert key in err and "Traceback" not in err


@pytest.mark.slow
def test_cli_tune_prints_the_summary_and_refuses_another_tunes_directory(scene, tmp_path, capsys):
    path = _write(tmp_path, _tune_text(scene, budget=4, batch=4))
    assert main(["tune", str(path), "--out", str(tmp_path / "c"), "--no-progress", "--workers", "0"]) == 0
    out = capsys.readouterr().out
    summary = json.loads(out.strip().splitlines()[-1])
    assert summary["evaluated_configs"] == 4 and summary["sampler"] == "tpe"
    other = _write(tmp_path, _tune_text(scene, budget=4, batch=2), "other.toml")
    assert main(["tune", str(other), "--out", str(tmp_path / "c"), "--no-progress", "--workers", "0"]) == 2
    assert "--force" in capsys.readouterr().err
    stale = tmp_path / "c" / "fold_0" / "journal.log"         # an old nested fold's study must not be resumed
    stale.parent.mkdir()
    stale.write_text("")
    assert main(["tune", str(other), "--out", str(tmp_path / "c"), "--no-progress", "--workers", "0",
                 "--force"]) == 0
    assert not stale.parent.exists()


@pytest.mark.slow
def test_transfer_scores_the_chosen_config_unchanged_beside_the_other_baseline(scene, tmp_path):
    extra = '[tune.transfer]\ndet3d = "synth3d"\nbaseline = {a_l = 3.0}\n'
    res = run_tune(_write(tmp_path, _tune_text(scene, budget=4, batch=4, extra=extra)), tmp_path / "t", **_quiet())
    tr = res.transfer
    comb = res.table[res.table["sequence"] == "COMBINED"]
    # the same detections here: the chosen config scores its in-sample value, and the baseline is the
    # tune's baseline with a_l = 3 (as a sweep of that one change scores it)
    assert tr["chosen"]["HOTA"] == res.best_value
    assert tr["baseline_params"] == {"a_l": 3.0}
    from dfrmot_jax import run_sweep

    sw = run_sweep({"name": "a_l3", "data": {"root": str(scene), "det2d": "synth2d", "det3d": "synth3d"},
                    "params": {"a_l": [3.0]}}, progress=False, workers=0, log=lambda m: None)
    row = sw[(sw["sequence"] == "COMBINED") & (sw["a_l"] == 3.0)].iloc[0]
    assert tr["baseline"]["HOTA"] == row["HOTA"] != comb.loc[comb["baseline"], "HOTA"].iloc[0]
    assert json.loads((tmp_path / "t" / "transfer.json").read_text())["chosen"] == tr["chosen"]
    assert "transfer: the chosen config unchanged on synth2d + synth3d" in sweep_report(tmp_path / "t").text


@pytest.mark.slow      # (the not-slow tier's 3-minute budget)
def test_unstable_fixed_gains_fail_without_a_run_and_do_not_count(scene, tmp_path):
    from dfrmot_jax.trackers.dfr.filters import fixed_gain_radius

    text = _tune_text(scene, budget=4, batch=4).replace(
        'score_2d = {uniform = [0.2, 0.7]}', 'gain_beta = {uniform = [0.02, 0.45]}\ngain_gamma = {uniform = [0.15, 0.4]}')
    res = run_tune(_write(tmp_path, text), tmp_path / "u", **_quiet())
    states = [t.state.name for t in res.study.get_trials()]
    assert states.count("COMPLETE") == 4 and states.count("FAIL") >= 1        # most draws are unstable
    for t in res.study.get_trials():
        p = {**{"gain_alpha": 0.9, "gain_beta": 0.9, "gain_gamma": 0.1}, **t.params}
        stable = fixed_gain_radius(p["gain_alpha"], p["gain_beta"], p["gain_gamma"]) <= 1 + 1e-9
        assert stable == (t.state.name == "COMPLETE")
    assert res.table["config"].nunique() == 4


def test_fixed_gain_radius_says_when_errors_grow():
    import numpy as np

    from dfrmot_jax.trackers.dfr.filters import fixed_gain_radius

    F = np.array([[1.0, 1.0, 0.5], [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]])
    for a, b, g in [(0.9, 0.9, 0.1), (1.0, 0.4, 0.03), (0.97, 0.12, 0.16), (0.55, 0.13, 0.155)]:
        e = np.array([1.0, 0.0, 0.0])
        for _ in range(400):                      # the predicted state's error under the filter, no noise
            e = F @ (e - np.array([a, b, 2 * g]) * e[0])
        grows = np.abs(e).max() > 1e3
        assert grows == (fixed_gain_radius(a, b, g) > 1), (a, b, g)


def test_a_sweep_writing_filtered_boxes_with_unstable_gains_is_refused(scene):
    from dfrmot_jax.sweep import expand

    spec = {"name": "u", "data": {"root": str(scene), "det2d": "synth2d", "det3d": "synth3d"},
            "params": {"gain_beta": [0.9, 0.12], "gain_gamma": [0.1, 0.16]}, "options": {"output": "filtered"}}
    with pytest.raises(SweepConfigError) as e:
        expand(spec)
    assert e.value.key == "params.gain_beta" and "stability" in str(e.value)
    spec["options"]["output"] = "detections"           # raw boxes: finite, the score is the tracker's
    assert len(expand(spec)) == 4


def _variants_text(root: Path, budget: int, batch: int, sampler: str, gamma2="") -> str:
    return f"""
name = "tune_variants"
[data]
root = "{root}"
det2d = "synth2d"
det3d = "synth3d"
[params]
a_l = [8.0, 4.0, 2.0]
[options]
output = ["detections", "filtered"]
[[variants]]
name = "code"
params.gain_alpha = 0.9
params.gain_beta = 0.9
params.gain_gamma = 0.1
[[variants]]
name = "low_accel"
params.gain_alpha = 1.0
params.gain_beta = 0.4
params.gain_gamma = [0.03{gamma2}]
[tune]
sampler = "{sampler}"
budget = {budget}
batch = {batch}
seed = 1
"""


@pytest.mark.slow
def test_a_tune_over_variants_and_a_finite_space_spends_its_budget_on_distinct_configs(scene, tmp_path):
    """[[variants]] are one ``variant`` dim (each sets its one-valued gains); the space has 3 x 2 x 2 =
    12 points and random draws repeat them: repeats are refused (FAIL, phase "repeat") and the budget of
    10 buys 10 distinct configs; a budget beyond the space ends with repeats kept after REPEAT_ASKS."""
    from dfrmot_jax.tuning.space import search_space

    spec, _ = load_tune(_write(tmp_path, _variants_text(scene, 10, 10, "random")))
    space = search_space(spec)
    assert space.dims[-1].name == "variant" and space.dims[-1].values == ("code", "low_accel")
    assert space.baseline_values()["variant"] == "code"           # dfr2023's gains are the "code" variant's
    res = run_tune(tmp_path / "tune.toml", tmp_path / "v", **_quiet())
    assert len(res.trials) == 10 and res.table["config_hash"].nunique() == 10
    assert res.trials.iloc[0]["baseline"] and res.trials.iloc[0]["variant"] == "code"
    comb = res.table[res.table["sequence"] == "COMBINED"]
    low = comb[comb["variant"] == "low_accel"]
    assert len(low) and (low[["gain_alpha", "gain_beta", "gain_gamma"]].to_numpy() == [1.0, 0.4, 0.03]).all()
    assert np.allclose(comb.loc[comb["variant"] == "code", "gain_beta"], 0.9)
    repeats = [t for t in res.study.get_trials() if t.user_attrs.get("phase") == "repeat"]
    assert repeats and all(t.state.name == "FAIL" for t in repeats)
    # more budget than points: the 12 points once each, then repeats are kept (looked up, not run)
    over = run_tune(_write(tmp_path, _variants_text(scene, 13, 13, "random"), "over.toml"), tmp_path / "o", **_quiet())
    assert len(over.trials) == 13 and over.table["config_hash"].nunique() == 12


def test_variants_must_search_the_same_axes(scene, tmp_path, capsys):
    path = _write(tmp_path, _variants_text(scene, 4, 4, "tpe", gamma2=", 0.05"))
    assert main(["tune", str(path), "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert "variants.low_accel" in err and "same axes" in err and "Traceback" not in err


def test_pairwise_sampler_finds_the_optimum_of_an_interacting_objective():
    """A real Optuna study, batched ask / tell: 8 settings (two of three levels), an objective with
    main effects and two interactions whose optimum is not the best of each setting on its own; the
    first batch is random, then each batch is the best predicted unasked points: the optimum of the
    2 ** 6 x 3 ** 2 = 576 points is found within 96 trials, the model never asks a point twice."""
    import optuna
    from optuna.distributions import CategoricalDistribution

    from dfrmot_jax.tuning.pairwise import pairwise_sampler

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    levels = [2, 2, 3, 2, 2, 3, 2, 2]
    dists = {f"x{i}": CategoricalDistribution(list(range(k))) for i, k in enumerate(levels)}
    rng = np.random.default_rng(0)
    main_eff = [rng.normal(size=k) for k in levels]

    def f(p):
        v = [p[f"x{i}"] for i in range(len(levels))]
        return sum(m[x] for m, x in zip(main_eff, v)) + 3.0 * (v[0] == 1) * (v[2] == 2) - 2.5 * (v[1] == v[3])

    import itertools
    best = max(f({f"x{i}": x for i, x in enumerate(c)}) for c in itertools.product(*[range(k) for k in levels]))
    study = optuna.create_study(direction="maximize")
    seen = []
    for b in range(6):
        study.sampler = pairwise_sampler(dists, seed=b, n_startup=16)
        ts = [study.ask(dists) for _ in range(16)]
        for t in ts:
            seen.append(tuple(t.params.values()))
            study.tell(t.number, f(t.params))
    assert len(set(seen)) == len(set(seen[:16])) + 80       # the model's 80 asks: each a new point
    assert study.best_value == best
    with pytest.raises(ValueError, match="lists, grids or integer ranges"):
        pairwise_sampler({"a": optuna.distributions.FloatDistribution(0, 1)}, 0, 4)


def test_pairwise_sampler_refuses_a_continuous_dim_naming_its_key(scene, tmp_path, capsys):
    path = _write(tmp_path, _tune_text(scene, sampler="pairwise"))
    assert main(["tune", str(path), "--out", str(tmp_path / "p")]) == 2
    err = capsys.readouterr().err
    assert "params.a_l" in err and "pairwise" in err and "Traceback" not in err


@pytest.mark.slow
def test_a_baseline_outside_the_space_is_said_not_printed_as_nan(scene, tmp_path, capsys):
    """A tune whose space leaves the baseline out (its ``[[variants]]`` fix gains that dfr2023 does not
    have, so the baseline is no trial) says so, rather than printing its value as NaN; its report gives
    the trials it ran (a tune's identity holds no budget)."""
    from dfrmot_jax.testing.cli import run_cli

    f = tmp_path / "t.toml"
    variants = ('\n[[variants]]\nname = "low"\nparams.gain_beta = 0.4\n[[variants]]\nname = "mid"\n'
                'params.gain_beta = 0.6\n')
    text = _tune_text(scene, budget=4, batch=4)
    f.write_text(text.replace("[tune]", variants + "[tune]"))
    status, out, err = run_cli(capsys, ["tune", f, "--out", tmp_path / "t", "--no-progress"])
    assert status == 0, err
    line = next(s for s in out.splitlines() if s.startswith("best HOTA"))
    assert "nan" not in line and "the baseline lies outside the search space" in line
    status, out, err = run_cli(capsys, ["report", tmp_path / "t"])
    assert status == 0, err
    tune_line = next(s for s in out.splitlines() if s.startswith("tune: sampler"))
    assert "None" not in tune_line and " trials in batches of 4" in tune_line
