"""The tracker family protocol (``dfrmot_jax.trackers.protocol``): DFR-FastMOT registered as the first family,
the registries (``family_configs``, ``families``), and the machinery (sweep files, config tables,
chunks, a stored config's result files, tunes) asking the registry for a sweep's family instead of
naming DFR's modules: shown with a second family registered here, DFR's tracker behind counters
under another name with a preset and a narrower range of its own, whose sweep must score exactly
what DFR's does (real tracking and scoring on both sides)."""

from __future__ import annotations

import ast
import importlib
import json
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dfrmot_jax.trackers.dfr import track as api, config, family as dfr, results
from dfrmot_jax.trackers.dfr import run as core_run, step as core_step
from dfrmot_jax.trackers.protocol import DEFAULT_FAMILY, TrackerFamily, config_problems, family_problems
from dfrmot_jax.trackers.registry import CONFIGS, all_presets, family_config, family_names, preset_family
from dfrmot_jax.trackers.registry import FAMILIES, family_of, register, unregister
from dfrmot_jax.sweep import SweepConfigError, config_hash, expand, load_spec, parse_spec, run_sweep
from dfrmot_jax.sweep.config_output import write_config_output
from dfrmot_jax.synthetic import make_scene
from dfrmot_jax.tuning.space import search_space

ROOT = Path(__file__).resolve().parents[2]
SPY = "dfr_spy"
#: the tracker fields the spy family counts calls of
COUNTED = ("track", "prepare_frames", "compact_split", "default_capacity", "output_slots", "class_run", "write_runs",
           "table_problem", "failing_rows")


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    return make_scene(tmp_path_factory.mktemp("family_scene"), n_sequences=2, n_frames=60, n_cars=4, seed=5)


@pytest.fixture
def spy():
    """A second family registered for one test: DFR-FastMOT's tracker under the name ``dfr_spy``,
    each of its counted fields counting its calls, with a preset of its own (``spy_base``, its
    default: a_l 4) and a narrower range (a_l <= 9)."""
    base = config.FAMILY_CONFIG
    calls = dict.fromkeys(COUNTED, 0)

    def counted(name):
        fn = getattr(dfr.FAMILY, name)

        def call(*args, **kwargs):
            calls[name] += 1
            return fn(*args, **kwargs)
        return call

    def param_problem(name, value):
        if name == "a_l" and not isinstance(value, str) and np.any(np.asarray(value, np.float64) > 9):
            return "above 9, the spy family's largest a_l"
        return base.param_problem(name, value)

    presets = {**{k: v for k, v in base.presets.items() if v[0].a_l <= 9},      # (dfr_head's a_l is 10)
               "spy_base": (config.Params(a_l=4.0), config.Options())}

    def preset(name, cls="car"):
        params, options = presets[name]
        return params._replace(**base.class_defaults[cls]), options

    fc = base._replace(name=SPY, title="DFR-FastMOT, counted", presets=presets, default_preset="spy_base",
                       preset=preset, param_problem=param_problem)
    family = register(dfr.FAMILY._replace(config=fc, **{n: counted(n) for n in COUNTED}))
    try:
        yield family, calls
    finally:
        unregister(SPY)
    assert SPY not in FAMILIES and SPY not in CONFIGS


# ---- the protocol and the registries ----------------------------------------------------------------


