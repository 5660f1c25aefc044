"""Where the data root is found: $DFRMOT_DATA, then ../shared/data/kitti/training from the cwd."""

from pathlib import Path

from dfrmot_jax import paths


def _root(base: Path) -> Path:
    root = base / "shared" / "data" / "kitti" / "training"
    (root / "label_02").mkdir(parents=True)
    (root / "detections").mkdir()
    return root


def test_env_var_wins(tmp_path, monkeypatch):
    monkeypatch.setenv(paths.ENV_VAR, str(tmp_path / "mine"))
    assert paths.default_data_root() == tmp_path / "mine"
    assert not paths.data_available()
    assert str(tmp_path / "mine") in paths.missing_data_message()


def test_relative_to_the_current_directory(tmp_path, monkeypatch):
    monkeypatch.delenv(paths.ENV_VAR, raising=False)
    root = _root(tmp_path)
    work = tmp_path / "project"
    work.mkdir()
    monkeypatch.chdir(work)
    assert paths.default_data_root().resolve() == root.resolve()
    assert paths.data_available()


def test_message_names_every_place_looked(tmp_path, monkeypatch):
    monkeypatch.delenv(paths.ENV_VAR, raising=False)
    monkeypatch.setattr(paths, "_CHECKOUT", tmp_path / "nowhere" / "checkout")
    monkeypatch.chdir(tmp_path)
    msg = paths.missing_data_message()
    assert paths.ENV_VAR in msg and str(tmp_path / paths.RELATIVE) in msg and "nowhere" in msg
