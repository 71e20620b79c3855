"""What the input checks cost: a header read against the file size, on a 64 MB grid (4000 x 4000 float32)."""

import numpy as np
import pytest
import xarray as xr

from lost.host.io.filecheck import check_whole


@pytest.mark.parametrize("fmt", ["NETCDF3_CLASSIC", "NETCDF4"])
def test_truncation_check_of_a_64_mb_grid(benchmark, tmp_path, fmt):
    path = tmp_path / "big.nc"
    z = np.zeros((4000, 4000), np.float32)
    xr.Dataset({"z": (("y", "x"), z)}, coords={"x": np.arange(4000.0) * 10, "y": np.arange(4000.0) * 10}).to_netcdf(path, format=fmt)
    benchmark(check_whole, path)
