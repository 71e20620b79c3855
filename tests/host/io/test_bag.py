"""BAG grids written by GDAL's BAG driver (an independent writer) read back: depth, uncertainty, holes, orientation."""

from __future__ import annotations

import numpy as np
import pytest

from lost.host.io import read_grid
from lost.host.io.bag import read_bag


def write_bag(path, elevation_north_first, uncertainty_north_first, *, west=500_000.0, north=5_700_030.0, node=10.0, crs="EPSG:32631"):
    import rasterio
    from affine import Affine

    rows, cols = elevation_north_first.shape
    with rasterio.open(path, "w", driver="BAG", width=cols, height=rows, count=2, dtype="float32", crs=crs,
                       transform=Affine(node, 0.0, west, 0.0, -node, north), nodata=1e6) as dst:
        dst.write(elevation_north_first.astype(np.float32), 1)
        dst.write(uncertainty_north_first.astype(np.float32), 2)
    return path


@pytest.fixture
def bag(tmp_path):
    elevation = -(100.0 + np.arange(12.0).reshape(3, 4))  # north row first: -100 .. -103 is the northern edge
    uncertainty = 0.25 + np.arange(12.0).reshape(3, 4) / 100
    elevation[1, 2] = uncertainty[1, 2] = 1e6  # a hole
    return write_bag(tmp_path / "survey.bag", elevation, uncertainty)


def test_depth_and_uncertainty_read_node_for_node_south_row_first(bag):
    result = read_bag(bag)
    g = result.grid
    assert g.shape == (3, 4) and g.node_m == 10.0 and g.crs == "EPSG:32631"
    assert (g.x0_m, g.y0_m) == (500_005.0, 5_700_005.0)  # the south-west node's centre
    np.testing.assert_array_equal(g.depth_m[2], [100.0, 101.0, 102.0, 103.0])  # the northern row is the last
    np.testing.assert_allclose(result.uncertainty_m[0], [0.33, 0.34, 0.35, 0.36], rtol=1e-6)
    assert np.isnan(g.depth_m[1, 2]) and np.isnan(result.uncertainty_m[1, 2])
    assert np.isfinite(g.depth_m).sum() == 11 and np.isfinite(result.uncertainty_m).sum() == 11


def test_read_grid_reads_a_bags_depth_like_read_bag(bag):
    g = read_grid(bag)
    np.testing.assert_array_equal(g.depth_m, read_bag(bag).grid.depth_m)
    assert (g.x0_m, g.y0_m, g.node_m) == (500_005.0, 5_700_005.0, 10.0)


def test_a_bags_uncertainty_is_read_grids_sigma(tmp_path):
    elevation = -(100.0 + np.arange(12.0).reshape(3, 4))
    uncertainty = 0.25 + np.arange(12.0).reshape(3, 4) / 100
    elevation[1, 2] = uncertainty[1, 2] = 1e6
    path = write_bag(tmp_path / "s.bag", elevation, uncertainty)
    grid = read_grid(path)
    np.testing.assert_array_equal(grid.sigma_m, read_bag(path).uncertainty_m)
