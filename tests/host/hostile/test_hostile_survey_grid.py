"""A grid's uncertainty layer that is no standard deviation: another shape, negative, infinite, not metres; named errors."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from lost.host.io import read_grid
from lost.host.io.errors import UncertaintyLayerError


def _grid(path, sigma, dims=("y", "x"), units="m", extra_coords=None):
    depth = 100.0 + np.arange(12.0).reshape(3, 4)
    coords = {"x": ("x", 10.0 * np.arange(4)), "y": ("y", 10.0 * np.arange(3)), **(extra_coords or {})}
    xr.Dataset({"depth": (("y", "x"), depth, {"positive": "down"}), "depth_std": (dims, sigma, {"units": units})}, coords=coords).to_netcdf(path)
    return path


def test_a_layer_of_another_shape_is_refused_naming_both(tmp_path):
    path = _grid(tmp_path / "g.nc", np.full((3, 5), 0.5), dims=("y", "x2"), extra_coords={"x2": ("x2", np.arange(5.0))})
    with pytest.raises(UncertaintyLayerError, match=r"'depth_std' has dimensions \('y', 'x2'\) \(3 x 5 nodes\) but the depth 'depth' \('y', 'x'\) \(3 x 4\)"):
        read_grid(path, source_crs="EPSG:32631")


def test_a_negative_standard_deviation_is_refused_with_its_node(tmp_path):
    sigma = np.full((3, 4), 0.5)
    sigma[2, 1] = -0.3
    with pytest.raises(UncertaintyLayerError, match=r"1 negative standard deviation\(s\) \(first -0.3 m at row 2, column 1"):
        read_grid(_grid(tmp_path / "g.nc", sigma), source_crs="EPSG:32631")


def test_an_infinite_standard_deviation_is_refused(tmp_path):
    sigma = np.full((3, 4), 0.5)
    sigma[0, 0] = np.inf
    with pytest.raises(UncertaintyLayerError, match="1 infinite value"):
        read_grid(_grid(tmp_path / "g.nc", sigma), source_crs="EPSG:32631")


def test_a_layer_in_centimetres_is_refused_not_read_as_metres(tmp_path):
    with pytest.raises(UncertaintyLayerError, match="'depth_std' is in 'cm'; LOST reads it in metres"):
        read_grid(_grid(tmp_path / "g.nc", np.full((3, 4), 50.0), units="cm"), source_crs="EPSG:32631")
