"""The sweep and tune file parsers under any value type in any key (issue 23, bugs 2 and 3).

A valid sweep file and a valid tune file cover every table ([data], [baseline], [params] with
per-class axes and distributions, [options], [[variants]], [report] with a contrast,
[distortion], [tune] with refine and transfer). Hypothesis puts any value (numbers, booleans,
strings, dates, nested lists, tables) in place of any key's value: the parser either accepts the
file or raises :class:`SweepConfigError` whose key is the full path of the replaced key (or of a
key below it); an error about another key (a rule between two keys) names a key the file has, by
its full path. Never another exception.
"""

from __future__ import annotations

import copy
import datetime as dt
import re

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dfrmot_jax.sweep import SweepConfigError, parse_spec
from dfrmot_jax.testing.cli import error_line, run_cli
from dfrmot_jax.tuning.settings import parse_tune_file

SWEEP = {
    "name": "fuzz", "description": "every table", "chunk": 8, "seed": 1, "samples": 2,
    "data": {"root": "/nonexistent", "det2d": "rrc", "det3d": "pointrcnn", "class": ["car", "pedestrian"],
             "sequences": ["0000", 1]},
    "baseline": {"preset": "dfr2023", "class": "car"},
    "params": {"a_l": [4.0, 8.0], "score_2d": {"linspace": [0.3, 0.5, 3]}, "alpha_c": {"uniform": [0.2, 0.8]},
               "epsilon": {"randint": [5, 9]}, "kf_q": {"logspace": [0.01, 1, 3]}, "kf_r": {"choice": [1.0, 2.0]},
               "pedestrian": {"a_l": [1.0, 2.0]}, "pedestrian.score_3d": [2.0, 3.0]},
    "options": {"output": ["detections", "filtered"], "filter": {"grid": ["fixed_gain", "kalman"]},
                "capacity": 0, "truncate": True},
    "variants": [{"name": "raw", "params": {"keep_lost": 0}},
                 {"name": "kept", "params": {"keep_lost": [0, 2]}, "options": {"output": "filtered"}}],
    "report": {"objective": "HOTA", "folds": 3, "top": 5, "class": "average",
               "contrast": {"axis": "epsilon", "high": [30, 60], "low": [1, 2], "by": ["filter"]}},
    "distortion": {"kind": ["drop", "burst", "clutter"], "level": [0.0, 0.5],
                   "levels": {"burst": {"linspace": [0, 5, 3]}, "clutter": {"grid": [0, 1]}}, "seeds": [0, 3],
                   "clutter_slots": 2, "burst_dist": "geometric", "burst_max": 10, "burst_rate": 0.1,
                   "burst_len": 4.0},
}
TUNE = {
    "name": "fuzz_tune", "data": {"root": "/nonexistent", "det2d": "rrc", "det3d": "pointrcnn"},
    "params": {"a_l": {"uniform": [2.0, 10.0]}, "min_hits": [1, 2]},
    "options": {"output": ["detections", "filtered"]},
    "tune": {"sampler": "tpe", "budget": 16, "batch": 8, "objectives": ["HOTA"], "folds": 3, "seed": 0,
             "refine": {"steps": 2, "pairs": 2, "sigma": 0.1, "learning_rate": 0.1, "patience": 1},
             "transfer": {"det3d": "pointgnn", "baseline": {"a_l": 4.0}}},
}


def _paths(node, prefix=()):
    """Every key path of a document (tables' keys and list items), depth first."""
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for k, v in items:
        yield prefix + (k,)
        yield from _paths(v, prefix + (k,))


def _name(path) -> str:
    out = ""
    for k in path:
        out += f"[{k}]" if isinstance(k, int) else (f".{k}" if out else k)
    return out


def _resolves(doc, key: str) -> bool:
    """Whether an error's key is a full path of the document: every part from the top is there (a
    quoted key holding a dot, ``"pedestrian.a_l"``, counts as one part)."""
    tokens = [t for t in re.findall(r"\[(\d+)\]|([^.\[\]]+)", key)]
    parts = [int(i) if i else s for i, s in tokens]
    node, i = doc, 0
    while i < len(parts):
        p = parts[i]
        if isinstance(p, int):
            if not isinstance(node, list) or p >= len(node):
                return False
            node, i = node[p], i + 1
            continue
        if not isinstance(node, dict):
            return False
        for j in range(len(parts), i, -1):          # the longest run of parts that is one key
            k = ".".join(str(x) for x in parts[i:j])
            if all(isinstance(x, str) for x in parts[i:j]) and k in node:
                node, i = node[k], j
                break
        else:
            return False
    return True


