"""Parity of dfrmot_jax.metrics with the reference ``trackeval`` package (KITTI 2D box), run in-process.

Every field of HOTA / CLEAR / Identity / Count must match TrackEval within 1e-9 (counts exactly),
per sequence and COMBINED, on (a) the published DFR-FastMOT output, (b) seeded edits that stress
the preprocessing and assignment rules, (c) a pedestrian tracker, and (d) the array entry point
must equal the file entry point bit for bit.
"""

from __future__ import annotations

import numpy as np
import pytest

trackeval = pytest.importorskip("trackeval")

from dfrmot_jax.io.kitti import read_detections_2d, read_tracking_labels  # noqa: E402
from dfrmot_jax.metrics import evaluate_arrays, evaluate_files, prepare_gt  # noqa: E402
from dfrmot_jax.testing.metric_edits import (SeqResults, f32, load_results, naive_tracks, pack_arrays,  # noqa: E402
                                             stress_edit, write_results)
from dfrmot_jax.testing.trackeval_adapter import make_gt_folder, run_trackeval  # noqa: E402

REF = "reference/dfr_fastmot_rrc_pointrcnn"
STRESS_SEQS = ["0000", "0008", "0011", "0014", "0017"]  # vans, DontCare, dense traffic, no cars at all (0017)
PED_SEQS = ["0012", "0013", "0014", "0016", "0017"]  # 0013 has 'Person' (sitting) distractors

INT_FIELDS = {"CLR_TP", "CLR_FN", "CLR_FP", "IDSW", "MT", "PT", "ML", "Frag", "CLR_Frames", "IDTP", "IDFN", "IDFP",
              "Dets", "GT_Dets", "IDs", "GT_IDs", "HOTA_TP", "HOTA_FN", "HOTA_FP"}


def assert_same(te: dict, ours: dict, atol: float = 1e-9, exact: bool = False, tag: str = "") -> None:
    """Every (seq, field) of TrackEval's flattened result equals ours (counts exactly, floats within atol)."""
    assert set(te) == set(ours), f"{tag}: sequences differ: {sorted(te)} vs {sorted(ours)}"
    bad = []
    for seq in te:
        assert set(te[seq]) == set(ours[seq]), f"{tag} {seq}: fields differ: {set(te[seq]) ^ set(ours[seq])}"
        for f, v in te[seq].items():
            a = np.asarray(v, dtype=np.float64)
            b = np.asarray(ours[seq][f], dtype=np.float64)
            if exact or f in INT_FIELDS:
                ok = a.shape == b.shape and np.array_equal(a, b)
            else:
                ok = a.shape == b.shape and np.allclose(a, b, atol=atol, rtol=0)
            if not ok:
                bad.append(f"{seq}.{f}: trackeval={v!r} ours={ours[seq][f]!r}")
    assert not bad, f"{tag}: {len(bad)} mismatches:\n" + "\n".join(bad[:20])


# ----------------------------------------------------------------------------------------- (a)

@pytest.fixture(scope="module")
def reference_run(kitti_root, tmp_path_factory):
    refdir = kitti_root / REF
    seqs = sorted(p.stem for p in refdir.glob("*.txt"))
    gt = prepare_gt(kitti_root, "car", seqs)
    tmp = tmp_path_factory.mktemp("te_ref")
    make_gt_folder(tmp / "gt", kitti_root, gt.lengths_dict)
    data = tmp / "trackers" / "dfr" / "data"
    data.mkdir(parents=True)
    for s in seqs:
        (data / f"{s}.txt").symlink_to((refdir / f"{s}.txt").resolve())
    te = run_trackeval(tmp / "gt", tmp / "trackers", "car")["dfr"]
    return gt, refdir, te


@pytest.mark.slow
def test_reference_parity(reference_run):
    gt, refdir, te = reference_run
    ours = evaluate_files(refdir, gt)
    assert len(ours) == 21  # 20 sequences + COMBINED
    assert_same(te, ours, tag="reference")


@pytest.mark.slow
def test_reference_published_figures(reference_run, kitti_root):
    _, refdir, te = reference_run
    # default: every label_02 sequence (0017 has no cars and no result file -> contributes nothing)
    ours = evaluate_files(refdir, kitti_root, "car")
    c = ours["COMBINED"]
    pct = {k: round(100 * float(np.mean(c[k])), 2) for k in ("HOTA", "DetA", "AssA", "MOTA", "MOTP", "IDF1")}
    assert pct == {"HOTA": 82.79, "DetA": 83.12, "AssA": 82.59, "MOTA": 90.73, "MOTP": 90.57, "IDF1": 91.36}
    assert (c["IDSW"], c["MT"], c["ML"], c["Frag"]) == (177, 503, 8, 238)
    for f, v in te["COMBINED"].items():  # the extra, empty sequence 0017 changes no combined field
        assert np.allclose(np.asarray(c[f], float), np.asarray(v, float), atol=1e-9, rtol=0), f


