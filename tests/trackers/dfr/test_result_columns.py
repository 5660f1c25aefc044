"""Result-file column sets (``io/columns.py``): the authors' 18 columns byte for byte, standard KITTI
columns carrying each object's own 3D detection, the filtered-output inversion, and readers/metrics
that treat both sets alike."""

from __future__ import annotations

import numpy as np
import pytest

from dfrmot_jax.data import box3d_extent, load_sequences, pack
from dfrmot_jax.trackers.dfr.frames import prepare_frames
from dfrmot_jax.io.columns import (COLUMN_SETS, authors_box_columns, fmt_cxx, fmt_exact, format_lines,
                                  invert_box3d_extent)
from dfrmot_jax.io.kitti import read_tracking_labels
from dfrmot_jax.io.result_writer import write_tracking_results
from dfrmot_jax.trackers.dfr.config import Options, Params, preset
from dfrmot_jax.testing.parity import reference_lane, reference_rows
from dfrmot_jax.testing.reference import track_sequence
from dfrmot_jax.trackers.dfr.results import write_lane

from test_reference import _seq

REFERENCE = "reference/dfr_fastmot_rrc_pointrcnn"
PLACEHOLDER_3D = ["-1", "-1", "-1", "-1000", "-1000", "-1000"]


# ---------------------------------------------------------------------------------------------
# Formats, without data


def _one(columns, centroid="legacy", **kw):
    return format_lines([7], [3], [[296, 160, 452, 288]], "Car", columns, centroid, **kw)[0].split()


DET = dict(dims=[[1.9605, 1.8137, 4.7549]], loc=[[-4.572, 1.8435, 13.5308]], rot_y=[-2.1125], alpha=[-1.7867],
           score3=[8.2981])


def test_authors_columns_per_axis_convention():
    assert _one("authors", **DET) == (
        "7 3 Car -1 -1 -1.7867 296 160 452 288 1.9605 -1.8137 -4.7549 -4.572 1.8435 13.5308 -2.1125 8.2981".split())
    # head axes: D = (w, -h, -l), L = (-y, -x, z) (spec section 6)
    assert _one("authors", "head", **DET)[10:16] == ["1.8137", "-1.9605", "-4.7549", "-1.8435", "4.572", "13.5308"]
    # the stale box of the matched track: alpha, rot_y -10 and score 0
    stale = _one("authors", has3=[True], own3=[False], score2=[0.9], **DET)
    assert stale[5] == "-10" and stale[10:] == "1.9605 -1.8137 -4.7549 -4.572 1.8435 13.5308 -10 0".split()
    # no 3D at all
    assert _one("authors", score2=[0.9]) == "7 3 Car -1 -1 -10 296 160 452 288 -1 -1 -1 -1000 -1000 -1000 -10 0".split()


def test_kitti_columns_own_stale_and_none():
    assert _one("kitti", **DET) == (
        "7 3 Car -1 -1 -1.7867 296 160 452 288 1.9605 1.8137 4.7549 -4.572 1.8435 13.5308 -2.1125 8.2981".split())
    for kw in (dict(has3=[True], own3=[False], **DET), {}):   # stale or no 3D: placeholders, the 2D score
        assert _one("kitti", score2=[0.52923], **kw)[5:] == (
            "-10 296 160 452 288 -1 -1 -1 -1000 -1000 -1000 -10 0.52923".split())
    assert _one("kitti")[-1] == "1"   # 2D score unknown


def test_number_formats():
    # C++ ostream: %g of the float32 value, 6 significant digits, "-0" kept, exponents as printf
    assert fmt_cxx(np.array([-0.0, 1e-5, 123456789.0, 13.53080, 0.5, -1000.0])) == [
        "-0", "1e-05", "1.23457e+08", "13.5308", "0.5", "-1000"]
    # kitti: integers as integers, others with the fewest digits (>= 6) that read back exactly
    v = np.array([37.871676417751885, 13.5308, -0.0, 2.0, 1.9970636])
    s = fmt_exact(v)
    assert s[1:] == ["13.5308", "0", "2", "1.9970636"]
    np.testing.assert_array_equal(np.array(s, float), v)
    assert fmt_exact(np.float32([13.645607, 1.5])) == ["13.645607", "1.5"]


