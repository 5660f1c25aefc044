"""Every ```python block of the README runs as written, as a plain script from the repository root
with the data found by default."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
BLOCKS = re.findall(r"```python\n(.*?)```", (REPO / "README.md").read_text(), flags=re.S)


def test_the_readme_has_python_blocks():
    assert len(BLOCKS) >= 2


@pytest.mark.slow
@pytest.mark.parametrize("i", range(len(BLOCKS)))
def test_readme_python_block_runs(i, kitti_root):
    out = subprocess.run([sys.executable, "-c", BLOCKS[i]], cwd=REPO, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, f"README python block {i + 1} failed:\n{out.stderr[-3000:]}"
