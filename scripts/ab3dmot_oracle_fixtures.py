"""Write tests/fixtures/ab3dmot_oracle/{affinity_pairs.json, random_scenes.json.gz} with AB3DMOT's own
code, or compare the oracle with it on many more random scenes (``--stress``).

AB3DMOT is not part of this repository and is not copied into it: this script imports it from a
checkout of xinshuoweng/AB3DMOT at 61f3bd7 (``AB3DMOT_DIR``), in the environment of the reference
runs: ``--site DIR`` is put first on ``sys.path`` and should hold numpy 1.23.5, scipy 1.11.4 and
filterpy 1.4.5 (``pip install --no-deps --target DIR numpy==1.23.5 scipy==1.11.4 filterpy==1.4.5``).
The Xinshuo_PyToolbox helpers and numba's ``jit`` are replaced by stand-ins (none is on the
tracking path; numba's rotation helpers ran in object mode in the reference runs).

    python scripts/ab3dmot_oracle_fixtures.py AB3DMOT_DIR --site DIR            # the fixtures
    python scripts/ab3dmot_oracle_fixtures.py AB3DMOT_DIR --site DIR --stress 5000 400 40 > stress.json
    PYTHONPATH=. python scripts/ab3dmot_oracle_fixtures.py --check stress.json   # the oracle, as installed
"""

import argparse
import gzip
import json
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "tests" / "fixtures" / "ab3dmot_oracle"
DIST = ("dist_2d", "dist_3d", "m_dis")
NAMES = {1: "Pedestrian", 2: "Car", 3: "Cyclist"}
THRES = {"iou_2d": 0.1, "iou_3d": 0.01, "giou_2d": -0.3, "giou_3d": -0.2, "dist_2d": 2.5, "dist_3d": 3, "m_dis": 6}
STUBS = {
    "xinshuo_miscellaneous.py": "def print_log(*a, **k): pass\ndef get_timestring(): return ''\n",
    "xinshuo_io.py": "def mkdir_if_missing(*a, **k): pass\n" + "".join(
        f"def {n}(*a, **k): raise NotImplementedError\n"
        for n in ("fileparts", "load_txt_file", "save_txt_file", "load_list_from_folder", "is_path_exists")),
    "xinshuo_visualization.py": "def random_colors(*a, **k): return []\n",
    "numba.py": "def jit(*a, **k):\n    return a[0] if a and callable(a[0]) else (lambda f: f)\n",
}


def setup(ab3dmot_dir, site):
    stubs = Path(tempfile.mkdtemp(prefix="ab3dmot_stubs_"))
    for name, text in STUBS.items():
        (stubs / name).write_text(text)
    sys.path[:0] = ([site] if site else []) + [str(ab3dmot_dir), str(stubs)]


def pair_cases(np, ab):
    """120 box pairs (random, perturbed, identical, turned by pi, turned by +-pi/2 or 2 pi, far
    perturbed) with AB3DMOT's float32 affinity for all seven metrics (None where it raises)."""
    from AB3DMOT_libs.box import Box3D
    from AB3DMOT_libs.dist_metrics import dist3d, dist_ground, iou, m_distance

    def box(s):
        return Box3D.array2bbox(np.array(s, dtype=float))

    rng = np.random.default_rng(20261128)

    def rbox():
        return np.array([rng.uniform(-20, 20), rng.uniform(0, 3), rng.uniform(5, 60), rng.uniform(-3.9, 3.9),
                         rng.uniform(3, 5), rng.uniform(1.4, 2), rng.uniform(1.3, 1.8)]).round(4)
    pairs = []
    for k in range(120):
        a = rbox()
        kind = k % 6
        if kind == 0:
            b = rbox()
        elif kind == 1:
            b = (a + rng.normal(0, 0.3, 7) * np.array([1, .1, 1, .2, .1, .05, .05])).round(4)
        elif kind == 2:
            b = a.copy()
        elif kind == 3:
            b = a.copy()
            b[3] += np.pi
        elif kind == 4:
            b = a.copy()
            b[3] += rng.choice([np.pi / 2, -np.pi / 2, 2 * np.pi])
        else:
            b = (a + rng.normal(0, 2, 7) * np.array([1, .1, 1, 1, .1, .05, .05])).round(4)
        s_diag = rng.uniform(1, 20, 7).round(3)
        vals = {}
        for m in ["iou_2d", "iou_3d", "giou_2d", "giou_3d"]:
            try:
                vals[m] = float(np.float32(iou(box(a), box(b), m)))
            except Exception:
                vals[m] = None
        vals["dist_2d"] = float(np.float32(-dist_ground(box(a), box(b))))
        vals["dist_3d"] = float(np.float32(-dist3d(box(a), box(b))))
        vals["m_dis"] = float(np.float32(-m_distance(box(a), box(b), np.linalg.inv(np.diag(s_diag)))))
        pairs.append({"det": a.tolist(), "trk": b.tolist(), "S_diag": s_diag.tolist(), "affinity": vals})
    return pairs


