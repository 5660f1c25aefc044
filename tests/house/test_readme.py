"""Every ```python block of the README runs as written, as a plain script from the repository root
with the data found by default."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
BLOCKS = re.findall(r"```python\n(.*?)```", (REPO / "README.md").read_text(), flags=re.S)


def test_the_readme_has_python_blocks():
    assert len(BLOCKS) >= 2


@pytest.mark.slow
@pytest.mark.parametrize("i", range(len(BLOCKS)))
def test_readme_python_block_runs(i, kitti_root):
    out = subprocess.run([sys.executable, "-c", BLOCKS[i]], cwd=REPO, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, f"README python block {i + 1} failed:\n{out.stderr[-3000:]}"


def _shell_commands() -> list[str]:
    """The README's shell commands (```bash blocks and plain transcripts): each `dfrmot ...` line,
    continuations joined, comments dropped."""
    blocks, lang, lines = [], None, []
    for line in (REPO / "README.md").read_text().splitlines():
        if line.startswith("```"):
            if lang is None:
                lang, lines = line[3:].strip(), []
            else:
                if lang in ("", "bash"):
                    blocks.append("\n".join(lines))
                lang = None
        elif lang is not None:
            lines.append(line)
    return [re.sub(r"\s+#.*", "", c) for b in blocks for c in re.sub(r"\\\n\s*", " ", b).splitlines()
            if c.startswith("dfrmot ")]


SHELL = _shell_commands()


def test_the_readme_writes_nothing_into_the_repository_root():
    """Issue 41, item 18: the examples wrote scores.csv and grid.html beside the code, which .gitignore
    does not cover: every file or folder a README command writes is under results/ or out/ (ignored)."""
    ignored = (REPO / ".gitignore").read_text().split()
    assert "/results/" in ignored and "out/" in ignored
    written = [(c, m) for c in SHELL for m in re.findall(r"--(?:csv|html|recall-table|out) (\S+)", c)]
    assert len(written) > 10
    assert [(c, m) for c, m in written if not m.startswith(("results/", "out/"))] == []


def test_the_readme_makes_each_track_folder_once():
    """Issue 41, item 18: the compare example re-created results/dfr2023, made by "Tracking KITTI", and
    exits 2 there (an output folder that is not empty): each `dfrmot track --out D` of the README once,
    unless --overwrite."""
    outs = [re.search(r"--out (\S+)", c).group(1) for c in SHELL
            if c.startswith("dfrmot track ") and "--overwrite" not in c]
    assert len(outs) > 3
    assert sorted(d for d in set(outs) if outs.count(d) > 1) == []
