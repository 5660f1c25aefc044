"""The Ray backend on a real two-node Ray cluster on this machine (``ray start --head`` with 2 CPUs +
``ray start --address`` with 1): the same tables as the local backend, from the CLI and the API; a worker node
killed mid-run; a sweep interrupted on one backend and finished on the other; a tune on the cluster."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd
import pytest

ray = pytest.importorskip("ray", reason="the Ray backend needs the [ray] extra (part of [dev])")
if not sys.platform.startswith("linux"):
    pytest.skip("the local cluster's nodes are stopped through /proc", allow_module_level=True)

from dfrmot_jax.sweep import (  # noqa: E402
    ray_backend,
    run_sweep,  # noqa: E402
    runner,
)
from dfrmot_jax.synthetic import make_scene  # noqa: E402
from dfrmot_jax.testing.cli import error_line, run_cli  # noqa: E402

RAY_ENV = {"RAY_AUTH_MODE": "disabled", "RAY_USAGE_STATS_ENABLED": "0"}


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _descendants(pid: int) -> list[int]:
    """Every process below ``pid`` (from /proc)."""
    children: dict[int, list[int]] = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                ppid = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            children.setdefault(ppid, []).append(int(d.name))
    out, todo = [], [pid]
    while todo:
        for c in children.get(todo.pop(), []):
            out.append(c)
            todo.append(c)
    return out


class LocalCluster:
    """A head node and worker nodes, each a ``ray start --block`` process (SIGTERM stops a node)."""

    def __init__(self, tmp: Path):
        self.port = _free_port()
        self.address = f"127.0.0.1:{self.port}"
        self.env = {**os.environ, **RAY_ENV}
        self.logs = tmp
        # the head's worker gets 2 CPUs (its chunks scored in metric processes beside the tracker),
        # the worker node's 1 (scored in the worker itself)
        self.head = self._start(["--head", f"--port={self.port}", "--include-dashboard=false", "--num-cpus=2"],
                                "head")
        self.workers = [self.add_worker()]

    def _start(self, args, name):
        log = open(self.logs / f"{name}-{time.monotonic_ns()}.log", "w")
        exe = Path(sys.executable).parent / "ray"           # the ray CLI of this interpreter's environment
        if not any(a.startswith("--num-cpus") for a in args):
            args = [*args, "--num-cpus=1"]
        return subprocess.Popen([str(exe) if exe.exists() else "ray", "start", *args, "--block"],
                                env=self.env,
                                stdout=log, stderr=subprocess.STDOUT, start_new_session=True)

    def alive_nodes(self) -> int:
        if ray.is_initialized():
            return sum(n["Alive"] for n in ray.nodes())
        out = subprocess.run([sys.executable, "-c", "import ray; ray.init(address='%s', logging_level='ERROR'); "
                              "print(sum(n['Alive'] for n in ray.nodes()))" % self.address],
                             env=self.env, capture_output=True, text=True, timeout=120)
        return int(out.stdout.strip().splitlines()[-1]) if out.returncode == 0 and out.stdout.strip() else 0

    def add_worker(self):
        proc = self._start([f"--address={self.address}"], "worker")
        return proc

    def wait_nodes(self, n: int, timeout: float = 120) -> None:
        t = time.monotonic()
        while time.monotonic() - t < timeout:
            if self.alive_nodes() == n:
                return
            time.sleep(1)
        raise RuntimeError(f"the local Ray cluster did not reach {n} alive nodes")

    @staticmethod
    def stop(*procs, grace: float = 5.0) -> None:
        """SIGTERM the nodes (``ray start --block`` stops its raylet and workers); what is left after
        ``grace`` seconds (a head node takes ~30 s to stop politely) is SIGKILLed."""
        family = []
        for p in procs:
            if p.poll() is None:
                family += _descendants(p.pid)
                os.killpg(p.pid, signal.SIGTERM)
        deadline = time.monotonic() + grace
        for p in procs:
            try:
                p.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()
        for q in family:
            try:
                os.kill(q, signal.SIGKILL)
            except ProcessLookupError:
                pass

    def shutdown(self) -> None:
        self.stop(*self.workers, self.head)
        # a head stopped the hard way leaves its address as the machine's "current cluster", which a
        # bare ray.init() would then try to join
        current = Path(tempfile.gettempdir()) / "ray" / "ray_current_cluster"
        try:
            if current.read_text().strip().endswith(f":{self.port}"):
                current.unlink()
        except OSError:
            pass


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    saved = {k: os.environ.get(k) for k in RAY_ENV}
    os.environ.update(RAY_ENV)
    c = LocalCluster(tmp_path_factory.mktemp("ray-logs"))
    try:
        c.wait_nodes(2)
        yield c
    finally:
        ray_backend.release()
        if ray.is_initialized():
            ray.shutdown()
        c.shutdown()
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    return make_scene(tmp_path_factory.mktemp("ray-scene"), n_sequences=3, n_frames=120, n_cars=5, seed=5)


def _spec(root: Path, name: str = "rayt") -> dict:
    return {"name": name, "chunk": 4,
            "data": {"root": str(root), "det2d": "synth2d", "det3d": "synth3d"},
            "params": {"a_l": [4.0, 6.0, 8.0], "score_2d": [0.3, 0.5, 0.7], "gain_beta": [0.3, 0.6]},
            "options": {"output": ["detections", "filtered"]}}


@pytest.fixture(scope="module")
def local_table(scene, tmp_path_factory):
    out = tmp_path_factory.mktemp("ray-local") / "local"
    return run_sweep(_spec(scene), out, progress=False, workers=0, log=lambda m: None)


@pytest.mark.ray
@pytest.mark.slow
def test_cli_sweep_on_a_two_node_cluster_equals_the_local_table(cluster, scene, local_table, tmp_path):
    """The acceptance command, in its own driver process, against `ray start` nodes."""
    import json

    toml = tmp_path / "s.toml"
    spec = _spec(scene)
    toml.write_text(f'name = "{spec["name"]}"\nchunk = 4\n[data]\nroot = "{scene}"\ndet2d = "synth2d"\n'
                    f'det3d = "synth3d"\n[params]\n' + "".join(f"{k} = {json.dumps(v)}\n" for k, v in spec["params"].items())
                    + '[options]\noutput = ["detections", "filtered"]\n')
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "dfrmot_jax.cli", "sweep", str(toml), "--out", str(out),
                           "--backend", "ray", "--address", cluster.address, "--no-progress"],
                          env=cluster.env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "Traceback" not in proc.stderr
    assert proc.stderr.count("ray: worker on node") == 2, proc.stderr      # one worker per node
    assert "2 CPU(s), 2 JAX device(s)" in proc.stderr and "1 CPU(s), 1 JAX device(s)" in proc.stderr
    assert "by 2 worker(s)" in proc.stderr
    pd.testing.assert_frame_equal(pd.read_parquet(out / "results.parquet"), local_table)


@pytest.mark.ray
@pytest.mark.slow
def test_a_worker_node_killed_mid_run_loses_and_duplicates_nothing(cluster, scene, local_table, tmp_path,
                                                                  monkeypatch):
    logs: list[str] = []
    written: list[str] = []
    real_write = runner.write_chunk
    victim = cluster.workers[0]

    def write_then_kill(out, chunk, df, *rest):
        real_write(out, chunk, df, *rest)
        written.append(chunk.id)
        if len(written) == 1:           # the other node holds chunks in flight now: stop it
            LocalCluster.stop(victim)

    monkeypatch.setattr(runner, "write_chunk", write_then_kill)
    out = tmp_path / "lost"
    df = run_sweep(_spec(scene), out, progress=False, backend="ray", address=cluster.address, log=logs.append)
    text = "\n".join(logs)
    assert "lost the worker" in text, text
    assert len(written) == len(set(written)) == local_table["chunk"].nunique()     # every chunk written once
    pd.testing.assert_frame_equal(df, local_table)
    pd.testing.assert_frame_equal(pd.read_parquet(out / "results.parquet"), local_table)
    # the cluster gets its second node back for the tests after this one
    cluster.workers = [cluster.add_worker()]
    cluster.wait_nodes(2)
    ray_backend.release()


class _Stop(Exception):
    pass


def _interrupted(monkeypatch, after: int):
    real_write = runner.write_chunk
    n = [0]

    def write(out, chunk, df, *rest):
        if n[0] == after:
            raise _Stop
        real_write(out, chunk, df, *rest)
        n[0] += 1

    monkeypatch.setattr(runner, "write_chunk", write)


@pytest.mark.ray
@pytest.mark.slow
@pytest.mark.parametrize("first,second", [("local", "ray"), ("ray", "local")])
def test_a_sweep_started_on_one_backend_is_finished_on_the_other(cluster, scene, local_table, tmp_path,
                                                                 monkeypatch, first, second):
    out = tmp_path / "both"
    kw = {"local": dict(workers=0), "ray": dict(backend="ray", address=cluster.address)}
    with monkeypatch.context() as m:
        _interrupted(m, after=2)
        with pytest.raises(_Stop):
            run_sweep(_spec(scene), out, progress=False, log=lambda s: None, **kw[first])
    assert len(list((out / "chunks").glob("*.parquet"))) == 2
    logs: list[str] = []
    df = run_sweep(_spec(scene), out, progress=False, log=logs.append, **kw[second])
    assert any("2 done" in line for line in logs), logs
    pd.testing.assert_frame_equal(df, local_table)


@pytest.mark.ray
@pytest.mark.slow
def test_an_ab3dmot_sweep_on_the_cluster_equals_the_local_table(cluster, scene, tmp_path):
    """A sweep of the second tracker family (``[options] family = "ab3dmot"``, its figures too) on the
    cluster's workers: the same table, its columns, as in this process."""
    spec = {"name": "rayab", "chunk": 2, "data": {"root": str(scene), "det3d": "synth3d"},
            "params": {"threshold": [-0.2, 0.1], "max_age": [2, 3]}, "options": {"family": "ab3dmot"},
            "metrics": {"ab3dmot": True}}
    local = run_sweep(spec, tmp_path / "local", progress=False, workers=0, log=lambda s: None)
    logs: list[str] = []
    remote = run_sweep(spec, tmp_path / "ray", progress=False, backend="ray", address=cluster.address, log=logs.append)
    assert any("by 2 worker(s)" in line for line in logs), logs
    assert {"threshold", "max_age", "metric", "sAMOTA"} <= set(remote.columns) and "a_l" not in remote.columns
    pd.testing.assert_frame_equal(remote, local)


