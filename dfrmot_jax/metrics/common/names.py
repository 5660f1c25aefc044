"""Names picked from a list: the classes, metric families, ... a user names, as one rule."""

from __future__ import annotations

__all__ = ["name_list"]


def name_list(text, allowed, unknown, empty: str) -> tuple:
    """``'a,b'`` or a list -> the names, stripped and lower case, in the given order, duplicates
    dropped. ValueError(``unknown(name)``) for a name not in ``allowed``, ValueError(``empty``) for none."""
    out = []
    for name in (text.split(",") if isinstance(text, str) else list(text)):
        name = str(name).strip().lower()
        if not name:
            continue
        if name not in allowed:
            raise ValueError(unknown(name))
        if name not in out:
            out.append(name)
    if not out:
        raise ValueError(empty)
    return tuple(out)
