"""The AB3DMOT oracle (dfrmot_jax.testing.ab3dmot_oracle) against AB3DMOT's own output files
(reference/ab3dmot_tracker/head61f3bd7_*, 21 KITTI sequences, PointRCNN detections), line for line.

Fast tier: two short sequences (0012, 0017) of every run, ids up to one renaming per sequence (the
counter runs across sequences). Slow tier: all 21 sequences in order from id 1, ids literal. Each
prints its counts: lines equal as printed, lines within 2e-6 (an ulp moving a printed digit of a
Kalman-filter column), lines differing.
"""

import functools
import time
from pathlib import Path

import pytest

from dfrmot_jax.testing.ab3dmot_compare import Comparison, compare_folder
from dfrmot_jax.testing.ab3dmot_oracle import PRESETS, track_sequences

REFERENCE = Path("reference") / "ab3dmot_tracker"
FAST_SEQUENCES = ("0012", "0017")
ALL_SEQUENCES = tuple(f"{i:04d}" for i in range(21))


@functools.lru_cache(maxsize=None)
def _oracle(root: str, settings, sequences):
    """The oracle's lines {seq: [line]} and its wall time (cached: car_noaffipro reuses car_default)."""
    t0 = time.perf_counter()
    lines = track_sequences(root, settings, sequences)
    return lines, time.perf_counter() - t0


def _compare(kitti_root, run, sequences):
    ref_dir = kitti_root / REFERENCE / f"head61f3bd7_{run}"
    if not ref_dir.is_dir():
        pytest.skip(f"AB3DMOT reference run not found at {ref_dir}")
    lines, wall = _oracle(str(kitti_root), PRESETS[run], sequences)
    assert sorted(lines) == list(sequences)
    per_seq = compare_folder(lines, ref_dir)
    total = Comparison(diffs=[])
    for c in per_seq.values():
        total += c
    print(f"{run} ({len(sequences)} sequences): exact {total.exact}, within 2e-6 {total.close}, "
          f"differing {total.differing}; oracle {wall:.1f} s")
    for k, ours, ref in total.diffs[:10]:
        print(f"  line {k}\n    oracle    {ours}\n    reference {ref}")
    assert not total.length_mismatch, {s: c.length_mismatch for s, c in per_seq.items()}
    assert total.differing == 0
    return lines, ref_dir


@pytest.mark.parametrize("run", list(PRESETS))
def test_short_sequences_match_reference(kitti_root, run):
    _compare(kitti_root, run, FAST_SEQUENCES)


@pytest.mark.slow
@pytest.mark.parametrize("run", list(PRESETS))
def test_all_sequences_match_reference(kitti_root, run):
    lines, ref_dir = _compare(kitti_root, run, ALL_SEQUENCES)
    # from sequence 0000 with id 1 the global counter gives the reference's ids literally
    for seq, ours in lines.items():
        ref = (ref_dir / f"{seq}.txt").read_text().splitlines()
        assert [s.split(" ", 2)[1] for s in ours] == [s.split(" ", 2)[1] for s in ref], seq


LINE = "5 7 Car 0 0 -1.647400 636.773800 179.318900 664.390200 202.557600 1.520400 1.628800 3.718500 2.754900 1.986700 50.124400 -3.141592 6.984400"


def _edit(line, col, value):
    t = line.split(" ")
    t[col] = value
    return " ".join(t)


def test_compare_lines_rules():
    from dfrmot_jax.testing.ab3dmot_compare import compare_lines
    other = _edit(LINE, 1, "9")
    c = compare_lines([LINE, other], [_edit(LINE, 1, "3"), _edit(LINE, 1, "4")])   # a renaming
    assert (c.exact, c.close, c.differing) == (2, 0, 0)
    c = compare_lines([LINE, other], [_edit(LINE, 1, "3"), _edit(LINE, 1, "3")])   # not a bijection
    assert (c.exact, c.differing) == (1, 1)
    c = compare_lines([_edit(LINE, 13, "2.754901")], [LINE])                       # 1e-6: close
    assert (c.exact, c.close, c.differing) == (0, 1, 0)
    c = compare_lines([_edit(LINE, 13, "2.754903")], [LINE])                       # 3e-6: differs
    assert c.differing == 1
    c = compare_lines([_edit(LINE, 16, "3.141593")], [LINE])                       # rot_y modulo 2 pi
    assert (c.close, c.differing) == (1, 0)
    c = compare_lines([_edit(LINE, 17, "6.984401")], [LINE])                       # score as printed
    assert c.differing == 1
    c = compare_lines([LINE], [LINE, LINE])
    assert c.length_mismatch and c.differing == 1