def test_format_lines_rejects_bad_input():
    with pytest.raises(ValueError, match="columns"):
        format_lines([0], [0], [[0, 0, 1, 1]], columns="mot")
    with pytest.raises(ValueError, match="dims"):
        format_lines([0], [0], [[0, 0, 1, 1]], dims=[[1, 2]], loc=[[0, 0, 0]])
    with pytest.raises(ValueError, match="non-finite"):
        format_lines([0], [0], [[0, 0, 1, 1]], **{**DET, "alpha": [np.nan]})
    with pytest.raises(ValueError, match="authors"):
        format_lines([0], [0], [[0, 0, 1, 1]], columns="authors", has3=[True], alpha=[0.1])
    assert format_lines([], [], np.zeros((0, 4)), columns="authors") == []


@pytest.mark.parametrize("centroid", ["legacy", "head", "kitti"])
def test_inverse_of_box3d_extent(centroid):
    rng = np.random.default_rng(7)
    n = 1000
    dims = rng.uniform([1.0, 1.0, 2.5], [4.0, 3.0, 16.0], (n, 3))
    loc = rng.uniform([-40, -2, 0.5], [40, 3, 90], (n, 3))
    lo, hi = box3d_extent(dims, loc, centroid)
    d, l = invert_box3d_extent(lo, hi, centroid)
    np.testing.assert_allclose(d, dims, rtol=0, atol=2e-5)
    np.testing.assert_allclose(l, loc, rtol=0, atol=2e-5)
    # through the filtered-output lines: kitti columns give back h w l x y z, authors' the corners
    box3 = np.concatenate([lo, hi], 1).astype(np.float64)
    box3[0] = np.nan  # a track without a 3D filter
    frame, ids, box = np.zeros(n, int), np.arange(n), np.tile([0.5, 1.5, 10.25, 20.0], (n, 1))
    t = _parse(format_lines(frame, ids, box, "Car", "kitti", centroid, box3=box3))
    np.testing.assert_allclose(t[1:, 10:13], dims[1:], atol=2e-5)
    np.testing.assert_allclose(t[1:, 13:16], loc[1:], atol=2e-5)
    np.testing.assert_array_equal(t[0, 10:18], [-1, -1, -1, -1000, -1000, -1000, -10, 1])
    t = _parse(format_lines(frame, ids, box, "Car", "authors", centroid, box3=box3))
    dd, ll = authors_box_columns(lo, hi)
    np.testing.assert_allclose(t[1:, 10:13], dd[1:], rtol=1e-5)
    np.testing.assert_allclose(t[1:, 13:16], ll[1:], rtol=1e-5, atol=1e-4)


def _parse(lines):
    return np.array([[float(x) if i != 2 else 0.0 for i, x in enumerate(s.split())] for s in lines])


def test_oracle_rows_name_own_and_stale_3d_detections():
    # frame 0: a 2D detection with its 3D twin; frame 1: the same car, 2D only; frame 2: 2D + 3D again
    box = [100, 100, 200, 200]
    seq = _seq([0, 1, 2], [box] * 3, [0.9] * 3, 3, frames3=[0, 2], boxes3=[box, box], scores3=[8.0, 9.0],
               loc3=[[0, 1.6, 20], [0.1, 1.6, 20.2]])
    rows = track_sequence(seq, Params(), Options())
    assert [(r[0], r[1], r[8], r[9], r[10]) for r in rows] == [
        (0, 0, 0, True, None), (1, 0, 0, False, None), (2, 0, 1, True, None)]
    rows = track_sequence(seq, Params(), Options(output="filtered"))
    assert [(r[6], r[8], r[9]) for r in rows] == [("track", 0, True), ("track", 0, False), ("track", 1, True)]
    lo, hi = box3d_extent(np.array([1.5, 1.6, 3.9]), np.array([0, 1.6, 20.0]), "legacy")
    np.testing.assert_array_equal(rows[0][10], np.concatenate([lo, hi]))   # first observation: the detection
    assert rows[1][10].shape == (6,) and np.isfinite(rows[1][10]).all()
    seq2 = _seq([0], [box], [0.9], 1)
    assert track_sequence(seq2, Params(), Options(output="filtered"))[0][8:] == (-1, False, None)


