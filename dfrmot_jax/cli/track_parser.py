"""The ``dfrmot track`` parser, apart from the command (:mod:`dfrmot_jax.cli.track`): its options and
the epilog listing every parameter, option and preset with its meaning, generated from the tracker
family's settings (``config_help``: its :class:`~dfrmot_jax.trackers.protocol.FamilyConfig`, through
:mod:`dfrmot_jax.trackers.registry`). It needs nothing else, so that ``dfrmot track --help`` imports no
tracker; the command's module is imported when it runs (``errors.run_later``)."""

from __future__ import annotations

import argparse
import inspect
import re
import shutil
import textwrap

from ..trackers.protocol import DEFAULT_FAMILY
from ..trackers.registry import all_presets, family_config, family_names
from ..paths import ENV_VAR
from .args import seqs_arg
from .commands import HELP
from .errors import run_later

__all__ = ["add_parser", "config_help", "families_help", "docstring_fields"]


# ---- help text generated from the family's settings ------------------------------------------------

#: a ``name: text`` / ``a, b: text`` line of a docstring cleaned by ``inspect.cleandoc`` (the entries at
#: its left margin: Python >= 3.13 strips a docstring's common indentation when compiling, earlier
#: versions keep it, and cleandoc gives the same text on both)
_FIELD = re.compile(r"^\s*([a-z_][a-z0-9_]*(?:,\s*[a-z_][a-z0-9_]*)*):\s+(\S.*)$")


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
    for line in inspect.cleandoc(doc or "").splitlines():
        m = _FIELD.match(line)
        names = [n.strip() for n in m.group(1).split(",")] if m else []
        if names and all(n in fields for n in names):
            entries.append((names, [m.group(2).strip()]))
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


def config_help(width: int | None = None, family: str = DEFAULT_FAMILY) -> str:
    """The ``track --help`` epilog: every parameter, option and preset with its meaning, generated
    from the tracker ``family``'s settings (its ``FamilyConfig``: the Params / Options docstrings,
    param_ranges, option_choices, option_ranges, presets, class_defaults)."""
    fc = family_config(family)
    Params, Options = fc.Params, fc.Options
    width = width or max(60, min(120, shutil.get_terminal_size().columns) - 2)

    def meaning(text):
        return textwrap.fill(text, width, initial_indent=" " * 6, subsequent_indent=" " * 6) if text else None

    base_p, base_o = Params(), Options()
    out = [f"parameters (--set NAME=VALUE; default = the {fc.default_preset} value; ranges inclusive):"]
    for names, text in _grouped(docstring_fields(Params.__doc__, Params._fields), Params._fields):
        for name in names:
            lo, hi = fc.param_ranges[name]
            kind = "integer" if name in fc.int_params else "number"
            out.append(f"  {name:<12} default {_fmt(getattr(base_p, name)):<6} {kind} in [{_fmt(lo)}, {_fmt(hi)}]")
        out += [meaning(text)] if text else []
    out += ["", "options (--set NAME=VALUE; each value compiles its own program):"]
    for names, text in _grouped(docstring_fields(Options.__doc__, Options._fields), Options._fields):
        for name in names:
            if name in fc.option_choices:
                values = " | ".join(fc.option_choices[name])
            elif isinstance(getattr(base_o, name), bool):
                values = "true | false"
            elif name in fc.option_ranges:
                values = f"integer in [{fc.option_ranges[name][0]}, {fc.option_ranges[name][1]}]"
            else:
                values = ""
            out.append(f"  {name:<12} default {_fmt(getattr(base_o, name)):<12} {values}")
        out += [meaning(text)] if text else []
    out += ["", "presets (--preset NAME; what differs from the defaults above):"]
    for name, (p, o) in fc.presets.items():
        diff = [f"{k}={_fmt(v)}" for k, v in p._asdict().items() if v != getattr(base_p, k)]
        diff += [f"{k}={_fmt(v)}" for k, v in o._asdict().items() if v != getattr(base_o, k)]
        out.append(f"  {name:<12} {' '.join(diff) or '(the defaults)'}")
    for cls, changes in fc.class_defaults.items():
        if changes:
            out.append(meaning(f"--class {cls}: every preset with "
                               + " ".join(f"{k}={_fmt(v)}" for k, v in changes.items())).replace(" " * 6, "  ", 1))
    return "\n".join(out)


