"""Building blocks of dfrmot_jax.metrics against TrackEval / numpy / scipy, plus random synthetic scenes."""

from __future__ import annotations

import csv
import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment

from dfrmot_jax.metrics import evaluate_arrays, evaluate_files, metrics_table, prepare_gt
from dfrmot_jax.metrics.common import pairs
from dfrmot_jax.metrics.common.pairs import (assign_frames, enumerate_pairs, nontrivial_segments, numpy_col_sums,
                                             numpy_row_sums, segment_starts, solve_blocks)
from dfrmot_jax.metrics.kitti2d.boxes import columns, gather_iou, pair_ioa, pair_iou
from dfrmot_jax.testing.metric_edits import SeqResults, f32, pack_arrays, write_results


def _random_boxes(rng, n):
    x1 = rng.choice([0.0, 10.0, 50.5, 100.0], n) + rng.integers(0, 5, n)
    y1 = rng.choice([0.0, 20.0, 33.25], n) + rng.integers(0, 5, n)
    w = rng.choice([0.0, 1e-9, 5.0, 40.0, 40.5, 80.0], n)  # includes degenerate boxes
    h = rng.choice([0.0, 25.0, 30.0, 60.0], n)
    return np.stack([x1, y1, x1 + w, y1 + h], 1)


def test_iou_bitwise_like_trackeval():
    base = pytest.importorskip("trackeval.datasets._base_dataset")
    calc = base._BaseDataset._calculate_box_ious
    rng = np.random.default_rng(0)
    for _ in range(50):
        a = _random_boxes(rng, int(rng.integers(1, 9)))
        b = _random_boxes(rng, int(rng.integers(1, 9)))
        ref = calc(a, b, box_format="x0y0x1y1")
        ia, ib = np.repeat(np.arange(len(a)), len(b)), np.tile(np.arange(len(b)), len(a))
        assert np.array_equal(pair_iou(a[ia], b[ib]).reshape(ref.shape), ref)
        assert np.array_equal(gather_iou(columns(a), ia, columns(b), ib).reshape(ref.shape), ref)
        ref_ioa = calc(a, b, box_format="x0y0x1y1", do_ioa=True)
        assert np.array_equal(pair_ioa(a[ia], b[ib]).reshape(ref.shape), ref_ioa)


def test_frame_sums_bitwise_like_numpy():
    rng = np.random.default_rng(1)
    mats = []
    for _ in range(400):
        g, n = int(rng.integers(1, 25)), int(rng.integers(1, 40))
        if rng.random() < 0.2:
            n = 1
        m = rng.random((g, n)) * (rng.random((g, n)) < 0.6)
        mats.append(m)
    nr = np.array([m.shape[0] for m in mats])
    nc = np.array([m.shape[1] for m in mats])
    values = np.concatenate([m.reshape(-1) for m in mats])
    pstart = segment_starts(nr * nc)
    seg, row, col, ps2 = enumerate_pairs(nr, segment_starts(nr)[:-1], nc, segment_starts(nc)[:-1])
    assert np.array_equal(ps2, pstart) and len(seg) == len(values)
    row_first = np.concatenate([pstart[s] + np.arange(nr[s]) * nc[s] for s in range(len(mats))])
    rs = numpy_row_sums(values, row_first, np.repeat(nc, nr))
    cs = numpy_col_sums(values, col, int(nc.sum()), np.repeat(np.arange(len(mats)), nc), nr, nc, pstart)
    assert np.array_equal(rs, np.concatenate([m.sum(1) for m in mats]))
    assert np.array_equal(cs, np.concatenate([m.sum(0) for m in mats]))


def test_assign_frames_matches_scipy_with_ties():
    rng = np.random.default_rng(2)
    mats = []
    for _ in range(300):
        g, n = int(rng.integers(1, 7)), int(rng.integers(1, 7))
        m = rng.choice([0.0, 0.0, 0.3, 0.5, 0.5, 0.7], (g, n))  # many exact ties
        mats.append(m)
    nr = np.array([m.shape[0] for m in mats])
    nc = np.array([m.shape[1] for m in mats])
    score = np.concatenate([m.reshape(-1) for m in mats])
    seg, row, col, pstart = enumerate_pairs(nr, segment_starts(nr)[:-1], nc, segment_starts(nc)[:-1])
    pos = score > 0
    matched = pos.copy()
    hard = nontrivial_segments(seg, row, col, pos)
    assign_frames(hard, pstart, nr, nc, score, matched, 0.0)
    for s, m in enumerate(mats):
        r, c = linear_sum_assignment(-m)
        want = np.zeros(m.shape, bool)
        ok = m[r, c] > 0
        want[r[ok], c[ok]] = True
        assert np.array_equal(matched[pstart[s]:pstart[s + 1]].reshape(m.shape), want), s


def _scipy_pairs(m: np.ndarray) -> np.ndarray:
    r, c = linear_sum_assignment(-m)
    want = np.zeros(m.shape, bool)
    ok = m[r, c] > 0
    want[r[ok], c[ok]] = True
    return want.reshape(-1)


