"""``dfrmot track``: track a KITTI split with a preset and ``--set`` overrides, one result file per sequence.

``--out`` is a new or empty folder: a non-empty one is refused (exit 2) unless ``--overwrite``, which
removes its old result files (``SSSS.txt`` and temporaries of an interrupted write) before writing
and keeps every other file, so that no stale sequence is scored with the new ones. The folder is
locked while the run writes it (:func:`dfrmot_jax.io.lock.folder_lock`): a second run on it fails at
once, naming the folder and the process writing it. ``--set CLASS.NAME=VALUE`` for a class not in
``--class`` is checked as if that class were tracked, then refused (exit 2) rather than ignored.
"""

from __future__ import annotations

import argparse
import re
import shutil
import textwrap
import time
from pathlib import Path

from ..api import track
from ..config import (
    CLASS_DEFAULTS,
    CLASSES,
    INT_PARAMS,
    MAX_CAPACITY,
    OPTION_CHOICES,
    PARAM_RANGES,
    PRESETS,
    Options,
    Params,
    parse_assignment,
    preset,
)
from ..data import load_split
from ..io.lock import LOCK_NAME, folder_lock
from ..lidar import LiftSettings, lidar_dir, lift_setting_name, tie_scores, with_setting
from ..paths import ENV_VAR, default_data_root
from ..results import ClassRun, result_files, write_runs
from ..sweep.table import unstable_gains, unstable_message
from .errors import guarded

__all__ = ["add_parser", "run", "config_help"]


def parse_seqs(text: str | None) -> list[str] | None:
    """``--seqs 1,0002`` -> ["0001", "0002"] (KITTI names are zero-padded to 4 digits)."""
    if not text:
        return None
    return [s.strip().zfill(4) for s in text.split(",") if s.strip()]


def _classes(text: str) -> list[str]:
    classes = [c.strip() for c in text.split(",") if c.strip()]
    bad = [c for c in classes if c not in CLASSES]
    if bad or not classes or len(set(classes)) != len(classes):
        raise ValueError(f"--class {text!r}: expected one or more of {list(CLASSES)}, comma-separated, each once")
    return classes


def lift_of(args) -> LiftSettings:
    """The lifting settings of ``--det3d lidar:DIR``: ``--set shrink=0.1`` (or ``lift.shrink``), ..."""
    s = LiftSettings()
    for item in args.set or []:
        lhs, eq, rhs = item.partition("=")
        if lift_setting_name(lhs) is not None:
            s = with_setting(s, lhs, rhs.strip())
    return s


def class_settings(args, cls: str = "car"):
    """The preset for the class, then every ``--set NAME=VALUE`` and ``--set CLASS.NAME=VALUE`` of it
    (lifting settings excepted, :func:`lift_of`). With ``--det3d lidar:DIR`` score_3d is score_2d
    (a lifted box carries its 2D detection's score) unless set. A bad ``CLASS.NAME=VALUE`` is a
    ValueError naming ``CLASS.NAME``; a lifting setting under a class prefix is refused (one lifting
    for every class)."""
    params, options = preset(args.preset, cls)
    lifted = lidar_dir(getattr(args, "det3d", "")) is not None
    set_3d = False
    for item in args.set or []:
        lhs, eq, rhs = item.partition("=")
        if lift_setting_name(lhs) is not None:
            if not lifted:
                raise ValueError(f"--set {item}: a lifting setting, for --det3d lidar:DIR only")
            continue
        prefix, dot, name = lhs.strip().partition(".")
        if dot:
            if prefix not in CLASSES:
                raise ValueError(f"--set {item}: {prefix!r} is not a class; per-class settings are CLASS.NAME=VALUE "
                                 f"with CLASS one of {list(CLASSES)}")
            if prefix != cls:
                continue
            name = name.strip()
            if not eq:
                raise ValueError(f"--set {item!r}: expected CLASS.NAME=VALUE")
            if lift_setting_name(name) is not None:
                raise ValueError(f"--set {item}: {name!r} is a lifting setting, one for every class: --set "
                                 f"{name}=VALUE (with --det3d lidar:DIR)")
            try:
                params, options = parse_assignment(f"{name}{eq}{rhs}", params, options)
            except ValueError as e:       # name the setting as given: CLASS.NAME
                msg = str(e)
                head = f"--set {name}"
                raise ValueError(f"--set {prefix}.{name}{msg[len(head):]}" if msg.startswith(head)
                                 else f"--set {item.strip()}: {msg}") from None
            set_3d = set_3d or name == "score_3d"
            continue
        set_3d = set_3d or lhs.strip() == "score_3d"
        params, options = parse_assignment(item, params, options)
    return (tie_scores(params) if lifted and not set_3d else params), options


