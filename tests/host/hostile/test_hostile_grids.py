"""Hostile grid files: truncated, undeclared nodata, ambiguous sign, foreign formats, holes in gridded soundings."""

from __future__ import annotations

import json
import logging
import struct

import numpy as np
import pytest
import rasterio
import xarray as xr
from affine import Affine

from lost.host.io import read_grid

X0, Y0, NODE = 500_000.0, 5_700_000.0, 50.0


def _depths(rows=40, cols=50, seed=1):
    rng = np.random.default_rng(seed)
    return 1000.0 + 30.0 * rng.standard_normal((rows, cols))


def _netcdf(path, z, *, fmt="NETCDF3_CLASSIC", attrs=None):
    rows, cols = z.shape
    ds = xr.Dataset({"z": (("y", "x"), z, attrs or {})}, coords={"x": X0 + NODE * np.arange(cols), "y": Y0 + NODE * np.arange(rows)})
    ds.to_netcdf(path, format=fmt)
    return path


def _geotiff(path, band, *, dtype, nodata=None, **options):
    rows, cols = band.shape
    with rasterio.open(path, "w", driver="GTiff", height=rows, width=cols, count=1, dtype=dtype, crs="EPSG:32631",
                       transform=Affine(NODE, 0, X0, 0, -NODE, Y0 + rows * NODE), nodata=nodata, **options) as dst:
        dst.write(band.astype(dtype), 1)
    return path


def _cut(path, keep):
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * keep)] if isinstance(keep, float) else data[:keep])
    return path


# ------------------------------------------------------------------ truncation


@pytest.mark.parametrize("keep", [0.5, 0.9, 0.999])
def test_a_truncated_classic_gmt_grid_is_refused_not_read_as_zeros(tmp_path, keep):
    path = _cut(_netcdf(tmp_path / "cut.grd", -_depths(), attrs={"positive": "up"}), keep)
    with pytest.raises(ValueError, match=r"cut.grd is truncated: its header describes [\d,]+ bytes but the file has"):
        read_grid(path)


def test_a_classic_grid_cut_inside_its_header_is_refused(tmp_path):
    path = _cut(_netcdf(tmp_path / "head.nc", _depths()), 40)
    with pytest.raises(ValueError, match="head.nc is truncated"):
        read_grid(path)


def test_a_whole_classic_grid_with_a_record_dimension_still_reads(tmp_path):
    z = _depths(6, 5)
    ds = xr.Dataset({"z": (("y", "x"), z, {"positive": "down"})}, coords={"x": X0 + NODE * np.arange(5), "y": Y0 + NODE * np.arange(6)})
    ds.to_netcdf(tmp_path / "rec.nc", format="NETCDF3_64BIT", unlimited_dims=["y"])
    np.testing.assert_array_equal(read_grid(tmp_path / "rec.nc").depth_m, z)


def test_a_record_grid_missing_its_last_records_is_refused(tmp_path):
    z = _depths(6, 5)
    ds = xr.Dataset({"z": (("y", "x"), z, {"positive": "down"})}, coords={"x": X0 + NODE * np.arange(5), "y": Y0 + NODE * np.arange(6)})
    ds.to_netcdf(tmp_path / "rec.nc", format="NETCDF3_CLASSIC", unlimited_dims=["y"])
    with pytest.raises(ValueError, match="rec.nc is truncated"):
        read_grid(_cut(tmp_path / "rec.nc", 0.8))


@pytest.mark.parametrize("keep", [0.5, 0.97])
def test_a_truncated_netcdf4_grid_is_named(tmp_path, keep):
    path = _cut(_netcdf(tmp_path / "cut4.nc", _depths(), fmt="NETCDF4", attrs={"positive": "down"}), keep)
    with pytest.raises(ValueError, match="cut4.nc is truncated"):
        read_grid(path)


def test_a_netcdf_with_an_unknown_version_byte_is_named(tmp_path):
    (tmp_path / "v9.nc").write_bytes(b"CDF\x09" + bytes(100))
    with pytest.raises(ValueError, match="unknown version byte 9"):
        read_grid(tmp_path / "v9.nc")


