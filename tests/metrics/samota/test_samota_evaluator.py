"""AB3DMOT's KITTI metrics (dfrmot_jax.metrics.samota): every figure its reference evaluator printed
for the fixture folders (reference/ab3dmot_eval/figures.jsonl), hand-made sequences, and bad input."""

import json
from pathlib import Path

import numpy as np
import pytest

from dfrmot_jax.io.kitti import KittiFormatError
from dfrmot_jax.metrics.samota.evaluate import evaluate_ab3dmot_files, parse_iou
from dfrmot_jax.metrics.samota.passes import ids_frag, traj_layout
from dfrmot_jax.metrics.samota.prep import prepare_ab3dmot_gt, read_seqmap
from dfrmot_jax.paths import default_data_root

FIXTURES = default_data_root() / "reference" / "ab3dmot_eval"


def _figure_lines():
    path = FIXTURES / "figures.jsonl"
    if not path.is_file():
        return [pytest.param(None, marks=pytest.mark.skip(reason=f"AB3DMOT fixtures not found at {FIXTURES}"))]
    lines = [json.loads(s) for s in path.read_text().splitlines() if s.strip()]
    return [pytest.param(f, id=f"{Path(f['folder']).name}-{f['mode']}{f['thres']}-{f['seqmap']}") for f in lines]


@pytest.mark.parametrize("fig", _figure_lines())
def test_reference_figures(fig, kitti_root):
    seqmap = FIXTURES / "seqmaps" / f"evaluate_tracking.seqmap.{fig['seqmap']}"
    r = evaluate_ab3dmot_files(FIXTURES / fig["folder"], kitti_root, "car", iou=f"{fig['mode']}:{fig['thres']}",
                               seqmap=seqmap, sum_mode="sequential")      # the figures of CPython 3.11
    got = {k: round(100 * r[k], 4) for k in ("sAMOTA", "AMOTA", "AMOTP", "MOTA", "MOTP", "recall", "precision")}
    got.update({k: r[k] for k in ("IDS", "FRAG", "FP", "FN", "TP", "n_recall_points")})
    want = {k: fig[k] for k in got}
    assert got == want
    assert r["best_threshold"] == pytest.approx(fig["best_threshold"], rel=1e-15, abs=0)
    at = r["all_tracks"]
    got_all = {k: (round(100 * at[k], 4) if k in ("MOTA", "MOTP", "recall") else at[k]) for k in fig["all_tracks"]}
    assert got_all == fig["all_tracks"]
    for k, v in fig["printed"].items():                      # what the evaluator printed itself
        assert (round(r[k], 4) if isinstance(v, float) else r[k]) == v, k


def test_seqmaps_of_the_fixtures(kitti_root):
    if not FIXTURES.is_dir():
        pytest.skip(f"AB3DMOT fixtures not found at {FIXTURES}")
    val = read_seqmap(FIXTURES / "seqmaps" / "evaluate_tracking.seqmap.val", kitti_root)
    assert val == ("0001", "0006", "0008", "0010", "0012", "0013", "0014", "0015", "0016", "0018", "0019")
    assert len(read_seqmap(FIXTURES / "seqmaps" / "evaluate_tracking.seqmap.all", kitti_root)) == 21


# ---------------------------------------------------------------- hand-made sequences

CAR = dict(h=1.5, w=1.6, l=3.9, y=1.7, ry=0.2)


def _label(frame, tid, x, z, typ="Car", trunc=0, occ=0, box=None, h=None):
    x1, y1, x2, y2 = box if box is not None else (100 + 40 * x, 150, 180 + 40 * x, 220)
    return (f"{frame} {tid} {typ} {trunc} {occ} -1 {x1} {y1} {x2} {y2} {h or CAR['h']} {CAR['w']} {CAR['l']} "
            f"{x} {CAR['y']} {z} {CAR['ry']}")


def _root(tmp_path, labels: dict) -> Path:
    root = tmp_path / "data"
    (root / "label_02").mkdir(parents=True)
    for name, rows in labels.items():
        (root / "label_02" / f"{name}.txt").write_text("\n".join(rows) + "\n")
    return root


