"""The AB3DMOT oracle (dfrmot_jax.testing.ab3dmot_oracle) on cases made with AB3DMOT's own code
(61f3bd7 under numpy 1.23.5 / scipy 1.11.4 / filterpy 1.4.5, run outside this repository; see the
``source`` field of each fixture): affinities of box pairs for all seven metrics (degenerate pairs
included), and whole random scenes for every metric with both assignments; then rules of AB3DMOT
that the reference runs rely on, checked on hand-made inputs, and internal consistency."""

import gzip
import json
import math
from pathlib import Path

import numpy as np
import pytest
from shapely.geometry import Polygon

from dfrmot_jax.testing import ab3dmot_geometry as geo
from dfrmot_jax.testing import ab3dmot_oracle as ab

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures" / "ab3dmot_oracle"


def _pairs():
    return json.loads((FIXTURES / "affinity_pairs.json").read_text())["pairs"]


def _scenes():
    with gzip.open(FIXTURES / "random_scenes.json.gz", "rt") as f:
        return json.load(f)["cases"]


@pytest.mark.parametrize("metric", ab.METRICS)
def test_affinity_pairs_match_ab3dmot(metric):
    """Every pair's float32 affinity as AB3DMOT computed it; where its qhull call raised (identical
    or collinear-edged boxes), the oracle raises DegenerateGeometry. Garbage values of nearly
    degenerate pairs (IoU above 1 or below 0) are reproduced too."""
    raised = 0
    for p in _pairs():
        det, trk = np.array([p["det"]]), np.array([p["trk"]])
        inv_s = np.linalg.inv(np.diag(p["S_diag"]))[None]
        want = p["affinity"][metric]
        if want is None:
            raised += 1
            with pytest.raises(geo.DegenerateGeometry):
                ab.affinity_matrix(det, trk, metric, inv_s)
            continue
        got = ab.affinity_matrix(det, trk, metric, inv_s)[0, 0]
        assert got == np.float32(want), (p, got)
    assert raised < 20


@pytest.mark.parametrize("case", _scenes(), ids=lambda c: f"{c['settings']['metric']}-{c['settings']['algorithm']}-{c['seed']}")
def test_random_scenes_match_ab3dmot(case):
    """A random 20-frame scene (missed detections, false positives, near-duplicates, heading flips
    and headings beyond +-pi, empty frames, the same box again) gives AB3DMOT's lines exactly."""
    st = ab.Settings("Car", **case["settings"])
    lines, next_id = ab.track_sequence(ab.parse_detections(case["detections"]), case["n_frames"], st, case["first_id"])
    assert lines == case["lines"]
    assert next_id == case["next_id"]


# ------------------------------------------------------------------------------------------
# rules on hand-made inputs

def test_threshold_is_compared_in_float64():
    """float32(-0.2) < -0.2 in float64: a pair exactly at the threshold, as float32, is rejected
    (NumPy 1.x compared a float32 scalar with a Python float in float64; NumPy 2 would not)."""
    aff = np.array([[np.float32(-0.2)], [np.float32(-0.1)]], dtype=np.float32)
    for algorithm in ("hungar", "greedy"):
        m, ud, ut = ab.associate(aff, algorithm, -0.2)
        assert m.tolist() == [[1, 0]] and ud == [0] and ut == []
    aff = np.array([[np.float32(0.01)]], dtype=np.float32)
    m, ud, ut = ab.associate(aff, "hungar", 0.01)
    assert len(m) == 0 and ud == [0] and ut == [0]


def test_birth_order_unassigned_then_rejected():
    """Unmatched detections: those left out by the assignment (ascending), then the rejected ones
    in assignment order (Hungarian: by detection; greedy: by ascending cost)."""
    aff = np.array([[0.0, -0.9, -0.9],
                    [-0.9, -0.5, -0.9],
                    [-0.9, -0.9, -0.3],
                    [-0.9, -0.95, -0.95]], dtype=np.float32)
    m, ud, ut = ab.associate(aff, "hungar", -0.2)
    assert m.tolist() == [[0, 0]] and ud == [3, 1, 2] and ut == [1, 2]
    m, ud, ut = ab.associate(aff, "greedy", -0.2)
    assert m.tolist() == [[0, 0]] and ud == [3, 2, 1] and ut == [2, 1]