def test_a_damaged_netcdf4_is_named_not_a_raw_oserror(tmp_path):
    path = _netcdf(tmp_path / "bad4.nc", _depths(), fmt="NETCDF4")
    data = bytearray(path.read_bytes())
    data[64:2000] = bytes(1936)  # the root group's object header zeroed
    path.write_bytes(bytes(data))
    with pytest.raises(ValueError, match="bad4.nc cannot be read as NetCDF, it is truncated or damaged"):
        read_grid(path)


@pytest.mark.parametrize("layout", [{}, {"tiled": True, "blockxsize": 16, "blockysize": 16}, {"BIGTIFF": "YES"}, {"compress": "deflate"}],
                         ids=["strips", "tiles", "bigtiff", "deflate"])
@pytest.mark.parametrize("keep", [0.3, 0.8])
def test_a_truncated_geotiff_is_refused_by_its_header(tmp_path, keep, layout):
    path = _cut(_geotiff(tmp_path / "cut.tif", _depths(), dtype="float32", **layout), keep)
    with pytest.raises(ValueError, match=r"cut.tif is truncated"):
        read_grid(path, positive="down")


def test_a_geotiff_with_damaged_compressed_data_is_named_not_a_raw_rasterio_error(tmp_path):
    path = _geotiff(tmp_path / "bad.tif", _depths(), dtype="float32", compress="deflate")
    with rasterio.open(path) as src:
        offset = int(src.get_tag_item("BLOCK_OFFSET_0_0", "TIFF", bidx=1))
    data = bytearray(path.read_bytes())
    data[offset:offset + 64] = b"\xff" * 64  # the first strip's deflate stream scrambled
    path.write_bytes(bytes(data))
    with pytest.raises(ValueError, match="bad.tif cannot be read as a raster, it is truncated or damaged"):
        read_grid(path, positive="down")


# ------------------------------------------------------------------ implausible values


def test_an_untagged_int16_nodata_is_flagged_with_the_fix(tmp_path):
    band = -_depths()
    band[5:8, 5:9] = -32768
    path = _geotiff(tmp_path / "dem16.tif", band, dtype="int16")
    with pytest.raises(ValueError, match=r"12 of them hold exactly -32768.*pass nodata=-32768"):
        read_grid(path)


def test_nodata_makes_the_untagged_value_holes(tmp_path):
    band = -_depths()
    band[5:8, 5:9] = -32768
    grid = read_grid(_geotiff(tmp_path / "dem16.tif", band, dtype="int16"), nodata=-32768, positive="up")
    assert np.isnan(grid.depth_m).sum() == 12 and np.nanmax(grid.depth_m) < 1200


def test_a_grid_in_centimetres_is_flagged(tmp_path):
    with pytest.raises(ValueError, match="centimetres or feet"):
        read_grid(_netcdf(tmp_path / "cm.nc", _depths() * 100, attrs={"positive": "down"}))


@pytest.mark.parametrize("nodata", ["-32768", True, float("nan")])
def test_nodata_must_be_a_finite_number(tmp_path, nodata):
    with pytest.raises(ValueError, match="nodata must be a finite number"):
        read_grid(_netcdf(tmp_path / "g.nc", _depths()), nodata=nodata)


def test_nodata_does_not_apply_to_an_npz_cache(recorded):
    with pytest.raises(ValueError, match="nodata do not apply"):
        read_grid(recorded["npz"], nodata=-9999.0)


# ------------------------------------------------------------------ sign


def _land_and_sea(rows=40, cols=50):
    z = np.full((rows, cols), 60.0)
    z[:, : int(cols * 0.3)] = -40.0  # 30 % sea at -40 m, 70 % land at +60 m
    return z + np.random.default_rng(2).uniform(-1, 1, (rows, cols))


def test_a_mostly_land_grid_without_metadata_is_refused_not_read_as_60_m_deep(tmp_path):
    with pytest.raises(ValueError, match=r"holds both signs in earnest \(70% above zero, 30% below\).*positive='up'"):
        read_grid(_netcdf(tmp_path / "coast.nc", _land_and_sea()))