def _results(tmp_path, files: dict, name="res") -> Path:
    d = tmp_path / name
    d.mkdir()
    for seq, rows in files.items():
        (d / f"{seq}.txt").write_text("\n".join(rows) + ("\n" if rows else ""))
    return d


# two cars over four frames, one van (a neighbour) and a DontCare region
CARS = [_label(f, 1, 0.0, 10.0 + f) for f in range(4)] + [_label(f, 2, 4.0, 20.0) for f in range(4)]
VAN = _label(1, 3, -4.0, 15.0, typ="Van")
DONTCARE = "0 -1 DontCare -1 -1 -10 600 150 700 250 -1 -1 -1 -1000 -1000 -1000 -10"
GT = {"0000": sorted(CARS + [VAN, DONTCARE], key=lambda s: int(s.split()[0]))}


def _as_result(label_row, tid=None, score=0.9, dims=None):
    f = label_row.split()
    if tid is not None:
        f[1] = str(tid)
    if dims is not None:
        f[10:13] = [str(v) for v in dims]
    return " ".join(f + [str(score)])


def test_perfect_output_in_2d_and_3d(tmp_path):
    """Result boxes identical to the ground truth (3D IoU 1, where the reference crashes): 2D and 3D agree."""
    root = _root(tmp_path, GT)
    res = _results(tmp_path, {"0000": [_as_result(r) for r in CARS]})
    for iou in ("2d:0.5", "3d:0.25", "3d:0.7"):
        r = evaluate_ab3dmot_files(res, root, "car", ["0000"], iou=iou)
        assert (r["MOTA"], r["MOTP"], r["IDS"], r["FRAG"], r["FP"], r["FN"], r["TP"]) == (1.0, 1.0, 0, 0, 0, 0, 8)
        # constant scores: every recall point keeps every track; 8 objects give 7 recall points
        assert r["n_recall_points"] == 7
        assert r["sAMOTA"] == r["AMOTA"] == 7 / 40 and r["AMOTP"] == 7 / 40


def test_turned_boxes_and_2d_only_rows(tmp_path):
    root = _root(tmp_path, GT)
    rows = CARS
    turned = [_as_result(r, dims=(CAR["h"], -CAR["w"], -CAR["l"])) for r in rows]     # h -w -l
    r = evaluate_ab3dmot_files(_results(tmp_path, {"0000": turned}), root, "car", ["0000"], iou="3d:0.7")
    assert (r["TP"], r["FP"], r["FN"]) == (8, 0, 0)
    placeholder = [_as_result(r) for r in rows[:4]] + [
        " ".join(r.split()[:10] + ["-1", "-1", "-1", "-1000", "-1000", "-1000", "-10", "0.9"]) for r in rows[4:]]
    res = _results(tmp_path, {"0000": placeholder}, "placeholder")
    r3 = evaluate_ab3dmot_files(res, root, "car", ["0000"], iou="3d:0.25")
    assert (r3["TP"], r3["FP"], r3["FN"]) == (4, 4, 4)    # 2D-only rows are unmatched in 3D
    r2 = evaluate_ab3dmot_files(res, root, "car", ["0000"], iou="2d:0.5")
    assert (r2["TP"], r2["FP"], r2["FN"]) == (8, 0, 0)


def test_id_switch_ignored_rows_and_thresholds(tmp_path):
    root = _root(tmp_path, GT)
    g = CARS
    rows = [_as_result(g[0], 7), _as_result(g[1], 7), _as_result(g[2], 8), _as_result(g[3], 8)]  # a switch
    rows += [_as_result(r, 9, score=0.3) for r in g[4:8]]
    rows.append(_as_result(VAN, 10))                              # matches the van: ignored
    rows.append("0 11 Car 0 0 -1 610 160 690 240 1.5 1.6 3.9 30 1.7 40 0 0.9")   # in the DontCare region
    rows.append("2 12 Car 0 0 -1 10 10 60 30 1.5 1.6 3.9 -30 1.7 40 0 0.9")      # 20 px high, unmatched
    rows.append("3 13 Car 0 0 -1 900 100 1000 200 1.5 1.6 3.9 30 1.7 40 0 0.05")  # a false positive
    r = evaluate_ab3dmot_files(_results(tmp_path, {"0000": rows}), root, "car", ["0000"], iou="2d:0.5")
    at = r["all_tracks"]
    assert (at["TP"], at["FN"], at["IDS"], at["FRAG"], at["FP"]) == (9, 0, 1, 1, 1)
    assert at["MOTA"] == pytest.approx(1 - (0 + 1 + 1) / 8)
    # the 0.05 track is dropped at every threshold: the best pass has no FP
    assert (r["FP"], r["IDS"], r["TP"]) == (0, 1, 9)
    assert r["MOTA"] == pytest.approx(1 - 1 / 8)