def test_write_tracking_results_columns(tmp_path):
    p = tmp_path / "a.txt"
    write_tracking_results(p, [0, 1], [0, 0], [[1, 2, 3, 4]] * 2, columns="authors", has3=[True, False],
                           score2=[0.5, 0.7], **{k: v * 2 for k, v in DET.items() if k != "score3"}, score=[8.2981] * 2)
    assert p.read_text() == (
        "0 0 Car -1 -1 -1.7867 1 2 3 4 1.9605 -1.8137 -4.7549 -4.572 1.8435 13.5308 -2.1125 8.2981\n"
        "1 0 Car -1 -1 -10 1 2 3 4 -1 -1 -1 -1000 -1000 -1000 -10 0\n")
    assert not list(tmp_path.glob(".*tmp"))
    with pytest.raises(ValueError, match="columns"):
        write_tracking_results(p, [0], [0], [[1, 2, 3, 4]], columns="bad")


# ---------------------------------------------------------------------------------------------
# The published run


@pytest.fixture(scope="module")
def dfr2023(kitti_root):
    """The oracle's dfr2023 run on the 20 sequences of the published files, as one lane's arrays."""
    names = sorted(p.stem for p in (kitti_root / REFERENCE).glob("*.txt"))
    assert len(names) == 20
    seqs = load_sequences(kitti_root, "rrc", "pointrcnn", "car", names)
    split = pack(seqs)
    params, options = preset("dfr2023")
    ref = reference_rows(seqs, params, options)
    return seqs, split, options, ref, reference_lane(split, seqs, ref, options), prepare_frames(split, options)


@pytest.fixture(scope="module")
def written(dfr2023, tmp_path_factory):
    """Both column sets written by ``write_lane`` from the oracle's arrays."""
    seqs, split, options, ref, lane, frames = dfr2023
    out = tmp_path_factory.mktemp("columns")
    for columns in COLUMN_SETS:
        write_lane(out / columns, split, frames, options, lane.ids, columns=columns, src3=lane.src3, own3=lane.own3)
    return out


@pytest.mark.slow
def test_authors_columns_reproduce_the_published_files_byte_for_byte(dfr2023, written, kitti_root):
    seqs, split, options, ref, lane, frames = dfr2023
    lines = files = 0
    for seq, rows in zip(seqs, ref):
        want = (kitti_root / REFERENCE / f"{seq.name}.txt").read_bytes()
        # straight from the oracle's rows ...
        d3 = seq.det3d
        r3 = np.array([r[8] for r in rows]); i = np.maximum(r3, 0)
        got = format_lines([r[0] for r in rows], [r[1] for r in rows], np.array([r[2:6] for r in rows]), "Car",
                           "authors", options.centroid, has3=r3 >= 0, own3=[r[9] for r in rows], dims=d3.dims[i],
                           loc=d3.loc[i], rot_y=d3.rot_y[i], alpha=d3.alpha[i], score3=d3.score[i])
        assert "".join(got).encode() == want, f"{seq.name}: oracle rows differ from the published file"
        # ... and through write_lane (the tracker's arrays: global 3D index per output slot)
        assert (written / "authors" / f"{seq.name}.txt").read_bytes() == want, f"{seq.name}: write_lane differs"
        lines += want.count(b"\n")
        files += 1
    assert (files, lines) == (20, 28812)


