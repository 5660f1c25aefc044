"""Issue 51, item 21: the first run after an install compiles the scoring kernels (numba, ~20 s of CPU).
A sweep starts compiling them in a thread (``sweep.chunks.warm_scoring_kernels``: ``LaneScorer.warm``
on a made-up lane) as soon as its ground truth is loaded, beside the split's compaction and the first
chunk's tracking, instead of after it. The made-up lane must reach every kernel the real scoring calls
with the types it calls them with: after ``warm`` a real sweep's scoring adds no compiled signature."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

SCRIPT = textwrap.dedent("""
    import sys, threading
    import numba
    from dfrmot_jax.synthetic import make_scene
    from dfrmot_jax.metrics.kitti2d.evaluate import cached_gt
    from dfrmot_jax.metrics.kitti2d.lane_scorer import LaneScorer
    from dfrmot_jax.sweep import chunks

    def signatures():
        out = {}
        for name, mod in list(sys.modules.items()):
            if name.startswith("dfrmot_jax.metrics"):
                for k, v in vars(mod).items():
                    if isinstance(v, numba.core.registry.CPUDispatcher):
                        out[f"{name}.{k}"] = set(map(str, v.signatures))
        return out

    root = make_scene(sys.argv[1] + "/scene", n_sequences=2, n_frames=25, seed=2)
    started = []
    real = chunks.warm_scoring_kernels
    chunks.warm_scoring_kernels = lambda scorer: started.append(scorer)     # (the test warms by itself)
    gt = cached_gt(root, "car", ["0000", "0001"])
    LaneScorer(gt, gt.offsets[:-1], as_written="g6").warm()
    before = signatures()
    from dfrmot_jax import run_sweep
    run_sweep({"name": "w", "data": {"root": str(root), "det2d": "synth2d", "det3d": "synth3d"},
               "params": {"score_2d": [0.3, 0.5]}, "options": {"output": ["detections", "filtered"]}},
              progress=False, workers=0, log=lambda m: None)
    after = signatures()
    new = {k: sorted(v - before.get(k, set())) for k, v in after.items() if v - before.get(k, set())}
    assert started, "the sweep did not start warming the kernels"
    assert sum(map(len, before.values())) >= 5, before
    print("NEW", new)
    sys.exit(1 if new else 0)
""")


def test_warm_reaches_every_kernel_the_scoring_calls(tmp_path):
    r = subprocess.run([sys.executable, "-c", SCRIPT, str(tmp_path)], capture_output=True, text=True, timeout=900,
                       env={**__import__("os").environ, "PYTHONPATH": str(REPO)})
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]


def test_warm_on_a_scorer_leaves_nothing_behind(tmp_path):
    from dfrmot_jax.metrics.kitti2d.evaluate import cached_gt
    from dfrmot_jax.metrics.kitti2d.lane_scorer import LaneScorer
    from dfrmot_jax.synthetic import make_scene

    root = make_scene(tmp_path / "scene", n_sequences=1, n_frames=12, seed=1)
    gt = cached_gt(root, "car", ["0000"])
    sc = LaneScorer(gt, gt.offsets[:-1], as_written="g6")
    sc.warm()
    assert len(sc) <= 1                         # one made-up output at most, in its own scorer's memo