def test_dfr_is_the_first_family_and_follows_the_protocol():
    fam = family_of()
    assert fam is family_of("dfr") is FAMILIES["dfr"] is dfr.FAMILY and fam.name == DEFAULT_FAMILY == "dfr"
    assert fam.config is family_config() is config.FAMILY_CONFIG is CONFIGS["dfr"]
    assert family_names() == ("dfr", "ab3dmot", "bytetrack") and family_problems(fam) == [] and config_problems(fam.config) == []
    # the family wraps DFR's own code, it does not copy it
    assert (fam.init, fam.step, fam.run_batch) == (core_step.init, core_step.step, core_run.run_batch)
    assert (fam.track, fam.default_capacity) == (api.track, api.default_capacity)
    assert (fam.rows, fam.row_arrays, fam.write_runs) == (results.kitti_rows, results.kitti_row_arrays,
                                                          results.write_runs)
    assert fam.config.Params is config.Params and fam.config.Options is config.Options
    assert fam.config.preset("tuned_both", "pedestrian") == config.preset("tuned_both", "pedestrian")
    assert fam.config.detections == ("2d", "3d")
    assert importlib.import_module(fam.oracle).__name__ == "dfrmot_jax.testing.reference"
    with pytest.raises(ValueError, match=r"unknown tracker family 'nope': expected one of \['dfr', 'ab3dmot', 'bytetrack'\]"):
        family_of("nope")


