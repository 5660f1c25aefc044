import pytest
"""Importing the package changes nothing; the first tracking call asks for one device per core."""

import subprocess
import sys

SCRIPT_IMPORT = """
import os, sys
before = dict(os.environ)
import dfrmot_jax
assert dict(os.environ) == before, "import changed the environment"
assert 'jax' not in sys.modules or not __import__('jax')._src.xla_bridge.backends_are_initialized()
print("ok")
"""

SCRIPT_TRACK = """
import dfrmot_jax as dm, jax
from dfrmot_jax.synthetic import make_scene
import tempfile
root = make_scene(tempfile.mkdtemp(), n_sequences=1, n_frames=20, seed=1)
dm.track(dm.load_split(root, "synth2d", "synth3d", "car"), dm.Params())
print(jax.local_device_count())
"""

SCRIPT_LATE = """
import warnings, jax, jax.numpy as jnp
jnp.zeros(1).block_until_ready()          # the user's own JAX work initialises the backend first
import dfrmot_jax as dm
with warnings.catch_warnings(record=True) as w:
    warnings.simplefilter("always")
    n = dm.setup_host_devices(2)
print(n, any("setup_host_devices" in str(x.message) for x in w))
"""


def _run(script, **env):
    import os
    e = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "DFRMOT_HOST_DEVICES", "DFRMOT_COMPILE_CACHE")}
    e.update(env)
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=e, timeout=300)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip().splitlines()[-1]


def test_import_changes_no_environment():
    assert _run(SCRIPT_IMPORT) == "ok"


@pytest.mark.slow
def test_first_tracking_call_uses_one_device_per_core():
    import os
    assert _run(SCRIPT_TRACK) == str(min(os.cpu_count() or 1, 8))
    assert _run(SCRIPT_TRACK, DFRMOT_HOST_DEVICES="1") == "1"


def test_late_setup_warns_and_reports_the_devices_in_use():
    assert _run(SCRIPT_LATE) == "1 True"


def test_the_platform_choice(monkeypatch):
    """$DFRMOT_DEVICE: auto follows JAX's default backend (the CPU here), cpu is the CPU devices, gpu
    where JAX sees none is a clear error naming the install command; lanes per call by platform."""
    from dfrmot_jax import devices

    monkeypatch.delenv("DFRMOT_DEVICE", raising=False)
    assert devices.chosen_platform() == "cpu" == devices.chosen_platform("auto") == devices.chosen_platform("CPU")
    assert [d.platform for d in devices.batch_devices()] == ["cpu"] * len(devices.batch_devices())
    assert devices.default_lanes_per_call() == 64 and devices.default_lanes_per_call("gpu") == 1024
    assert devices.platform_of("cuda") == devices.platform_of("rocm") == "gpu"
    with pytest.raises(ValueError, match=r'pip install -e "\.\[cuda\]"'):
        devices.chosen_platform("gpu")
    monkeypatch.setenv("DFRMOT_DEVICE", "tpu")
    with pytest.raises(ValueError, match="DFRMOT_DEVICE='tpu'"):
        devices.chosen_platform()
    monkeypatch.setenv("DFRMOT_DEVICE", "cuda")
    with pytest.raises(ValueError, match="sees no GPU"):
        devices.chosen_platform()


def test_track_on_the_chosen_platform(monkeypatch, tmp_path):
    """The tracker runs on the platform chosen: cpu gives auto's output here; gpu without one is
    refused before any tracking, and `dfrmot track` says so in one line, exit 2."""
    import numpy as np

    import dfrmot_jax as dm
    from dfrmot_jax.cli import main
    from dfrmot_jax.synthetic import make_scene

    root = make_scene(str(tmp_path / "scene"), n_sequences=1, n_frames=20, seed=1)
    split = dm.load_split(root, "synth2d", "synth3d", "car")
    params = dm.stack_params([dm.Params(), dm.Params(a_l=3.0)])
    monkeypatch.delenv("DFRMOT_DEVICE", raising=False)
    auto = dm.track(split, params)
    monkeypatch.setenv("DFRMOT_DEVICE", "cpu")
    cpu = dm.track(split, params)
    assert np.array_equal(auto.ids, cpu.ids) and (auto.ids >= 0).any()
    monkeypatch.setenv("DFRMOT_DEVICE", "gpu")
    with pytest.raises(ValueError, match="sees no GPU"):
        dm.track(split, params)
    assert main(["track", "--data", str(root), "--det2d", "synth2d", "--det3d", "synth3d", "--class", "car",
                 "--out", str(tmp_path / "out")]) == 2


