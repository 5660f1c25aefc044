"""Argument types shared by the commands' parsers (light: no heavy import, so that ``--help`` stays fast)."""

from __future__ import annotations

import argparse

__all__ = ["output_file", "seed_arg"]


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
