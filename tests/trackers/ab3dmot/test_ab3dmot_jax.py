"""AB3DMOT in JAX (dfrmot_jax.trackers.ab3dmot) against the NumPy oracle (dfrmot_jax.testing.ab3dmot_oracle)
and AB3DMOT's own outputs: line for line, ids included.

Every compiled program costs seconds, so the tests share them: a program is one ``Options`` and one
frame shape, and each test packs everything it checks (KITTI sequences, the fixture's random scenes,
edge scenes made here) as sequences of one split, run once for a batch of lanes, one lane per
setting; each lane's lines are read for the sequences that are its own.

Fast tier: one program, m_dis with Hungarian assignment (the quickest to compile: no footprint
geometry), on KITTI 0012 and 0017 (AB3DMOT's car_mdis run) and on the fixture's and this file's m_dis
Hungarian scenes; the validator and the writer. Slow tier: every metric with both assignments on the
fixture's scenes and edge scenes (the car preset's giou_3d Hungarian program also on KITTI 0012 and
0017), the seven reference runs on all 21 sequences, a batch against its lanes run alone, capacity
overflow, the association's slot buckets.
"""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import jax
import numpy as np
import pytest

from dfrmot_jax.trackers import ab3dmot as J
from dfrmot_jax.trackers.ab3dmot.batch import tracking_lanes
from dfrmot_jax.testing import ab3dmot_oracle as ab
from dfrmot_jax.testing.ab3dmot_compare import Comparison, compare_folder
from dfrmot_jax.testing.ab3dmot_geometry import DegenerateGeometry

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures" / "ab3dmot_oracle"
REFERENCE = Path("reference") / "ab3dmot_tracker"
N_DET = 12              # detection slots of every scene split (KITTI 0012 / 0017 car: 5 and 6)
TRACKS = 32
SCENE_FRAMES = 20
ALGORITHMS = {"hungar": "hungarian", "greedy": "greedy"}
#: the oracle's fixture thresholds per metric (scripts/ab3dmot_oracle_fixtures.py)
THRESHOLDS = {"iou_2d": 0.1, "iou_3d": 0.01, "giou_2d": -0.3, "giou_3d": -0.2, "dist_2d": 2.5, "dist_3d": 3,
              "m_dis": 6}


def _fixture_scenes():
    with gzip.open(FIXTURES / "random_scenes.json.gz", "rt") as f:
        return json.load(f)["cases"]


def _row(f, cls, box, rng):
    x1, y1 = float(rng.integers(0, 100)) * 10, float(rng.integers(10, 30)) * 10
    return "%d,%d,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f" % (
        f, cls, x1, y1, x1 + 50, y1 + 25, round(rng.uniform(-3, 15), 2), *box, round(rng.uniform(-np.pi, np.pi), 2))


