"""Line-for-line comparison of AB3DMOT output files (``ab3dmot_oracle``'s lines against the files
AB3DMOT wrote): ids up to one renaming per sequence, the detection-derived columns as printed, the
Kalman-filter columns as printed or within a tolerance (rot_y modulo 2 pi)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

PI = np.pi
TWO_PI = np.pi * 2


@dataclass
class Comparison:
    """Line-for-line comparison of one sequence with a reference file: ``exact`` lines (every field
    as printed, ids up to the sequence's renaming), ``close`` lines (a 3D column differs in print
    but by at most ``tol``; rot_y compared modulo 2 pi), ``differing`` lines (``diffs`` holds
    ``(line number, ours, reference)``), and whether the id renaming is a bijection."""

    exact: int = 0
    close: int = 0
    differing: int = 0
    length_mismatch: bool = False
    diffs: list = None

    def __iadd__(self, other):
        self.exact += other.exact
        self.close += other.close
        self.differing += other.differing
        self.length_mismatch |= other.length_mismatch
        self.diffs = (self.diffs or []) + (other.diffs or [])
        return self


def compare_lines(ours: list[str], ref: list[str], tol: float = 2e-6) -> Comparison:
    """Compare two sequences' output lines pairwise (see ``Comparison``). Frame, type, the ``0 0``,
    alpha, 2D box and score must be equal as printed; ids equal under one bijection for the
    sequence (a line whose id breaks it differs); h w l x y z equal as printed or within ``tol``;
    rot_y likewise, modulo 2 pi."""
    res = Comparison(diffs=[])
    fwd, bwd = {}, {}
    if len(ours) != len(ref):
        res.length_mismatch = True
    for k, (a, b) in enumerate(zip(ours, ref)):
        ta, tb = a.split(" "), b.split(" ")
        ok = len(ta) == len(tb) == 18 and ta[0] == tb[0] and ta[2:10] == tb[2:10] and ta[17] == tb[17]
        if ok:
            ia, ib = ta[1], tb[1]
            ok = fwd.setdefault(ia, ib) == ib and bwd.setdefault(ib, ia) == ia
        exact = ok and ta[10:17] == tb[10:17]
        if ok and not exact:
            va, vb = np.array(ta[10:17], dtype=float), np.array(tb[10:17], dtype=float)
            d = np.abs(va - vb)
            d[6] = abs((va[6] - vb[6] + PI) % TWO_PI - PI)
            ok = bool(np.all(d <= tol))
        if exact:
            res.exact += 1
        elif ok:
            res.close += 1
        else:
            res.differing += 1
            res.diffs.append((k, a, b))
    res.differing += abs(len(ours) - len(ref))
    return res


def compare_folder(lines: dict[str, list[str]], ref_dir, tol: float = 2e-6) -> dict[str, Comparison]:
    """``compare_lines`` for each sequence of ``lines`` against ``ref_dir/SSSS.txt``."""
    out = {}
    for seq, ours in lines.items():
        ref = (Path(ref_dir) / f"{seq}.txt").read_text().splitlines()
        out[seq] = compare_lines(ours, ref, tol)
    return out
