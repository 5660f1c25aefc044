"""A recompile guard: a block of tracking calls that must reuse the compiled programs."""

from __future__ import annotations

from contextlib import contextmanager

from ..trackers.dfr.run import compilations


@contextmanager
def no_recompile():
    """Raise AssertionError if the tracking calls inside the block compile anything new (a new
    static setting, or new shapes or dtypes reaching a compiled program)."""
    before = compilations()
    yield
    after = compilations()
    if after != before:
        raise AssertionError(f"recompiled: {after - before} new compilation(s) of the batch program")