def scene_csv(np, rng, n_frames):
    """A random scene in the PointRCNN CSV format: 2-6 objects at constant velocity with noise,
    20 % missed, heading flips by pi (12 %), headings beyond +-pi, the same box again (4 %),
    near-duplicate detections (6 %), false positives, empty frames (8 %), shuffled rows."""
    objs = []
    for _ in range(rng.integers(2, 7)):
        start = int(rng.integers(0, n_frames // 2))
        end = int(rng.integers(start + 3, n_frames + 3))
        objs.append(dict(start=start, end=end, p=np.array([rng.uniform(-12, 12), rng.uniform(1, 2), rng.uniform(6, 45)]),
                         v=rng.normal(0, 0.6, 3) * np.array([1, .02, 1]), th=rng.uniform(-np.pi, np.pi),
                         dims=np.array([rng.uniform(3, 5), rng.uniform(1.4, 2), rng.uniform(1.3, 1.8)]),
                         cls=int(rng.choice([1, 2, 2, 3])), last=None))
    rows = []
    for f in range(n_frames):
        fr = []
        if rng.random() < 0.08:
            continue
        for o in objs:
            if not (o["start"] <= f < o["end"]) or rng.random() < 0.2:
                continue
            p = o["p"] + o["v"] * (f - o["start"]) + rng.normal(0, 0.15, 3) * np.array([1, .1, 1])
            th = o["th"] + rng.normal(0, 0.05)
            if rng.random() < 0.12:
                th += np.pi
            if th > np.pi and rng.random() < 0.5:
                pass
            elif th > np.pi:
                th -= 2 * np.pi
            if th < -np.pi and rng.random() < 0.5:
                th += 2 * np.pi
            th = float(np.clip(th, -3.9, 3.9))
            lwh = o["dims"] + rng.normal(0, 0.05, 3)
            box3 = [lwh[2], lwh[1], lwh[0], p[0], p[1], p[2], th]
            if o["last"] is not None and rng.random() < 0.04:
                box3 = o["last"]
            o["last"] = box3
            fr.append((o["cls"], box3))
            if rng.random() < 0.06:
                fr.append((o["cls"], (np.array(box3) + rng.normal(0, 0.03, 7)).tolist()))
        for _ in range(rng.poisson(0.4)):
            fr.append((int(rng.choice([1, 2, 3])), [rng.uniform(1.3, 1.8), rng.uniform(1.4, 2), rng.uniform(3, 5),
                       rng.uniform(-15, 15), rng.uniform(1, 2), rng.uniform(5, 50), rng.uniform(-3.9, 3.9)]))
        for i in rng.permutation(len(fr)):
            cls, b3 = fr[i]
            x1, y1 = float(rng.integers(0, 100)) * 10, float(rng.integers(10, 30)) * 10
            rows.append("%d,%d,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f" % (
                f, cls, x1, y1, x1 + 50, y1 + 25, round(rng.uniform(-3, 15), 2), *b3, round(rng.uniform(-np.pi, np.pi), 2)))
    return "\n".join(rows) + "\n"


def run_ab3dmot(np, csv, n_frames, st, first_id, tmp):
    """AB3DMOT.track over one sequence (get_param's values replaced by ``st``), lines as main.py
    writes them."""
    from AB3DMOT_libs.io import get_frame_det, load_detection
    from AB3DMOT_libs.model import AB3DMOT

    class Cfg:
        vis, ego_com, affi_pro, dataset, det_name = False, False, False, "KITTI", "pointrcnn"
    path = Path(tmp) / "scene.txt"
    path.write_text(csv)
    seq_dets, _ = load_detection(str(path))
    t = AB3DMOT(Cfg, "Car", ID_init=first_id)
    t.algm, t.metric, t.min_hits, t.max_age = st["algorithm"], st["metric"], st["min_hits"], st["max_age"]
    t.thres = -st["threshold"] if st["metric"] in DIST else st["threshold"]
    lines = []
    for frame in range(n_frames):
        results, _ = t.track(get_frame_det(seq_dets, frame), frame, "scene")
        for r in results[0]:
            lines.append("%d %d %s 0 0 %f %f %f %f %f %f %f %f %f %f %f %f %f" % (
                frame, r[7], NAMES[r[9]], r[8], r[10], r[11], r[12], r[13], r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[14]))
    return lines, int(t.ID_count[0])


def check(path):
    """The oracle on each scene of a --stress file: lines and next id equal, or both raise."""
    from dfrmot_jax.testing import ab3dmot_oracle as ab
    counts = {"equal": 0, "differ": 0, "both raise": 0, "only AB3DMOT raises": 0}
    for c in json.loads(Path(path).read_text()):
        try:
            got = ab.track_sequence(ab.parse_detections(c["detections"]), c["n_frames"],
                                    ab.Settings("Car", **c["settings"]), c["first_id"])
        except ab.DegenerateGeometry:
            got = None
        if c["lines"] is None:
            counts["both raise" if got is None else "only AB3DMOT raises"] += 1
        elif got == (c["lines"], c["next_id"]):
            counts["equal"] += 1
        else:
            counts["differ"] += 1
            print("differs:", c["seed"], c["settings"])
    print(counts)
    return 1 if counts["differ"] or counts["only AB3DMOT raises"] else 0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("ab3dmot_dir", nargs="?")
    ap.add_argument("--check", metavar="STRESS_JSON", help="run the oracle on --stress output and compare")
    ap.add_argument("--site", help="folder with numpy 1.23.5, scipy 1.11.4, filterpy 1.4.5")
    ap.add_argument("--stress", nargs=3, type=int, metavar=("FIRST_SEED", "N", "FRAMES"))
    args = ap.parse_args()
    if args.check:
        return check(args.check)
    setup(args.ab3dmot_dir, args.site)
    import warnings
    import numpy as np
    warnings.simplefilter("ignore")
    tmp = tempfile.mkdtemp(prefix="ab3dmot_scene_")
    combos = [(m, a) for m in THRES for a in ("hungar", "greedy")]
    if args.stress:                               # AB3DMOT's lines to stdout as JSON, for the oracle to check
        first, n, n_frames = args.stress
        out = []
        for seed in range(first, first + n):
            r = np.random.default_rng(seed)
            metric, algm = combos[seed % len(combos)]
            csv = scene_csv(np, r, n_frames)
            st = dict(algorithm=algm, metric=metric, threshold=THRES[metric], min_hits=int(r.integers(1, 4)),
                      max_age=int(r.integers(1, 5)))
            try:
                lines, next_id = run_ab3dmot(np, csv, n_frames, st, 1, tmp)
            except Exception as e:                # degenerate geometry: AB3DMOT's qhull raises
                lines, next_id = None, repr(e)
            out.append(dict(seed=seed, settings=st, n_frames=n_frames, first_id=1, next_id=next_id,
                            detections=csv, lines=lines))
        json.dump(out, sys.stdout)
        return
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "affinity_pairs.json").write_text(json.dumps({
        "source": "AB3DMOT 61f3bd7 dist_metrics (iou, dist_ground, dist3d, m_distance with inv(diag(S_diag))), "
                  "numpy 1.23.5, scipy 1.11.4; values rounded to float32; null: AB3DMOT raises (QhullError); "
                  "boxes [x, y, z, theta, l, w, h]", "pairs": pair_cases(np, None)}))
    cases, seed = [], 0
    for metric, algm in combos * 2:
        while True:                               # the first seed on which AB3DMOT runs through
            seed += 1
            r = np.random.default_rng(seed)
            csv = scene_csv(np, r, 20)
            st = dict(algorithm=algm, metric=metric, threshold=THRES[metric], min_hits=int(r.integers(1, 4)),
                      max_age=int(r.integers(1, 5)))
            first_id = int(r.choice([1, 57]))
            try:
                lines, next_id = run_ab3dmot(np, csv, 20, st, first_id, tmp)
                break
            except Exception:
                continue
        cases.append(dict(seed=seed, settings=st, n_frames=20, first_id=first_id, next_id=next_id,
                          detections=csv, lines=lines))
    with gzip.GzipFile(OUT / "random_scenes.json.gz", "wb", mtime=0) as f:
        f.write(json.dumps({
            "source": "AB3DMOT 61f3bd7 AB3DMOT.track (get_param values overridden by settings; threshold as "
                      "written, negated for distance metrics), numpy 1.23.5, scipy 1.11.4, filterpy 1.4.5; one "
                      "sequence per case; detections in the PointRCNN CSV format; made by "
                      "scripts/ab3dmot_oracle_fixtures.py", "cases": cases}).encode())


if __name__ == "__main__":
    sys.exit(main())