def test_a_mostly_land_grid_reads_right_with_positive_up(tmp_path):
    grid = read_grid(_netcdf(tmp_path / "coast.nc", _land_and_sea()), positive="up")
    assert np.all(grid.depth_m[:, :15] > 38) and np.all(grid.depth_m[:, 15:] < -58)


def test_a_sea_grid_signed_by_its_median_says_so_and_points_to_positive(tmp_path, caplog):
    with caplog.at_level(logging.WARNING, logger="lost.host.io"):
        grid = read_grid(_netcdf(tmp_path / "sea.nc", -_depths()))
    assert np.nanmin(grid.depth_m) > 800
    assert "its median is" in caplog.text and "--positive" in caplog.text


def test_a_depth_grid_with_a_little_dry_ground_is_read_as_depth(tmp_path, caplog):
    z = _depths()
    z[:2, :] = -3.0  # 5 % drying heights
    with caplog.at_level(logging.WARNING, logger="lost.host.io"):
        grid = read_grid(_netcdf(tmp_path / "tidal.nc", z))
    assert grid.depth_m[0, 0] == -3.0 and "read as depth" in caplog.text


def test_a_run_on_a_grid_signed_by_its_median_reports_it(recorded, tmp_path, run_cli):
    out = tmp_path / "run"
    code, printed, _ = run_cli("run", "--log", recorded["nav"], "--bathy", recorded["nc"], "--sonar", recorded["sonar"], "--out", out)
    assert code == 0
    warnings = json.loads((out / "summary.json").read_text())["warnings"]
    assert len(warnings) == 1 and "map.nc: z has no sign convention" in warnings[0] and "--positive" in warnings[0]
    assert "warning: map.nc: z has no sign convention" in printed


def test_a_run_with_positive_given_has_no_sign_warning(recorded, tmp_path, run_cli):
    out = tmp_path / "run"
    args = ("run", "--log", recorded["nav"], "--bathy", recorded["nc"], "--sonar", recorded["sonar"], "--out", out, "--positive", "up")
    assert run_cli(*args)[0] == 0
    assert json.loads((out / "summary.json").read_text())["warnings"] == []


# ------------------------------------------------------------------ foreign formats


def _gmt_native(path, z, *, code="bf", registration=0, x_units="x", z_units="z"):
    rows, cols = z.shape
    half = 0.5 * registration
    w, s = X0 - half * NODE, Y0 - half * NODE
    e, n = w + (cols - 1 + registration) * NODE, s + (rows - 1 + registration) * NODE
    header = struct.pack("<3i", cols, rows, registration) + struct.pack("<10d", w, e, s, n, np.nanmin(z), np.nanmax(z), NODE, NODE, 1.0, 0.0)
    header += b"".join(t.encode().ljust(80, b"\0") for t in (x_units, "y", z_units, "title")) + bytes(320 + 160)
    dtype = {"bf": "<f4", "bd": "<f8", "bs": "<i2", "bi": "<i4", "bb": "u1"}[code]
    path.write_bytes(header + z[::-1].astype(dtype).tobytes())  # GMT stores the north row first
    return path


@pytest.mark.parametrize("code", ["bf", "bd"])
@pytest.mark.parametrize("registration", [0, 1])
def test_gmt_native_float_grids_are_read_node_for_node(tmp_path, code, registration):
    z = np.round(-_depths(), 2)
    z[10, 12] = np.nan
    grid = read_grid(_gmt_native(tmp_path / "native.grd", z, code=code, registration=registration), positive="up")
    np.testing.assert_allclose(grid.depth_m, -z, rtol=1e-6)
    assert np.isnan(grid.depth_m[10, 12]) and (grid.x0_m, grid.y0_m, grid.node_m) == (X0, Y0, NODE)