def _put(doc, path, value):
    doc = copy.deepcopy(doc)
    node = doc
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value
    return doc


_words = st.sampled_from(["", "all", "car", "pedestrian", "average", "HOTA", "IDSW", "grid", "linspace", "uniform",
                          "choice", "drop", "burst", "clutter", "filtered", "kalman", "fixed_gain", "tpe", "dfr2023",
                          "geometric", "epsilon", "a_l", "1e3", "nan", "0000", "x.y"])
_scalars = st.one_of(st.integers(-2**70, 2**70), st.integers(-3, 70), st.floats(), st.booleans(),
                     st.text(max_size=6), _words, st.datetimes(), st.dates(), st.times())
_values = st.recursive(_scalars, lambda inner: st.one_of(
    st.lists(inner, max_size=3), st.dictionaries(st.one_of(_words, st.text(max_size=4)), inner, max_size=3)),
    max_leaves=6)


def _check(doc, parse, path, value):
    bad = _put(doc, path, value)
    try:
        parse(bad)
    except SweepConfigError as e:
        where = _name(path)
        assert e.key == where or e.key.startswith((where + ".", where + "[")) or _resolves(bad, e.key), \
            f"{where} = {value!r}: the error names {e.key!r}: {e}"


@pytest.mark.slow
@pytest.mark.parametrize("which", ["sweep", "tune"])
@settings(max_examples=1500, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_any_value_in_any_key_is_refused_by_its_full_key_or_accepted(which, data):
    doc, parse = (SWEEP, lambda d: parse_spec(d, "fuzz.toml")) if which == "sweep" else \
        (TUNE, lambda d: parse_tune_file(d, "fuzz.toml"))
    path = data.draw(st.sampled_from(list(_paths(doc))), label="key")
    _check(doc, parse, path, data.draw(_values, label="value"))


def test_the_base_documents_parse():
    assert parse_spec(SWEEP).name == "fuzz"
    assert parse_tune_file(TUNE)[1].budget == 16


@pytest.mark.parametrize("doc, key", [
    ({"params": {"a_l": [[4.0, 6.0]]}}, "params.a_l[0]"),
    ({"params": {"a_l": {"grid": [[4.0]]}}}, "params.a_l.grid[0]"),
    ({"params": {"a_l": {"choice": [{"x": 1}]}}}, "params.a_l.choice[0]"),
    ({"baseline": ["dfr2023"]}, "baseline"),
    ({"report": {"contrast": {"axis": "epsilon", "high": [[30]], "low": [1]}}}, "report.contrast.high[0]"),
    ({"report": {"folds": 1}}, "report.folds"),
    ({"report": {"top": 0}}, "report.top"),
    ({"report": {"folds": True}}, "report.folds"),
    ({"distortion": {"kind": "drop", "level": [0.1], "seeds": 1, "burst_max": 0}}, "distortion.burst_max"),
    ({"chunk": "8"}, "chunk"),
    ({"description": ["a"]}, "description"),
])
def test_examples_name_the_full_key(doc, key):
    with pytest.raises(SweepConfigError) as e:
        parse_spec(doc)
    assert e.value.key == key, str(e.value)


@pytest.mark.parametrize("tune, key", [({"folds": 1}, "tune.folds"), ({"refine": {"steps": 0}}, "tune.refine.steps"),
                                       ({"budget": [2]}, "tune.budget"), ({"sampler": ["tpe"]}, "tune.sampler")])
def test_tune_errors_name_the_full_key(tune, key):
    with pytest.raises(SweepConfigError) as e:
        parse_tune_file({"params": {"a_l": [4.0, 8.0]}, "tune": tune})
    assert e.value.key == key, str(e.value)


def test_a_nested_list_in_a_sweep_axis_is_bad_input_naming_the_key(tmp_path, capsys):
    f = tmp_path / "s.toml"
    f.write_text("[params]\na_l = [[4.0, 6.0]]\n")
    status, _, err = run_cli(capsys, ["sweep", f, "--dry-run"])
    assert status == 2, err
    assert "params.a_l[0]" in error_line(err, "sweep"), err


def test_dates_are_values_too():
    with pytest.raises(SweepConfigError) as e:
        parse_spec({"params": {"a_l": [dt.date(2024, 1, 1)]}})
    assert e.value.key == "params.a_l[0]"
