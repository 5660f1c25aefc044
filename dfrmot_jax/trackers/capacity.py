"""The one capacity policy of every tracker family (jax-md's neighbour lists: allocate from the data,
update where it overflows): a lane's track slots are chosen from the data, a lane that overflows
runs again with twice as many, up to :data:`MAX_CAPACITY`; what still overflows there is counted and
reported, never dropped silently. A family supplies only what differs: how many slots an object of
the fullest frame needs (``per_object``). NumPy only.
"""

from __future__ import annotations

import numpy as np

__all__ = ["MAX_CAPACITY", "MIN_CAPACITY", "from_data", "grown"]

#: the most track slots a lane grows to (``Options.capacity`` of every family is at most this)
MAX_CAPACITY = 4096
#: the fewest track slots a lane is given from the data
MIN_CAPACITY = 16


def from_data(most: int, per_object: float, extra: int = 0) -> int:
    """Track slots for a lane whose fullest frame holds ``most`` objects: ``per_object`` slots each,
    rounded up to a multiple of 8, at least :data:`MIN_CAPACITY`, at most :data:`MAX_CAPACITY`;
    ``extra`` slots more (room for a distortion's clutter births, a multiple of 8 by the caller)."""
    cap = max(MIN_CAPACITY, int(np.ceil(per_object * int(most) / 8.0)) * 8)
    return min(MAX_CAPACITY, cap + int(extra))


def grown(capacity: int) -> int | None:
    """The capacity a lane that overflowed with ``capacity`` slots runs again with (twice as many, at
    most :data:`MAX_CAPACITY`), or None when it had the most already."""
    return None if capacity >= MAX_CAPACITY else min(2 * int(capacity), MAX_CAPACITY)
