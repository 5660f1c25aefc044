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


SHELL = "\n".join(body for lang, body in re.findall(r"```(\w*)\n(.*?)```", (REPO / "README.md").read_text(), flags=re.S)
                  if lang in ("", "bash", "sh", "text"))


def test_the_readme_examples_write_under_results_and_do_not_clash():
    """The examples wrote ``scores.csv`` and ``grid.html`` into the repository root (not ignored by git),
    and the compare example re-created ``results/dfr2023``, which exits 2 for a reader who followed
    "Tracking KITTI": every ``--csv`` / ``--html`` of a command goes under ``results/`` (ignored), and no
    two ``dfrmot track`` commands write one folder."""
    commands = [c for c in re.sub(r"\\\n\s*", " ", SHELL).splitlines() if c.lstrip("$ ").startswith("dfrmot ")]
    outputs = [p for c in commands for p in re.findall(r"--(?:csv|html) (\S+)", c)]
    assert outputs and all(p.startswith("results/") for p in outputs), outputs
    assert "/results/" in (REPO / ".gitignore").read_text().split()
    tracked = [p for c in commands if c.lstrip("$ ").startswith("dfrmot track ") for p in re.findall(r"--out (\S+)", c)]
    assert len(tracked) >= 3 and len(tracked) == len(set(tracked)), tracked