# ----------------------------------------------------------------------------------------- (b)

def _stress_lanes(kitti_root) -> dict[str, dict[str, SeqResults]]:
    labels = {s: read_tracking_labels(kitti_root / "label_02" / f"{s}.txt") for s in STRESS_SEQS}
    ref = load_results(kitti_root / REF, STRESS_SEQS)  # no 0017 file -> empty
    lanes = {
        "mixed": stress_edit(ref, labels, np.random.default_rng(0), strength=1.0),
        "heavy": stress_edit(ref, labels, np.random.default_rng(1), strength=3.0),
        "ties": stress_edit(ref, labels, np.random.default_rng(2), kinds=("swap", "dup", "drop"), strength=3.0),
        "rules": stress_edit(ref, labels, np.random.default_rng(3), kinds=("dontcare", "tiny", "van", "jitter", "other"),
                             strength=4.0),
    }
    lanes["heavy"]["0008"] = SeqResults.empty()  # an empty sequence
    return lanes


@pytest.fixture(scope="module")
def stress_run(kitti_root, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("te_stress")
    gt = prepare_gt(kitti_root, "car", STRESS_SEQS)
    make_gt_folder(tmp / "gt", kitti_root, gt.lengths_dict)
    lanes = _stress_lanes(kitti_root)
    dirs = {}
    for name, lane in lanes.items():
        dirs[name] = write_results(tmp / "trackers" / name / "data", lane, STRESS_SEQS)
    # a tracker with no output at all: TrackEval needs (empty) files, ours gets an empty folder
    write_results(tmp / "trackers" / "nothing" / "data", {}, STRESS_SEQS)
    dirs["nothing"] = tmp / "no_files"
    dirs["nothing"].mkdir()
    te = run_trackeval(tmp / "gt", tmp / "trackers", "car")
    return gt, lanes, dirs, te


@pytest.mark.slow
@pytest.mark.parametrize("name", ["mixed", "heavy", "ties", "rules", "nothing"])
def test_stress_parity(stress_run, name):
    gt, _, dirs, te = stress_run
    ours = evaluate_files(dirs[name], gt)
    assert_same(te[name], ours, tag=name)


@pytest.mark.slow
def test_stress_cases_are_exercised(stress_run):
    """The edits really hit the rules: distractor matches, DontCare / tiny removals, empty sequences."""
    gt, lanes, dirs, te = stress_run
    r = te["rules"]
    dets_in = sum(int(np.sum((np.char.lower(lanes["rules"][s].type.astype(str)) == "car")
                             & (lanes["rules"][s].track_id >= 0))) for s in STRESS_SEQS)
    assert r["COMBINED"]["Dets"] < dets_in - 200  # many boxes removed by preprocessing
    assert te["heavy"]["0008"]["Dets"] == 0 and te["heavy"]["0008"]["CLR_FN"] > 0
    assert te["mixed"]["0017"]["GT_Dets"] == 0 and te["mixed"]["0017"]["CLR_FP"] > 0
    assert te["nothing"]["COMBINED"]["HOTA_TP"].sum() == 0
    assert te["heavy"]["COMBINED"]["IDSW"] > te["mixed"]["COMBINED"]["IDSW"] > 0


# ----------------------------------------------------------------------------------------- (c)

def _pedestrian_lanes(kitti_root) -> dict[str, dict[str, SeqResults]]:
    naive, own = {}, {}
    for s in PED_SEQS:
        d = read_detections_2d(kitti_root / "detections" / "rrc" / "pedestrian" / f"{s}.txt")
        keep = np.flatnonzero(d.score >= 0.5)
        keep = keep[np.argsort(d.frame[keep], kind="stable")]
        fr, box = d.frame[keep].astype(np.int64), f32(d.box[keep])
        types = np.full(len(fr), "Pedestrian", dtype="<U16")
        naive[s] = SeqResults(fr, naive_tracks(fr, box), types, box)
        own[s] = SeqResults(fr, np.arange(len(fr), dtype=np.int64), types, box)
    labels = {s: read_tracking_labels(kitti_root / "label_02" / f"{s}.txt") for s in PED_SEQS}
    edited = stress_edit(naive, labels, np.random.default_rng(7), strength=2.0, cls_name="Pedestrian")
    return {"naive": naive, "own_ids": own, "edited": edited}


@pytest.fixture(scope="module")
def pedestrian_run(kitti_root, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("te_ped")
    gt = prepare_gt(kitti_root, "pedestrian", PED_SEQS)
    make_gt_folder(tmp / "gt", kitti_root, gt.lengths_dict)
    lanes = _pedestrian_lanes(kitti_root)
    dirs = {n: write_results(tmp / "trackers" / n / "data", lane, PED_SEQS) for n, lane in lanes.items()}
    te = run_trackeval(tmp / "gt", tmp / "trackers", "pedestrian")
    return gt, lanes, dirs, te


@pytest.mark.slow
@pytest.mark.parametrize("name", ["naive", "own_ids", "edited"])
def test_pedestrian_parity(pedestrian_run, name):
    gt, _, dirs, te = pedestrian_run
    ours = evaluate_files(dirs[name], gt)
    assert_same(te[name], ours, tag=name)
    assert te[name]["COMBINED"]["HOTA_TP"][0] > 0


@pytest.mark.slow
def test_stress_parity_clear_frames_in_order(stress_run):
    """CLEAR's frames that need the solver, solved one by one in time order in compiled code (the
    continuation bonus from the previous frame's matches): equal to TrackEval on the tie-heavy edits
    (duplicates, swaps), several lanes in one batch."""
    gt, lanes, _, te = stress_run
    names = ["ties", "heavy"]
    ids, boxes, offsets = pack_arrays([lanes[n] for n in names], STRESS_SEQS, gt.lengths)
    for name, res in zip(names, evaluate_arrays(gt, ids, boxes, offsets, lanes_per_batch=2)):
        assert_same(te[name], res, tag=name)


# ----------------------------------------------------------------------------------------- (d)

@pytest.mark.slow
def test_arrays_equal_files_car(stress_run):
    gt, lanes, dirs, _ = stress_run
    names = ["mixed", "heavy", "ties", "rules"]
    lane_list = [lanes[n] for n in names] + [{}]
    ids, boxes, offsets = pack_arrays(lane_list, STRESS_SEQS, gt.lengths)
    assert ids.dtype == np.int32 and boxes.dtype == np.float32 and ids.shape[0] == 5
    got = evaluate_arrays(gt, ids, boxes, offsets, lanes_per_batch=2)
    for name, res in zip(names + ["nothing"], got):
        assert_same(evaluate_files(dirs[name], gt), res, exact=True, tag=name)


@pytest.mark.slow
def test_arrays_layout_with_gaps_and_padding(stress_run):
    """Sequences placed anywhere along T (gaps ignored) and extra empty K slots change nothing."""
    gt, lanes, dirs, _ = stress_run
    ids, boxes, offsets = pack_arrays([lanes["mixed"], lanes["ties"]], STRESS_SEQS, gt.lengths, k=40)
    B, T, K = ids.shape
    gap = 7
    T2 = T + gap * len(STRESS_SEQS)
    ids2 = np.full((B, T2, K), -1, np.int32)
    boxes2 = np.full((B, T2, K, 4), np.nan, np.float32)
    new_off = offsets + gap * np.arange(1, len(STRESS_SEQS) + 1)
    for s, n in enumerate(gt.lengths):
        ids2[:, new_off[s]:new_off[s] + n] = ids[:, offsets[s]:offsets[s] + n]
        boxes2[:, new_off[s]:new_off[s] + n] = boxes[:, offsets[s]:offsets[s] + n]
    ids2[:, :gap, 0] = 5  # junk in frames that belong to no sequence
    boxes2[:, :gap, 0] = [10, 10, 100, 100]
    a = evaluate_arrays(gt, ids, boxes, offsets)
    b = evaluate_arrays(gt, ids2, boxes2, new_off)
    for x, y, name in zip(a, b, ["mixed", "ties"]):
        assert_same(x, y, exact=True, tag=name)
        assert_same(evaluate_files(dirs[name], gt), y, exact=True, tag=name)


@pytest.mark.slow
def test_arrays_equal_files_pedestrian(pedestrian_run):
    gt, lanes, dirs, _ = pedestrian_run
    names = ["naive", "edited"]
    ids, boxes, offsets = pack_arrays([lanes[n] for n in names], PED_SEQS, gt.lengths, cls="pedestrian")
    for name, res in zip(names, evaluate_arrays(gt, ids, boxes, offsets)):
        assert_same(evaluate_files(dirs[name], gt), res, exact=True, tag=name)
