import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dfrmot_jax.trackers.dfr import memory


@pytest.fixture(autouse=True)
def _x64():
    with jax.enable_x64(True):
        yield


def test_births_fill_free_slots_in_row_order_and_count_overflow():
    alive = jnp.array([True, False, True, False])
    newborn = jnp.array([False, True, True, False, True])
    birth, rank, dropped = memory.births(alive, newborn)
    b = np.asarray(birth)
    assert b.sum() == 2 and int(dropped) == 1
    assert b[1, 1] and b[2, 3]  # first newborn -> first free slot, second -> second
    np.testing.assert_array_equal(np.asarray(rank)[[1, 2, 4]], [0, 1, 2])


def test_gather_rows_moves_values_into_slots():
    assign = jnp.array([[False, True], [True, False]])
    vals = jnp.array([[1.0, 2.0], [3.0, 4.0]])
    np.testing.assert_array_equal(memory.gather_rows(assign, vals), [[3, 4], [1, 2]])
    np.testing.assert_array_equal(memory.gather_rows(assign, jnp.array([True, False])), [False, True])


def test_end_of_frame_deletes_after_epsilon_and_ages():
    mem = memory.empty(3, False)._replace(alive=jnp.array([True, True, False]), age=jnp.array([30, 31, 0]))
    out = memory.end_of_frame(mem, 30)
    np.testing.assert_array_equal(out.alive, [True, False, False])
    np.testing.assert_array_equal(out.age, [31, 32, 1])


def test_reset_clears_tracks_and_ids():
    mem = memory.empty(2, True)._replace(alive=jnp.array([True, True]), next_id=jnp.int32(7))
    out = memory.reset(mem, jnp.bool_(True))
    assert not np.any(out.alive) and int(out.next_id) == 0 and out.filt.cov.shape == (6, 2, memory.N_COORDS)
