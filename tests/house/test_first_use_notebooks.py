"""Issue 51, item 20: a reader opening a committed notebook sees its figures. Every code cell that draws
a figure (``plt.subplots``, ``plt.figure``, ``plt.show()``, ``display(fig)``) holds an image in its
saved outputs (the notebooks display the Figure itself, ``display(fig)``, which embeds it under any
Matplotlib backend, Agg included, where ``plt.show()`` embeds nothing)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

NOTEBOOKS = sorted((Path(__file__).resolve().parents[2] / "notebooks").glob("*.ipynb"))
DRAWS = re.compile(r"plt\.subplots\(|plt\.figure\(|plt\.show\(\)|display\(fig\)")
IMAGES = ("image/png", "image/svg+xml", "image/jpeg")


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.name for p in NOTEBOOKS])
def test_every_cell_that_plots_has_an_image(path):
    nb = json.loads(path.read_text())
    missing = []
    for i, c in enumerate(c for c in nb["cells"] if c["cell_type"] == "code"):
        src = "".join(c["source"])
        if not DRAWS.search(re.sub(r"#.*", "", src)):         # (comments do not draw)
            continue
        if re.search(r"^if (KITTI|not QUICK)\b", src, re.M) and not c.get("outputs"):
            missing.append(f"cell {i} (guarded, not run: executed without its data?)")
            continue
        if not any(k in o.get("data", {}) for o in c.get("outputs", []) for k in IMAGES):
            missing.append(f"cell {i}")
    assert not missing, f"{path.name}: cells that plot without an image in their saved outputs: {missing}"
