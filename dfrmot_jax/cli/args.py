"""Argument types shared by the commands' parsers (light: no heavy import, so that ``--help`` stays fast)."""

from __future__ import annotations

import argparse

__all__ = ["output_file"]


def output_file(text: str) -> str:
    """An output file name (``--html``, ``--csv``, ``--recall-table``): refused when empty (argparse:
    exit 2), since an empty name would otherwise write nothing and say nothing."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"{text!r}: expected a file name")
    return text