def test_a_gmt_native_grid_in_degrees_is_projected(tmp_path):
    lonlat = tmp_path / "geo.grd"
    z = -_depths(21, 21)
    rows, cols = z.shape
    header = struct.pack("<3i", cols, rows, 0) + struct.pack("<10d", 5.0, 5.1, 52.0, 52.1, z.min(), z.max(), 0.005, 0.005, 1.0, 0.0)
    header += b"".join(t.encode().ljust(80, b"\0") for t in ("longitude [degrees_east]", "latitude [degrees_north]", "z", "")) + bytes(480)
    lonlat.write_bytes(header + z[::-1].astype("<f4").tobytes())
    assert read_grid(lonlat, positive="up", node_m=500.0).crs == "EPSG:32631"


@pytest.mark.parametrize("code", ["bs", "bi", "bb"])
def test_gmt_native_integer_grids_are_refused_with_the_conversion(tmp_path, code):
    path = _gmt_native(tmp_path / "int.grd", np.round(np.clip(_depths() / 10, 0, 250)), code=code)
    with pytest.raises(ValueError, match=rf"GMT native binary grid of .*\(={code}\).*gmt grdconvert"):
        read_grid(path)


@pytest.mark.parametrize("magic, name", [(b"DSAA", "Surfer ASCII grid"), (b"DSBB", "Surfer 6 binary grid"), (b"DSRB", "Surfer 7 binary grid")])
def test_surfer_grids_are_named_with_the_conversion(tmp_path, magic, name):
    (tmp_path / "s.grd").write_bytes(magic + bytes(1000))
    with pytest.raises(ValueError, match=rf"s.grd is a {name}.*gdal_translate"):
        read_grid(tmp_path / "s.grd")


def test_a_grd_of_garbage_is_neither_netcdf_nor_native(tmp_path):
    (tmp_path / "junk.grd").write_bytes(bytes(range(256)) * 8)
    with pytest.raises(ValueError, match="content is not grd.*892-byte header"):
        read_grid(tmp_path / "junk.grd")


# ------------------------------------------------------------------ gridded soundings keep their holes


def _xyz(path, z, *, node=20.0):
    rows, cols = z.shape
    y, x = np.mgrid[:rows, :cols]
    keep = np.isfinite(z)
    lines = [f"{500000 + node * c:.1f} {5700000 + node * r:.1f} {d:.3f}" for r, c, d in zip(y[keep], x[keep], z[keep])]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_a_single_node_hole_in_gridded_soundings_stays_a_hole(tmp_path):
    z = _depths(15, 15)
    z[7, 7] = np.nan
    grid = read_grid(_xyz(tmp_path / "one.xyz", z), positive="down")
    np.testing.assert_array_equal(np.isnan(grid.depth_m), np.isnan(z))
    np.testing.assert_allclose(grid.depth_m[np.isfinite(z)], z[np.isfinite(z)], atol=1e-3)


def test_a_5x5_hole_in_gridded_soundings_stays_5x5(tmp_path):
    z = _depths(20, 20)
    z[6:11, 8:13] = np.nan
    grid = read_grid(_xyz(tmp_path / "five.xyz", z), positive="down")
    assert np.isnan(grid.depth_m).sum() == 25 and np.isnan(grid.depth_m[6:11, 8:13]).all()


def test_gridded_soundings_give_no_depth_past_the_datas_edge(tmp_path):
    z = _depths(20, 20)
    z[10:, 10:] = np.nan  # an L-shaped survey: the missing quadrant lies inside the soundings' bounding box
    grid = read_grid(_xyz(tmp_path / "ell.xyz", z), positive="down")
    np.testing.assert_array_equal(np.isnan(grid.depth_m), np.isnan(z))


def test_scattered_soundings_do_not_bridge_a_hole(tmp_path):
    rng = np.random.default_rng(4)
    x, y = rng.uniform(0, 400, 8000), rng.uniform(0, 400, 8000)
    keep = np.hypot(x - 200, y - 200) > 60  # a round hole, 120 m across
    lines = [f"{500000 + a:.2f},{5700000 + b:.2f},{1000 + 0.01 * a:.3f}" for a, b in zip(x[keep], y[keep])]
    (tmp_path / "ring.csv").write_text("x,y,depth\n" + "\n".join(lines) + "\n")
    grid = read_grid(tmp_path / "ring.csv", node_m=10.0)
    rows, cols = np.mgrid[: grid.shape[0], : grid.shape[1]]
    gx, gy = grid.xy(rows, cols)
    inside = np.hypot(gx - 500200, gy - 5700200) < 40
    assert inside.sum() > 30 and np.isnan(grid.depth_m[inside]).all()


