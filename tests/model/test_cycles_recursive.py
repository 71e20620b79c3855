"""The recursive core's cycle model and the shared reducer timing, on their own (the HDL tests check them
against the simulated core)."""

import numpy as np
import pytest

from lost.model.cycles import reducer_geometry, reducer_latency, surface_beats
from lost.model.cycles_recursive import requests_per_placement, schedule


def test_full_size_figures():
    # 501 x 501 map, 10 x 10 patch, all nodes valid: 492 x 492 placements of 100 clocks in either mode.
    mean = schedule((501, 501), (10, 10))
    plain = schedule((501, 501), (10, 10), mean_compensation=False)
    assert mean.surface.shape == (492 * 492,)
    assert mean.surface[0] == 2 * 100 + 11 + 2 * 100
    assert plain.surface[-1] == 2 * 100 + 11 + (492 * 492 + 1) * 100
    np.testing.assert_array_equal(mean.surface, plain.surface)
    assert mean.best == mean.surface[-1] + 492 + 4 * 492 + 8
    assert mean.total == mean.best


def test_beats_are_one_placement_apart():
    mask = np.array([[True, False, True], [False, True, True]])
    result = schedule((6, 8), (2, 3), mask, True)
    assert set(np.diff(result.surface).tolist()) == {4}
    assert result.surface[0] == 2 * 6 + 11 + 2 * 4
    assert requests_per_placement(mask, False) == requests_per_placement(mask, True) == 4


def test_reducer_geometry_and_latency():
    assert reducer_geometry((10, 10), 4, 1) == (4, 3)
    assert reducer_geometry((3, 10), 1, 2) == (3, 10)  # no more slots than rows
    assert reducer_latency((10, 10), 4, 1) == 10 + 4 * 3 + 2 * 2 + 8  # 2 tree levels for 4 lanes
    assert reducer_latency((10, 10), 5, 1) == 10 + 4 * 2 + 2 * 3 + 8
    assert surface_beats((2, 5), 2) == [(0, 0, 2), (0, 2, 2), (0, 4, 1), (1, 0, 2), (1, 2, 2), (1, 4, 1)]


@pytest.mark.parametrize(("kwargs", "message"), [
    (dict(map_shape=(4, 4), patch_shape=(5, 1)), "larger"),
    (dict(map_shape=(4, 4), patch_shape=(2, 2), mask=np.ones((3, 3), bool)), "shape"),
    (dict(map_shape=(4, 4), patch_shape=(2, 2), mask=np.zeros((2, 2), bool)), "no valid node"),
])
def test_refuses_bad_input(kwargs, message):
    with pytest.raises(ValueError, match=message):
        schedule(**kwargs)


def test_shared_functions_refuse_bad_input():
    with pytest.raises(ValueError, match="lanes"):
        reducer_geometry((4, 4), 0, 1)
    with pytest.raises(ValueError, match="exclusion_radius"):
        reducer_latency((4, 4), 1, -1)
    with pytest.raises(ValueError, match="surface_shape"):
        surface_beats((0, 4), 1)
