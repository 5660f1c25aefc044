import numpy as np
import pytest

from dfrmot_jax.trackers.dfr.config import (INT_PARAMS, PARAM_RANGES, Options, Params, as_arrays, batch_size, parse_assignment, preset, stack_params, unstack_params, validate_params)


def test_presets_hold_the_published_and_head_settings():
    p, o = preset("dfr2023")
    assert (p.a_l, o.centroid, p.score_2d, p.score_3d, p.epsilon, p.merge_iou, p.alpha_c) == (8.0, "legacy", 0.45, 4.0, 30, 0.25, 0.5)
    p, o = preset("dfr_head")
    assert (p.a_l, o.centroid) == (10.0, "head")
    with pytest.raises(ValueError, match="unknown preset"):
        preset("nope")


def test_every_param_has_a_range_and_int_params_are_ints():
    assert set(PARAM_RANGES) == set(Params._fields)
    arr = as_arrays(Params())
    for k in Params._fields:
        assert arr._asdict()[k].dtype == (np.int32 if k in INT_PARAMS else np.float64)


def test_validation_names_the_field():
    with pytest.raises(ValueError, match="merge_iou"):
        validate_params(Params(merge_iou=1.5))
    with pytest.raises(ValueError, match="epsilon"):
        validate_params(Params(epsilon=2.5))
    with pytest.raises(ValueError, match="a_l"):
        validate_params(Params(a_l=float("nan")))
    with pytest.raises(ValueError, match="filter"):
        Options(filter="ukf").validate()
    with pytest.raises(ValueError, match="capacity"):
        Options(capacity=-1).validate()


def test_parse_assignment_sets_params_and_options():
    p, o = parse_assignment("a_l=6", Params(), Options())
    assert p.a_l == 6.0
    p, o = parse_assignment("filter=kalman", p, o)
    assert o.filter == "kalman"
    p, o = parse_assignment("truncate=false", p, o)
    assert o.truncate is False
    for bad, match in [("a_l", "name=value"), ("zzz=1", "unknown"), ("a_l=x", "not a number"), ("epsilon=-1", "epsilon")]:
        with pytest.raises(ValueError, match=match):
            parse_assignment(bad, Params(), Options())


def test_stack_and_unstack_round_trip():
    settings = [Params(a_l=float(i), epsilon=i) for i in range(1, 5)]
    stacked = stack_params(settings)
    assert batch_size(stacked) == 4 and stacked.epsilon.dtype == np.int32
    back = unstack_params(stacked)
    assert [b.a_l for b in back] == [1.0, 2.0, 3.0, 4.0] and [b.epsilon for b in back] == [1, 2, 3, 4]