def _ids_frag_reference(trajs):
    """The reference's trajectory loop, written out plainly."""
    ids = frag = 0
    for g, ign in trajs:
        if all(ign) or all(v == -1 for v in g):
            continue
        last = g[0]
        f = 0
        for f in range(1, len(g)):
            if ign[f]:
                last = -1
                continue
            if last != g[f] and last != -1 and g[f] != -1 and g[f - 1] != -1:
                ids += 1
            if f < len(g) - 1 and g[f - 1] != g[f] and last != -1 and g[f] != -1 and g[f + 1] != -1:
                frag += 1
            if g[f] != -1:
                last = g[f]
        if len(g) > 1 and g[f - 1] != g[f] and last != -1 and g[f] != -1 and not ign[f]:
            frag += 1
    return ids, frag


def test_ids_and_frag_match_the_reference_loop():
    """Random trajectories, three passes each: an object's only candidate track (or none) is matched
    in a pass when the track is kept; the same matches once as lone pairs (tracks kept per pass) and
    once through components (the matched track given per pass), against the reference's loop."""
    rng = np.random.default_rng(5)
    n_tracks, P = 5, 3
    for _ in range(300):
        n_traj = int(rng.integers(1, 6))
        lengths = rng.integers(1, 10, n_traj)
        traj = np.repeat(np.arange(n_traj), lengths)
        frame = np.concatenate([np.arange(n) for n in lengths])
        n = len(traj)
        cand = rng.integers(-1, n_tracks, n)
        ign = rng.random(n) < 0.2
        kept = rng.random((P, n_tracks)) < 0.7
        g = np.where((cand >= 0) & kept[:, np.maximum(cand, 0)], cand, -1)           # [P, n]
        want = [_ids_frag_reference([(g[j, traj == t].tolist(), ign[traj == t].tolist()) for t in range(n_traj)])
                for j in range(P)]
        perm = rng.permutation(n)                          # objects in any order; the layout's order sorts them
        order = np.lexsort((frame[perm], traj[perm]))
        lone = traj_layout(order, traj[perm], ign[perm], cand[perm], n_tracks, np.full(n, -1))
        got = ids_frag(lone, kept, np.zeros((P, 0), dtype=np.int64), np.full(n, -1))
        assert list(zip(got[0].tolist(), got[1].tolist())) == want
        comp = traj_layout(order, traj[perm], ign[perm], np.full(n, -2), n_tracks, np.arange(n))
        got = ids_frag(comp, np.zeros((P, n_tracks), dtype=bool), g[:, perm], np.arange(n))
        assert list(zip(got[0].tolist(), got[1].tolist())) == want


# ---------------------------------------------------------------- bad input


@pytest.fixture
def tiny(tmp_path):
    return _root(tmp_path, GT), CARS


@pytest.mark.parametrize("edit, field, text", [
    (lambda f: f.__setitem__(10, "nan"), "h", "not finite"),
    (lambda f: f.__setitem__(15, "inf"), "z", "not finite"),
    (lambda f: f.__setitem__(10, "-1.5"), "h", "not positive"),
    (lambda f: f.__setitem__(11, "0"), "w", "zero"),
    (lambda f: f.__setitem__(12, "-3.9"), "w", "differ in sign"),
    (lambda f: f.__setitem__(17, "nan"), "score", "not finite"),
    (lambda f: f.__setitem__(13, "abc"), "x", "not a number"),
    (lambda f: f.__setitem__(0, "9"), "frame", "past the ground truth's end"),
    (lambda f: f.__setitem__(1, "-2"), "track_id", "negative id"),
    (lambda f: f.__setitem__(2, "DontCare"), "type", "DontCare"),
    (lambda f: f.__setitem__(10, "-1"), "h", "not positive"),  # half a placeholder is no placeholder
])
def test_bad_result_rows_are_located(tmp_path, tiny, edit, field, text):
    root, rows = tiny
    res_rows = [_as_result(r) for r in rows]
    f = res_rows[2].split()
    edit(f)
    res_rows[2] = " ".join(f)
    res = _results(tmp_path, {"0000": res_rows})
    with pytest.raises(KittiFormatError) as e:
        evaluate_ab3dmot_files(res, root, "car", ["0000"], iou="3d:0.25")
    assert (e.value.line, e.value.field) == (3, field) and text in e.value.message, str(e.value)