def test_greedy_takes_pairs_by_ascending_cost():
    cost = np.array([[0.1, 0.2], [0.05, 0.3]])
    assert ab.greedy_assignment(cost).tolist() == [[1, 0], [0, 1]]


def test_heading_rules():
    assert ab.wrap_angle(math.pi) == -math.pi and ab.wrap_angle(-math.pi) == -math.pi
    assert ab.wrap_angle(3.9) == 3.9 - 2 * math.pi and ab.wrap_angle(-3.9) == -3.9 + 2 * math.pi
    rng = np.random.default_rng(1)
    for pre, obs in rng.uniform(-3.9, 3.9, (2000, 2)):
        p, o = ab.orientation_correction(float(pre), float(obs))
        assert o == ab.wrap_angle(float(obs))
        assert abs(o - p) <= math.pi / 2 + 1e-12
        assert math.isclose(math.cos(2 * p), math.cos(2 * pre), abs_tol=1e-9)   # turned by multiples of pi
    assert ab.yaw_difference(2.0) == 2.0 - math.pi and ab.yaw_difference(-2.0) == -2.0 + math.pi
    assert ab.yaw_difference(5.0) == 5.0 - math.pi                             # one shift only


def test_birth_keeps_the_detection_heading_unwrapped():
    dets = ab.parse_detections("0,2,1,2,3,4,0.5,1.5,1.6,4.0,1.0,1.5,20.0,3.9,0.1\n")
    lines, next_id = ab.track_sequence(dets, 2, ab.PRESETS["car_default"], 7)
    assert next_id == 8
    assert [s.split()[16] for s in lines] == ["3.900000", "%f" % (3.9 - 2 * math.pi)]
    assert [s.split()[:2] for s in lines] == [["0", "7"], ["1", "7"]]


def test_output_rule_and_deletion():
    """min_hits 3, max_age 2: a track is written in the first 3 frames regardless, then only with
    3 hits; it coasts one frame (written, predicted), and is deleted after the second miss."""
    row = "{f},2,1,2,3,4,0.5,1.5,1.6,4.0,{x},1.5,20.0,0.1,0.1\n"
    text = "".join(row.format(f=f, x=1.0 + 0.1 * f) for f in (0, 4, 5, 6, 7))
    lines, _ = ab.track_sequence(ab.parse_detections(text), 10, ab.PRESETS["car_default"])
    frames_ids = [tuple(s.split()[:2]) for s in lines]
    # frame 0: born (id 1), written (first frames); 1: coasting, written (frame_count <= 3);
    # 2: second miss, deleted; 4: new track id 2 (hits 1, not written) ... 6: third hit, written
    assert frames_ids == [("0", "1"), ("1", "1"), ("6", "2"), ("7", "2"), ("8", "2")]


# ------------------------------------------------------------------------------------------
# internal consistency

def _random_rects(rng, n):
    return np.column_stack([rng.uniform(-3, 3, n), rng.uniform(0, 2, n), rng.uniform(-3, 3, n),
                            rng.uniform(-4, 4, n), rng.uniform(1, 5, n), rng.uniform(0.5, 2, n),
                            rng.uniform(1, 2, n)])


def test_intersection_and_hull_areas_against_shapely():
    rng = np.random.default_rng(2)
    a, b = _random_rects(rng, 300), _random_rects(rng, 300)
    ca, cb = geo.box_corners(a), geo.box_corners(b)
    for i in range(300):
        pa, pb = geo.bottom_polygon(ca[i]), geo.bottom_polygon(cb[i])
        sa, sb = Polygon(pa), Polygon(pb)
        assert sa.exterior.is_ccw and math.isclose(sa.area, a[i, 4] * a[i, 5], rel_tol=1e-12)
        clipped = geo.clip_polygon(pa, pb)
        inter = 0.0 if clipped is None else geo.hull_area(clipped)
        assert math.isclose(inter, sa.intersection(sb).area, rel_tol=1e-9, abs_tol=1e-9)
        assert math.isclose(geo.hull_area(pa + pb), sa.union(sb).convex_hull.area, rel_tol=1e-12)
        g = geo.iou_pair(geo.box_dict(a[i]), geo.box_dict(b[i]), "giou_3d", pa, pb)
        j = geo.iou_pair(geo.box_dict(a[i]), geo.box_dict(b[i]), "iou_3d", pa, pb)
        assert -1.0 <= g <= j <= 1.0