def test_ab3dmot_is_the_second_family_and_follows_the_protocol():
    """AB3DMOT's family wraps its tracker package (``dfrmot_jax.trackers.ab3dmot``); its settings are read
    without JAX (a fresh interpreter) and the preset names its family."""
    from dfrmot_jax.trackers.ab3dmot import (batch as ab_batch, config as ab_config, family as ab_family, tracker as ab_tracker)
    fam = family_of("ab3dmot")
    assert fam is FAMILIES["ab3dmot"] is ab_family.FAMILY and family_problems(fam) == []
    assert fam.config is CONFIGS["ab3dmot"] is ab_config.FAMILY_CONFIG and fam.config.detections == ("3d",)
    assert (fam.init, fam.step, fam.run_batch) == (ab_tracker.init, ab_tracker.step, ab_batch.run)
    assert fam.box_format == "f6" and family_of().box_format == "g6"
    assert preset_family("ab3dmot_pedestrian") is fam.config and preset_family("tuned_both") is config.FAMILY_CONFIG
    ab = all_presets().index("ab3dmot_car")
    assert all_presets()[:1] == ("dfr2023",) and all_presets()[ab:ab + 4] == (
        "ab3dmot_car", "ab3dmot_pedestrian", "ab3dmot_car_tuned", "ab3dmot_pedestrian_tuned")
    assert all_presets()[-3:] == ("bytetrack_car", "bytetrack_pedestrian", "bytetrack_car_tuned")
    with pytest.raises(ValueError, match="unknown preset 'nope': expected one of .*'ab3dmot_car'"):
        preset_family("nope")
    assert importlib.import_module(fam.oracle).__name__ == "dfrmot_jax.testing.ab3dmot_oracle"
    code = ("import sys; from dfrmot_jax.trackers.registry import family_config; fc = family_config('ab3dmot'); "
            "print(fc.preset('ab3dmot_pedestrian', 'car'), 'jax' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip().endswith("False") and "threshold=-0.4" in out and "algorithm='greedy'" in out
    p, o = fam.config.parse_assignment("metric=m_dis", *fam.config.preset("ab3dmot_car"))
    p, o = fam.config.parse_assignment("max_age=5", p, o)
    assert (o.metric, p.max_age, type(p.max_age)) == ("m_dis", 5, int)
    for bad, why in (("max_age=0", "outside the valid range"), ("min_hits=1.5", "expected an integer"),
                     ("algorithm=hungar", "expected one of"), ("capacity=-1", "from 0 to 4096"),
                     ("nope=1", "unknown; parameters are")):
        with pytest.raises(ValueError, match=why):
            fam.config.parse_assignment(bad, p, o)


def test_the_registry_refuses_a_family_that_breaks_the_protocol():
    broken = dfr.FAMILY._replace(config=config.FAMILY_CONFIG._replace(name="broken", default_preset="nope",
                                                                       int_params=frozenset({"nope"})), track=None)
    problems = family_problems(broken)
    assert any("default preset 'nope'" in p for p in problems) and any("int_params names ['nope']" in p
                                                                         for p in problems)
    assert "track is not callable" in problems
    with pytest.raises(ValueError, match="does not follow the protocol"):
        register(broken)
    with pytest.raises(ValueError, match="registered already"):
        register(dfr.FAMILY)
    with pytest.raises(ValueError, match="stays registered"):
        unregister("dfr")
    assert "broken" not in FAMILIES and set(TrackerFamily._fields) >= {"config", "init", "step", "track", "oracle"}


#: the machinery around the tracker: it names the protocol (``families`` / ``family_configs``), never
#: one family's settings or code; but for what is DFR-FastMOT's own (its distortions act on its frames
#: inside its scan; the Kalman noise fit is of its filter)
MACHINERY = ("sweep", "tuning", "report", "cli", "distort")
DFR_OWN: tuple[str, ...] = ()
#: one family's modules: every family's folder (settings, tracker, family record, rows)
FAMILY_MODULES = ("dfrmot_jax.trackers.dfr", "dfrmot_jax.trackers.ab3dmot")


def _imports(path: Path, module: str) -> list[tuple[str, str | None]]:
    """(module, name) of each import statement of a package module (relative ones resolved)."""
    out = []
    package = module.split(".")[:-1] if path.name != "__init__.py" else module.split(".")
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out += [(a.name, None) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = ".".join(package[:len(package) - node.level + 1] + ([node.module] if node.module else [])) \
                if node.level else node.module
            out += [(base, a.name) for a in node.names]
    return out


def test_the_machinery_names_the_protocol_not_one_family():
    pkg = ROOT / "dfrmot_jax"
    paths = [p for m in MACHINERY for p in sorted((pkg / m).rglob("*.py"))]
    assert len(paths) > 40
    bad = []
    for path in paths:
        module = "dfrmot_jax." + ".".join(path.relative_to(pkg).with_suffix("").parts)
        module = module.removesuffix(".__init__")
        if module in DFR_OWN:
            continue
        for target, name in _imports(path, module):
            full = f"{target}.{name}" if name else target
            if any(full == f or full.startswith(f + ".") or target == f for f in FAMILY_MODULES):
                bad.append(f"{module} imports {full}")
            elif target == "dfrmot_jax.trackers.dfr.track" and name != "TrackResult":
                bad.append(f"{module} imports {full} (a family's batch entry point is TrackerFamily.track)")
    assert not bad, "\n".join(bad)
    asked = {"sweep.table": "family_of", "sweep.chunks": "family_of", "sweep.plan": "family_of",
             "sweep.config_output": "family_of", "tuning.study": "family_of", "tuning.composite": "family_of",
             "sweep.spec": "family_config", "table_columns": "family_config"}
    for m, name in asked.items():
        assert any(n == name for _, n in _imports(pkg / Path(*m.split(".")).with_suffix(".py"), "dfrmot_jax." + m)), m


def test_config_hashes_of_dfr_configs_are_the_ones_they_always_had(spy):
    """The family enters a config's hash only when it is not the default: the grid sweep's config 848
    keeps the hash ``grid_cv`` was chosen by (config.PRESETS), and every DFR row hashes as before."""
    t = expand(load_spec(ROOT / "sweeps" / "kitti_dfr_grid.toml"))
    assert t.loc[848, "config_hash"] == "1189d802072f6209" and t.loc[0, "config_hash"] == "2373fa0eace4e653"
    row = t.drop(columns=["config", "config_hash"]).iloc[5].to_dict()
    assert config_hash(row) == config_hash(row, family="dfr") == t.loc[5, "config_hash"]
    assert config_hash(row, family=SPY) != config_hash(row)


# ---- a second family through the machinery ------------------------------------------------------------


def _spec(root, family=None, **extra) -> dict:
    doc = {"name": "fam", "chunk": 4, "baseline": "dfr2023",
           "data": {"root": str(root), "det2d": "synth2d", "det3d": "synth3d"},
           "params": {"a_l": [4.0, 8.0], "score_2d": [0.3, 0.45]},
           "options": {"output": ["detections", "filtered"], **({"family": family} if family else {})}}
    doc.update(extra)
    return doc


def test_a_sweep_file_is_read_with_its_familys_settings(spy):
    doc = {"params": {"a_l": [4.0, 8.0]}}
    assert parse_spec(doc).family == "dfr" and parse_spec(doc).baseline == "dfr2023"
    s = parse_spec({**doc, "options": {"family": SPY}})
    assert s.family == SPY and s.baseline == "spy_base"                     # the family's default preset
    assert expand(s).loc[0, "a_l"] == 4.0
    parse_spec({"params": {"a_l": [4.0, 10.0]}})                            # DFR's range
    with pytest.raises(SweepConfigError, match=r"params.a_l\[1\]: 10.0: parameter a_l: above 9"):
        parse_spec({"params": {"a_l": [4.0, 10.0]}, "options": {"family": SPY}})
    with pytest.raises(SweepConfigError, match="baseline: 'spy_base': unknown preset"):
        parse_spec({**doc, "baseline": "spy_base"})
    two = [{"name": "a"}, {"name": "b", "options": {"family": "dfr"}}]
    with pytest.raises(SweepConfigError, match=r"variants\[1\].options.family: 'dfr': a sweep is of one tracker"):
        parse_spec({**doc, "options": {"family": SPY}, "variants": two})
    with pytest.raises(SweepConfigError, match=r"options.family: 'nope': expected one tracker family of \['dfr', "):
        parse_spec({**doc, "options": {"family": "nope"}})


def _ab3dmot_spec(root, **extra) -> dict:
    doc = {"name": "ab", "chunk": 4, "baseline": "ab3dmot_car", "data": {"root": str(root), "det3d": "synth3d"},
           "params": {"threshold": [-0.2, 0.1], "max_age": [2, 3]},
           "options": {"family": "ab3dmot", "metric": ["giou_3d", "dist_3d"]}}
    doc.update(extra)
    return doc


def test_an_ab3dmot_sweeps_table_holds_its_columns_and_no_dfr_ones(scene):
    """Every table is one family's: an AB3DMOT sweep's config table has AB3DMOT's parameter and option
    columns (none of DFR-FastMOT's), hashed with its family, planned in groups of its Options, its
    data read without 2D detections; DFR's names are refused in its file, and so is a distortion."""
    from dfrmot_jax.table_columns import option_names, param_names, table_family
    from dfrmot_jax.sweep.plan import option_groups, resolve_data

    ab = family_config("ab3dmot")
    spec = parse_spec(_ab3dmot_spec(scene))
    t = expand(spec)
    assert list(t.columns) == ["config", "config_hash", "variant", "baseline", *ab.Params._fields, *ab.Options._fields]
    assert param_names("ab3dmot") == ab.Params._fields and option_names("ab3dmot") == ab.Options._fields
    dfr_only = set(config.Params._fields + config.Options._fields) - set(ab.Params._fields + ab.Options._fields)
    assert dfr_only and not dfr_only & set(t.columns)
    assert len(t) == 2 * 2 * 2 and t.loc[0, "variant"] == "baseline"       # (the baseline is one of the grid)
    assert t.loc[0, "threshold"] == -0.2 and t.loc[0, "metric"] == "giou_3d"
    assert t["min_hits"].dtype == np.int64 and t["threshold"].dtype == np.float64 and t["boxes"].dtype == bool
    rows = t.drop(columns=["config", "config_hash"]).to_dict("records")
    assert list(t["config_hash"]) == [config_hash(r, family="ab3dmot") for r in rows]
    assert table_family(t.columns) is ab and table_family(expand(parse_spec(_spec(scene))).columns) is config.FAMILY_CONFIG
    groups = option_groups(t, "ab3dmot")
    assert list(groups) == [ab.Options(), ab.Options(metric="dist_3d")] and sum(map(len, groups.values())) == len(t)
    assert resolve_data(spec).det2d is None and resolve_data(parse_spec(_spec(scene))).det2d == "synth2d"
    with pytest.raises(SweepConfigError, match=r"params.a_l: unknown parameter; parameters are \['threshold'"):
        parse_spec(_ab3dmot_spec(scene, params={"a_l": [4.0, 8.0]}))
    with pytest.raises(SweepConfigError, match=r"options.output: unknown option; options are \['metric'"):
        parse_spec(_ab3dmot_spec(scene, options={"family": "ab3dmot", "output": "filtered"}))
    # a [distortion] table distorts AB3DMOT's 3D detections (tests/trackers/ab3dmot/test_ab3dmot_distort.py); the kinds
    # of 2D detections only, which it does not read, are refused
    assert parse_spec(_ab3dmot_spec(scene, distortion={"kind": "drop", "level": [0.1]})).distortion.kinds == (
        ("drop", (0.1,)),)
    with pytest.raises(SweepConfigError, match=r"distortion.kind: kind 'drop_2d' distorts 2D detections only"):
        parse_spec(_ab3dmot_spec(scene, distortion={"kind": "drop_2d", "level": [0.1]}))


@pytest.mark.slow
def test_a_sweep_tracks_with_its_family_and_scores_what_dfr_scores(spy, scene, tmp_path):
    """The same configs swept as DFR-FastMOT and as the spy family: the spy's tracker fields were
    the ones called (the table's check once, its compaction, sizing and tracking per chunk), every
    metric of every row is DFR's, the configs hash apart (another family), the manifest names it,
    and ``compare DIR:best``'s result files are written by its ``class_run`` / ``write_runs`` with
    the same bytes."""
    _, calls = spy
    quiet = dict(progress=False, workers=0, log=lambda m: None)
    plain = run_sweep(_spec(scene), out=tmp_path / "dfr", **quiet)
    assert calls == dict.fromkeys(COUNTED, 0)
    spied = run_sweep(_spec(scene, SPY), out=tmp_path / "spy", **quiet)
    n_chunks = spied["chunk"].nunique()
    assert calls["table_problem"] == 1 and calls["compact_split"] == 1 and calls["output_slots"] >= n_chunks
    assert calls["track"] == n_chunks and calls["prepare_frames"] >= 2 and calls["default_capacity"] == 2
    assert not set(plain["config_hash"]) & set(spied["config_hash"])
    assert not set(plain["chunk"]) & set(spied["chunk"])
    same = [c for c in plain.columns if c not in ("config_hash", "chunk")]
    pd.testing.assert_frame_equal(plain[same], spied[same])
    assert (plain["HOTA"] > 0).all()
    manifest = json.loads((tmp_path / "spy" / "manifest.json").read_text())
    assert manifest["family"] == SPY and "family" not in json.loads((tmp_path / "dfr" / "manifest.json").read_text())
    before = dict(calls)
    a = write_config_output(tmp_path / "dfr", "best", tmp_path / "out_dfr")
    b = write_config_output(tmp_path / "spy", "best", tmp_path / "out_spy")
    assert a.split(" config ")[1].split(" ")[0] == b.split(" config ")[1].split(" ")[0]      # the same best config
    assert calls["track"] == before["track"] + 1 and calls["class_run"] == 1 and calls["write_runs"] == 1
    files = sorted(p.name for p in (tmp_path / "out_dfr").iterdir())
    assert files and files == sorted(p.name for p in (tmp_path / "out_spy").iterdir())
    for f in files:
        assert (tmp_path / "out_dfr" / f).read_bytes() == (tmp_path / "out_spy" / f).read_bytes()


def test_a_tune_hashes_and_checks_its_familys_configs(spy, scene):
    family, calls = spy
    doc = {**_spec(scene), "params": {"a_l": {"uniform": [2.0, 8.0]}, "gain_gamma": [0.1, 1.9]},
           "options": {"family": SPY}}
    space = search_space(parse_spec(doc))
    assert space.family == SPY
    rows = [space.row({"a_l": 3.0, "gain_gamma": g}) for g in (0.1, 1.9)]
    table = space.table(rows)
    assert list(table["config_hash"]) == [config_hash(r, family=SPY) for r in rows]
    assert space.config_hash({"a_l": 3.0, "gain_gamma": 0.1}) == table.loc[0, "config_hash"] != config_hash(rows[0])
    assert list(family.failing_rows(table)) == [False, True] and calls["failing_rows"] == 1


def test_an_ab3dmot_sweep_file_through_the_command_line(scene, tmp_path, capsys):
    """``dfrmot sweep FILE --dry-run`` of an AB3DMOT file plans its option groups (its Options'
    columns), a ``[distortion]`` table's lanes too; a kind of 2D detections only is refused: exit 2,
    the key named, no traceback."""
    from dfrmot_jax.testing.cli import error_line, run_cli

    text = (f'name = "abcli"\nchunk = 3\n[data]\nroot = "{scene}"\ndet3d = "synth3d"\n[params]\n'
            f'threshold = [-0.2, 0.1]\nmax_age = [2, 3]\n[options]\nfamily = "ab3dmot"\n'
            f'algorithm = ["hungarian", "greedy"]\n')
    f = tmp_path / "ab.toml"
    f.write_text(text)
    status, out, err = run_cli(capsys, ["sweep", f, "--dry-run", "--out", tmp_path / "never"])
    assert status == 0, err
    assert "sweep abcli of tracker family 'ab3dmot': 8 configs, 2 option group(s), 4 chunks" in out
    assert "metric   algorithm" in out and "a_l" not in out and not (tmp_path / "never").exists()
    f.write_text(text + "[distortion]\nkind = [\"drop\", \"jitter_2d\"]\nlevel = [0.1]\n")
    status, out, err = run_cli(capsys, ["sweep", f, "--dry-run"])
    assert status == 2 and "distortion.kind[1]: kind 'jitter_2d' distorts 2D detections only" in error_line(err, "sweep")
    f.write_text(text + "[distortion]\nkind = \"drop\"\nlevel = [0, 0.1]\nseeds = 2\n")
    status, out, err = run_cli(capsys, ["sweep", f, "--dry-run", "--out", tmp_path / "never"])
    assert status == 0, err
    assert "24 configs" in out


@pytest.mark.slow
def test_an_ab3dmot_sweep_is_stored_resumed_reported_written_alone_and_tuned(scene, tmp_path, capsys):
    """An AB3DMOT sweep end to end (real tracking and scoring): its directory's manifest names the
    family and no 2D detections, its stored rows hold its columns, a rerun resumes every chunk, the
    report (text, ``--html``) reads its axes, ``compare DIR:best``'s files are its config tracked
    alone by the family and written by its ``write_runs`` (and score what its row says), and a tune
    file of the family searches its parameters."""
    from dfrmot_jax.metrics import evaluate_files, metrics_table, prepare_gt
    from dfrmot_jax.report import load_results, sweep_report
    from dfrmot_jax.report.html import write_html
    from dfrmot_jax.data import load_split
    from dfrmot_jax.testing.cli import run_cli
    from dfrmot_jax.tuning import run_tune

    fam = family_of("ab3dmot")
    ab = fam.config
    dfr_only = set(config.Params._fields + config.Options._fields) - set(ab.Params._fields + ab.Options._fields)
    spec = _ab3dmot_spec(scene, chunk=2, metrics={"ab3dmot": True},
                         options={"family": "ab3dmot", "metric": "giou_3d"})       # 4 configs, one option group
    out = tmp_path / "ab"
    logs: list[str] = []
    df = run_sweep(spec, out, progress=False, workers=0, log=logs.append)
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["family"] == "ab3dmot" and manifest["data"]["det2d"] is None
    stored = load_results(out)
    pd.testing.assert_frame_equal(stored, df)
    assert set(ab.Params._fields + ab.Options._fields) <= set(stored.columns) and not dfr_only & set(stored.columns)
    assert df["config"].nunique() == 4 and (df.loc[df["sequence"] == "COMBINED", "sAMOTA"] > 0).all()
    assert df.loc[df["sequence"] == "COMBINED", "HOTA"].nunique() > 1          # the settings change the figure
    again: list[str] = []
    pd.testing.assert_frame_equal(run_sweep(spec, out, progress=False, workers=0, log=again.append), df)
    assert any("2 chunks of <= 2; 2 done" in line for line in again), again

    rep = sweep_report(out)
    assert rep.family == "ab3dmot" and "threshold" in rep.text and "max_age" in rep.text
    assert set(rep.sensitivity["axis"]) == {"threshold", "max_age"}
    assert not dfr_only & set(rep.top.columns)
    page = write_html(rep, tmp_path / "report.html").read_text()
    assert "threshold" in page and "a_l" not in page
    with warnings.catch_warnings():         # sAMOTA has no per-sequence values: no empty heatmap drawn
        warnings.simplefilter("error")
        page = write_html(sweep_report(out, objective="sAMOTA"), tmp_path / "samota.html").read_text()
    assert "no per-sequence heatmap" in page and "sAMOTA per sequence" not in page
    status, text, err = run_cli(capsys, ["report", out, "--html", tmp_path / "cli.html"])
    assert status == 0 and "threshold" in text and (tmp_path / "cli.html").is_file(), err

    said = write_config_output(out, "best", tmp_path / "best")
    best = int(said.split(" config ")[1].split(" ")[0])
    row = df[(df["config"] == best) & (df["sequence"] == "COMBINED")].iloc[0]
    split = load_split(scene, None, "synth3d", "car")
    params = ab.Params(**{n: row[n] for n in ab.Params._fields})
    options = ab.Options(**{n: type(ab.Options._field_defaults[n])(row[n]) for n in ab.Options._fields})
    fam.write_runs(tmp_path / "alone", [fam.class_run(split, fam.track(split, params, options), 0)])
    files = sorted(p.name for p in (tmp_path / "best").iterdir())
    assert files == sorted(p.name for p in (tmp_path / "alone").iterdir()) and files
    for f in files:
        assert (tmp_path / "best" / f).read_bytes() == (tmp_path / "alone" / f).read_bytes()
    scored = metrics_table(evaluate_files(tmp_path / "best", prepare_gt(scene, "car", split.names)))
    assert scored.loc["COMBINED", "HOTA"] == row["HOTA"] and scored.loc["COMBINED", "IDSW"] == row["IDSW"]

    tune = {**_ab3dmot_spec(scene), "params": {"threshold": {"uniform": [-0.4, 0.2]}, "max_age": [2, 3]},
            "options": {"family": "ab3dmot"},
            "tune": {"sampler": "random", "budget": 4, "batch": 4, "seed": 1, "objectives": ["HOTA"]}}
    space = search_space(parse_spec({k: v for k, v in tune.items() if k != "tune"}))
    assert space.family == "ab3dmot" and {d.name for d in space.dims} == {"threshold", "max_age"}
    res = run_tune(tune, tmp_path / "tune", progress=False, workers=0, log=lambda m: None, refine_steps=0,
                   plots=False)
    assert json.loads((tmp_path / "tune" / "manifest.json").read_text())["family"] == "ab3dmot"
    assert res.table["config_hash"].nunique() == 4 and not dfr_only & set(res.table.columns)
    assert res.table["threshold"].between(-0.4, 0.2).all()
    assert "threshold" in sweep_report(tmp_path / "tune").text