def families_help(width: int | None = None) -> str:
    """The ``track --help`` epilog: :func:`config_help` of every registered family, each under a
    heading naming it, its presets and the detections it reads."""
    width = width or max(60, min(120, shutil.get_terminal_size().columns) - 2)
    out = []
    for name in family_names():
        fc = family_config(name)
        reads = " and ".join({"2d": "2D", "3d": "3D"}[d] for d in fc.detections)
        head = (f"{fc.title} (family {name!r}; --preset {' | '.join(fc.presets)}; reads {reads} detections)")
        out += [head, "=" * min(len(head), width), config_help(width, name), ""]
    return "\n".join(out).rstrip()


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``track`` on an argparse ``subparsers`` object; returns its parser."""


    width = max(60, min(120, shutil.get_terminal_size().columns) - 2)
    t = sub.add_parser("track", help=HELP["track"],
                       description=textwrap.fill(
                           "Track a KITTI split with a preset and --set overrides and write one result file per "
                           "sequence. Exit status 3 when a lane overflowed its track memory.", width),
                       epilog=families_help(width), formatter_class=argparse.RawDescriptionHelpFormatter)
    t.add_argument("--data", help=f"KITTI tracking training root (default ${ENV_VAR} or ../shared/data/kitti/training)")
    t.add_argument("--det2d", default=None,
                   help="2D detector: name under ROOT/detections, or a directory (of SSSS.txt files, or of a folder "
                        "per class) (default rrc; a family reading 3D detections only reads none: a --det2d given "
                        "to it is named in a warning)")
    t.add_argument("--det3d", default="pointrcnn",
                   help="3D detector: name under ROOT/detections, or a directory (of SSSS.txt files, or of a folder "
                        "per class), or lidar:DIR: the 2D detections lifted to 3D from the scans "
                        "DIR/velodyne/SSSS/FFFFFF.bin (settings --set shrink=0.2, leaf, crop_lo, crop_hi, tolerance, "
                        "min_cluster, score_cut; score_3d follows score_2d)")
    fc = family_config()
    t.add_argument("--preset", default=fc.default_preset,
                   help="the settings to start from, and the tracker family they are of: " + " | ".join(all_presets())
                        + " (listed below, by family; a family reading 3D detections only reads no --det2d)")
    t.add_argument("--set", action="append", metavar="NAME=VALUE",
                   help="override a parameter or option (repeatable); CLASS.NAME=VALUE for one class only, "
                        "e.g. pedestrian.a_l=2 (checked like any setting; refused when CLASS is not in --class, "
                        "rather than ignored)")
    t.add_argument("--class", dest="cls", default="car",
                   help="car | pedestrian | car,pedestrian (each class with its own settings, one file per sequence)")
    t.add_argument("--seqs", type=seqs_arg,
                   help="comma-separated sequences (default: those whose ground truth has the class; an AB3DMOT "
                        "preset: every sequence, as AB3DMOT's own runs, so that its ids are AB3DMOT's)")
    t.add_argument("--columns", default="kitti", choices=["kitti", "kitti-stale", "authors"],
                   help="result columns: kitti (standard KITTI rows with each row's own 3D box and score; rows "
                        "without one: placeholders) | kitti-stale (as kitti, but a row without its own 3D box "
                        "carries its track's last one, as the authors' files) | authors (the authors' C++ 18 "
                        "columns, byte for byte)")
    t.add_argument("--out", required=True, help="output directory: new or empty (see --overwrite)")
    t.add_argument("--overwrite", action="store_true",
                   help="write into a non-empty --out: its old result files (SSSS.txt) are removed first, other "
                        "files are kept")
    t.set_defaults(func=run_later("dfrmot_jax.cli.track"))
    return t