def test_kalman_update_against_the_textbook_form():
    rng = np.random.default_rng(3)
    t = ab.Track(np.array([1.0, 1.5, 20.0, 0.2, 4.0, 1.6, 1.5]), np.zeros(7), 1)
    for _ in range(5):
        t.predict()
        P_prior, x_prior = t.P.copy(), t.x.copy()
        z = x_prior[:7, 0] + rng.normal(0, 0.3, 7)
        z[3] = x_prior[3, 0]                                       # no heading wrap involved
        t.update(z)
        H, R = ab.KF_H, ab.KF_R
        K = P_prior @ H.T @ np.linalg.solve(H @ P_prior @ H.T + R, np.eye(7))
        np.testing.assert_allclose(t.x[:, 0], (x_prior + K @ (z[:, None] - H @ x_prior))[:, 0], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(t.P, (np.eye(10) - K @ H) @ P_prior, rtol=1e-9, atol=1e-9)
        np.testing.assert_array_equal(t.P, t.P.T)


def test_numpy_argsort_ties_as_numpy_1_23():
    """NumPy 1.23.5's np.argsort (default quicksort) of float32 zeros, recorded there; distinct
    values sort as any argsort does."""
    assert ab.numpy_argsort(np.zeros(16, np.float32)) == list(range(16))
    assert ab.numpy_argsort(np.zeros(17, np.float32)) == [0, 14, 13, 12, 11, 10, 9, 15, 8, 6, 5, 4, 3, 2, 1, 7, 16]
    assert ab.numpy_argsort(np.zeros(19, np.float32)) == [0, 16, 15, 14, 13, 12, 11, 10, 17, 9, 7, 6, 5, 4, 3, 2, 1, 8, 18]
    rng = np.random.default_rng(4)
    for n in (1, 2, 17, 50, 300):
        v = rng.normal(size=n).astype(np.float32)
        assert ab.numpy_argsort(v) == np.argsort(v, kind="stable").tolist()


def test_sequences_share_one_id_counter_and_empty_files_are_skipped(tmp_path):
    """Ids run on across sequences in order; a sequence with an empty detection file is skipped
    (AB3DMOT writes no file for it and its counter does not move); frames come from label_02."""
    det_dir = tmp_path / "detections" / "pointrcnn" / "car"
    det_dir.mkdir(parents=True)
    (tmp_path / "label_02").mkdir()
    row = "{f},2,1,2,3,4,0.5,1.5,1.6,4.0,{x},1.5,20.0,0.1,0.1\n"
    (det_dir / "0000.txt").write_text(row.format(f=0, x=1.0) + row.format(f=0, x=9.0))
    (det_dir / "0001.txt").write_text("")
    (det_dir / "0002.txt").write_text(row.format(f=1, x=1.0))
    for seq, last in (("0000", 2), ("0001", 3), ("0002", 1)):
        (tmp_path / "label_02" / f"{seq}.txt").write_text(   # one full KITTI label row (read by io.kitti)
            f"{last} -1 DontCare -1 -1 -10 1 2 3 4 -1000 -1000 -1000 -10 -1 -1 -1\n")
    out = ab.track_sequences(tmp_path, ab.PRESETS["car_default"], ["0000", "0001", "0002"], out_dir=tmp_path / "out")
    assert sorted(out) == ["0000", "0002"]
    assert [s.split()[:2] for s in out["0000"]] == [["0", "2"], ["0", "1"], ["1", "2"], ["1", "1"]]
    assert [s.split()[:2] for s in out["0002"]] == [["1", "3"]]
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["0000.txt", "0002.txt"]
