"""A grid's uncertainty layer read into Grid.sigma_m: lost grid's depth_std, CF-named layers, a BAG's uncertainty, resampled."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from lost.host.grid import Grid
from lost.host.io import read_grid
from lost.host.io.survey_grid import grid_survey, write_survey_grid
from lost.host.io.uncertainty import fill_sigma_gaps

REAL = Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "real_survey"
EM122 = REAL / "ga4430_em122_all" / "0243_P007_MBES_EM122_20150207_044356_Supporter_GA4430.all"
needs_real = pytest.mark.skipif(not EM122.is_file(), reason=f"the real survey files are not at {REAL} (shared/data/real_survey beside the repository)")


@needs_real
def test_lost_grids_depth_std_is_the_grids_sigma_node_for_node(tmp_path):
    result = grid_survey([EM122], node_m=50.0)
    grid = read_grid(write_survey_grid(result, tmp_path / "em122.nc"))
    assert grid.sigma_m is not None
    np.testing.assert_array_equal(grid.sigma_m, result.std_m)  # NaN where the count is 0 or 1, equal elsewhere
    one = result.count == 1
    assert one.any() and np.all(np.isnan(grid.sigma_m[one])) and np.all(np.isfinite(grid.depth_m[one]))
    assert np.all(np.isfinite(grid.sigma_m[result.count > 1]))


def _cf_grid(path, sigma, name="spread", attrs=None, depth_attrs=None):
    depth = 100.0 + np.arange(12.0).reshape(3, 4)
    ds = xr.Dataset({"depth": (("y", "x"), depth, {"positive": "down", **(depth_attrs or {})}),
                     name: (("y", "x"), sigma, {"units": "m", **(attrs or {})})},
                    coords={"x": ("x", 500_000.0 + 10.0 * np.arange(4)), "y": ("y", 5_700_000.0 + 10.0 * np.arange(3))})
    ds.to_netcdf(path)
    return path


@pytest.mark.parametrize(("name", "attrs", "depth_attrs"), [
    ("spread", {"standard_name": "sea_floor_depth_below_sea_surface standard_error"}, None),
    ("spread", {"long_name": "Standard deviation of the soundings"}, None),
    ("u", {"long_name": "total vertical uncertainty"}, None),
    ("q", {"long_name": "a 1-sigma"}, {"ancillary_variables": "q"}),  # named by the depth, but saying nothing of a spread
    ("Uncertainty", {}, None),
])
def test_a_layer_is_recognised_by_cf_standard_name_long_name_or_name(tmp_path, name, attrs, depth_attrs):
    sigma = 0.1 + np.arange(12.0).reshape(3, 4) / 100
    grid = read_grid(_cf_grid(tmp_path / "g.nc", sigma, name, attrs, depth_attrs), source_crs="EPSG:32631")
    if name == "q":  # an ancillary variable that does not say it is a standard deviation is not read as one
        assert grid.sigma_m is None
        return
    np.testing.assert_allclose(grid.sigma_m, sigma)


def test_a_grid_without_a_layer_has_no_sigma(tmp_path):
    path = tmp_path / "g.nc"
    xr.Dataset({"depth": (("y", "x"), np.full((3, 4), 50.0), {"positive": "down"})},
               coords={"x": ("x", np.arange(4.0) * 10), "y": ("y", np.arange(3.0) * 10)}).to_netcdf(path)
    assert read_grid(path, source_crs="EPSG:32631").sigma_m is None


def test_holes_of_the_depth_are_holes_of_the_sigma_and_resampling_keeps_them(tmp_path):
    sigma = np.full((3, 4), 0.5)
    path = tmp_path / "g.nc"
    depth = 100.0 + np.arange(12.0).reshape(3, 4)
    depth[1, 1] = np.nan
    xr.Dataset({"depth": (("y", "x"), depth, {"positive": "down"}), "depth_std": (("y", "x"), sigma, {"units": "m"})},
               coords={"x": ("x", 10.0 * np.arange(4)), "y": ("y", 10.0 * np.arange(3))}).to_netcdf(path)
    grid = read_grid(path, source_crs="EPSG:32631")
    assert np.isnan(grid.sigma_m[1, 1]) and np.isfinite(grid.sigma_m).sum() == 11
    fine = read_grid(path, source_crs="EPSG:32631", node_m=5.0)
    assert fine.sigma_m.shape == fine.depth_m.shape
    np.testing.assert_array_equal(np.isnan(fine.sigma_m), np.isnan(fine.depth_m))
    np.testing.assert_allclose(fine.sigma_m[np.isfinite(fine.sigma_m)], 0.5)


def test_gaps_of_the_layer_on_depth_nodes_take_survey_sigma_and_are_counted():
    depth = np.array([[10.0, 11.0], [np.nan, 12.0]])
    grid = Grid(depth, 0.0, 0.0, 1.0, None, np.array([[0.2, np.nan], [np.nan, 0.4]]))
    filled, report = fill_sigma_gaps(grid, 0.5)
    np.testing.assert_array_equal(filled.sigma_m, [[0.2, 0.5], [np.nan, 0.4]])
    assert (report["nodes_from_layer"], report["nodes_from_survey_sigma_m"]) == (2, 1)
    bare, report = fill_sigma_gaps(Grid(depth, 0.0, 0.0, 1.0), 0.5)
    assert bare.sigma_m is None and report["nodes_from_survey_sigma_m"] == 3
