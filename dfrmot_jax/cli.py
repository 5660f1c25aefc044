"""``dfrmot`` command line: track | demo | eval | sweep | report."""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from .io.kitti import KittiFormatError
from .paths import ENV_VAR, default_data_root


def _parse_seqs(text: str | None):
    if not text:
        return None
    return [s.strip().zfill(4) for s in text.split(",") if s.strip()]


def _classes(text: str) -> list[str]:
    from .config import CLASSES

    classes = [c.strip() for c in text.split(",") if c.strip()]
    bad = [c for c in classes if c not in CLASSES]
    if bad or not classes or len(set(classes)) != len(classes):
        raise ValueError(f"--class {text!r}: expected one or more of {list(CLASSES)}, comma-separated, each once")
    return classes


def _settings(args, cls: str = "car"):
    """The preset for the class, then every ``--set NAME=VALUE`` and ``--set CLASS.NAME=VALUE`` of it."""
    from .config import CLASSES, parse_assignment, preset

    params, options = preset(args.preset, cls)
    for item in args.set or []:
        lhs, eq, rhs = item.partition("=")
        prefix, dot, name = lhs.strip().partition(".")
        if dot:
            if prefix not in CLASSES:
                raise ValueError(f"--set {item}: {prefix!r} is not a class; per-class settings are CLASS.NAME=VALUE "
                                 f"with CLASS one of {list(CLASSES)}")
            if prefix != cls:
                continue
            item = f"{name}{eq}{rhs}"
        params, options = parse_assignment(item, params, options)
    return params, options


def cmd_track(args) -> int:
    from .api import track
    from .data import load_split
    from .results import ClassRun, write_runs

    root = Path(args.data) if args.data else default_data_root()
    classes = _classes(args.cls)
    settings = {cls: _settings(args, cls) for cls in classes}
    t0 = time.perf_counter()
    runs, status = [], 0
    for cls in classes:
        params, options = settings[cls]
        split = load_split(root, args.det2d, args.det3d, cls, _parse_seqs(args.seqs))
        res = track(split, params, options, detail=True)
        runs.append(ClassRun(split, res.frames, options, res.ids[0],
                             None if options.output == "detections" else res.lane_boxes(0),
                             res.src3[0], res.own3[0], None if res.box3 is None else res.box3[0]))
        n = int((res.ids[0] >= 0).sum())
        print(f"{cls}: tracked {len(split.names)} sequences, {split.n_frames} frames, {n} lines; capacity "
              f"{int(res.capacity[0])}, peak {int(res.peak[0])} live tracks, overflow {int(res.overflow[0])}")
        status = status or (0 if res.overflow[0] == 0 else 3)
    paths = write_runs(args.out, runs, columns=args.columns)
    print(f"wrote {len(paths)} files to {Path(args.out)} in {time.perf_counter() - t0:.1f} s"
          + (" (classes " + " + ".join(classes) + " merged per sequence, ids unique per file)" if len(classes) > 1 else ""))
    return status


def cmd_demo(args) -> int:
    from .api import track
    from .data import load_split
    from .config import Options, Params
    from .results import write_lane
    from .synthetic import make_scene

    work = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="dfrmot_demo_"))
    root = make_scene(work / "scene", n_sequences=args.sequences, n_frames=args.frames, seed=args.seed)
    split = load_split(root, "synth2d", "synth3d", "car")
    params, options = Params(), Options()
    res = track(split, params, options)
    write_lane(work / "results", split, res.frames, options, res.ids[0])
    print(f"synthetic scene: {len(split.names)} sequences, {split.n_frames} frames at {root}")
    print(f"tracked with the dfr2023 settings -> {work / 'results'}")
    try:
        from .metrics import evaluate_files, metrics_table
    except ImportError:  # metrics not installed in this build
        return 0
    table = metrics_table(evaluate_files(work / "results", root, "car"))
    cols = ["HOTA", "DetA", "AssA", "MOTA", "IDF1", "IDSW"]
    print(table[cols].to_string(float_format=lambda v: f"{v:.2f}"))
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="dfrmot", description=__doc__)
    sub = p.add_subparsers(dest="command", required=True)

    t = sub.add_parser("track", help="track a KITTI split and write one result file per sequence")
    t.add_argument("--data", help=f"KITTI tracking training root (default ${ENV_VAR} or ../shared/data/kitti/training)")
    t.add_argument("--det2d", default="rrc", help="2D detector: name under ROOT/detections or a directory")
    t.add_argument("--det3d", default="pointrcnn", help="3D detector: name under ROOT/detections or a directory")
    t.add_argument("--preset", default="dfr2023", help="dfr2023 (published run) | dfr_head (authors' code at HEAD)")
    t.add_argument("--set", action="append", metavar="NAME=VALUE",
                   help="override a parameter or option (repeatable); CLASS.NAME=VALUE for one class only, "
                        "e.g. pedestrian.a_l=2")
    t.add_argument("--class", dest="cls", default="car",
                   help="car | pedestrian | car,pedestrian (each class with its own settings, one file per sequence)")
    t.add_argument("--seqs", help="comma-separated sequences (default: those whose ground truth has the class)")
    t.add_argument("--columns", default="kitti", choices=["kitti", "authors"],
                   help="result columns: kitti (standard KITTI rows with each row's 3D box and score) | authors "
                        "(the authors' C++ 18 columns, byte for byte)")
    t.add_argument("--out", required=True, help="output directory")
    t.set_defaults(func=cmd_track)

    d = sub.add_parser("demo", help="generate a synthetic scene, track it and score it (no data needed)")
    d.add_argument("--out", help="work directory (default: a new temporary directory)")
    d.add_argument("--sequences", type=int, default=2)
    d.add_argument("--frames", type=int, default=120)
    d.add_argument("--seed", type=int, default=0)
    d.set_defaults(func=cmd_demo)

    try:
        from .metrics.cli import add_eval_parser
    except ImportError:
        pass
    else:
        add_eval_parser(sub)
    from .sweep_cli import add_report_parser, add_sweep_parser
    add_sweep_parser(sub)
    add_report_parser(sub)
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (KittiFormatError, ValueError, FileNotFoundError) as e:
        print(f"dfrmot {args.command}: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
