"""lost grid's binning against an independent NumPy/pandas binning of the same soundings, and its NetCDF read back."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from lost.host.io import read_grid
from lost.host.io.survey import open_survey
from lost.host.io.survey_grid import grid_survey, write_survey_grid

REAL = Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "real_survey"
needs_real = pytest.mark.skipif(not REAL.is_dir(), reason=f"the real survey files are not at {REAL} (shared/data/real_survey beside the repository)")

GSF = sorted(REAL.glob("noaa_okeanos_ex1604_gsf/*.gsf"))
EM710 = sorted(REAL.glob("ausseabed_investigator_em710_all/*.all"))


def _soundings(paths):
    e, n, d = [], [], []
    for ping in open_survey(paths):
        e.append(ping.beam_east_m[ping.valid])
        n.append(ping.beam_north_m[ping.valid])
        d.append(ping.depth_m[ping.valid])
    return np.concatenate(e), np.concatenate(n), np.concatenate(d)


@needs_real
@pytest.mark.parametrize(("files", "node_m", "holes"), [(GSF, 100.0, True), (EM710, 1.0, False)])  # EM710: moored, one swath over and over
def test_the_grid_is_the_mean_count_and_std_of_an_independent_binning(files, node_m, holes):
    result = grid_survey(files, node_m=node_m)
    g = result.grid
    e, n, d = _soundings(files)
    table = pd.DataFrame({"col": np.rint((e - g.x0_m) / node_m).astype(int), "row": np.rint((n - g.y0_m) / node_m).astype(int), "d": d})
    per_node = table.groupby(["row", "col"])["d"].agg(["mean", "count", "std"])
    rows, cols = per_node.index.get_level_values(0), per_node.index.get_level_values(1)
    assert result.count.sum() == d.size and (result.count[rows, cols] == per_node["count"]).all()
    np.testing.assert_allclose(g.depth_m[rows, cols], per_node["mean"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(result.std_m[rows, cols], per_node["std"], rtol=0, atol=1e-6, equal_nan=True)
    empty = result.count == 0
    assert empty.any() == holes and np.isnan(g.depth_m[empty]).all() and np.isnan(result.std_m[empty]).all()  # holes stay holes
    assert g.x0_m % node_m == 0 and g.y0_m % node_m == 0


@needs_real
def test_the_netcdf_reads_back_node_for_node_through_read_grid_and_xarray(tmp_path):
    result = grid_survey(GSF, node_m=100.0)
    path = write_survey_grid(result, tmp_path / "ex1604.nc")
    back = read_grid(path)
    np.testing.assert_array_equal(back.depth_m, result.grid.depth_m)
    assert (back.x0_m, back.y0_m, back.node_m) == (result.grid.x0_m, result.grid.y0_m, result.grid.node_m)
    assert back.crs == result.grid.crs
    with xr.open_dataset(path) as ds:
        np.testing.assert_array_equal(ds["depth"].values, result.grid.depth_m)
        np.testing.assert_array_equal(ds["depth_std"].values, result.std_m)
        np.testing.assert_array_equal(ds["count"].values, result.count)
        assert ds["depth"].attrs["positive"] == "down" and list(ds.data_vars)[0] == "depth"
    assert not list(tmp_path.glob("*.partial"))


def test_a_node_spacing_that_is_no_length_is_refused():
    with pytest.raises(ValueError, match="node_m must be a positive number"):
        grid_survey([], node_m=0.0)