def untracked_settings(args, classes) -> None:
    """Refuse ``--set CLASS.NAME=VALUE`` for a class not in ``classes`` (it would be ignored): each is
    first checked as if its class were tracked (an unknown name or a bad value is that error), then
    a valid one is refused too, naming the class and how to track it."""
    prefixes = [lhs.partition(".")[0] if "." in lhs else None
                for lhs in (item.partition("=")[0].strip() for item in args.set or [])]
    untracked = [c for c in dict.fromkeys(prefixes) if c in CLASSES and c not in classes]
    for cls in untracked:
        class_settings(args, cls)
    for item, prefix in zip(args.set or [], prefixes):
        if prefix in untracked:
            raise ValueError(f"--set {item}: class {prefix!r} is not tracked (--class {','.join(classes)}), so this "
                             f"setting would be ignored: track it too (--class {','.join(classes)},{prefix}) or drop "
                             f"the setting")


# ---- help text generated from dfrmot_jax.config ----------------------------------------------------

_FIELD = re.compile(r"^(\s+)([a-z_][a-z0-9_]*(?:,\s*[a-z_][a-z0-9_]*)*):\s+(\S.*)$")


def _plain(text: str) -> str:
    return text.replace("``", "").replace("`", "")


def _first_sentence(text: str) -> str:
    """Up to the first full stop outside parentheses (``(e.g. a. b)`` does not end a sentence)."""
    depth = 0
    for i, ch in enumerate(text):
        depth += ch == "("
        depth -= ch == ")"
        if ch == "." and depth == 0 and (i + 1 == len(text) or text[i + 1].isspace()):
            return text[:i]
    return text


def docstring_fields(doc: str, fields) -> list[tuple[tuple[str, ...], str]]:
    """The ``name: text`` entries of a NamedTuple docstring, in order: [(names, first sentence)]
    (``a, b: text`` is one entry for both names; continuation lines are joined; RST markup dropped)."""
    entries: list[tuple[list[str], list[str]]] = []
    for line in (doc or "").splitlines():
        m = _FIELD.match(line)
        names = [n.strip() for n in m.group(2).split(",")] if m else []
        if names and all(n in fields for n in names):
            entries.append((names, [m.group(3).strip()]))
        elif entries and line.strip():
            entries[-1][1].append(line.strip())
        elif entries:
            entries.append(([], []))                 # a blank line ends the entry
    out = []
    for names, lines in entries:
        if not names:
            continue
        text = ""
        for part in lines:
            text += part if text.endswith("-") or not text else " " + part
        out.append((tuple(names), _first_sentence(_plain(text))))
    return out


def _fmt(v) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def _grouped(entries, fields):
    """Every field once, in docstring order then field order: [(names, meaning)]."""
    seen = {n for names, _ in entries for n in names}
    return list(entries) + [((n,), "") for n in fields if n not in seen]