@pytest.mark.slow
def test_kitti_columns_carry_each_objects_own_3d_detection(dfr2023, written):
    seqs, split, options, ref, lane, frames = dfr2023
    n_own = n_2d = 0
    for seq, rows in zip(seqs, ref):
        t = read_tracking_labels(written / "kitti" / f"{seq.name}.txt")
        assert len(t.frame) == len(rows)
        assert t.frame.tolist() == [r[0] for r in rows] and t.track_id.tolist() == [r[1] for r in rows]
        np.testing.assert_array_equal(t.box, [r[2:6] for r in rows])
        own = np.array([r[9] for r in rows])
        r3 = np.array([r[8] for r in rows])[own]
        d3 = seq.det3d
        np.testing.assert_array_equal(t.dims[own], d3.dims[r3])
        np.testing.assert_array_equal(t.loc[own], d3.loc[r3])
        np.testing.assert_array_equal(t.rot_y[own], d3.rot_y[r3])
        np.testing.assert_array_equal(t.alpha[own], d3.alpha[r3])
        np.testing.assert_array_equal(t.score[own], d3.score[r3])
        other = ~own
        assert all(r[6] == "2d" for r, o in zip(rows, own) if not o)   # a lone 3D object always has its own
        np.testing.assert_array_equal(t.score[other], seq.det2d.score[[r[7] for r, o in zip(rows, own) if not o]])
        np.testing.assert_array_equal(t.dims[other], -1.0)
        np.testing.assert_array_equal(t.loc[other], -1000.0)
        np.testing.assert_array_equal(t.alpha[other], -10.0)
        np.testing.assert_array_equal(t.rot_y[other], -10.0)
        n_own += int(own.sum()); n_2d += int(other.sum())
    assert n_own + n_2d == 28812 and n_2d == 2033 + 2687   # stale 3D + no 3D at all


@pytest.mark.slow
def test_both_column_sets_score_identically(dfr2023, written, kitti_root, tmp_path):
    from test_metrics_parity import assert_same

    from dfrmot_jax.metrics import evaluate_files

    seqs, split, *_ = dfr2023
    scores = {c: evaluate_files(written / c, kitti_root, "car", list(split.names)) for c in COLUMN_SETS}
    assert_same(scores["authors"], scores["kitti"], exact=True, tag="kitti vs authors columns")
    assert round(100 * float(np.mean(scores["kitti"]["COMBINED"]["HOTA"])), 2) == 82.79
    assert int(scores["kitti"]["COMBINED"]["IDSW"]) == 177

    pytest.importorskip("trackeval")
    from dfrmot_jax.testing.trackeval_adapter import make_gt_folder, make_tracker_folder, run_trackeval

    few = ["0000", "0011", "0014", "0020"]
    gt = make_gt_folder(tmp_path / "gt", kitti_root, {s: int(split.lengths[split.names.index(s)]) for s in few})
    for c in COLUMN_SETS:
        make_tracker_folder(tmp_path / "trackers", c, {s: written / c / f"{s}.txt" for s in few}, few)
    te = run_trackeval(gt, tmp_path / "trackers", "car")
    assert_same(te["authors"], te["kitti"], exact=True, tag="TrackEval: kitti vs authors columns")
    assert_same(te["kitti"], evaluate_files(written / "kitti", kitti_root, "car", few), tag="TrackEval vs ours")


@pytest.mark.slow
def test_readers_accept_both_column_sets(dfr2023, written, kitti_root):
    from dfrmot_jax.metrics import prepare_gt
    from dfrmot_jax.testing.metric_edits import load_results
    from dfrmot_jax.metrics.kitti2d.tracker_files import read_tracker_files

    seqs, split, *_ = dfr2023
    a = {s: read_tracking_labels(written / "authors" / f"{s}.txt") for s in split.names}
    k = {s: read_tracking_labels(written / "kitti" / f"{s}.txt") for s in split.names}
    for s in split.names:
        for f in ("frame", "track_id", "box", "type"):
            np.testing.assert_array_equal(getattr(a[s], f), getattr(k[s], f))
        none_k = (k[s].dims == -1).all(axis=1)          # kitti: placeholders unless the object's own 3D
        none_a = (a[s].loc == -1000).all(axis=1)        # authors: placeholders only without any 3D
        assert (k[s].dims[~none_k] > 0).all() and (a[s].dims[~none_a][:, 1:] < 0).all()
        assert (none_a <= none_k).all() and np.isfinite(a[s].score).all()
    gt = prepare_gt(kitti_root, "car", list(split.names))
    ra, rk = (read_tracker_files(written / c, gt) for c in ("kitti", "authors"))
    assert len(ra.frame) > 28000
    for f in ("lane", "frame", "track_id", "box", "source"):
        np.testing.assert_array_equal(getattr(ra, f), getattr(rk, f))
    la, lk = (load_results(written / c, list(split.names)) for c in ("kitti", "authors"))
    for s in split.names:
        np.testing.assert_array_equal(la[s].box, lk[s].box)
        np.testing.assert_array_equal(la[s].track_id, lk[s].track_id)


