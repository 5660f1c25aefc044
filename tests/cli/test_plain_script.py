"""The Python API from a plain script (no ``if __name__ == "__main__":``): metric workers must
not re-run the script."""

import subprocess
import sys

import pytest

SCRIPT = """
import dfrmot_jax as dm
from dfrmot_jax.synthetic import make_scene
root = make_scene({scene!r}, n_sequences=2, n_frames=40, seed=3)
spec = {{"name": "plain", "chunk": 4,
        "data": {{"root": str(root), "det2d": "synth2d", "det3d": "synth3d", "class": "car"}},
        "params": {{"a_l": [4.0, 6.0, 8.0], "score_2d": [0.3, 0.5]}}}}
df = dm.run_sweep(spec, out={out!r}, workers=2)
print("ROWS", len(df))
"""


@pytest.mark.slow
def test_run_sweep_with_workers_from_a_plain_script(tmp_path):
    script = tmp_path / "plain.py"
    script.write_text(SCRIPT.format(scene=str(tmp_path / "scene"), out=str(tmp_path / "out")))
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.count("ROWS") == 1 and "ROWS 21" in out.stdout
    assert out.stderr.count("sweep plain: 7 configs (") == 1     # the script ran once, not again in a worker
