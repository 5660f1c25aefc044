"""``dfrmot track``: track a KITTI split with a preset and ``--set`` overrides, one result file per sequence.

``--out`` is a new or empty folder: a non-empty one is refused (exit 2) unless ``--overwrite``, which
removes its old result files (``SSSS.txt`` and temporaries of an interrupted write) before writing
and keeps every other file, so that no stale sequence is scored with the new ones. The folder is
locked while the run writes it (:func:`dfrmot_jax.io.lock.folder_lock`): a second run on it fails at
once, naming the folder and the process writing it. ``--set CLASS.NAME=VALUE`` for a class not in
``--class`` is checked as if that class were tracked, then refused (exit 2) rather than ignored.

The preset names the tracker family (``--preset dfr2023``: DFR-FastMOT; ``--preset ab3dmot_car``:
AB3DMOT), whose settings ``--set`` changes and whose tracker runs (through the family protocol,
:mod:`dfrmot_jax.trackers.registry`); a family that reads 3D detections only reads no ``--det2d``.

The command's parser and ``--help`` (every parameter, option and preset) are
:mod:`dfrmot_jax.cli.track_parser`'s, which imports nothing of the tracker.
"""

from __future__ import annotations

import time
import warnings
from pathlib import Path

from ..data import load_split
from ..trackers.registry import family_of
from ..trackers.registry import preset_family
from ..trackers.protocol import preset_class_note
from ..io.lock import LOCK_NAME, folder_lock
from ..lidar import LiftSettings, lidar_dir, lift_setting_name, tie_scores, with_setting
from ..paths import default_data_root
from ..io.result_writer import result_files
from .args import parse_seqs
from .track_parser import add_parser, config_help  # this command's parser (it needs only config)

#: the 2D detector ``--det2d`` names by default (a family that reads 2D detections)
DEFAULT_DET2D = "rrc"

__all__ = ["add_parser", "run", "config_help", "parse_seqs", "class_settings"]


def _classes(text: str, known) -> list[str]:
    """The classes of ``--class`` (comma-separated, each once), each one of ``known`` (the family's)."""
    classes = [c.strip() for c in text.split(",") if c.strip()]
    bad = [c for c in classes if c not in known]
    if bad or not classes or len(set(classes)) != len(classes):
        raise ValueError(f"--class {text!r}: expected one or more of {list(known)}, comma-separated, each once")
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
    fc = preset_family(args.preset)
    known, parse_assignment = fc.classes, fc.parse_assignment
    params, options = fc.preset(args.preset, cls)
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
            if prefix not in known:
                raise ValueError(f"--set {item}: {prefix!r} is not a class; per-class settings are CLASS.NAME=VALUE "
                                 f"with CLASS one of {list(known)}")
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
    return (tie_scores(params) if lifted and not set_3d and "score_2d" in params._fields else params), options


def untracked_settings(args, classes) -> None:
    """Refuse ``--set CLASS.NAME=VALUE`` for a class not in ``classes`` (it would be ignored): each is
    first checked as if its class were tracked (an unknown name or a bad value is that error), then
    a valid one is refused too, naming the class and how to track it."""
    known = preset_family(args.preset).classes
    prefixes = [lhs.partition(".")[0] if "." in lhs else None
                for lhs in (item.partition("=")[0].strip() for item in args.set or [])]
    untracked = [c for c in dict.fromkeys(prefixes) if c in known and c not in classes]
    for cls in untracked:
        class_settings(args, cls)
    for item, prefix in zip(args.set or [], prefixes):
        if prefix in untracked:
            raise ValueError(f"--set {item}: class {prefix!r} is not tracked (--class {','.join(classes)}), so this "
                             f"setting would be ignored: track it too (--class {','.join(classes)},{prefix}) or drop "
                             f"the setting")


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
    fc = preset_family(args.preset)
    family = family_of(fc.name)
    classes = _classes(args.cls, fc.classes)
    settings = {cls: class_settings(args, cls) for cls in classes}
    untracked_settings(args, classes)
    reads_2d = "2d" in fc.detections or lidar_dir(args.det3d) is not None
    if args.det2d is not None and not reads_2d:
        warnings.warn(f"--det2d {args.det2d}: {fc.title} reads 3D detections only (--det3d {args.det3d}), so no 2D "
                      f"detection is read: the option changes nothing (drop it)")
    args.det2d = args.det2d if args.det2d is not None else DEFAULT_DET2D
    note = preset_class_note(fc, args.preset, classes, " (--preset)")
    if note is not None:
        warnings.warn(f"--class {','.join(classes)}: {note}")
    for cls, (p, o) in settings.items():
        problem = family.setting_problem(f"the {cls} settings (--preset {args.preset} and --set)", p, o)
        if problem:
            raise ValueError(problem)
    with folder_lock(args.out, "track"):
        family.write_runs(args.out, [], columns=args.columns)       # (columns the family cannot write: refused now)
        return _track(args, classes, settings, family)


def _sequences(args, family, root: Path) -> list[str] | None:
    """The sequences to track: ``--seqs``, else the family's default (``FamilyConfig.default_sequences``):
    every ``label_02`` sequence for a family run as its own code runs (AB3DMOT), None (those whose
    ground truth has the class) for the others."""
    seqs = parse_seqs(args.seqs)
    if seqs is None and family.config.default_sequences == "all" and (root / "label_02").is_dir():
        seqs = sorted(p.stem for p in (root / "label_02").glob("*.txt"))
    return seqs


def _track(args, classes, settings, family) -> int:
    """Track and write, holding the lock of ``--out``."""
    old = _old_results(Path(args.out), args.overwrite)
    root = Path(args.data) if args.data else default_data_root()
    lift = lift_of(args)
    det2d = args.det2d if "2d" in family.config.detections or lidar_dir(args.det3d) is not None else None
    det3d = args.det3d if "3d" in family.config.detections else None        # (a camera-only family reads none)
    t0 = time.perf_counter()
    runs, status = [], 0
    for cls in classes:
        params, options = settings[cls]
        split = load_split(root, det2d, det3d, cls, _sequences(args, family, root), lift=lift)
        res = family.track(split, params, options, detail=True)
        runs.append(family.class_run(split, res, 0))
        n = int((res.ids[0] >= 0).sum())
        print(f"{cls}: tracked {len(split.names)} sequences, {split.n_frames} frames, {n} lines; capacity "
              f"{int(res.capacity[0])}, peak {int(res.peak[0])} live tracks, overflow {int(res.overflow[0])}")
        status = status or (0 if res.overflow[0] == 0 else 3)
    for p in old:
        p.unlink(missing_ok=True)
    paths = family.write_runs(args.out, runs, columns=args.columns)
    print(f"wrote {len(paths)} files to {Path(args.out)} in {time.perf_counter() - t0:.1f} s"
          + (" (classes " + " + ".join(classes) + " merged per sequence, ids unique per file)" if len(classes) > 1 else ""))
    return status