@pytest.mark.slow
def test_write_lane_without_3d_sources_writes_placeholders_and_detection_scores(dfr2023, tmp_path):
    seqs, split, options, ref, lane, frames = dfr2023
    sub = [0, 3]  # two sequences are enough here
    paths = {c: write_lane(tmp_path / c, split, frames, options, lane.ids, columns=c) for c in COLUMN_SETS}
    for s in sub:
        seq, rows = seqs[s], ref[s]
        k = read_tracking_labels(paths["kitti"][s])
        want = [seq.det2d.score[r[7]] if r[6] == "2d" else seq.det3d.score[r[7]] for r in rows]
        np.testing.assert_array_equal(k.score, want)
        np.testing.assert_array_equal(k.dims, -1.0)
        np.testing.assert_array_equal(k.alpha, -10.0)
        for line in paths["authors"][s].read_text().splitlines():
            assert line.split()[10:] == PLACEHOLDER_3D + ["-10", "0"]


def test_filtered_output_rows(kitti_root, tmp_path):
    """Output "filtered": tracks' filtered 3D boxes in both column sets, from the oracle's arrays."""
    seqs = load_sequences(kitti_root, "rrc", "pointrcnn", "car", ["0000", "0003"])
    split = pack(seqs)
    params, options = Params(keep_lost=2), Options(output="filtered", filter="kalman", truncate=False)
    ref = reference_rows(seqs, params, options)
    lane = reference_lane(split, seqs, ref, options)
    frames = prepare_frames(split, options)
    for c in COLUMN_SETS:
        write_lane(tmp_path / c, split, frames, options, lane.ids, lane.boxes, columns=c, src3=lane.src3,
                   own3=lane.own3, box3=lane.box3)
    for s, (seq, rows) in enumerate(zip(seqs, ref)):
        k = read_tracking_labels(tmp_path / "kitti" / f"{seq.name}.txt")
        a = read_tracking_labels(tmp_path / "authors" / f"{seq.name}.txt")
        assert len(k.frame) == len(a.frame) == len(rows)
        has = np.array([r[10] is not None for r in rows])
        assert has.any()
        b3 = np.array([r[10] for r in rows if r[10] is not None])
        d, l = invert_box3d_extent(b3[:, :3], b3[:, 3:], options.centroid)
        np.testing.assert_allclose(k.dims[has], d, rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(k.loc[has], l, rtol=1e-6, atol=1e-5)
        r3 = np.array([r[8] for r in rows])[has]
        np.testing.assert_array_equal(k.rot_y[has], seq.det3d.rot_y[r3])        # the track's last 3D detection
        np.testing.assert_array_equal(k.score[has], seq.det3d.score[r3])
        np.testing.assert_array_equal(k.dims[~has], -1.0)
        dd, ll = authors_box_columns(b3[:, :3], b3[:, 3:])
        np.testing.assert_allclose(a.dims[has], dd, rtol=1e-5, atol=1e-4)
        np.testing.assert_allclose(a.loc[has], ll, rtol=1e-5, atol=1e-4)
        own = np.array([r[9] for r in rows])
        np.testing.assert_array_equal(a.rot_y[has & ~own], -10.0)
        np.testing.assert_array_equal(a.score[~own], 0.0)
    # without the 3D arrays (callers that have none): placeholders, score 1 (a track has no 2D score)
    paths = write_lane(tmp_path / "plain", split, frames, options, lane.ids, lane.boxes)
    lines = paths[0].read_text().splitlines()
    assert len(lines) == len(ref[0]) and all(s.split()[10:] == PLACEHOLDER_3D + ["-10", "1"] for s in lines)