def config_help(width: int | None = None) -> str:
    """The ``track --help`` epilog: every parameter, option and preset with its meaning, generated
    from :mod:`dfrmot_jax.config` (Params / Options docstrings, PARAM_RANGES, OPTION_CHOICES,
    PRESETS, CLASS_DEFAULTS)."""


    width = width or max(60, min(120, shutil.get_terminal_size().columns) - 2)

    def meaning(text):
        return textwrap.fill(text, width, initial_indent=" " * 6, subsequent_indent=" " * 6) if text else None

    base_p, base_o = Params(), Options()
    out = ["parameters (--set NAME=VALUE; default = the dfr2023 value; ranges inclusive):"]
    for names, text in _grouped(docstring_fields(Params.__doc__, Params._fields), Params._fields):
        for name in names:
            lo, hi = PARAM_RANGES[name]
            kind = "integer" if name in INT_PARAMS else "number"
            out.append(f"  {name:<12} default {_fmt(getattr(base_p, name)):<6} {kind} in [{_fmt(lo)}, {_fmt(hi)}]")
        out += [meaning(text)] if text else []
    out += ["", "options (--set NAME=VALUE; each value compiles its own program):"]
    for names, text in _grouped(docstring_fields(Options.__doc__, Options._fields), Options._fields):
        for name in names:
            if name in OPTION_CHOICES:
                values = " | ".join(OPTION_CHOICES[name])
            elif name == "truncate":
                values = "true | false"
            elif name == "capacity":
                values = f"integer in [0, {MAX_CAPACITY}]"
            else:
                values = ""
            out.append(f"  {name:<12} default {_fmt(getattr(base_o, name)):<12} {values}")
        out += [meaning(text)] if text else []
    out += ["", "presets (--preset NAME; what differs from the defaults above):"]
    for name, (p, o) in PRESETS.items():
        diff = [f"{k}={_fmt(v)}" for k, v in p._asdict().items() if v != getattr(base_p, k)]
        diff += [f"{k}={_fmt(v)}" for k, v in o._asdict().items() if v != getattr(base_o, k)]
        out.append(f"  {name:<12} {' '.join(diff) or '(the defaults)'}")
    for cls, changes in CLASS_DEFAULTS.items():
        if changes:
            out.append(meaning(f"--class {cls}: every preset with "
                               + " ".join(f"{k}={_fmt(v)}" for k, v in changes.items())).replace(" " * 6, "  ", 1))
    return "\n".join(out)


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``track`` on an argparse ``subparsers`` object; returns its parser."""


    width = max(60, min(120, shutil.get_terminal_size().columns) - 2)
    t = sub.add_parser("track", help="track a KITTI split and write one result file per sequence",
                       description=textwrap.fill(
                           "Track a KITTI split with a preset and --set overrides and write one result file per "
                           "sequence. Exit status 3 when a lane overflowed its track memory.", width),
                       epilog=config_help(width), formatter_class=argparse.RawDescriptionHelpFormatter)
    t.add_argument("--data", help=f"KITTI tracking training root (default ${ENV_VAR} or ../shared/data/kitti/training)")
    t.add_argument("--det2d", default="rrc",
                   help="2D detector: name under ROOT/detections, or a directory (of SSSS.txt files, or of a folder "
                        "per class)")
    t.add_argument("--det3d", default="pointrcnn",
                   help="3D detector: name under ROOT/detections, or a directory (of SSSS.txt files, or of a folder "
                        "per class), or lidar:DIR: the 2D detections lifted to 3D from the scans "
                        "DIR/velodyne/SSSS/FFFFFF.bin (settings --set shrink=0.2, leaf, crop_lo, crop_hi, tolerance, "
                        "min_cluster, score_cut; score_3d follows score_2d)")
    t.add_argument("--preset", default="dfr2023",
                   help="the settings to start from: " + " | ".join(PRESETS) + " (listed below)")
    t.add_argument("--set", action="append", metavar="NAME=VALUE",
                   help="override a parameter or option (repeatable); CLASS.NAME=VALUE for one class only, "
                        "e.g. pedestrian.a_l=2 (checked like any setting; refused when CLASS is not in --class, "
                        "rather than ignored)")
    t.add_argument("--class", dest="cls", default="car",
                   help="car | pedestrian | car,pedestrian (each class with its own settings, one file per sequence)")
    t.add_argument("--seqs", help="comma-separated sequences (default: those whose ground truth has the class)")
    t.add_argument("--columns", default="kitti", choices=["kitti", "kitti-stale", "authors"],
                   help="result columns: kitti (standard KITTI rows with each row's own 3D box and score; rows "
                        "without one: placeholders) | kitti-stale (as kitti, but a row without its own 3D box "
                        "carries its track's last one, as the authors' files) | authors (the authors' C++ 18 "
                        "columns, byte for byte)")
    t.add_argument("--out", required=True, help="output directory: new or empty (see --overwrite)")
    t.add_argument("--overwrite", action="store_true",
                   help="write into a non-empty --out: its old result files (SSSS.txt) are removed first, other "
                        "files are kept")
    t.set_defaults(func=guarded(run))
    return t


def _old_results(out: Path, overwrite: bool) -> list[Path]:
    """The result files to remove from ``out`` before writing; ValueError when ``out`` is not a
    directory, or is not empty and not to be overwritten."""
    if not out.exists() and not out.is_symlink():
        return []
    if not out.is_dir():
        raise ValueError(f"--out {out}: exists and is not a directory")
    entries = sorted(p.name for p in out.iterdir() if p.name != LOCK_NAME)
    if not entries:
        return []
    if not overwrite:
        more = ", ..." if len(entries) > 5 else ""
        raise ValueError(f"--out {out} is not empty ({len(entries)} entries: {', '.join(entries[:5])}{more}): pass "
                         f"--overwrite to replace its result files (SSSS.txt; other files are kept), or choose a new "
                         f"folder")
    return result_files(out)


def run(args) -> int:
    _old_results(Path(args.out), args.overwrite)           # (a bad --out fails before anything else)
    classes = _classes(args.cls)
    settings = {cls: class_settings(args, cls) for cls in classes}
    untracked_settings(args, classes)
    for cls, (p, o) in settings.items():
        if o.output == "filtered" and unstable_gains([o.filter == "fixed_gain"], p.gain_alpha, p.gain_beta,
                                                     p.gain_gamma)[0]:
            raise ValueError(unstable_message(f"the {cls} settings (--preset {args.preset} and --set)", p.gain_alpha,
                                              p.gain_beta, p.gain_gamma, more=", or output=detections"))
    with folder_lock(args.out, "track"):
        return _track(args, classes, settings)


def _track(args, classes, settings) -> int:
    """Track and write, holding the lock of ``--out``."""
    old = _old_results(Path(args.out), args.overwrite)
    root = Path(args.data) if args.data else default_data_root()
    lift = lift_of(args)
    t0 = time.perf_counter()
    runs, status = [], 0
    for cls in classes:
        params, options = settings[cls]
        split = load_split(root, args.det2d, args.det3d, cls, parse_seqs(args.seqs), lift=lift)
        res = track(split, params, options, detail=True)
        runs.append(ClassRun(split, res.frames, options, res.ids[0],
                             None if options.output == "detections" else res.lane_boxes(0),
                             res.src3[0], res.own3[0], None if res.box3 is None else res.box3[0]))
        n = int((res.ids[0] >= 0).sum())
        print(f"{cls}: tracked {len(split.names)} sequences, {split.n_frames} frames, {n} lines; capacity "
              f"{int(res.capacity[0])}, peak {int(res.peak[0])} live tracks, overflow {int(res.overflow[0])}")
        status = status or (0 if res.overflow[0] == 0 else 3)
    for p in old:
        p.unlink(missing_ok=True)
    paths = write_runs(args.out, runs, columns=args.columns)
    print(f"wrote {len(paths)} files to {Path(args.out)} in {time.perf_counter() - t0:.1f} s"
          + (" (classes " + " + ".join(classes) + " merged per sequence, ids unique per file)" if len(classes) > 1 else ""))
    return status
