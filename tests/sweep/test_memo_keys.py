"""Every memo sees a change of what its value depends on: the file memo (and each reader cache on
it), the compiled-program cache, the config hash (a tune's repeats), AB3DMOT's lane digests. (The
scores' memo: tests/sweep/test_sweep_equals_alone.py; the LiDAR caches: tests/lidar/test_lidar_source.py.)"""

from __future__ import annotations

import inspect
import os
import shutil
import time
from pathlib import Path

import pytest

from dfrmot_jax.trackers.dfr.config import OPTION_CHOICES, Options, Params
from dfrmot_jax.io.memo import RACY_NS, FileMemo, file_stamps
from dfrmot_jax.synthetic import make_scene


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    root = make_scene(tmp_path_factory.mktemp("memo_scene"), n_sequences=2, n_frames=30, n_cars=3, seed=2)
    old = time.time() - 60                # files older than the racy window
    for p in root.rglob("*.txt"):
        os.utime(p, (old, old))
    return root


def _age(path: Path, seconds: float = 60) -> None:
    t = time.time() - seconds
    os.utime(path, (t, t))


def test_file_memo_sees_a_same_size_rewrite_a_rename_and_a_fresh_file(tmp_path):
    f = tmp_path / "a.txt"
    f.write_text("1234")
    _age(f)
    builds = []
    memo = FileMemo()

    def get():
        return memo.get("k", file_stamps([f]), lambda: builds.append(f.read_text()) or f.read_text())

    assert get() == "1234" and get() == "1234" and len(builds) == 1         # an old file: read once
    st = os.stat(f)
    f.write_text("5678")                                                   # same size, same mtime
    os.utime(f, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert get() == "5678" and len(builds) == 2                            # (its ctime moved)
    g = tmp_path / "b.txt"
    g.write_text("abcd")
    os.utime(g, ns=(st.st_atime_ns, st.st_mtime_ns))
    os.replace(g, f)                                                       # replaced by a rename
    assert get() == "abcd" and len(builds) == 3
    h = tmp_path / "c.txt"
    h.write_text("fresh")                                                  # modified just now: racy
    fresh = FileMemo()
    for _ in range(2):
        fresh.get("k", file_stamps([h]), lambda: builds.append(1))
    assert len(builds) == 5 and RACY_NS > 0


def test_ground_truth_caches_see_an_edited_label_file(scene, tmp_path):
    from dfrmot_jax.metrics.samota.prep import cached_ab3dmot_gt
    from dfrmot_jax.metrics.common.sequences import cached_class_sequences
    from dfrmot_jax.metrics.kitti2d.evaluate import cached_gt

    root = tmp_path / "root"
    shutil.copytree(scene, root)
    gt, gt3 = cached_gt(root, "car"), cached_ab3dmot_gt(root, "car")
    assert cached_gt(root, "car") is gt and cached_ab3dmot_gt(root, "car") is gt3
    seqs = cached_class_sequences(root, "car")
    label = root / "label_02" / "0001.txt"
    lines = label.read_text().splitlines(keepends=True)
    label.write_text("".join(lines[: len(lines) // 2]))
    _age(label, 30)
    assert cached_gt(root, "car") is not gt and cached_gt(root, "car").n_frames != gt.n_frames
    assert cached_ab3dmot_gt(root, "car") is not gt3
    shutil.copy(label, root / "label_02" / "0002.txt")                    # a sequence added
    _age(root / "label_02" / "0002.txt", 30)
    assert cached_class_sequences(root, "car") == tuple(seqs) + ("0002",)


def test_a_split_sees_an_edited_calibration(scene, tmp_path):
    from dfrmot_jax.data import cached_split

    root = tmp_path / "root"
    shutil.copytree(scene, root)
    args = (root, "synth2d", "synth3d", "car", ("0000",))
    split = cached_split(*args)
    assert cached_split(*args) is split
    calib = root / "calib" / "0000.txt"
    text = calib.read_text()
    calib.write_text(text.replace("P2: 7", "P2: 8", 1) if "P2: 7" in text else text + "\n")
    _age(calib, 30)
    assert cached_split(*args) is not split


def test_every_static_argument_selects_its_own_program():
    """``trackers.dfr.run.compiled``'s key is every argument it builds from (shapes and dtypes: jit's own)."""
    from dfrmot_jax.trackers.dfr import run

    sig = inspect.signature(run.compiled)
    base = dict(options=Options(), capacity=16, n_devices=1, hook_fn=None, detail=False, small=None,
                shared_objects=False, platform="cpu")
    assert list(sig.parameters) == list(base)
    changed = dict(options=Options(truncate=False), capacity=32, n_devices=2, hook_fn=len, detail=True,
                   small=(4, 4), shared_objects=True, platform="gpu")       # (built lazily: no GPU needed)
    first = run.compiled(**base)
    assert run.compiled(**base) is first
    for name, value in changed.items():
        assert run.compiled(**{**base, name: value}) is not first, name
    for name in OPTION_CHOICES:
        other = next(v for v in OPTION_CHOICES[name] if v != getattr(Options(), name))
        assert run.compiled(**{**base, "options": Options(**{name: other})}) is not first, name


def test_the_config_hash_names_every_parameter_and_option():
    """A tune refuses a repeat by its config hash: a config changed in any one setting is new."""
    from dfrmot_jax.sweep import OPTION_NAMES, PARAM_NAMES, config_hash

    row = {**Params()._asdict(), **Options()._asdict()}
    h = config_hash(row)
    for name in PARAM_NAMES:
        v = row[name]
        assert config_hash({**row, name: v + 1 if isinstance(v, int) else v + 0.015625}) != h, name
    for name in OPTION_NAMES:
        v = row[name]
        other = (not v) if isinstance(v, bool) else (v + 16 if isinstance(v, int) else
                                                     next(c for c in OPTION_CHOICES[name] if c != v))
        assert config_hash({**row, name: other}) != h, name


@pytest.mark.slow
def test_ab3dmot_lane_digests_name_the_options_and_the_shared_boxes(scene):
    import dfrmot_jax as dm
    from dfrmot_jax.sweep.samota_lanes import Ab3dmotLanes
    from dfrmot_jax.metrics.samota.prep import cached_ab3dmot_gt

    split = dm.load_split(scene, "synth2d", "synth3d", "car")
    lanes = Ab3dmotLanes(cached_ab3dmot_gt(scene, "car", split.names), split, "2d:0.5")
    got = {}
    for opts in (Options(), Options(truncate=False)):
        res = dm.track(split, dm.stack_params([Params()]), opts, detail=True)
        got[opts.truncate] = (lanes.digests(res)[0], lanes.score(res)[0])
    assert got[True][0] != got[False][0]
    assert len(lanes.memo) == 2
