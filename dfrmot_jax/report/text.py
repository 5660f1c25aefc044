"""Plain-text layout of reports: prose and tables wrapped to :data:`WIDTH` columns."""

from __future__ import annotations

import textwrap

import pandas as pd

WIDTH = 120


def paragraph(text: str) -> str:
    """A line of prose wrapped to WIDTH (continuation lines indented two spaces)."""
    return textwrap.fill(text, WIDTH, subsequent_indent="  ", break_long_words=False, break_on_hyphens=False)


def text_table(df: pd.DataFrame, keys=(), text=(), **fmt) -> str:
    """``df.to_string(index=False)`` in at most WIDTH columns: when wider, the columns are split into
    blocks that each repeat the ``keys`` columns, and the free-text columns ``text`` are moved under
    the table as one wrapped line per row."""
    def render(cols):
        return "\n".join(s.rstrip() for s in df[list(cols)].to_string(index=False, **fmt).splitlines())

    whole = render(df.columns)
    if max(map(len, whole.splitlines())) <= WIDTH:
        return whole
    blocks, cur = [], []
    for c in (c for c in df.columns if c not in keys and c not in text):
        if cur and max(map(len, render([*keys, *cur, c]).splitlines())) > WIDTH:
            blocks.append(cur)
            cur = []
        cur.append(c)
    out = [render([*keys, *b]) for b in blocks + [cur]]
    if text:
        rows = df.to_dict("records")
        out.append("\n".join(paragraph(", ".join(f"{k} {r[k]}" for k in keys) + ": "
                                    + "; ".join(f"{c.replace('_', ' ')} {r[c]}" for c in text)) for r in rows))
    return "\n\n".join(out)