@pytest.mark.ray
@pytest.mark.slow
def test_a_tune_runs_its_batches_on_the_cluster(cluster, scene, tmp_path, monkeypatch):
    from dfrmot_jax.tuning import run_tune

    spec = _spec(scene, "raytune")
    spec["params"] = {"a_l": {"uniform": [2.0, 10.0]}, "score_2d": {"uniform": [0.2, 0.8]}}
    del spec["options"]
    spec["tune"] = {"sampler": "tpe", "budget": 8, "batch": 4, "seed": 3}
    calls = []
    real = ray_backend.run_chunks

    def spy(*a, **k):                      # (runs the real thing; counts the batches sent to the cluster)
        calls.append(len(a[5]))     # (address, worker_cpus, spec, table, data, todo, ...)
        return real(*a, **k)

    monkeypatch.setattr(ray_backend, "run_chunks", spy)
    on_ray = run_tune(spec, tmp_path / "ray", progress=False, backend="ray", address=cluster.address,
                      log=lambda m: None, plots=False)
    assert len(calls) == 2 and sum(calls) >= 2, calls      # two batches of 4, each on the cluster
    local = run_tune(spec, tmp_path / "local", progress=False, workers=0, log=lambda m: None, plots=False)
    pd.testing.assert_frame_equal(on_ray.table, local.table)
    pd.testing.assert_frame_equal(on_ray.trials, local.trials)
    assert len(on_ray.table["config"].unique()) == 8


@pytest.mark.slow
def test_an_unreachable_address_is_exit_2_before_anything_is_written(scene, tmp_path):
    toml = tmp_path / "s.toml"
    toml.write_text(f'name = "x"\n[data]\nroot = "{scene}"\ndet2d = "synth2d"\ndet3d = "synth3d"\n'
                    '[params]\na_l = [4.0, 6.0]\n')
    out = tmp_path / "never"
    proc = subprocess.run([sys.executable, "-m", "dfrmot_jax.cli", "sweep", str(toml), "--out", str(out),
                           "--backend", "ray", "--address", f"127.0.0.1:{_free_port()}", "--no-progress"],
                          env={**os.environ, **RAY_ENV}, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    error_line(proc.stderr.splitlines(), "sweep")
    assert "no Ray cluster answers there" in proc.stderr
    assert not out.exists()


def test_backend_options_are_checked(capsys):
    code, _, err = run_cli(capsys, ["sweep", "x.toml", "--address", "127.0.0.1:6379"])
    assert code == 2 and "need --backend ray" in error_line(err, "sweep")
    code, _, err = run_cli(capsys, ["sweep", "x.toml", "--backend", "ray", "--workers", "2"])
    assert code == 2 and "--workers is for the local backend" in error_line(err, "sweep")