def test_bad_rows_needing_no_3d_check(tmp_path, tiny):
    root, rows = tiny
    res_rows = [_as_result(r) for r in rows]
    nan_h = res_rows[1].split()
    nan_h[10] = "nan"
    ok = _results(tmp_path, {"0000": res_rows[:1] + [" ".join(nan_h)] + res_rows[2:]}, "ok")
    assert evaluate_ab3dmot_files(ok, root, "car", ["0000"], iou="2d:0.5")["TP"] == 8   # 2D reads 3D unchecked
    short = _results(tmp_path, {"0000": res_rows[:3] + [" ".join(res_rows[3].split()[:10])]}, "short")
    with pytest.raises(KittiFormatError, match=r"0000.txt:4: expected 17 or 18 columns"):
        evaluate_ab3dmot_files(short, root, "car", ["0000"], iou="2d:0.5")
    dup = _results(tmp_path, {"0000": res_rows + [res_rows[0]]}, "dup")
    with pytest.raises(KittiFormatError, match="occurs twice") as e:
        evaluate_ab3dmot_files(dup, root, "car", ["0000"], iou="2d:0.5")
    assert e.value.line == 9
    skipped = _results(tmp_path, {"0000": res_rows + ["0 -1 Car 0 0 -1 1 1 2 2 1 1 1 1 1 1 0 0.5", "0 5 Cyclist x"]},
                       "skipped")                                # id -1 skipped; other classes not read
    assert evaluate_ab3dmot_files(skipped, root, "car", ["0000"], iou="2d:0.5")["TP"] == 8


def test_bad_seqmaps_and_missing_files(tmp_path, tiny):
    root, rows = tiny
    good = tmp_path / "good.seqmap"
    good.write_text("0000 empty 000000 000005\n")
    assert read_seqmap(good, root) == ("0000",)
    for text, line, field, msg in (("0000 empty 000000 000005\n0001 empty 000000 000010\n", 2, "sequence",
                                    "no ground truth"),
                                   ("0000 empty 000000 000002\n", 1, "frames", "frames 0..3"),
                                   ("0000 empty 000000\n", 1, None, "expected 4 fields"),
                                   ("0000 empty 0 x\n", 1, "frames", "not integers")):
        bad = tmp_path / "bad.seqmap"
        bad.write_text(text)
        with pytest.raises(KittiFormatError) as e:
            evaluate_ab3dmot_files(tmp_path, root, "car", seqmap=bad)
        assert (e.value.line, e.value.field) == (line, field) and msg in e.value.message, str(e.value)
    empty = _results(tmp_path, {}, "empty")
    r = evaluate_ab3dmot_files(empty, root, "car", ["0000"])
    assert (r["TP"], r["FN"], r["FP"], r["MOTA"], r["sAMOTA"]) == (0, 8, 0, 0.0, 0)
    with pytest.raises(KittiFormatError, match="result file not found"):
        evaluate_ab3dmot_files(empty, root, "car", ["0000"], missing="error")
    with pytest.raises(KittiFormatError, match="no ground truth"):
        prepare_ab3dmot_gt(root, "car", ["0007"])


@pytest.mark.parametrize("spec", ["3d", "4d:0.5", "3d:x", "2d:0", "3d:1.5", "3d:-0.2"])
def test_bad_iou_specs(spec):
    with pytest.raises(ValueError, match="AB3DMOT IoU"):
        parse_iou(spec)
    assert parse_iou("3D:0.7") == ("3d", 0.7)
