"""Fixed-capacity track memory: N slots with an ``alive`` mask, births into free slots, ageing.

Births go to free slots in row order by matching cumulative-sum ranks (no scatter). When more
objects are born than there are free slots, the surplus is *not* stored: it is counted in
``overflow`` (per lane, cumulative) and in the frame's ``dropped`` output, so that a too-small
capacity is always reported, never silent.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp

from .filters import FilterState

#: coordinates per track: 2D top-left (x, y), bottom-right (x, y); 3D min corner (3), max corner (3)
N_COORDS = 10


class Memory(NamedTuple):
    """Track memory of one lane.

    alive [N] bool; tid [N] int32 track id; age [N] int32 frames since the last match;
    hits [N] int32 matches including the birth; has3d [N] bool (3D filter started);
    filt: FilterState with p, v, a [N, 10] float64 (cov [6, N, 10] for the Kalman filter, [0, N, 10] else);
    next_id [] int32; overflow [] int32 births dropped for want of a slot (cumulative);
    peak [] int32 largest number of live tracks seen (capacity headroom);
    cov0 [6, 10] float64 Kalman covariance of a new track's coordinates with the "steady" start (else unused);
    last3 [N] int32 the last 3D detection a track took (global index ``t * M3 + slot``, -1 none),
    kept only when the step runs with ``detail``.
    """

    alive: jnp.ndarray
    tid: jnp.ndarray
    age: jnp.ndarray
    hits: jnp.ndarray
    has3d: jnp.ndarray
    filt: FilterState
    next_id: jnp.ndarray
    overflow: jnp.ndarray
    peak: jnp.ndarray
    cov0: jnp.ndarray
    last3: jnp.ndarray


def empty(capacity: int, kalman: bool) -> Memory:
    n = capacity
    zeros = jnp.zeros((n, N_COORDS), jnp.float64)
    cov = jnp.zeros((6 if kalman else 0, n, N_COORDS), jnp.float64)
    return Memory(
        alive=jnp.zeros(n, bool), tid=jnp.zeros(n, jnp.int32), age=jnp.zeros(n, jnp.int32),
        hits=jnp.zeros(n, jnp.int32), has3d=jnp.zeros(n, bool), filt=FilterState(zeros, zeros, zeros, cov),
        next_id=jnp.int32(0), overflow=jnp.int32(0), peak=jnp.int32(0), cov0=jnp.zeros((6, N_COORDS), jnp.float64),
        last3=jnp.full(n, -1, jnp.int32),
    )


def reset(mem: Memory, flag) -> Memory:
    """At a sequence's first frame: no live tracks, ids restart at 0 (overflow and peak are kept)."""
    return mem._replace(alive=mem.alive & ~flag, next_id=jnp.where(flag, 0, mem.next_id))


def births(alive, newborn):
    """Assign newborn objects [O] bool to free slots of ``alive`` [N], in row order.

    Returns (birth [O, N] bool, rank [O] int32 order of each newborn among this frame's births,
    dropped [] int32 newborns that found no free slot).
    """
    rank = jnp.cumsum(newborn.astype(jnp.int32)) - 1
    free = ~alive
    free_rank = jnp.cumsum(free.astype(jnp.int32)) - 1
    birth = newborn[:, None] & free[None, :] & (rank[:, None] == free_rank[None, :])
    dropped = jnp.maximum(jnp.sum(newborn, dtype=jnp.int32) - jnp.sum(free, dtype=jnp.int32), 0)
    return birth, rank, dropped


def gather_rows(assign, values):
    """values [O, ...] taken into the slots that ``assign`` [O, N] (one-hot columns) names -> [N, ...];
    slots with no row get zeros (False)."""
    rows = jnp.arange(assign.shape[0], dtype=jnp.int32)[:, None]
    idx = jnp.sum(jnp.where(assign, rows, 0), axis=0, dtype=jnp.int32)
    taken = jnp.take(values, idx, axis=0, mode="clip")
    has = jnp.any(assign, axis=0).reshape((-1,) + (1,) * (values.ndim - 1))
    return taken & has if values.dtype == jnp.bool_ else jnp.where(has, taken, 0)


def end_of_frame(mem: Memory, epsilon) -> Memory:
    """Forget tracks unmatched for more than epsilon frames; age the others by one."""
    alive = mem.alive & (mem.age <= epsilon)
    return mem._replace(alive=alive, age=mem.age + 1)
