"""Axis kinds (sweep/axes.py): the table and the plan cross, hash, split and name chunks by any kind
that implements ``AxisKind``; a new kind is one class (its columns registered for the hash)."""

from dataclasses import dataclass, replace
from typing import NamedTuple

import pytest

from dfrmot_jax.sweep import DataSettings, SweepSpec, config_count, config_hash, expand, parse_spec, plan
from dfrmot_jax import table_columns as spec_mod     # (the config table's axis columns are registered there)

AXES = {"params": {"a_l": [4.0, 8.0]}}


class ModelKey(NamedTuple):
    model: str

    def identity(self) -> dict:
        return {"model": self.model}


@dataclass(frozen=True)
class Models:
    """A toy kind: a ``model`` column crossed with every config, each model its own split."""

    models: tuple = ("plain", "deep")
    columns = {"model": "plain"}

    def values(self, baseline: bool) -> list[dict]:
        return [{"model": m} for m in self.models]

    def size(self, configs: int):
        return configs * len(self.models), f"x {len(self.models)} models", [(len(self.models), "models")]

    def hash_settings(self, row) -> dict:
        return {"depth": 3} if row["model"] == "deep" else {}

    def split_key(self, row):
        return None if row["model"] == "plain" else ModelKey(row["model"])

    def chunk_identity(self) -> dict:
        return {"models": list(self.models)}


def test_a_new_kind_is_crossed_hashed_and_split_without_edits(monkeypatch):
    plain = expand(AXES)
    monkeypatch.setitem(spec_mod.EXTRA_AXES, "model", "plain")
    monkeypatch.setattr(SweepSpec, "axes", property(lambda s: (Models(),)))
    crossed = expand(AXES)
    assert list(crossed.columns) == list(plain.columns) + ["model"] and len(crossed) == 2 * len(plain)
    assert crossed["model"].tolist() == ["plain", "deep"] * len(plain)
    assert (crossed[crossed["model"] == "plain"]["config_hash"].to_numpy() == plain["config_hash"].to_numpy()).all()
    assert crossed["baseline"].tolist() == [True] + [False] * (len(crossed) - 1)
    row = crossed.iloc[1].to_dict()
    assert row["model"] == "deep" and row["config_hash"] == config_hash(row, {"depth": 3})
    assert config_count(AXES)[1].endswith("; x 2 models")
    data = DataSettings("/r", "d2", "d3", "car", ("0000",), (10,))
    spec = parse_spec(AXES)
    for d, want in ((data, "plain"), (replace(data, lidar=ModelKey("deep")), "deep")):
        chunks = plan(crossed, d, 64, spec.axes)
        assert {crossed.loc[i, "model"] for c in chunks for i in c.configs} == {want}
    assert {c.id for c in plan(crossed, data, 64, spec.axes)}.isdisjoint(c.id for c in plan(crossed, data, 64))


def test_the_shipped_kinds_implement_the_protocol():
    spec = parse_spec({**AXES, "data": {"det3d": "lidar:x"}, "lift": {"shrink": [0.1, 0.2]},
                       "distortion": {"kind": "drop", "level": [0.0, 0.5]}})
    for kind in spec.axes:
        for name in ("values", "size", "hash_settings", "split_key", "chunk_identity"):
            assert callable(getattr(kind, name)), (kind, name)
        assert set(kind.columns) <= set(spec_mod.extra_axes())
    assert [list(k.columns) for k in spec.axes] == [["lift.shrink"], list(spec_mod.DISTORTION_AXES)]


def test_an_unregistered_column_is_refused(monkeypatch):
    monkeypatch.setattr(SweepSpec, "axes", property(lambda s: (Models(),)))
    with pytest.raises(ValueError, match="not registered"):
        expand(AXES)