@pytest.mark.parametrize("seed", [0, 1])
def test_solve_blocks_equals_scipy_on_each_full_matrix(seed):
    """Ties, near ties, crossings, CLEAR's continuation bonus: the compiled solve of every block gives
    scipy's positive pairs on the full matrix, pair for pair."""
    rng = np.random.default_rng(seed)
    mats = []
    for i in range(3000):
        g, k = int(rng.integers(1, 10)), int(rng.integers(1, 10))
        kind = i % 6
        if kind == 0:       # exact ties everywhere
            m = rng.choice([0.0, 0.0, 0.0, 0.3, 0.5, 0.5, 0.7], (g, k))
        elif kind == 1:     # generic and sparse, as HOTA's overlapping cars
            m = rng.random((g, k)) * (rng.random((g, k)) < 0.3)
        elif kind == 2:     # a duplicated column (one box twice under two ids)
            m = rng.random((g, k)) * (rng.random((g, k)) < 0.4)
            m[:, -1] = m[:, 0]
        elif kind == 3:     # near ties: each row's best a rounding error above its next entry
            m = np.zeros((g, k))
            d = np.arange(min(g, k))
            m[d, d] = 0.9
            m[d[:-1], d[:-1] + 1] = 0.9 - 1e-13
        elif kind == 4:     # CLEAR: the continuation bonus on some entries
            m = np.where(rng.random((g, k)) < 0.4, 0.5 + 0.5 * rng.random((g, k)), 0.0)
            m += 1000.0 * ((rng.random((g, k)) < 0.15) & (m > 0))
        else:               # a diagonal of clear winners: certified
            m = 0.1 * rng.random((g, k)) * (rng.random((g, k)) < 0.5)
            d = np.arange(min(g, k))
            m[d, d] = 0.5 + 0.5 * rng.random(len(d))
        mats.append(m)
    nr = np.array([m.shape[0] for m in mats])
    nc = np.array([m.shape[1] for m in mats])
    got = solve_blocks(nr, nc, np.concatenate([m.reshape(-1) for m in mats]))
    assert np.array_equal(got, np.concatenate([_scipy_pairs(m) for m in mats]))


def test_match_entries_equals_scipy_on_the_full_matrices():
    """Sparse entries of many frames (zeros elsewhere), crowded and tied ones among them: the entries
    match_entries takes are those scipy takes on each frame's full matrix."""
    rng = np.random.default_rng(5)
    mats = []
    for i in range(2000):
        g, k = int(rng.integers(1, 9)), int(rng.integers(1, 9))
        m = np.where(rng.random((g, k)) < 0.25, rng.choice([0.5, 0.6, 0.6, 0.75, 0.9], (g, k)), 0.0)
        if i % 3 == 0:
            m = np.where(m > 0, 0.5 + 0.5 * rng.random((g, k)), 0.0)   # generic values: mostly certified
        mats.append(m)
    nr = np.array([m.shape[0] for m in mats])
    nc = np.array([m.shape[1] for m in mats])
    seg = np.concatenate([np.full(int((m > 0).sum()), s) for s, m in enumerate(mats)])
    r_loc = np.concatenate([np.nonzero(m > 0)[0] for m in mats])
    c_loc = np.concatenate([np.nonzero(m > 0)[1] for m in mats])
    val = np.concatenate([m[m > 0] for m in mats])
    rowkey = segment_starts(nr)[seg] + r_loc
    colkey = segment_starts(nc)[seg] + c_loc
    got = pairs.match_entries(seg, rowkey, colkey, val, np.ones(len(mats), bool), nr, nc, r_loc, c_loc)
    want = np.concatenate([_scipy_pairs(m).reshape(m.shape)[m > 0] for m in mats])
    assert np.array_equal(got, want)
    ok, _ = pairs.certify_sparse(seg, rowkey, colkey, val, len(mats))
    crowded = pairs.nontrivial_segments(seg, rowkey, colkey, np.ones(len(val), bool))
    assert 0.2 < ok[crowded].mean() < 0.9           # both the certificate and scipy decide crowded frames


# ------------------------------------------------------------------ random synthetic scenes vs TrackEval

LABEL = "{f} {i} {t} {tr} {oc} -10 {b[0]!r} {b[1]!r} {b[2]!r} {b[3]!r} 1.5 1.6 3.9 1 1 10 0\n"


