"""Comparing ByteTrack result lines with the reference runs (``reference/bytetrack_tracker/``).

Lines are compared as written (boxes and scores as printed, ``%.6f``), frame by frame, the order
inside a frame ignored, ids up to one renaming per sequence: the k-th distinct id of a file (in
order of first appearance, frame by frame, ties inside a frame broken by the rest of the line) is
renamed k on both sides before the comparison.
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path
from typing import NamedTuple

__all__ = ["REFERENCE_DIR", "Comparison", "canonical", "compare_lines", "reference_lines"]

REFERENCE_DIR = Path("reference") / "bytetrack_tracker"


class Comparison(NamedTuple):
    """``matched`` lines of ``total`` (the reference's), ``extra`` lines only on the other side, the
    first difference (or None)."""
    matched: int
    total: int
    extra: int
    first_difference: str | None

    @property
    def identical(self) -> bool:
        return self.matched == self.total and self.extra == 0


def canonical(lines: list[str]) -> list[tuple]:
    """``(frame, renamed id, rest of the line)`` for every line, ids renamed by first appearance
    (inside a frame in the order of the rest of the line, so that the order of writing does not
    matter)."""
    parsed = []
    for line in lines:
        tok = line.split()
        if tok:
            parsed.append((int(tok[0]), int(tok[1]), " ".join(tok[2:])))
    by_frame = defaultdict(list)
    for f, i, rest in parsed:
        by_frame[f].append((rest, i))
    names: dict[int, int] = {}
    out = []
    for f in sorted(by_frame):
        for rest, i in sorted(by_frame[f]):
            if i not in names:
                names[i] = len(names) + 1
            out.append((f, names[i], rest))
    return out


def compare_lines(got: list[str], want: list[str]) -> Comparison:
    """Lines ``got`` against the reference's ``want`` (one sequence)."""
    g, w = canonical(got), canonical(want)
    gs = defaultdict(int)
    for t in g:
        gs[t] += 1
    matched = 0
    first = None
    for t in w:
        if gs[t] > 0:
            gs[t] -= 1
            matched += 1
        elif first is None:
            first = f"reference line {t} not produced"
    extra = sum(gs.values())
    if first is None and extra:
        first = f"extra line {next(t for t, k in gs.items() if k > 0)}"
    return Comparison(matched, len(w), extra, first)


def reference_lines(root, run: str, seq: str) -> list[str]:
    """The reference run's lines of one sequence."""
    path = Path(root) / REFERENCE_DIR / run / f"{seq}.txt"
    return [line for line in path.read_text().splitlines() if line.strip()]
