import numpy as np
import pytest

from lost.host.grid import Grid


def test_node_coordinates_round_trip():
    grid = Grid(np.zeros((3, 4)), x0_m=500.0, y0_m=1000.0, node_m=10.0)
    x, y = grid.xy(2, 3)
    assert (x, y) == (530.0, 1020.0)
    assert grid.row_col(x, y) == (2.0, 3.0)
    assert grid.contains(530.0, 1020.0) and not grid.contains(531.0, 1020.0)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(depth_m=np.zeros(3), x0_m=0, y0_m=0, node_m=1), "2-D"),
        (dict(depth_m=np.zeros((2, 2)), x0_m=0, y0_m=0, node_m=0), "node_m"),
        (dict(depth_m=np.zeros((2, 2)), x0_m=np.nan, y0_m=0, node_m=1), "origin"),
    ],
)
def test_bad_grid_is_named(kwargs, message):
    with pytest.raises(ValueError, match=message):
        Grid(**kwargs)