def edge_scene(seed: int, n_frames: int = SCENE_FRAMES, most: int = N_DET) -> str:
    """A scene in the PointRCNN CSV format stressing the rules: headings near +-90 degrees and
    turned by pi, boxes placed symmetrically about a track (equal affinities), exact duplicates in
    a frame and repeated across frames, empty frames, misses and clutter."""
    rng = np.random.default_rng(seed)
    objs = []
    for _ in range(int(rng.integers(2, 5))):
        th = float(rng.choice([np.pi / 2, -np.pi / 2, 0.0, np.pi])) + float(rng.normal(0, 1e-3))
        objs.append(dict(p=np.array([rng.uniform(-10, 10), rng.uniform(1, 2), rng.uniform(8, 40)]),
                         v=rng.normal(0, 0.5, 3) * [1, 0, 1], th=th, lwh=rng.uniform([3, 1.4, 1.3], [5, 2, 1.8]),
                         start=int(rng.integers(0, n_frames // 2)), last=None))
    rows = []
    for f in range(n_frames):
        if rng.random() < 0.1:
            continue                                                    # an empty frame
        frame = []
        for o in objs:
            if f < o["start"] or rng.random() < 0.15:
                continue
            p = o["p"] + o["v"] * (f - o["start"]) + rng.normal(0, 0.1, 3) * [1, 0.1, 1]
            th = o["th"] + (np.pi if rng.random() < 0.15 else 0.0) + float(rng.normal(0, 2e-3))
            box = [*np.round(o["lwh"][::-1], 4), *np.round(p, 4), round(float(np.clip(th, -3.9, 3.9)), 4)]
            if o["last"] is not None and rng.random() < 0.1:
                box = o["last"]                                         # the same box again
            o["last"] = box
            frame.append(box)
            if rng.random() < 0.1:
                frame.append(box)                                       # an exact duplicate
            if rng.random() < 0.15:                                     # two boxes mirrored about this one
                off = rng.uniform(0.3, 1.5)
                frame += [[*box[:3], box[3] + off, *box[4:]], [*box[:3], box[3] - off, *box[4:]]]
        for _ in range(int(rng.poisson(0.3))):
            frame.append([*np.round(rng.uniform([1.3, 1.4, 3], [1.8, 2, 5]), 4),
                          *np.round(rng.uniform([-15, 1, 5], [15, 2, 50]), 4),
                          round(float(rng.uniform(-3.9, 3.9)), 4)])
        for i in rng.permutation(len(frame))[:most]:
            rows.append(_row(f, 2, frame[i], rng))
    return "\n".join(rows) + "\n"


class Scene:
    """One sequence to check: its name, detections, frames, the oracle's settings and first id."""

    def __init__(self, name, text, settings, first_id=1, n_frames=SCENE_FRAMES, lines=None, next_id=None):
        self.name, self.text, self.settings, self.first_id = name, text, settings, first_id
        self.n_frames = n_frames
        self.lines, self.next_id, self.states = lines, next_id, None
        try:                                                             # the oracle's answer
            tracker = ab.SequenceTracker(settings, first_id)
            dets = ab.parse_detections(text)
            rows = [(f, row) for f in range(n_frames) for row in tracker.step(dets.get(f, ab.EMPTY))]
            self.states = np.array([row[2] for _, row in rows]).reshape(-1, 7)      # full precision
            if lines is None:
                self.lines, self.next_id = [ab.format_line(f, row) for f, row in rows], tracker.next_id
        except DegenerateGeometry:
            assert lines is None                                         # AB3DMOT stops here


def _params(st: ab.Settings) -> J.Params:
    return J.Params(st.threshold, st.min_hits, st.max_age)


def run_scenes(scenes: list[Scene], options: J.Options, kitti: J.Split | None = None, kitti_params=None,
               grow: bool = True):
    """Run every scene's setting as a lane over one split (KITTI sequences first, then the scenes);
    returns (split, output, {scene name: lane})."""
    packed = J.pack([(s.name, J.parse_detections(s.text), s.n_frames) for s in scenes], N_DET)
    assert packed.dropped == 0
    split = packed if kitti is None else _concat(kitti, packed)
    lanes = ([kitti_params] if kitti is not None else []) + [_params(s.settings) for s in scenes]
    out = J.run(J.stack_params(lanes), split.frames, options, grow=grow)
    first = 1 if kitti is not None else 0
    return split, out, {s.name: first + k for k, s in enumerate(scenes)}


def _concat(a: J.Split, b: J.Split) -> J.Split:
    def pad(x, n):
        return np.concatenate([x, np.zeros(x.shape[:1] + (n - x.shape[1],) + x.shape[2:], x.dtype)], 1)
    n = max(a.info.shape[1], b.info.shape[1])
    frames = J.Frames(*(np.concatenate([pad(x, n) if x.ndim > 1 else x, pad(y, n) if y.ndim > 1 else y])
                        for x, y in zip(a.frames, b.frames)))
    return J.Split(frames, np.concatenate([pad(a.info, n), pad(b.info, n)]),
                   np.concatenate([a.sequence, b.sequence + len(a.names)]), np.concatenate([a.frame, b.frame]),
                   a.names + b.names, a.dropped + b.dropped)


def check_scenes(split, out, lanes, scenes):
    """Each scene's lines from its lane equal the oracle's (AB3DMOT's), ids included, and its 3D
    boxes the oracle's bit for bit; a scene where AB3DMOT stops (degenerate geometry) is reported
    by its lane (the counters cover a lane's whole split: every lane runs every scene's frames)."""
    assert not out.overflow.any() and not out.pairs_left.any() and not out.fallback.any()
    for s in scenes:
        lane = lanes[s.name]
        got = J.result_lines(split, out, lane, starts={s.name: s.first_id})[s.name]
        if s.lines is None:
            assert out.degenerate[lane] > 0, s.name
            continue
        assert out.degenerate[lane] == 0, s.name
        assert got == s.lines, (s.name, s.settings)
        seq = np.flatnonzero(split.sequence == split.names.index(s.name))
        ids = out.ids[lane, seq]
        boxes = np.concatenate([out.boxes[lane, t][np.flatnonzero(ids[k] >= 0)[::-1]] for k, t in enumerate(seq)])
        np.testing.assert_array_equal(boxes, s.states, err_msg=s.name)          # the 3D boxes bit for bit
        t0, t1 = np.flatnonzero(split.sequence == split.names.index(s.name))[[0, -1]]
        start = out.next_id[lane, t0 - 1] if t0 else 1
        assert out.next_id[lane, t1] - start + s.first_id == s.next_id


def fixture_scenes(metric: str, algorithm: str) -> list[Scene]:
    return [Scene(f"f{c['seed']}", c["detections"], ab.Settings("Car", **c["settings"]), c["first_id"],
                  c["n_frames"], c["lines"], c["next_id"])
            for c in _fixture_scenes() if (c["settings"]["metric"], c["settings"]["algorithm"]) == (metric, algorithm)]


def own_scenes(metric: str, algorithm: str, seeds) -> list[Scene]:
    out = []
    for seed in seeds:
        rng = np.random.default_rng(seed + 1000)
        st = ab.Settings("Car", algorithm, metric, THRESHOLDS[metric], int(rng.integers(1, 4)), int(rng.integers(1, 5)))
        out.append(Scene(f"e{seed}", edge_scene(seed), st, int(rng.choice([1, 57]))))
    return out


def compare_reference(lines, ref_dir) -> Comparison:
    total = Comparison(diffs=[])
    for c in compare_folder(lines, ref_dir).values():
        total += c
    return total


# ----------------------------------------------------------------------------------------------
# fast tier: one program (m_dis, Hungarian: the quickest to compile)

@pytest.mark.slow
def test_one_program_matches_reference_and_oracle(kitti_root):
    """KITTI 0012 and 0017 give AB3DMOT's car_mdis lines (ids up to the counter's start); the
    fixture's m_dis Hungarian scenes give AB3DMOT's lines; edge scenes the oracle's."""
    ref = kitti_root / REFERENCE / "head61f3bd7_car_mdis"
    if not ref.is_dir():
        pytest.skip(f"AB3DMOT reference run not found at {ref}")
    options = J.Options("m_dis", "hungarian", capacity=TRACKS)
    kitti = J.read_split(kitti_root, "car", ("0012", "0017"), N_DET)
    scenes = fixture_scenes("m_dis", "hungar") + own_scenes("m_dis", "hungar", range(6))
    split, out, lanes = run_scenes(scenes, options, kitti, _params(ab.PRESETS["car_mdis"]))
    lines = J.result_lines(split, out, 0)
    total = compare_reference({k: lines[k] for k in kitti.names}, ref)
    assert (total.differing, total.close, total.length_mismatch) == (0, 0, False), total.diffs[:3]
    assert total.exact == 460
    check_scenes(split, out, lanes, scenes)


def test_settings_are_validated_readably():
    params, options = J.ab3dmot_pedestrian()
    assert (params, options.metric, options.algorithm) == (J.Params(-0.4, 1, 4), "giou_3d", "greedy")
    assert J.problems(params, options) == []
    bad = J.problems(J.Params(threshold=np.nan, min_hits=1.5, max_age=0),
                     J.Options(metric="iou", algorithm="hungar", capacity=-1))
    assert bad == ["threshold: not finite (nan)", "min_hits: expected an integer (1.5)",
                   "max_age: outside the valid range [1, 1e+06] (0)",
                   "metric: expected one of "
                   "('iou_2d', 'iou_3d', 'giou_2d', 'giou_3d', 'dist_2d', 'dist_3d', 'm_dis') ('iou')",
                   "algorithm: expected one of ('hungarian', 'greedy') ('hungar')",
                   "capacity: expected an integer from 0 to 4096 (-1)"]
    with pytest.raises(ValueError, match="invalid AB3DMOT setting"):
        J.validate(J.Params(min_hits=[1, 2], max_age=[1, 2, 3]), J.Options())
    assert J.compared_threshold(6.0, "m_dis") == -6.0 and J.compared_threshold(-0.2, "giou_3d") == -0.2


def test_writer_numbers_ids_as_the_counter_and_writes_newest_first():
    text = "0,2,1,2,3,4,0.5,1.5,1.6,4.0,1.0,1.5,20.0,0.1,0.1\n0,2,1,2,3,4,0.7,1.5,1.6,4.0,9.0,1.5,20.0,0.1,0.2\n"
    split = J.pack([("0000", J.parse_detections(text), 2), ("0001", {}, 3), ("0002", J.parse_detections(text), 1)], 2)
    assert split.names == ("0000", "0002") and split.frames.reset.tolist() == [True, False, True]
    t, k = 3, 4
    ids = np.full((1, t, k), -1)
    ids[0, 0, :2] = [7, 8]                                  # run ids from 7: frame 0 of 0000, two births
    ids[0, 2, :2] = [9, 10]
    src = np.zeros((1, t, k), int)
    src[0, 0, :2], src[0, 2, :2] = [0, 1], [4, 5]           # t * N + slot
    boxes = np.zeros((1, t, k, 7))
    out = J.RunOutput(ids, src, boxes, np.array([[9, 9, 11]]), np.zeros((1, t), int), *np.zeros((5, 1), int))
    lines = J.result_lines(split, out, run_first_id=7)
    assert [s.split()[:2] for s in lines["0000"]] == [["0", "2"], ["0", "1"]]      # newest first, from 1
    assert [s.split()[:2] for s in lines["0002"]] == [["0", "4"], ["0", "3"]]      # the counter runs on
    assert lines["0000"][1].split()[5] == "0.100000" and lines["0000"][0].split()[17] == "0.700000"


def test_lanes_that_track_alike_are_tracked_once_and_equal_each_lane_alone():
    """``min_hits`` and ``score_threshold`` choose written lines only: lanes equal in ``threshold``
    and ``max_age`` are tracked once (``tracking_lanes``), and every lane's output (ids, sources,
    boxes, id counter) equals that lane run alone."""
    scenes = own_scenes("dist_3d", "hungar", range(210, 213))
    split = J.pack([(s.name, J.parse_detections(s.text), s.n_frames) for s in scenes], N_DET)
    options = J.Options("dist_3d", "hungarian", capacity=TRACKS)
    params = J.stack_params([J.Params(3.0, 1, 2), J.Params(3.0, 3, 2), J.Params(3.0, 2, 2, 0.5),
                             J.Params(1.5, 3, 2), J.Params(3.0, 0, 2, -1.0), J.Params(1.5, 1, 2)])
    core, of = tracking_lanes(params)
    assert core.threshold.tolist() == [3.0, 1.5] and of.tolist() == [0, 0, 0, 1, 0, 1]
    assert core.min_hits.tolist() == [0, 0] and np.isneginf(core.score_threshold).all()
    batch = J.run(params, split.frames, options)
    written = 0
    for b in range(6):
        alone = J.run(J.Params(*(v[b] for v in params)), split.frames, options)
        for field in ("ids", "src", "boxes", "next_id", "dropped", "overflow", "peak"):
            assert np.array_equal(getattr(batch, field)[b], getattr(alone, field)[0]), (b, field)
        written += int((alone.ids >= 0).sum())
    assert len({int((batch.ids[b] >= 0).sum()) for b in range(6)}) >= 4 and written > 100


# ----------------------------------------------------------------------------------------------
# slow tier

COMBOS = [(m, a) for m in ab.METRICS for a in ALGORITHMS]


@pytest.mark.slow
@pytest.mark.parametrize("metric,algorithm", COMBOS, ids=[f"{m}-{a}" for m, a in COMBOS])
def test_every_metric_and_algorithm_matches_on_edge_scenes(metric, algorithm):
    """The fixture's scenes for this setting (AB3DMOT's own lines) and 8 edge scenes (the oracle's
    lines, or AB3DMOT's stop reported as degenerate), one program, one lane each."""
    scenes = fixture_scenes(metric, algorithm) + own_scenes(metric, algorithm, range(100, 108))
    options = J.Options(metric, ALGORITHMS[algorithm], capacity=TRACKS, pairs=48)
    split, out, lanes = run_scenes(scenes, options)
    check_scenes(split, out, lanes, scenes)


@pytest.mark.slow
def test_car_preset_with_buckets_matches_reference_and_oracle(kitti_root):
    """The car preset (giou_3d, Hungarian) with the association on 3 slot buckets: KITTI 0012 and
    0017 give AB3DMOT's car_default (= car_noaffipro) lines; the fixture's giou_3d Hungarian scenes
    AB3DMOT's; edge scenes the oracle's."""
    ref = kitti_root / REFERENCE / "head61f3bd7_car_default"
    if not ref.is_dir():
        pytest.skip(f"AB3DMOT reference run not found at {ref}")
    params, options = J.ab3dmot_car(capacity=TRACKS, pairs=24, buckets=3)
    kitti = J.read_split(kitti_root, "car", ("0012", "0017"), N_DET)
    scenes = fixture_scenes("giou_3d", "hungar") + own_scenes("giou_3d", "hungar", range(6))
    split, out, lanes = run_scenes(scenes, options, kitti, params)
    lines = J.result_lines(split, out, 0)
    total = compare_reference({k: lines[k] for k in kitti.names}, ref)
    assert (total.differing, total.close, total.length_mismatch) == (0, 0, False), total.diffs[:3]
    assert total.exact == 340
    check_scenes(split, out, lanes, scenes)


@pytest.mark.slow
def test_a_batch_equals_its_lanes_run_alone():
    """Four settings in one vmapped call give each lane's output of a call of its own, every field.
    The split, options and shapes of test_lanes_that_track_alike_are_tracked_once_and_equal_each_lane_alone
    (edge scenes 210-212, dist_3d Hungarian): the runs alone reuse its compiled one-lane program."""
    scenes = own_scenes("dist_3d", "hungar", range(210, 213))
    split = J.pack([(s.name, J.parse_detections(s.text), s.n_frames) for s in scenes], N_DET)
    options = J.Options("dist_3d", "hungarian", capacity=TRACKS)
    params = J.stack_params([J.Params(3.0, 1, 1), J.Params(1.0, 3, 2), J.Params(6.0, 2, 4), J.Params(0.5, 1, 3)])
    batch = J.run(params, split.frames, options)
    for b in range(4):
        alone = J.run(J.Params(*(v[b] for v in params)), split.frames, options)
        for field in (f for f in J.RunOutput._fields if f != "options"):   # capacity too
            np.testing.assert_array_equal(getattr(batch, field)[b], getattr(alone, field)[0], err_msg=field)
    assert len({J.result_lines(split, batch, b)[scenes[0].name].__len__() for b in range(4)}) > 1


@pytest.mark.slow
def test_capacity_overflow_is_reported():
    """Births beyond the track capacity are counted, never silently dropped; ``run`` grows the
    capacity until no lane overflows, and then the scenes give the oracle's lines."""
    scenes = own_scenes("dist_2d", "hungar", range(300, 304))
    small = J.Options("dist_2d", "hungarian", capacity=8)              # these scenes need 9-10 slots
    split, out, lanes = run_scenes(scenes, small, grow=False)
    assert (out.overflow > 0).any() and (out.peak[out.overflow > 0] > 8).all()
    split, out, lanes = run_scenes(scenes, small)                    # grown until no lane overflows
    assert out.options.capacity == 16 and (out.peak <= 16).all()
    check_scenes(split, out, lanes, scenes)
    scenes = own_scenes("iou_2d", "hungar", range(300, 304))            # the step alone clips at most
    few = J.Options("iou_2d", "hungarian", capacity=TRACKS, pairs=8)      # Options.pairs; these need 9-16
    split = J.pack([(s.name, J.parse_detections(s.text), s.n_frames) for s in scenes], N_DET)
    lane = jax.jit(lambda f, st: J.run_lane(J.Params(0.1, 1, 2), f, st, few)[0].pairs_left)
    with jax.enable_x64(True):
        assert int(lane(split.frames, J.init(few))) > 0                   # left unclipped: counted


@pytest.mark.slow
def test_where_ab3dmot_stops_the_lane_says_so():
    """A zero-width detection on a track: AB3DMOT's qhull raises (the oracle's DegenerateGeometry)
    and its run stops; the lane reports it (``degenerate``: counted over the lane's whole split)."""
    row = "{f},2,1,2,3,4,0.5,1.5,{w},4.0,{x},1.5,20.0,0.3,0.1\n"
    text = "".join(row.format(f=f, w=1.6 if f != 2 else 0.0, x=1.0 + 0.1 * f) for f in range(4))
    scene = Scene("stop", text, ab.Settings("Car", "hungar", "iou_2d", 0.1, 1, 2))
    assert scene.lines is None
    split, out, lanes = run_scenes([scene], J.Options("iou_2d", "hungarian", capacity=TRACKS))
    check_scenes(split, out, lanes, [scene])
    assert out.degenerate.tolist() == [1]


#: the reference runs tracked here; ``car_default`` goes through the family's path, ``dfrmot track``
#: (tests/cli/test_track_ab3dmot.py, byte for byte), and ``car_noaffipro``'s files are ``car_default``'s
#: (:func:`test_the_run_without_affinity_post_processing_is_the_default_run`)
TRACKED_RUNS = [r for r in ab.PRESETS if r not in ("car_default", "car_noaffipro")]


@pytest.mark.kitti
def test_the_run_without_affinity_post_processing_is_the_default_run(kitti_root):
    """``affi_pro`` changes only AB3DMOT's saved affinity matrices: its run's files are the default's."""
    runs = [kitti_root / REFERENCE / f"head61f3bd7_{r}" for r in ("car_default", "car_noaffipro")]
    if not all(r.is_dir() for r in runs):
        pytest.skip(f"AB3DMOT reference runs not found at {runs}")
    names = sorted(p.name for p in runs[0].glob("*.txt"))
    assert len(names) == 21 and names == sorted(p.name for p in runs[1].glob("*.txt"))
    assert all((runs[0] / n).read_bytes() == (runs[1] / n).read_bytes() for n in names)


#: detection slots of every class's 21-sequence split (the car split's fullest frame: 19)
KITTI_SLOTS = 19


@pytest.mark.slow
@pytest.mark.kitti
@pytest.mark.parametrize("run", TRACKED_RUNS)
def test_all_sequences_match_reference(kitti_root, run):
    """All 21 sequences in order from id 1: AB3DMOT's lines exactly, ids literal. Every class's split
    has ``KITTI_SLOTS`` detection slots (the car split's own; the pedestrian split's 13 padded with
    empty slots), so runs with the same ``Options`` (ped_default and car_greedy: giou_3d, greedy)
    have the same frame shape and share one compiled program; the padding is checked by the same
    exact comparison."""
    ref = kitti_root / REFERENCE / f"head61f3bd7_{run}"
    if not ref.is_dir():
        pytest.skip(f"AB3DMOT reference run not found at {ref}")
    st = ab.PRESETS[run]
    split = J.read_split(kitti_root, st.category, capacity=KITTI_SLOTS)
    assert split.dropped == 0 and split.frames.valid.shape[1] == KITTI_SLOTS
    out = J.run(_params(st), split.frames, J.Options(st.metric, ALGORITHMS[st.algorithm], capacity=40, buckets=3))
    assert not (out.overflow.any() or out.pairs_left.any() or out.degenerate.any() or out.fallback.any())
    lines = J.result_lines(split, out)
    total = compare_reference(lines, ref)
    print(f"{run}: exact {total.exact}, within 2e-6 {total.close}, differing {total.differing}")
    assert (total.differing, total.close, total.length_mismatch) == (0, 0, False), total.diffs[:3]
    for seq, ours in lines.items():
        want = (ref / f"{seq}.txt").read_text().splitlines()
        assert [s.split(" ", 2)[1] for s in ours] == [s.split(" ", 2)[1] for s in want], seq
