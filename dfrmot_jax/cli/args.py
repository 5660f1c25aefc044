"""Argument types and option groups shared by the commands' parsers (light: nothing heavy is imported, so
that ``--help`` stays fast; the names a user picks are :mod:`dfrmot_jax.choices`')."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..choices import (AB3DMOT_RESAMPLES, BACKENDS, DEFAULT_AB3DMOT_IOU, DEFAULT_SUM, parse_classes, parse_iou,
                       parse_metric_families)

__all__ = ["parse_seqs", "seqs_arg", "output_file", "seed_arg", "classes_arg", "families_arg", "iou_arg",
           "add_backend_arguments", "ab3dmot_settings", "check_output_files"]


def parse_seqs(text: str | None) -> list[str] | None:
    """``--seqs 1,0002`` -> ["0001", "0002"] (KITTI names are zero-padded to 4 digits); None when not
    given. A sequence listed twice (``1,0001`` too) is a ValueError naming it and the flag: scored
    twice it would count twice in every combined figure; so is a text naming none (``,``, ``''``),
    which would otherwise read as data without the class."""
    if text is None:
        return None
    seqs = [s.strip().zfill(4) for s in text.split(",") if s.strip()]
    if not seqs:
        raise ValueError(f"--seqs {text}: names no sequence (expected e.g. 0000,0002)")
    twice = next((s for i, s in enumerate(seqs) if s in seqs[:i]), None)
    if twice is not None:
        raise ValueError(f"--seqs {text}: sequence {twice} is listed twice")
    return seqs


def seqs_arg(text: str) -> str:
    """The argparse type of every ``--seqs``: ``text`` as given, once :func:`parse_seqs` accepts it
    (refused at parse time, before a command writes anything)."""
    try:
        parse_seqs(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e).removeprefix(f"--seqs {text}: ")) from None
    return text


def output_file(text: str) -> str:
    """An output file name (``--html``, ``--csv``, ``--recall-table``): refused when empty (argparse:
    exit 2), since an empty name would otherwise write nothing and say nothing."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"{text!r}: expected a file name")
    return text


def seed_arg(text: str) -> int:
    """A ``--seed``: a whole number >= 0 (argparse names the flag in its refusal: a negative seed
    otherwise failed deep in NumPy with a message naming nothing)."""
    try:
        seed = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a whole number >= 0") from None
    if seed < 0:
        raise argparse.ArgumentTypeError(f"{seed}: expected a whole number >= 0")
    return seed


def classes_arg(text: str) -> tuple:
    """A ``--class`` of ``eval`` / ``compare``: the classes :func:`~dfrmot_jax.choices.parse_classes` reads."""
    try:
        return parse_classes(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def families_arg(text: str) -> tuple:
    """A ``--metrics``: the families :func:`~dfrmot_jax.choices.parse_metric_families` reads."""
    try:
        return parse_metric_families(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def iou_arg(text: str) -> str:
    """An ``--ab3dmot-iou``: ``KIND:T`` as :func:`~dfrmot_jax.choices.parse_iou` reads it, written back
    in one form (``3D:0.250`` -> ``3d:0.25``)."""
    try:
        kind, thr = parse_iou(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None
    return f"{kind}:{thr:g}"


def add_backend_arguments(p) -> None:
    """The ``--workers`` / ``--backend`` / ``--address`` / ``--worker-cpus`` options of ``sweep`` and
    ``tune`` (the backend they name: :func:`dfrmot_jax.cli.backend.backend_from`, when the command runs)."""
    p.add_argument("--workers", type=int, help="local backend: metric processes beside the tracker (default: 2 for "
                                               "large sweeps, 0: in-process)")
    p.add_argument("--backend", choices=BACKENDS, default="local",
                   help="where chunks run: this process (default) or a Ray cluster (pip install \"dfrmot_jax[ray]\")")
    p.add_argument("--address", metavar="ADDR",
                   help="Ray cluster address (HOST:PORT of 'ray start --head', 'auto', ray://HOST:10001); "
                        "default: a local Ray instance")
    p.add_argument("--worker-cpus", type=int, metavar="N",
                   help="Ray: one worker per N CPUs of a node (default: one worker per node, all its CPUs)")


#: the options of ``eval`` / ``compare`` that only AB3DMOT's metric family reads, and their defaults
AB3DMOT_OPTIONS = {"ab3dmot_iou": DEFAULT_AB3DMOT_IOU, "ab3dmot_sum": DEFAULT_SUM, "ab3dmot_resamples": AB3DMOT_RESAMPLES}


def ab3dmot_settings(args) -> None:
    """Refuse (ValueError naming the flag) ``--ab3dmot-iou`` / ``--ab3dmot-sum`` / ``--ab3dmot-resamples``
    given without AB3DMOT's figures (``--metrics ab3dmot`` or ``--recall-table``): they would change
    nothing; then fill in the defaults of those not given (their parsers' default is None, so that a
    given one is told apart)."""
    wanted = "ab3dmot" in getattr(args, "metrics", ()) or getattr(args, "recall_table", None)
    for name, default in AB3DMOT_OPTIONS.items():
        if not hasattr(args, name):
            continue
        if getattr(args, name) is not None and not wanted:
            flag = "--" + name.replace("_", "-")
            raise ValueError(f"{flag} {getattr(args, name)}: AB3DMOT's figures are not computed (--metrics "
                             f"{','.join(getattr(args, 'metrics', ('kitti2d',)))}), so it would change nothing: add "
                             f"--metrics kitti2d,ab3dmot, or drop {flag}")
        if getattr(args, name) is None:
            setattr(args, name, default)


def check_output_files(outputs, inputs=(), input_dirs=()) -> None:
    """Refuse (ValueError naming both) before anything runs: two outputs naming one file (the second
    would replace the first: ``--csv F --recall-table F``), or an output naming an input (a file of
    ``inputs``, or a result file ``SSSS.txt`` / any ``*.txt`` of a folder of ``input_dirs``, which
    would be replaced after being scored). ``outputs``: (flag, path or None) pairs; ``inputs``:
    (what, path or None); ``input_dirs``: (what, folder)."""
    given = [(flag, Path(p)) for flag, p in outputs if p]
    seen: dict[Path, str] = {}
    for flag, path in given:
        r = path.resolve()
        if r in seen:
            raise ValueError(f"{seen[r]} and {flag} name one file ({path}): the second would replace the first; "
                             f"give each its own")
        seen[r] = f"{flag} {path}"
    for flag, path in given:
        r = path.resolve()
        for what, p in inputs:
            if p and Path(p).resolve() == r:
                raise ValueError(f"{flag} {path} is an input ({what}): it would be overwritten; write elsewhere")
        for what, d in input_dirs:
            if d and Path(d).is_dir() and r.parent == Path(d).resolve() and r.suffix == ".txt":
                raise ValueError(f"{flag} {path} is a file of the result folder {d} ({what}), whose *.txt files are "
                                 f"read as results: it would overwrite or join them; write elsewhere")