def test_repeated_soundings_of_a_lattice_node_are_averaged(tmp_path):
    z = _depths(5, 5)
    path = _xyz(tmp_path / "rep.xyz", z)
    path.write_text(path.read_text() + f"500000.0 5700000.0 {z[0, 0] + 2.0:.3f}\n")
    assert read_grid(path, positive="down").depth_m[0, 0] == pytest.approx(z[0, 0] + 1.0, abs=1e-3)


@pytest.mark.parametrize("fmt", ["NETCDF3_64BIT_OFFSET", "NETCDF3_64BIT_DATA"], ids=["cdf2", "cdf5"])
@pytest.mark.parametrize("record", [False, True], ids=["fixed", "record"])
def test_cdf2_and_cdf5_grids_are_read_whole_and_refused_cut(tmp_path, fmt, record):
    import netCDF4

    z = _depths(12, 9)
    path = tmp_path / "g.nc"
    with netCDF4.Dataset(path, "w", format=fmt) as ds:
        ds.createDimension("y", None if record else 12)
        ds.createDimension("x", 9)
        ds.createVariable("y", "f8", ("y",))[:] = Y0 + NODE * np.arange(12)
        ds.createVariable("x", "f8", ("x",))[:] = X0 + NODE * np.arange(9)
        variable = ds.createVariable("z", "f4", ("y", "x"))
        variable.positive = "down"
        variable[:] = z
    np.testing.assert_allclose(read_grid(path).depth_m, z.astype(np.float32))
    with pytest.raises(ValueError, match="g.nc is truncated"):
        read_grid(_cut(path, path.stat().st_size - 40))


def test_an_xyz_stray_line_is_named_with_the_file_and_its_line(tmp_path):
    path = tmp_path / "soundings.xyz"
    lines = [f"{x} {y} {100 + x}" for x in range(20) for y in range(20)]
    lines.insert(300, "3 4 5 6")
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=r"soundings.xyz: line 301 has 4 fields where the lines before it have 3: '3 4 5 6'"):
        read_grid(path, source_crs="EPSG:32631")


def write_bag(path, elevation, uncertainty, *, node=10.0):
    """A BAG written by GDAL's BAG driver (north row first), UTM 31 N."""
    import rasterio
    from affine import Affine

    with rasterio.open(path, "w", driver="BAG", width=elevation.shape[1], height=elevation.shape[0], count=2, dtype="float32",
                       crs="EPSG:32631", transform=Affine(node, 0.0, 500_000.0, 0.0, -node, 5_700_000.0), nodata=1e6) as dst:
        dst.write(elevation.astype(np.float32), 1)
        dst.write(uncertainty.astype(np.float32), 2)
    return path


def test_a_bag_without_its_uncertainty_layer_is_refused_by_name(tmp_path):
    h5py = pytest.importorskip("h5py")
    from lost.host.io.bag import read_bag
    from lost.host.io.errors import MissingLayerError

    path = write_bag(tmp_path / "nou.bag", -np.full((3, 4), 50.0), np.full((3, 4), 0.5))
    with h5py.File(path, "a") as f:
        del f["BAG_root/uncertainty"]
    with pytest.raises(MissingLayerError, match="nou.bag has no uncertainty layer"):
        read_bag(path)
    depth_only = read_bag(path, require_uncertainty=False)
    assert depth_only.uncertainty_m is None and (depth_only.grid.depth_m == 50.0).all()


def test_a_truncated_bag_is_named(tmp_path):
    from lost.host.io.bag import read_bag

    path = write_bag(tmp_path / "cut.bag", -np.full((30, 40), 50.0), np.full((30, 40), 0.5))
    path.write_bytes(path.read_bytes()[:-2000])
    with pytest.raises(ValueError, match="cut.bag"):
        read_bag(path)
