"""The presets are exact to the authors' C++ where last bits decide: constructed tracks judged by an
exact rational model of the C++'s double arithmetic, and random row drops of the KITTI files.

A track seen twice (frames 0 and 1, a jump of r) and then lost has, after k predictions, a corner at
z0 + r (alpha + k beta + gamma k^2): a whole number in exact arithmetic with 0.9 / 0.9 / 0.1 whenever
10 divides r (k^2 + 9k + 9). The C++'s effective gains (spec section 4, "Exact arithmetic") put it a
hair above or below, integer truncation then moves the predicted box by one pixel, and a probe
detection placed at IoU exactly 1/20 (or at distance exactly a_l) is matched or not on that hair.
The model below computes every corner in ``fractions.Fraction`` from the exact values of the C++'s
double constants; the tracker and the oracle must both take each decision it takes.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest

from dfrmot_jax.trackers.dfr.track import track
from dfrmot_jax.data import SequenceDets, load_sequences, pack
from dfrmot_jax.io.kitti import Calib, Detections2D, Detections3D
from dfrmot_jax.trackers.dfr.config import CXX_GAIN_ALPHA, CXX_GAIN_BETA, CXX_GAIN_GAMMA, preset
from dfrmot_jax.testing.parity import lane_mismatches, reference_pool, reference_rows
from dfrmot_jax.testing.reference import track_sequence

MS = range(1, 21)
JUMPS = [r for r in range(-20, 21) if r]

# The C++'s gains as exact rationals (every double is a rational), and the float32 reading of them
# that the tracker used before (beta = double(0.9f)), and the gate: IoU < 0.05 (double) is dropped.
CXX = (Fraction(CXX_GAIN_ALPHA), Fraction(CXX_GAIN_BETA), Fraction(CXX_GAIN_GAMMA))
F32_BETA = (Fraction(CXX_GAIN_ALPHA), Fraction(float(np.float32(0.9))), Fraction(CXX_GAIN_GAMMA))
GATE = 0.05
GATE_F32 = float(np.float32(0.05))

_P2 = np.array([[721.5, 0, 609.6, 44.9], [0, 721.5, 172.9, 0.2], [0, 0, 1, 0.003]])
_CALIB = Calib(_P2, np.eye(3), np.zeros((3, 4)), np.stack([_P2] * 4), np.zeros((3, 4)))


def _predict(z0: Fraction, z1: Fraction, k: int, gains) -> Fraction:
    """Position of a coordinate observed z0, then z1, after the update at z1 and k predictions
    (per-frame units: p += alpha r, v += beta r, a += 2 gamma r; p += v + a / 2, v += a)."""
    alpha, beta, gamma = gains
    r = z1 - z0
    p, v, a = z0 + alpha * r, beta * r, 2 * gamma * r
    for _ in range(k):
        p, v = p + v + a / 2, v + a
    return p


def _cxx_box(p) -> tuple[int, int, int, int]:
    """The C++'s predicted integer box from filter corners: x = trunc(tl), w = trunc(|x - br|)."""
    x, y = math.trunc(p[0]), math.trunc(p[1])
    w, h = math.trunc(abs(x - p[2])), math.trunc(abs(y - p[3]))
    return x, y, x + w, y + h