def _synthetic_gt(rng, n_frames=40, n_obj=9):
    """GT label text: moving objects of several classes with occlusion/truncation, plus DontCare."""
    lines = []
    objs = []
    for i in range(n_obj):
        t = rng.choice(["Car", "Car", "Car", "Van", "Pedestrian", "Pedestrian", "Person", "Truck"])
        x, y = rng.uniform(0, 600), rng.uniform(50, 250)
        w, h = (rng.uniform(30, 150), rng.uniform(20, 90)) if t != "Pedestrian" else (rng.uniform(10, 40), rng.uniform(20, 90))
        objs.append([i, t, x, y, w, h, rng.uniform(-6, 6), int(rng.integers(0, n_frames // 2)),
                     int(rng.integers(n_frames // 2, n_frames))])
    for f in range(n_frames):
        for i, t, x, y, w, h, v, f0, f1 in objs:
            if f0 <= f <= f1:
                x_ = x + v * (f - f0)
                b = f32([x_, y, x_ + w, y + h])
                lines.append(LABEL.format(f=f, i=i, t=t, tr=int(rng.choice([0, 0, 0, 1, 2])),
                                          oc=int(rng.choice([0, 1, 2, 3])), b=b.tolist()))
        if rng.random() < 0.5:
            x = rng.uniform(0, 800)
            b = f32([x, 150, x + rng.uniform(20, 120), 150 + rng.uniform(10, 60)])
            lines.append(LABEL.format(f=f, i=-1, t="DontCare", tr=-1, oc=-1, b=b.tolist()))
    if not any(line.startswith(f"{n_frames - 1} ") for line in lines):
        lines.append(LABEL.format(f=n_frames - 1, i=-1, t="DontCare", tr=-1, oc=-1, b=[0.0, 0.0, 10.0, 10.0]))
    return "".join(lines)


def _synthetic_tracker(rng, gt_text, cls_name):
    rows = [line.split() for line in gt_text.splitlines()]
    fr, ids, ty, bx = [], [], [], []
    for r in rows:
        f, i = int(r[0]), int(r[1])
        b = np.array([float(v) for v in r[6:10]])
        u = rng.random()
        if u < 0.15:
            continue
        if u < 0.35:
            b = f32(b + rng.normal(0, 4, 4))
            b = np.array([min(b[0], b[2]), min(b[1], b[3]), max(b[0], b[2]), max(b[1], b[3])])
        tid = (i + 100 if i >= 0 else 999) + (50 if (rng.random() < 0.1) else 0)  # some id switches
        fr.append(f), ids.append(tid), ty.append(cls_name), bx.append(b)
        if rng.random() < 0.15:  # exact duplicate under another id: assignment ties
            fr.append(f), ids.append(tid + 1000), ty.append(cls_name), bx.append(b.copy())
    n_frames = max(int(r[0]) for r in rows) + 1
    for k in range(25):  # clutter: random, tiny
        f = int(rng.integers(0, n_frames))
        x, y = rng.uniform(0, 800), rng.uniform(0, 300)
        h = rng.choice([10.0, 25.0, 26.0, 70.0])
        fr.append(f), ids.append(5000 + k), ty.append(cls_name), bx.append(f32([x, y, x + rng.uniform(5, 100), y + h]))
    order = np.argsort(np.array(fr), kind="stable")
    return SeqResults(np.array(fr)[order], np.array(ids)[order], np.array(ty, dtype="<U16")[order],
                      np.array(bx, dtype=np.float64)[order])


def _assert_close(te, ours, tag=""):
    assert set(te) == set(ours)
    for seq in te:
        assert set(te[seq]) == set(ours[seq])
        for f, v in te[seq].items():
            a, b = np.asarray(v, float), np.asarray(ours[seq][f], float)
            assert a.shape == b.shape and np.allclose(a, b, atol=1e-9, rtol=0), (tag, seq, f, v, ours[seq][f])


@pytest.mark.parametrize("cls", ["car", "pedestrian"])
def test_random_scenes_vs_trackeval(tmp_path, cls):
    """Dense random scenes (distractors, occlusion, truncation, DontCare, tiny boxes, exact duplicates)."""
    pytest.importorskip("trackeval")
    from dfrmot_jax.testing.trackeval_adapter import make_gt_folder, run_trackeval

    rng = np.random.default_rng(10 if cls == "car" else 11)
    root = tmp_path / "root"
    (root / "label_02").mkdir(parents=True)
    seqs = ["0000", "0001", "0002"]
    for s in seqs:
        (root / "label_02" / f"{s}.txt").write_text(_synthetic_gt(rng, n_frames=int(rng.integers(20, 50))))
    gt = prepare_gt(root, cls, seqs)
    make_gt_folder(tmp_path / "gt", root, gt.lengths_dict)
    name = "Car" if cls == "car" else "Pedestrian"
    lanes = []
    for k in range(4):
        lane = {s: _synthetic_tracker(rng, (root / "label_02" / f"{s}.txt").read_text(), name) for s in seqs}
        lanes.append(lane)
        write_results(tmp_path / "trackers" / f"t{k}" / "data", lane, seqs)
    te = run_trackeval(tmp_path / "gt", tmp_path / "trackers", cls)
    ids, boxes, offsets = pack_arrays(lanes, seqs, gt.lengths, cls=cls)
    arr = evaluate_arrays(gt, ids, boxes, offsets)
    for k in range(4):
        ours = evaluate_files(tmp_path / "trackers" / f"t{k}" / "data", gt)
        _assert_close(te[f"t{k}"], ours, f"t{k}")
        _assert_close(ours, arr[k], f"arrays t{k}")


# ------------------------------------------------------------------ table and CLI

def test_metrics_table(kitti_root):
    from dfrmot_jax.metrics.kitti2d.table import COUNT_FIELDS

    res = evaluate_files(kitti_root / "reference" / "dfr_fastmot_rrc_pointrcnn", kitti_root, "car", ["0000", "0001"])
    df = metrics_table(res, tracker="dfr")
    assert list(df.index) == ["0000", "0001", "COMBINED"]
    assert df.columns[0] == "tracker"
    for f in ("HOTA", "DetA", "AssA", "DetRe", "DetPr", "AssRe", "AssPr", "LocA", "MOTA", "MOTP", "MODA", "IDSW",
              "IDF1", "IDR", "IDP", "MT", "PT", "ML", "Frag", "CLR_TP", "CLR_FN", "CLR_FP", "IDTP", "IDFN", "IDFP"):
        assert f in df.columns, f
    c = res["COMBINED"]
    assert df.loc["COMBINED", "HOTA"] == pytest.approx(100 * np.mean(c["HOTA"]))
    assert df.loc["COMBINED", "MOTA"] == pytest.approx(100 * c["MOTA"])
    for f in COUNT_FIELDS:
        assert df[f].dtype == np.int64
    assert df.loc["COMBINED", "IDSW"] == c["IDSW"]


def test_cli_eval(kitti_root, tmp_path, capsys):
    import argparse

    from dfrmot_jax.cli.eval_parser import add_parser as add_eval_parser

    parser = argparse.ArgumentParser(prog="dfrmot")
    sub = parser.add_subparsers(dest="command")
    add_eval_parser(sub)
    ref = kitti_root / "reference" / "dfr_fastmot_rrc_pointrcnn"
    empty = tmp_path / "nothing"
    empty.mkdir()
    out_csv = tmp_path / "m.csv"
    args = parser.parse_args(["eval", str(ref), str(empty), "--data", str(kitti_root), "--seqs", "0000,0002",
                              "--per-seq", "--csv", str(out_csv), "--allow-missing"])   # "nothing" has no files
    assert args.func(args) == 0
    text = capsys.readouterr().out
    assert "COMBINED" in text and "dfr_fastmot_rrc_pointrcnn" in text and "HOTA" in text
    rows = list(csv.DictReader(out_csv.open()))
    assert [(r["tracker"], r["seq"]) for r in rows] == [
        ("dfr_fastmot_rrc_pointrcnn", "0000"), ("dfr_fastmot_rrc_pointrcnn", "0002"),
        ("dfr_fastmot_rrc_pointrcnn", "COMBINED"), ("nothing", "0000"), ("nothing", "0002"), ("nothing", "COMBINED")]
    res = evaluate_files(ref, kitti_root, "car", ["0000", "0002"])
    assert float(rows[2]["HOTA"]) == pytest.approx(100 * np.mean(res["COMBINED"]["HOTA"]))
    assert int(rows[2]["IDSW"]) == res["COMBINED"]["IDSW"]
    assert int(rows[5]["CLR_TP"]) == 0
    bad = parser.parse_args(["eval", str(tmp_path / "missing"), "--data", str(kitti_root)])
    assert bad.func(bad) == 2


def test_identity_matching_value_equals_trackeval_formulation():
    from dfrmot_jax.metrics.kitti2d.identity import max_matching_value

    rng = np.random.default_rng(5)
    for _ in range(30):
        G, T = int(rng.integers(1, 12)), int(rng.integers(1, 12))
        pm = rng.integers(1, 9, (G, T)) * (rng.random((G, T)) < 0.25)
        gc = pm.sum(1) + rng.integers(0, 5, G)
        tc = pm.sum(0) + rng.integers(0, 5, T)
        # TrackEval's (G+T) x (G+T) cost matrix
        fp = np.zeros((G + T, G + T))
        fn = np.zeros((G + T, G + T))
        fp[G:, :T] = 1e10
        fn[:G, T:] = 1e10
        for g in range(G):
            fn[g, :T] = gc[g]
            fn[g, T + g] = gc[g]
        for t in range(T):
            fp[:G, t] = tc[t]
            fp[t + G, t] = tc[t]
        fn[:G, :T] -= pm
        fp[:G, :T] -= pm
        r, c = linear_sum_assignment(fn + fp)
        idtp_te = gc.sum() - fn[r, c].sum()
        g, t = np.nonzero(pm)
        assert max_matching_value(g * 7 + 3, t, pm[g, t].astype(float)).sum() == idtp_te


@pytest.mark.slow
def test_evaluate_arrays_in_worker_processes(kitti_root):
    from dfrmot_jax.testing.metric_edits import load_results

    seqs = ["0000", "0003"]
    gt = prepare_gt(kitti_root, "car", seqs)
    ref = load_results(kitti_root / "reference" / "dfr_fastmot_rrc_pointrcnn", seqs)
    ids, boxes, offsets = pack_arrays([ref] * 3, seqs, gt.lengths)
    ids[1, ::3] = -1
    ids[2, :, 1:] = -1
    one = evaluate_arrays(gt, ids, boxes, offsets, lanes_per_batch=2)
    two = evaluate_arrays(gt, ids, boxes, offsets, lanes_per_batch=1, workers=2)
    for a, b in zip(one, two):
        for seq in a:
            for f in a[seq]:
                assert np.array_equal(np.asarray(a[seq][f]), np.asarray(b[seq][f])), (seq, f)
    assert one[0]["COMBINED"]["CLR_TP"] > one[1]["COMBINED"]["CLR_TP"]


def test_crowded_segments_from_the_rows_layout_equal_nontrivial_segments():
    """The compiled count over the rows' layout finds the same frames as the keyed count: those where
    a row or a column holds two or more positive pairs (empty frames and empty rows among them)."""
    rng = np.random.default_rng(21)
    for _ in range(20):
        G = 300
        nr = rng.integers(0, 6, G)
        nc = rng.integers(0, 6, G)
        rs, cs = pairs.segment_starts(nr)[:-1], pairs.segment_starts(nc)[:-1]
        seg, row, col, pstart = enumerate_pairs(nr, rs, nc, cs)
        positive = rng.random(len(seg)) < rng.uniform(0.05, 0.5)
        row_seg, row_first = pairs.segment_rows(nr, nc, pstart)
        col_seg = np.repeat(np.arange(G), nc)
        got = pairs.crowded_segments(positive, row_seg, row_first, col, col_seg)
        want = nontrivial_segments(seg, row, col, positive)
        assert np.array_equal(got, want) and len(want) > 0


def _random_table_inputs(rng, F=40, integer=False):
    """Ground-truth class rows, DontCare regions and tracker rows per frame, with repeats, degenerate
    boxes, boxes mostly inside a DontCare region and IoU at the 0.5 threshold."""
    def boxes(n):
        xy = rng.uniform(0, 200, (n, 2))
        wh = rng.uniform(0, 60, (n, 2))
        wh[rng.random(n) < 0.05] = 0.0                       # degenerate (area 0)
        b = np.concatenate([xy, xy + wh], axis=1)
        return np.round(b) if integer else b
    n_rows = rng.integers(0, 6, F)
    n_dc = rng.integers(0, 3, F)
    n_dc[0] = max(n_dc[0], 1)
    row_start = np.concatenate([[0], np.cumsum(n_rows)]).astype(np.int64)
    dc_start = np.concatenate([[0], np.cumsum(n_dc)]).astype(np.int64)
    rows, dc = boxes(int(n_rows.sum())), boxes(int(n_dc.sum()))
    dc[0] = [10, 10, 30, 20]
    frame, box = [], []
    for f in range(F):
        own = list(boxes(int(rng.integers(0, 8))))
        if f == 0:                                          # half inside a DontCare region, exactly
            own.append(np.array([0.0, 10, 20, 20]))
        gt = rows[row_start[f]:row_start[f + 1]]
        if len(gt):                                         # a box of IoU exactly 0.5 with a row
            g = gt[0]
            own.append(np.array([g[0], g[1], g[0] + (g[2] - g[0]) / 2, g[3]]))
            own.append(g.copy())
        if n_dc[f]:                                         # mostly inside a DontCare region
            d = dc[dc_start[f]]
            own.append(np.array([d[0], d[1], d[0] + (d[2] - d[0]) * 0.6, d[3]]))
        own += own[: int(rng.integers(0, 3))]               # repeated boxes
        frame += [f] * len(own)
        box += own
    order = rng.permutation(len(frame))
    return (row_start, tuple(np.ascontiguousarray(rows[:, i]) for i in range(4)), dc_start, dc.reshape(-1, 4),
            np.asarray(frame, np.int64)[order], np.asarray(box, np.float64).reshape(-1, 4)[order])


@pytest.mark.parametrize("seed", [0, 1] + [pytest.param(s, marks=pytest.mark.slow) for s in range(2, 6)])
def test_compiled_box_table_equals_numpy(seed):
    from dfrmot_jax.metrics.kitti2d.box_table import box_table, box_table_numpy
    rng = np.random.default_rng(seed)
    args = _random_table_inputs(rng, integer=seed % 2 == 1)
    got, want = box_table(*args), box_table_numpy(*args)
    assert want.cand_row.size and want.in_dontcare.any()          # the cases are there
    for f in want._fields:
        a, b = getattr(got, f), getattr(want, f)
        assert a.dtype == b.dtype, f
        np.testing.assert_array_equal(a, b, err_msg=f)
        if a.dtype.kind == "f":
            assert np.array_equal(a.view(np.uint64), b.view(np.uint64)), f    # bit for bit


@pytest.mark.parametrize("n", [0, 1, 7, 5000])
def test_distinct_rows_by_first_appearance_bit_for_bit(n):
    """The compiled factorisation of (frame, row) equals pandas' (first appearance order) of the exact
    bits: -0.0 and 0.0 apart, NaN equal to itself, the frame part of the key."""
    import pandas as pd

    from dfrmot_jax.metrics.common.distinct import distinct_rows, row_ids
    rng = np.random.default_rng(n)
    frame = rng.integers(0, 6, n)
    vals = np.round(rng.random((n, 4)) * 2)
    vals[rng.random((n, 4)) < 0.1] = -0.0
    vals[rng.random((n, 4)) < 0.05] = np.nan
    first, ids = distinct_rows(frame, vals)
    keys = [(int(f),) + tuple(r) for f, r in zip(frame, vals.view(np.uint64).tolist())]
    want = pd.factorize(pd.Series(keys, dtype=object))[0] if n else np.zeros(0, np.int64)
    np.testing.assert_array_equal(ids, want)
    np.testing.assert_array_equal(ids, row_ids(np.concatenate([frame[:, None].astype(np.float64), vals], axis=1)))
    np.testing.assert_array_equal(ids[first], np.arange(len(first)))
    assert (np.diff(first) > 0).all()


def _scene(tmp_path, rng, n_seqs: int, n_lanes: int, n_obj: int, n_frames: int | None = None):
    """Random dense ground truth of ``n_seqs`` sequences (``_synthetic_gt``) and ``n_lanes`` random outputs
    for it (``_synthetic_tracker``): (gt, outputs [{seq: SeqResults}])."""
    root = tmp_path / "root"
    (root / "label_02").mkdir(parents=True)
    seqs = [f"{s:04d}" for s in range(n_seqs)]
    for s in seqs:
        frames = n_frames if n_frames is not None else int(rng.integers(30, 60))
        (root / "label_02" / f"{s}.txt").write_text(_synthetic_gt(rng, n_frames=frames, n_obj=n_obj))
    gt = prepare_gt(root, "car", seqs)
    return gt, [{s: _synthetic_tracker(rng, (root / "label_02" / f"{s}.txt").read_text(), "Car") for s in seqs}
                for _ in range(n_lanes)]


def _dets(gt, outputs):
    """The outputs as the preprocessing's flat rows (packed, then flattened)."""
    from dfrmot_jax.metrics.kitti2d.padded import tracker_dets_from_arrays

    return tracker_dets_from_arrays(gt, *pack_arrays(outputs, list(gt.sequences), gt.lengths, cls="car"))


@pytest.mark.parametrize("seed", [0] + [pytest.param(s, marks=pytest.mark.slow) for s in (1, 2)])
def test_compiled_switches_and_fragments_equal_sorting(tmp_path, seed):
    """CLEAR's IDSW and Frag from one pass in time order equal the sorted NumPy reference on dense
    random scenes (id switches, duplicates, gaps), several lanes at once."""
    from dfrmot_jax.metrics.kitti2d import clear
    from dfrmot_jax.metrics.kitti2d.kitti import preprocess

    gt, outputs = _scene(tmp_path, np.random.default_rng(seed), 2, 5, 12)
    b = preprocess(gt, _dets(gt, outputs))
    p_gid, p_tid = gt.eval_gid[b.p_e], b.det_gid[b.p_k]
    m = np.flatnonzero(clear._matched_pairs(b, p_gid, p_tid))
    F, S, NG = gt.n_frames, len(gt.sequences), len(gt.gid_count)
    m_lf = b.p_lf[m]
    key = (m_lf // F) * NG + p_gid[m]
    m_ls = (m_lf // F) * S + gt.seq_of_frame[m_lf % F]
    got = clear._switches_and_fragments(b, key, m_lf, p_tid[m], m_ls)
    want = clear._switches_and_fragments_numpy(b, key, m_lf, p_tid[m], m_ls)
    assert want[0].sum() > 0 and want[1].sum() > 0         # switches and fragmentations are there
    for a, w in zip(got, want):
        assert a.dtype == w.dtype
        np.testing.assert_array_equal(a, w)


def test_compiled_pairwise_sum_equals_numpys_row_sums():
    """pairs.pairwise_sum (for compiled callers) is numpy's sum of a contiguous row bit for bit, at every
    length through the 8-way and the split regimes, with values of mixed magnitudes and zeros."""
    rng = np.random.default_rng(3)
    for n in list(range(0, 70)) + [127, 128, 129, 136, 255, 256, 257, 300, 1000]:
        for _ in range(3):
            m = rng.random((5, n)) * 10.0 ** rng.integers(-6, 6, (5, n)) * (rng.random((5, n)) < 0.7)
            flat = m.reshape(-1)
            got = np.array([pairs.pairwise_sum(flat, r * n, n) for r in range(5)])
            assert got.tobytes() == m.sum(1).tobytes(), n


def _dense_scene_batch(tmp_path, seed, lanes=5):
    """A preprocessed batch of random dense scenes (id switches, exact duplicates under other ids:
    frames whose positive scores share a row or column, and tied scores)."""
    from dfrmot_jax.metrics.kitti2d.kitti import preprocess

    rng = np.random.default_rng(seed)
    gt, out = _scene(tmp_path, rng, 3, lanes, 12)
    seqs = list(gt.sequences)
    e = out[-1]["0001"]
    out[-1]["0001"] = SeqResults(e.frame[:0], e.track_id[:0], e.type[:0], e.box[:0])   # a lane with an empty sequence
    for s in seqs:                   # a crowd: ten jittered copies of some boxes (rows of 8+ overlaps each)
        r = out[0][s]
        pick = rng.choice(len(r), size=min(len(r), 12), replace=False)
        add_f = np.repeat(r.frame[pick], 10)
        add_b = f32(np.repeat(r.box[pick], 10, axis=0) + rng.normal(0, 1.5, (10 * len(pick), 4)))
        add_b = np.concatenate([np.minimum(add_b[:, :2], add_b[:, 2:]), np.maximum(add_b[:, :2], add_b[:, 2:])], 1)
        order = np.argsort(np.concatenate([r.frame, add_f]), kind="stable")
        out[0][s] = SeqResults(np.concatenate([r.frame, add_f])[order],
                               np.concatenate([r.track_id, 7000 + np.arange(len(add_f))])[order],
                               np.concatenate([r.type, np.repeat(r.type[:1], len(add_f))])[order],
                               np.concatenate([r.box, add_b])[order])
    return preprocess(gt, _dets(gt, out))


@pytest.mark.parametrize("seed", [0] + [pytest.param(s, marks=pytest.mark.slow) for s in (1, 2, 3)])
def test_compiled_hota_equals_numpy(tmp_path, seed, monkeypatch):
    """HOTA's compiled pass per (config, sequence) equals the NumPy reference on every field, bit for
    bit, on dense random scenes where frames need the assignment solver; so does the NumPy fallback
    the compiled pass hands a too large id table to."""
    from dfrmot_jax.metrics.kitti2d import hota

    b = _dense_scene_batch(tmp_path, seed)
    positive = b.sim > 0
    row_lf, row_first = pairs.segment_rows(b.lf_eval_count, b.det_count, b.pair_start)
    assert len(pairs.crowded_segments(positive, row_lf, row_first, b.p_k, b.det_lf)) > 0   # the solver is needed
    want = hota.hota_sequences_numpy(b)
    got = hota.hota_sequences(b)
    with monkeypatch.context() as m:
        m.setattr(hota, "MAX_TABLE", 0)
        fallback = hota.hota_sequences(b)
    assert (b.det_count >= 8).any()                        # rows summed by numpy's pairwise scheme
    assert set(got) == set(want) == set(fallback)
    for f in want:
        w = np.asarray(want[f])
        for a in (got[f], fallback[f]):
            a = np.asarray(a)
            assert a.dtype == w.dtype and a.shape == w.shape and a.tobytes() == w.tobytes(), f


def test_compiled_hota_counts_an_alpha_passed_at_exactly_alpha_minus_eps():
    """A match passes alpha where ``sim >= alpha - eps`` (TrackEval's test), also at equality: the compiled
    pass buckets each similarity as ``np.searchsorted(alphas - eps, sim, 'right')``."""
    from dfrmot_jax.metrics.kitti2d import hota
    from dfrmot_jax.metrics.kitti2d.boxes import EPS

    th = hota.ALPHAS - EPS
    sims = np.concatenate([th, np.nextafter(th, 0), [1.0, 0.02]])
    n = len(sims)                                # one lane-frame per similarity, one GT id and tracker id each
    hist, loc, _ = hota._hota_kernel(np.array([0, n]), np.array([0]), np.arange(n + 1), np.ones(n, np.int64),
                                     np.ones(n, np.int64), sims, np.arange(n), np.arange(n), np.ones(n), np.ones(n),
                                     np.array([0, n]), np.array([0, n]), th, EPS)
    want = np.bincount(np.searchsorted(th, sims, side="right"), minlength=hota.NA + 1)
    assert hist[0].tolist() == want.tolist()


KERNEL_DEP = "import numba\n\n\n@numba.njit(cache=False)\ndef helper(x):\n    return x + {k}.0\n"
KERNEL_MOD = '''import kdep
from dfrmot_jax.metrics.common.kernel_cache import cached_njit


@cached_njit(calls=("kdep",))
def kernel(x):
    return kdep.helper(x) * 2.0


print(kernel(1.0), kernel.stats.cache_hits.total(), kernel.stats.cache_misses.total())
'''


@pytest.mark.slow
def test_a_cached_entry_point_is_compiled_anew_when_a_callees_module_changes(tmp_path):
    """kernel_cache's ``cached_njit(calls=...)`` (hota's, clear's, identity's and the kept boxes' kernels):
    a second process loads the kernel from numba's disk cache; after the module of a kernel it calls
    changes, it is compiled anew with the new callee (numba's own key names the kernel's file only)."""
    import os
    import subprocess
    import sys

    (tmp_path / "kmod.py").write_text(KERNEL_MOD)
    env = dict(os.environ, PYTHONPATH=str(tmp_path), NUMBA_CACHE_DIR=str(tmp_path / "cache"))

    def run(k):
        (tmp_path / "kdep.py").write_text(KERNEL_DEP.format(k=k))
        out = subprocess.run([sys.executable, "-c", "import kmod"], env=env, capture_output=True, text=True,
                             cwd=tmp_path, check=True).stdout.split()
        return float(out[0]), int(out[1]), int(out[2])

    assert run(1) == (4.0, 0, 1)          # compiled, and saved
    assert run(1) == (4.0, 1, 0)          # loaded from disk
    assert run(2) == (6.0, 0, 1)          # the callee's module changed: compiled anew, the new callee's result
    assert run(2) == (6.0, 1, 0)


@pytest.mark.parametrize("seed", [0] + [pytest.param(s, marks=pytest.mark.slow) for s in (1, 2, 3)])
def test_compiled_clear_equals_numpy(tmp_path, seed):
    """CLEAR's compiled pass per (config, sequence) equals the NumPy reference on every field, bit for
    bit, on dense random scenes (frames solved with the continuation bonus, id switches, gaps)."""
    from dfrmot_jax.metrics.kitti2d import clear

    b = _dense_scene_batch(tmp_path, seed)
    positive = b.sim >= clear.THRESHOLD - clear.EPS
    row_lf, row_first = pairs.segment_rows(b.lf_eval_count, b.det_count, b.pair_start)
    assert len(pairs.crowded_segments(positive, row_lf, row_first, b.p_k, b.det_lf)) > 0   # the solver is needed
    want = clear.clear_sequences_numpy(b)
    got = clear.clear_sequences(b)
    assert want["IDSW"].sum() > 0 and want["Frag"].sum() > 0 and want["MT"].sum() > 0 and want["PT"].sum() > 0
    assert set(got) == set(want)
    for f in want:
        w, a = np.asarray(want[f]), np.asarray(got[f])
        assert a.dtype == w.dtype and a.shape == w.shape and a.tobytes() == w.tobytes(), f


@pytest.mark.parametrize("seed", [0] + [pytest.param(s, marks=pytest.mark.slow) for s in (1, 2, 3)])
def test_compiled_kept_boxes_equal_numpy(tmp_path, seed):
    """The preprocessing's kept boxes from one compiled pass per lane-frame equal the NumPy reference
    on dense random scenes: boxes matched to vans, too low or inside DontCare regions, crowded frames."""
    from dfrmot_jax.metrics.kitti2d.box_table import box_table
    from dfrmot_jax.metrics.kitti2d.kept import _fragile, kept_boxes, kept_boxes_numpy

    gt, outputs = _scene(tmp_path, np.random.default_rng(200 + seed), 2, 4, 14)
    dets = _dets(gt, outputs)
    F = gt.n_frames
    lf = dets.lane * F + dets.frame
    g_of_lf = np.tile(np.arange(F, dtype=np.int64), dets.n_lanes)
    box = np.asarray(dets.box, np.float64)
    tab = box_table(gt.row_start, gt.row_cols, gt.dc_start, gt.dc_box, dets.frame, box)
    got = kept_boxes(gt, dets, tab, box, lf, g_of_lf)
    want = kept_boxes_numpy(gt, dets, tab, box, lf, g_of_lf)
    fragile = _fragile(tab, box)
    assert (~want & ~fragile).any() and (~want & fragile).any() and (want & fragile).any()   # every rule at work
    np.testing.assert_array_equal(got, want)


def test_compiled_metric_pairs_equal_enumerated_pairs_and_their_iou(tmp_path):
    """box_table.metric_pairs (every lane-frame's eval rows x kept boxes, and their IoU, in one pass) is
    enumerate_pairs and pair_iou, bit for bit, on a dense random batch."""
    from dfrmot_jax.metrics.kitti2d.box_table import box_table, metric_pairs, pair_iou

    rng = np.random.default_rng(11)
    gt, outputs = _scene(tmp_path, rng, 2, 3, 12, n_frames=40)
    dets = _dets(gt, outputs)
    F, L = gt.n_frames, dets.n_lanes
    lf = dets.lane * F + dets.frame
    g_of_lf = np.tile(np.arange(F, dtype=np.int64), L)
    tab = box_table(gt.row_start, gt.row_cols, gt.dc_start, gt.dc_box, dets.frame, np.asarray(dets.box, np.float64))
    kidx = np.flatnonzero(rng.random(len(lf)) < 0.8)                  # some boxes kept
    nk = np.bincount(lf[kidx], minlength=L * F).astype(np.int64)
    ev_rows = np.flatnonzero(gt.row_eval)
    got = metric_pairs(tab, gt.row_start, gt.eval_start, gt.eval_count, ev_rows, g_of_lf, nk, kidx)
    p_lf, p_e, p_k, pair_start = enumerate_pairs(gt.eval_count[g_of_lf], gt.eval_start[g_of_lf], nk,
                                                 segment_starts(nk)[:-1])
    want = (p_lf, p_e, p_k, pair_iou(tab, gt.row_start, ev_rows, p_e, kidx, p_k), pair_start)
    assert len(want[0]) > 1000
    for a, w in zip(got, want):
        assert a.dtype == w.dtype and a.tobytes() == w.tobytes()


def test_compiled_tracker_id_numbering_equals_hashing(tmp_path, monkeypatch):
    """The preprocessing's tracker ids numbered per (lane, sequence) run in one compiled pass equal the
    hashed / sorted numbering (every array, dtypes too); a repeated id still names its row."""
    from dfrmot_jax.metrics.kitti2d import kitti

    b = _dense_scene_batch(tmp_path, 5)
    with monkeypatch.context() as m:
        m.setattr(kitti, "_ids_by_run", lambda grp, tid, lf: (None, None, None, True))   # the general path
        want = _dense_scene_batch(tmp_path / "again", 5)
    for f in ("det_gid", "tid_lane", "tid_seq", "tid_count", "n_tr_ids"):
        a, w = np.asarray(getattr(b, f)), np.asarray(getattr(want, f))
        assert a.dtype == w.dtype and a.tobytes() == w.tobytes(), f


def test_compiled_argsort_is_numpys_stable_argsort():
    """metrics.common.sorting.argsort (the kernels' sort, cheaper to compile than numba's quicksort)
    equals ``np.argsort(kind="stable")`` on integer keys: empty, one, runs of equal keys, any order."""
    from dfrmot_jax.metrics.common.sorting import argsort

    rng = np.random.default_rng(7)
    cases = [np.zeros(0, np.int64), np.array([5]), np.arange(9)[::-1].copy(), np.zeros(17, np.int64),
             np.array([2**62, -2**62, 0, 2**62])]
    cases += [rng.integers(0, hi, n) for n in (2, 3, 31, 64, 65, 1000) for hi in (2, 10, 2**40)]
    for keys in cases:
        got = argsort(np.ascontiguousarray(keys, np.int64))
        assert got.dtype == np.int64 and got.tolist() == np.argsort(keys, kind="stable").tolist(), keys


def test_tracker_id_runs_ranked_by_table_or_by_sorting_alike():
    """kitti._ids_by_run ranks each run's ids by a table where their span is small and by sorting where
    it is not: both are the sorted ranks of (run, id), with a repeat within a lane-frame reported."""
    import pandas as pd

    from dfrmot_jax.metrics.kitti2d import kitti

    rng = np.random.default_rng(4)
    for span in (50, 10**12):                      # the table, then sorting
        runs = np.repeat(np.arange(6), rng.integers(1, 40, 6))
        tid = rng.integers(0, span, len(runs))
        tid[rng.random(len(runs)) < 0.5] = span - 1    # ids repeated within a run (in other lane-frames)
        lf = np.arange(len(runs))                  # one row per lane-frame: no repeat
        det_gid, tid_grp, count, repeated = kitti._ids_by_run(runs, tid, lf)
        codes, uniq = pd.factorize(pd.MultiIndex.from_arrays([runs, tid]), sort=True)
        assert det_gid.tolist() == codes.tolist() and not repeated
        assert tid_grp.tolist() == [r for r, _ in uniq] and count.tolist() == np.bincount(codes).tolist()
        lf2 = lf.copy()
        i = int(np.flatnonzero(runs[1:] == runs[:-1])[0])
        tid2 = tid.copy()
        tid2[i + 1], lf2[i + 1] = tid2[i], lf2[i]  # the same id twice in one lane-frame
        assert kitti._ids_by_run(runs, tid2, lf2)[3]


@pytest.mark.parametrize("seed", [0] + [pytest.param(s, marks=pytest.mark.slow) for s in (1, 2, 3)])
def test_compiled_identity_equals_numpy(tmp_path, seed, monkeypatch):
    """Identity's compiled pass per (config, sequence) (co-occurrence counts, the id graph's components,
    each solved) equals the NumPy reference on every field, bit for bit, on dense random scenes whose
    id graphs have components of several edges (id switches); so does the fallback for a too large id
    table."""
    from dfrmot_jax.metrics.kitti2d import identity

    b = _dense_scene_batch(tmp_path, seed)
    hit = b.sim >= identity.THRESHOLD
    pairs_of = np.unique(b.p_tid[hit] * len(b.gt.gid_count) + b.p_gid[hit])
    assert len(pairs_of) > len(np.unique(b.p_gid[hit]))                  # a GT id with two tracker ids
    want = identity.identity_sequences_numpy(b)
    got = identity.identity_sequences(b)
    with monkeypatch.context() as m:
        m.setattr(identity, "MAX_TABLE", 0)
        fallback = identity.identity_sequences(b)
    assert want["IDTP"].sum() > 0
    for f in want:
        w = np.asarray(want[f])
        for a in (np.asarray(got[f]), np.asarray(fallback[f])):
            assert a.dtype == w.dtype and a.shape == w.shape and a.tobytes() == w.tobytes(), f


def test_compiled_identity_matches_through_shared_ids_and_counts_overlaps_at_exactly_the_threshold():
    """Identity's pass on a hand-made sequence: tracker id 0 overlaps GT id 0 in 3 frames and GT id 1 in 5,
    tracker id 1 overlaps GT id 1 once and GT id 0 once at IoU exactly 0.5 (counted: TrackEval's ``>=``).
    One component; the best one-to-one matching is (0, 1) and (1, 0): IDTP 5 + 1."""
    from dfrmot_jax.metrics.kitti2d import identity

    pairs_ = [(0, 0, 0.9)] * 3 + [(0, 1, 0.8)] * 5 + [(1, 1, 0.7), (1, 0, 0.5)]
    n = len(pairs_)
    tid, gid, sim = (np.array(v) for v in zip(*pairs_))
    got = identity._identity_kernel(np.array([0, n]), np.array([0]), np.arange(n + 1), sim.astype(np.float64),
                                    gid.astype(np.int64), tid.astype(np.int64), np.array([0, 2]), np.array([0, 2]),
                                    identity.THRESHOLD)
    assert got.tolist() == [6.0]