@pytest.mark.parametrize("command", ["sweep", "tune"])
def test_sweep_and_tune_refuse_a_missing_gpu_before_writing(command, monkeypatch, tmp_path, capsys):
    """``DFRMOT_DEVICE=gpu dfrmot sweep ... --out NEW`` without a GPU wrote the manifest, ledger and
    config table before refusing, ``tune`` a batch folder: nothing is written now, exit 2."""
    import jax

    from dfrmot_jax.synthetic import make_scene
    from dfrmot_jax.testing.cli import error_line, run_cli

    try:
        if jax.devices("gpu"):
            pytest.skip("JAX sees a GPU here")
    except RuntimeError:
        pass
    root = make_scene(tmp_path / "scene", n_sequences=1, n_frames=20, seed=1)
    text = (f'name = "gpu"\nchunk = 4\n[data]\nroot = "{root}"\ndet2d = "synth2d"\ndet3d = "synth3d"\n'
            f'[baseline]\npreset = "dfr2023"\n')
    text += ('[params]\na_l = [4.0, 8.0]\n' if command == "sweep" else
             '[params]\na_l = {uniform = [2.0, 8.0]}\n[tune]\nbudget = 4\nbatch = 2\n')
    (tmp_path / "s.toml").write_text(text)
    monkeypatch.setenv("DFRMOT_DEVICE", "gpu")
    out = tmp_path / "out"
    status, _, err = run_cli(capsys, [command, tmp_path / "s.toml", "--out", out, "--no-progress"])
    assert status == 2 and "DFRMOT_DEVICE=gpu, but JAX sees no GPU" in error_line(err, command), err
    assert not out.exists()


def _cli(args, **env):
    import os
    e = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "DFRMOT_HOST_DEVICES", "DFRMOT_COMPILE_CACHE")}
    e.update(env)
    return subprocess.run([sys.executable, "-m", "dfrmot_jax.cli", *args], capture_output=True, text=True, env=e,
                          timeout=300)


@pytest.mark.slow
def test_compiled_programs_kept_between_runs(tmp_path):
    """``$DFRMOT_COMPILE_CACHE``: the first ``dfrmot track`` keeps its compiled program there, the second
    process takes it from there (JAX's own log of a cache hit) and writes the same files; ``dfrmot``
    without the variable keeps them under ``$XDG_CACHE_HOME`` (``off``: test_no_compile_cache_unless_asked)."""
    from dfrmot_jax.synthetic import make_scene

    root = make_scene(tmp_path / "scene", n_sequences=1, n_frames=40, seed=2)
    cache = tmp_path / "cache"
    runs = []
    for k in range(2):
        out = tmp_path / f"out{k}"
        r = _cli(["track", "--data", str(root), "--det2d", "synth2d", "--det3d", "synth3d", "--out", str(out)],
                 DFRMOT_COMPILE_CACHE=str(cache), JAX_LOG_COMPILES="1")
        assert r.returncode == 0, r.stderr
        runs.append((r.stderr, {f.name: f.read_bytes() for f in sorted(out.glob("*.txt"))}))
        assert any(cache.iterdir()), "nothing kept"
    assert "Persistent compilation cache hit" not in runs[0][0]
    assert "Persistent compilation cache hit" in runs[1][0]
    assert runs[0][1] and runs[0][1] == runs[1][1]
    r = _cli(["track", "--data", str(root), "--det2d", "synth2d", "--det3d", "synth3d", "--out", str(tmp_path / "o3")],
             XDG_CACHE_HOME=str(tmp_path / "xdg"))
    assert r.returncode == 0 and any((tmp_path / "xdg" / "dfrmot_jax" / "xla").iterdir()), r.stderr


def _read_only(folder):
    """Make ``folder`` unwritable, as a read-only mount is (``chattr +i`` where chmod does not bind,
    i.e. for root); None when neither can."""
    import shutil
    import tempfile

    folder.chmod(0o555)
    try:
        tempfile.TemporaryFile(dir=folder).close()
    except OSError:
        return lambda: folder.chmod(0o755)
    if shutil.which("chattr") and subprocess.run(["chattr", "+i", str(folder)], capture_output=True).returncode == 0:
        return lambda: subprocess.run(["chattr", "-i", str(folder)], check=True)
    folder.chmod(0o755)
    return None