def _iou(a, b) -> Fraction:
    iw = max(0, min(a[2], b[2]) - max(a[0], b[0]))
    ih = max(0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = iw * ih
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return Fraction(inter, union) if union > 0 else Fraction(0)


def _kept(iou: Fraction, gate: float = GATE) -> bool:
    """The C++ gate: the IoU rounded to double (int / int division) compared with the double 0.05."""
    return iou > 0 and not (iou.numerator / iou.denominator) < gate


def _probes(box):
    """Boxes whose IoU with ``box`` is exactly 1/20: an overlap of k columns (rows) on each side."""
    x1, y1, x2, y2 = box
    w, h = x2 - x1, y2 - y1
    if w <= 0 or h <= 0:
        return []
    kx, ky = -(-w // 20), -(-h // 20)
    wx, hy = 21 * kx - w, 21 * ky - h            # k / (w + wx - k) = 1/20
    return [(x2 - kx, y1, x2 - kx + wx, y2), (x1 + kx - wx, y1, x1 + kx, y2),
            (x1, y2 - ky, x2, y2 - ky + hy), (x1, y1 + ky - hy, x2, y1 + ky)]


def _cases_2d():
    """(m, r, mode, frames boxes, probe, C++ decision, decision with beta = double(0.9f))."""
    base = (2000, 2000, 2100, 2100)
    cases = []
    for mode in ("both", "tl", "br"):
        moving = {"both": (0, 2), "tl": (0, 1), "br": (2, 3)}[mode]
        for m in MS:
            for r in JUMPS:
                b1 = tuple(c + (r if i in moving else 0) for i, c in enumerate(base))
                pred = [_predict(Fraction(a), Fraction(b), m, CXX) for a, b in zip(base, b1)]
                alt = [_predict(Fraction(a), Fraction(b), m, F32_BETA) for a, b in zip(base, b1)]
                pc, pa = _cxx_box(pred), _cxx_box(alt)
                # probes at IoU exactly 1/20 with either reading of the box; where the two readings
                # differ, one that they decide differently
                candidates = _probes(pc) + _probes(pa)
                if not candidates:
                    continue
                split = [d for d in candidates if _kept(_iou(d, pc)) != _kept(_iou(d, pa))] or candidates
                probe = split[(m + r) % len(split)]
                cases.append((m, r, mode, (base, b1), probe, _kept(_iou(probe, pc)),
                              _kept(_iou(probe, pa), GATE_F32)))
    return cases


def _seq_2d(name, boxes, probe, m) -> SequenceDets:
    frames = [0, 1, m + 1]
    box = np.array([boxes[0], boxes[1], probe], float)
    d2 = Detections2D(np.array(frames, np.int64), box, np.full(3, 0.9))
    d3 = Detections3D(np.zeros(0, np.int64), np.zeros(0, object), np.zeros((0, 4)), np.zeros(0), np.zeros((0, 3)),
                      np.zeros((0, 3)), np.zeros(0), np.zeros(0))
    return SequenceDets(name, m + 2, d2, d3, _CALIB)


def _run(seqs, name):
    """(tracker ids of each sequence's probe, oracle ids of it) for the preset."""
    params, options = preset(name)
    split = pack(seqs)
    res = track(split, params, options)
    mine, theirs = [], []
    for s, seq in enumerate(seqs):
        sl = split.sequence_slice(s)
        ids = res.ids[0][sl][-1]
        mine.append(int(ids[ids >= 0][0]))
        rows = track_sequence(seq, params, options)
        theirs.append([row[1] for row in rows if row[0] == seq.n_frames - 1][0])
    return mine, theirs


@pytest.mark.slow
@pytest.mark.parametrize("name", ["dfr2023", "dfr_head"])
def test_2d_corners_of_lost_tracks_decide_as_the_cxx(name):
    cases = _cases_2d()
    assert len(cases) > 2000
    seqs = [_seq_2d(f"{i:04d}", c[3], c[4], c[0]) for i, c in enumerate(cases)]
    mine, theirs = _run(seqs, name)
    expected = [0 if c[5] else 1 for c in cases]          # the probe keeps id 0, or is born as id 1
    assert theirs == expected
    assert mine == expected
    # The cases decide things: both outcomes occur, IoU exactly 1/20 is kept, and the float32 reading
    # of the constants (beta = double(0.9f), gate 0.05f) would take other decisions on some of them.
    assert 0 < sum(c[5] for c in cases) < len(cases)
    assert sum(c[5] != c[6] for c in cases) > 50


def _centre(z0: int, length: int, r: int, m: int, gains) -> Fraction:
    """Predicted internal-x centroid of a box (z0, z0 + length) that jumped by r, m predictions on."""
    return sum(_predict(Fraction(c), Fraction(c + r), m, gains) for c in (z0, z0 + length)) / 2


def _cases_3d(a_l: float):
    """(m, r, KITTI z of frames 0, 1 and the probe, C++ decision, decision with beta = double(0.9f))."""
    cases = []
    z0, length = 2000, 4
    for m in MS:
        for r in JUMPS:
            # the internal x axis is KITTI z in both conventions: corners (z, z + l) in float32
            ideal = _centre(z0, length, r, m, (Fraction(9, 10), Fraction(9, 10), Fraction(1, 10)))
            side = 1 if (m + r) % 2 else -1
            zp = np.float32(float(ideal - length / 2 + side * Fraction(a_l)))
            probe = (Fraction(float(zp)) + Fraction(float(zp + np.float32(length)))) / 2
            d, d_alt = abs(probe - _centre(z0, length, r, m, CXX)), abs(probe - _centre(z0, length, r, m, F32_BETA))
            cases.append((m, r, (z0, z0 + r, float(zp)), d < Fraction(a_l), d_alt < Fraction(a_l)))
    return cases


def _seq_3d(name, zs, m) -> SequenceDets:
    frames = [0, 1, m + 1]
    boxes = np.array([[100, 100, 200, 200], [100, 100, 200, 200], [1000, 300, 1100, 370]], float)
    loc = np.array([[3.0, 1.5, z] for z in zs])
    d3 = Detections3D(np.array(frames, np.int64), np.array(["2"] * 3, object), boxes, np.full(3, 10.0),
                      np.tile([1.5, 1.8, 4.0], (3, 1)), loc, np.zeros(3), np.zeros(3))
    d2 = Detections2D(np.zeros(0, np.int64), np.zeros((0, 4)), np.zeros(0))
    return SequenceDets(name, m + 2, d2, d3, _CALIB)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["dfr2023", "dfr_head"])
def test_3d_corners_of_lost_tracks_decide_as_the_cxx(name):
    params, options = preset(name)
    cases = _cases_3d(float(params.a_l))
    seqs = [_seq_3d(f"{i:04d}", c[2], c[0]) for i, c in enumerate(cases)]
    mine, theirs = _run(seqs, name)
    expected = [0 if c[3] else 1 for c in cases]
    assert theirs == expected
    assert mine == expected
    assert 0 < sum(c[3] for c in cases) < len(cases)
    assert sum(c[3] != c[4] for c in cases) > 20


@pytest.fixture(scope="module")
def pool():
    with reference_pool(2) as p:
        yield p


@pytest.mark.slow
@pytest.mark.parametrize("name,fraction,seed", [("dfr2023", 0.25, 1), ("dfr2023", 0.5, 2),
                                                ("dfr_head", 0.25, 3), ("dfr_head", 0.5, 4)])
def test_random_row_drops_of_kitti_tracker_equals_oracle(kitti_root, pool, name, fraction, seed):
    """A random fraction of the 2D and 3D rows of every car sequence dropped; JAX tracks all of them
    in one call, the NumPy oracle checks (exactly, tol 0) half of them: those with index = seed mod 2.
    Each preset's two cases have seeds of both parities, so every sequence is compared under each
    preset (at one of the two fractions)."""
    rng = np.random.default_rng(seed)
    seqs = []
    for s in load_sequences(kitti_root, "rrc", "pointrcnn", "car"):
        keep2 = rng.random(s.det2d.frame.size) >= fraction
        keep3 = rng.random(s.det3d.frame.size) >= fraction
        seqs.append(s._replace(det2d=type(s.det2d)(*(np.asarray(v)[keep2] for v in s.det2d)),
                               det3d=type(s.det3d)(*(np.asarray(v)[keep3] for v in s.det3d))))
    params, options = preset(name)
    split = pack(seqs)
    res = track(split, params, options)
    half = [i for i in range(len(seqs)) if i % 2 == seed % 2]
    bad = lane_mismatches(split, res, 0, reference_rows([seqs[i] for i in half], params, options, pool), tol=0.0,
                          sequences=half)
    assert bad["lines"] > 4000
    assert (bad["missing"], bad["extra"], bad["id"], bad["box"]) == (0, 0, 0, 0), bad


def test_preset_gains_are_the_cxx_effective_doubles():
    assert CXX_GAIN_ALPHA == 0.89999997615814208984375
    assert CXX_GAIN_BETA == 0.0010000000474974513 * 899.99993896484375
    assert repr(CXX_GAIN_BETA).startswith("0.899999981712547")
    assert 2 * CXX_GAIN_GAMMA == float(np.float32(0.2))
    for name in ("dfr2023", "dfr_head"):
        p, _ = preset(name)
        assert (p.gain_alpha, p.gain_beta, p.gain_gamma, p.a_c) == (CXX_GAIN_ALPHA, CXX_GAIN_BETA, CXX_GAIN_GAMMA, 0.05)
