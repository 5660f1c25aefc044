"""The NumPy oracle against ByteTrack's own reference runs, line for line."""

import pytest

from dfrmot_jax.testing import bytetrack_oracle as O
from dfrmot_jax.testing.bytetrack_compare import compare_lines, reference_lines

SEQS = [f"{i:04d}" for i in range(21)]


def _check(root, run, seqs):
    cls, s = O.PRESETS[run]
    typ = "Car" if cls == "car" else "Pedestrian"
    for seq in seqs:
        c = compare_lines(O.run_sequence(O.load_frames(root, cls, seq), s, typ), reference_lines(root, run, seq))
        assert c.identical, (run, seq, c)


def test_oracle_car_default_fast(kitti_root):
    _check(kitti_root, "car_default", ["0000", "0003", "0012"])


@pytest.mark.slow
@pytest.mark.parametrize("run", list(O.PRESETS))
def test_oracle_all_runs(kitti_root, run):
    _check(kitti_root, run, SEQS)