@pytest.mark.slow          # the fast tier's budget: one of its costliest tests
def test_a_read_only_compile_cache_is_one_warning(tmp_path):
    """A compile cache folder that cannot be written (JAX also takes a lock file there to read) gave 8
    warning lines per run, one per program read and written: now one, and the run as without it."""
    from dfrmot_jax.synthetic import make_scene

    root = make_scene(tmp_path / "scene", n_sequences=1, n_frames=20, seed=2)
    cache = tmp_path / "cache"
    cache.mkdir()
    undo = _read_only(cache)
    if undo is None:
        pytest.skip("cannot make a folder read-only here")
    try:
        r = _cli(["track", "--data", str(root), "--det2d", "synth2d", "--det3d", "synth3d", "--out",
                  str(tmp_path / "o")], DFRMOT_COMPILE_CACHE=str(cache))
    finally:
        undo()
    assert r.returncode == 0, r.stderr
    [line] = [s for s in r.stderr.splitlines() if "warning" in s]
    assert line.startswith(f"dfrmot track: warning: DFRMOT_COMPILE_CACHE: {cache}: not writable"), line


@pytest.mark.slow
@pytest.mark.parametrize("damage", ["swapped", "truncated"])
def test_compile_cache_entries_that_do_not_load_are_compiled_anew(damage, tmp_path):
    """Two compile cache entries with swapped contents: ``internal error: AssertionError: (8, 6)``
    (JAX loads another program and its checks fail); a truncated entry: JAX's warning, every run, the
    entry never replaced. Now each is one warning naming it, compiled anew and replaced: the same
    files, and the next run loads the new entries without a word."""
    from dfrmot_jax.synthetic import make_scene

    root = make_scene(tmp_path / "scene", n_sequences=1, n_frames=40, seed=2)
    cache = tmp_path / "cache"
    args = ["track", "--data", str(root), "--det2d", "synth2d", "--det3d", "synth3d", "--out"]
    files = []
    for k in range(3):
        # every program kept, however fast this machine compiles it (JAX's own threshold variable)
        r = _cli(args + [str(tmp_path / f"o{k}")], DFRMOT_COMPILE_CACHE=str(cache),
                 JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS="0")
        assert r.returncode == 0, r.stderr
        files.append({f.name: f.read_bytes() for f in sorted((tmp_path / f"o{k}").glob("*.txt"))})
        warned = [s for s in r.stderr.splitlines() if "warning" in s]
        if k == 0:
            a, b = sorted(cache.glob("*-cache"), key=lambda p: p.stat().st_size)[-2:]
            data = a.read_bytes()
            a.write_bytes(b.read_bytes()[:100] if damage == "truncated" else b.read_bytes())
            b.write_bytes(b.read_bytes()[:100] if damage == "truncated" else data)
        elif k == 1 and damage == "swapped":
            assert len(warned) == 2 and all("do not load as their programs" in s for s in warned), r.stderr
            assert {str(a), str(b)} == {s.split("): ")[1].split(": compiled")[0] for s in warned}
        elif k == 1:
            assert len(warned) == 2 and all("Error reading persistent compilation cache entry" in s for s in warned)
            assert all(s.endswith(": compiled anew and replaced)") for s in warned), r.stderr
            assert {str(a), str(b)} == {s.rsplit(" (", 1)[1].split(": compiled")[0] for s in warned}
        else:
            assert not warned, r.stderr
    assert files[0] and files[0] == files[1] == files[2]


def test_no_compile_cache_unless_asked():
    """A library caller keeps nothing on disk unless ``$DFRMOT_COMPILE_CACHE`` names a folder; the
    variable's name is the one the command line sets."""
    from dfrmot_jax import devices
    from dfrmot_jax import paths

    assert devices.COMPILE_CACHE_VAR == paths.COMPILE_CACHE_VAR
    script = ("import dfrmot_jax, jax; dfrmot_jax.setup_host_devices(); "
              "print(jax.config.jax_compilation_cache_dir)")
    assert _run(script) == "None"
    assert _run(script, DFRMOT_COMPILE_CACHE="off") == "None"
    assert _run(script, DFRMOT_COMPILE_CACHE="/tmp/x") == "/tmp/x"
