"""Bathymetry readers: NetCDF, GeoTIFF, ESRI ASCII and npz grids written by the field's own libraries, read back node for node (XYZ: test_grids_xyz.py)."""

import logging

import numpy as np
import pytest
import rasterio
import xarray as xr
from affine import Affine
from pyproj import Transformer

from lost.host.grid import Grid
from lost.host.io import read_grid, utm_crs, write_npz

LON0, LAT0 = 5.5, 52.0  # off the central meridian of UTM zone 31N, so its grid north is rotated
UTM31N = "EPSG:32631"


def elevation_of(lon, lat):
    """A plane in lon/lat: bilinear resampling reproduces it exactly, so every node can be checked."""
    return -1000.0 - 800.0 * (lon - LON0) + 500.0 * (lat - LAT0)


def lonlat_dataset(*, north_up=False, name="elevation", lon_name="lon", lat_name="lat", attrs=None):
    lon = LON0 - 0.05 + np.arange(41) * 0.0025
    lat = LAT0 - 0.03 + np.arange(25) * 0.0025
    if north_up:
        lat = lat[::-1]
    z = elevation_of(lon[None, :], lat[:, None])
    da = xr.DataArray(z, dims=(lat_name, lon_name), coords={lat_name: lat, lon_name: lon}, attrs=attrs or {})
    da[lon_name].attrs["units"] = "degrees_east"
    da[lat_name].attrs["units"] = "degrees_north"
    return xr.Dataset({name: da})


def node_lonlat(grid):
    rows, cols = grid.shape
    x, y = grid.xy(*np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij"))
    return Transformer.from_crs(grid.crs, "EPSG:4326", always_xy=True).transform(x, y)


# ------------------------------------------------------------------ NetCDF


@pytest.mark.parametrize("north_up", [False, True])
def test_gebco_netcdf_is_projected_to_utm_and_negated(tmp_path, north_up):
    path = tmp_path / "gebco.nc"
    lonlat_dataset(north_up=north_up).to_netcdf(path)
    grid = read_grid(path, node_m=50.0)
    assert grid.crs == UTM31N and grid.node_m == 50.0
    assert grid.x0_m % 50.0 == 0 and grid.y0_m % 50.0 == 0
    lon, lat = node_lonlat(grid)
    inside = np.isfinite(grid.depth_m)
    # The projected footprint is not a rectangle: corners of the box are holes, most nodes are not.
    assert 0.8 < inside.mean() < 1.0
    np.testing.assert_allclose(grid.depth_m[inside], -elevation_of(lon, lat)[inside], atol=1e-6)
    assert not np.any(np.isfinite(grid.depth_m) & ((lon < LON0 - 0.05) | (lat > LAT0 + 0.03)))


def test_known_point_lands_at_its_node(tmp_path):
    path = tmp_path / "spike.nc"
    ds = lonlat_dataset()
    ds["elevation"].loc[dict(lat=ds.lat[12], lon=ds.lon[20])] = -5000.0  # a pinnacle, by index
    ds.to_netcdf(path)
    spike_lon, spike_lat = float(ds.lon[20]), float(ds.lat[12])
    grid = read_grid(path, node_m=10.0)
    x, y = Transformer.from_crs("EPSG:4326", UTM31N, always_xy=True).transform(spike_lon, spike_lat)
    row, col = np.unravel_index(np.nanargmax(grid.depth_m), grid.shape)
    px, py = grid.xy(row, col)
    assert np.hypot(px - x, py - y) <= 10.0 * np.sqrt(0.5)


def test_default_node_is_the_finer_native_spacing(tmp_path):
    path = tmp_path / "g.nc"
    lonlat_dataset().to_netcdf(path)
    grid = read_grid(path)
    # 0.0025 degree of longitude at 52 N is about 172 m, of latitude about 278 m.
    assert 165 < grid.node_m < 180


def test_projected_gmt_grid_is_kept_node_for_node(tmp_path):
    x = 430_000.0 + np.arange(6) * 25.0
    y = 5_760_000.0 + np.arange(4) * 25.0
    z = np.arange(24.0).reshape(4, 6) + 100.0
    z[2, 3] = np.nan
    ds = xr.Dataset({"z": (("y", "x"), z, {"positive": "down"})}, coords={"x": x, "y": y})
    ds["crs"] = xr.DataArray(0, attrs={"crs_wkt": __import__("pyproj").CRS(UTM31N).to_wkt()})
    ds["z"].attrs["grid_mapping"] = "crs"
    path = tmp_path / "gmt.grd"
    ds.to_netcdf(path, format="NETCDF3_CLASSIC")
    grid = read_grid(path)
    assert (grid.x0_m, grid.y0_m, grid.node_m, grid.crs) == (430_000.0, 5_760_000.0, 25.0, UTM31N)
    np.testing.assert_array_equal(grid.depth_m, z)  # NaN compares equal position for position


def test_projected_grid_without_crs_is_a_local_frame(tmp_path):
    z = np.full((3, 3), 40.0)
    path = tmp_path / "local.nc"
    xr.Dataset({"depth": (("y", "x"), z)}, coords={"x": [0.0, 5.0, 10.0], "y": [0.0, 5.0, 10.0]}).to_netcdf(path)
    grid = read_grid(path)
    assert grid.crs is None and grid.node_m == 5.0
    np.testing.assert_array_equal(grid.depth_m, z)


def test_resampling_keeps_holes_without_spreading_them_far(tmp_path):
    x = np.arange(11) * 10.0
    z = np.tile(x, (11, 1)) + 50.0
    z[5, 5] = np.nan
    path = tmp_path / "hole.nc"
    xr.Dataset({"depth": (("y", "x"), z)}, coords={"x": x, "y": x}).to_netcdf(path)
    grid = read_grid(path, node_m=5.0)
    holes = np.argwhere(np.isnan(grid.depth_m))
    # The hole at (50 m, 50 m) poisons only nodes that take weight from it: within one source node.
    assert len(holes) == 9 and np.all(np.abs(holes * 5.0 - 50.0) < 10.0)
    finite = np.isfinite(grid.depth_m)
    x_nodes = np.tile(np.arange(grid.shape[1]) * 5.0, (grid.shape[0], 1))
    np.testing.assert_allclose(grid.depth_m[finite], x_nodes[finite] + 50.0)


def test_sign_comes_from_metadata_then_data(tmp_path, caplog):
    z = np.full((2, 2), 30.0)
    coords = {"x": [0.0, 1.0], "y": [0.0, 1.0]}
    up = tmp_path / "up.nc"
    xr.Dataset({"z": (("y", "x"), z, {"positive": "up"})}, coords=coords).to_netcdf(up)
    assert np.all(read_grid(up).depth_m == -30.0)
    plain = tmp_path / "plain.nc"
    xr.Dataset({"z": (("y", "x"), -z)}, coords=coords).to_netcdf(plain)
    with caplog.at_level(logging.INFO, logger="lost.host.io"):
        assert np.all(read_grid(plain).depth_m == 30.0)
    assert "negated to depth" in caplog.text
    guesses = [r for r in caplog.records if "no sign convention" in r.getMessage()]
    assert len(guesses) == 1 and guesses[0].levelno == logging.WARNING
    assert np.all(read_grid(plain, positive="down").depth_m == -30.0)


def test_unknown_variable_names_what_was_found(tmp_path):
    path = tmp_path / "odd.nc"
    coords = {"x": [0.0, 1.0], "y": [0.0, 1.0]}
    xr.Dataset({"foo": (("y", "x"), np.ones((2, 2))), "bar": (("y", "x"), np.ones((2, 2)))}, coords=coords).to_netcdf(path)
    with pytest.raises(ValueError, match="2-D variables are foo, bar"):
        read_grid(path)
    with pytest.raises(ValueError, match="no variable 'baz'.*foo, bar"):
        read_grid(path, variable="baz")
    assert read_grid(path, variable="bar", positive="down").shape == (2, 2)


def test_netcdf_without_coordinates_is_refused(tmp_path):
    path = tmp_path / "bare.nc"
    xr.Dataset({"z": (("row", "col"), np.ones((2, 2)))}).to_netcdf(path)
    with pytest.raises(ValueError, match="without coordinate values"):
        read_grid(path)


def test_non_monotonic_coordinates_are_refused(tmp_path):
    path = tmp_path / "zigzag.nc"
    xr.Dataset({"z": (("y", "x"), np.ones((2, 3)))}, coords={"x": [0.0, 2.0, 1.0], "y": [0.0, 1.0]}).to_netcdf(path)
    with pytest.raises(ValueError, match="x coordinates are not strictly monotonic"):
        read_grid(path)


def test_contradicting_source_crs_is_refused(tmp_path):
    path = tmp_path / "g.nc"
    lonlat_dataset().to_netcdf(path)
    with pytest.raises(ValueError, match="contradicts"):
        read_grid(path, source_crs=UTM31N)


@pytest.mark.parametrize("pixel", [0, 1])
def test_legacy_gmt_netcdf_layout(tmp_path, pixel):
    # GMT before 4.1: z flattened north row first; the frame in x_range, y_range, dimension.
    north_first = np.array([[1.0, 2.0, 3.0], [4.0, np.nan, 6.0]])
    ranges = ([100.0, 130.0], [200.0, 220.0]) if pixel else ([100.0, 120.0], [200.0, 210.0])
    xr.Dataset(
        {
            "x_range": ("side", ranges[0], {"units": "m"}),
            "y_range": ("side", ranges[1], {"units": "m"}),
            "z_range": ("side", [1.0, 6.0]),
            "spacing": ("side", [10.0, 10.0]),
            "dimension": ("side", np.array([3, 2], dtype=np.int32)),
            "z": ("xysize", north_first.ravel(), {"node_offset": np.int32(pixel), "long_name": "depth"}),
        }
    ).to_netcdf(tmp_path / "old.grd", format="NETCDF3_CLASSIC")
    grid = read_grid(tmp_path / "old.grd")
    assert (grid.x0_m, grid.y0_m, grid.node_m, grid.crs) == (105.0 if pixel else 100.0, 205.0 if pixel else 200.0, 10.0, None)
    np.testing.assert_array_equal(grid.depth_m, north_first[::-1])


# ------------------------------------------------------------------ GeoTIFF and ESRI ASCII


def from_origin(west, north, xsize, ysize):
    # rasterio.transform.from_origin multiplies Affines with `*`, which affine 3.1 deprecates.
    return Affine(xsize, 0.0, west, 0.0, -ysize, north)


def write_tif(path, values, *, crs, transform, nodata=None):
    with rasterio.open(
        path, "w", driver="GTiff", height=values.shape[0], width=values.shape[1], count=1,
        dtype=values.dtype, crs=crs, transform=transform, nodata=nodata,
    ) as dst:
        dst.write(values, 1)


def test_projected_geotiff_is_flipped_to_south_first(tmp_path):
    north_up = np.arange(12, dtype=np.float32).reshape(3, 4) + 10.0
    north_up[0, 1] = -9999.0
    path = tmp_path / "utm.tif"
    # Top-left corner at (430000, 5760300); 100 m pixels.
    write_tif(path, north_up, crs=UTM31N, transform=from_origin(430_000, 5_760_300, 100, 100), nodata=-9999.0)
    grid = read_grid(path, positive="down")
    assert grid.crs == UTM31N and grid.node_m == 100.0
    # Node (0, 0) is the south-west pixel's centre.
    assert (grid.x0_m, grid.y0_m) == (430_050.0, 5_760_050.0)
    expected = north_up[::-1].astype(np.float64)
    expected[expected == -9999.0] = np.nan
    np.testing.assert_array_equal(grid.depth_m, expected)
    assert np.isnan(grid.depth_m[2, 1])  # the north row's hole


def test_geographic_geotiff_of_elevation_becomes_utm_depth(tmp_path):
    lon_left, lat_top, step = LON0 - 0.05, LAT0 + 0.03, 0.0025
    lon = lon_left + (np.arange(40) + 0.5) * step
    lat = lat_top - (np.arange(24) + 0.5) * step
    values = elevation_of(lon[None, :], lat[:, None])
    path = tmp_path / "gebco.tif"
    write_tif(path, values, crs="EPSG:4326", transform=from_origin(lon_left, lat_top, step, step))
    grid = read_grid(path, node_m=100.0)
    assert grid.crs == UTM31N
    node_lon, node_lat = node_lonlat(grid)
    inside = np.isfinite(grid.depth_m)
    assert inside.mean() > 0.8
    np.testing.assert_allclose(grid.depth_m[inside], -elevation_of(node_lon, node_lat)[inside], atol=1e-6)


def test_packed_geotiff_is_scaled(tmp_path):
    packed = np.array([[100, 200], [300, -32768]], dtype=np.int16)
    path = tmp_path / "packed.tif"
    write_tif(path, packed, crs=UTM31N, transform=from_origin(0, 20, 10, 10), nodata=-32768)
    with rasterio.open(path, "r+") as dst:
        dst.scales, dst.offsets = (0.5,), (-1000.0,)
    grid = read_grid(path)  # elevations -950, -900, -850 by the data's sign
    np.testing.assert_array_equal(grid.depth_m, [[850.0, np.nan], [950.0, 900.0]])


def test_rotated_geotiff_is_refused(tmp_path):
    path = tmp_path / "rot.tif"
    write_tif(path, np.ones((2, 2), np.float32), crs=UTM31N, transform=Affine(10, 1, 0, 1, -10, 0))
    with pytest.raises(ValueError, match="rotated or sheared"):
        read_grid(path)


def test_esri_ascii_grid_with_prj(tmp_path):
    path = tmp_path / "emodnet.asc"
    path.write_text(
        "ncols 3\nnrows 2\nxllcenter 430000\nyllcenter 5760000\ncellsize 50\nNODATA_value -9999\n"
        "-40 -41 -9999\n-30 -31 -32\n"
    )
    (tmp_path / "emodnet.prj").write_text(__import__("pyproj").CRS(UTM31N).to_wkt(version="WKT1_ESRI"))
    grid = read_grid(path)
    assert (grid.x0_m, grid.y0_m, grid.node_m) == (430_000.0, 5_760_000.0, 50.0)
    assert grid.crs is not None and __import__("pyproj").CRS(grid.crs).to_epsg() == 32631
    np.testing.assert_array_equal(grid.depth_m, [[30.0, 31.0, 32.0], [40.0, 41.0, np.nan]])


# ------------------------------------------------------------------ npz and dispatch


def test_npz_round_trip_is_exact(tmp_path):
    depth = np.random.default_rng(1).normal(100, 10, (7, 9))
    depth[3, 4] = np.nan
    grid = Grid(depth, x0_m=1234.5, y0_m=-6789.25, node_m=2.5, crs=UTM31N)
    written = write_npz(grid, tmp_path / "cache")
    assert written.name == "cache.npz"
    back = read_grid(written)
    np.testing.assert_array_equal(back.depth_m, depth)
    assert (back.x0_m, back.y0_m, back.node_m, back.crs) == (1234.5, -6789.25, 2.5, UTM31N)
    local = read_grid(write_npz(Grid(depth, x0_m=0, y0_m=0, node_m=1), tmp_path / "local.npz"))
    assert local.crs is None
    with pytest.raises(ValueError, match="local frame"):
        read_grid(tmp_path / "local.npz", crs=UTM31N)


def test_npz_missing_key_is_named(tmp_path):
    path = tmp_path / "partial.npz"
    np.savez(path, depth_m=np.ones((2, 2)), x0_m=0.0, y0_m=0.0)
    with pytest.raises(ValueError, match="lacks the key.*node_m.*has depth_m, x0_m, y0_m"):
        read_grid(path)


def test_npz_can_be_resampled(tmp_path):
    x = np.arange(5) * 10.0
    depth = np.tile(x, (5, 1)) + 7.0
    path = write_npz(Grid(depth, x0_m=0.0, y0_m=0.0, node_m=10.0), tmp_path / "g.npz")
    grid = read_grid(path, node_m=5.0)
    assert grid.shape == (9, 9)
    np.testing.assert_allclose(grid.depth_m[0], np.arange(9) * 5.0 + 7.0)


@pytest.mark.parametrize(
    "name, content, message",
    [
        ("map.dem", b"ncols 2\n", "unknown grid format '.dem'"),
        ("map.asc", b"0 0 1\n", "no ESRI ASCII grid header"),
        ("map.tif", b"not a tiff at all", "content is not tif"),
        ("map.nc", b"0 0 1\n", "content is not nc"),
        ("map.zip", b"PK\x03\x04rest", "zip archive"),
    ],
)
def test_bad_extension_or_content_is_named(tmp_path, name, content, message):
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(ValueError, match=message):
        read_grid(path)


def test_netcdf_is_recognised_by_content_whatever_its_name(tmp_path):
    path = tmp_path / "really_netcdf.grd"
    lonlat_dataset().to_netcdf(path)
    assert read_grid(path, node_m=200.0).crs == UTM31N


def test_bad_arguments_are_named(tmp_path):
    path = tmp_path / "g.nc"
    lonlat_dataset().to_netcdf(path)
    with pytest.raises(ValueError, match="positive must be"):
        read_grid(path, positive="sideways")
    with pytest.raises(ValueError, match="node_m must be a positive"):
        read_grid(path, node_m=-1.0)
    with pytest.raises(ValueError, match="projected"):
        read_grid(path, crs="EPSG:4326")
    with pytest.raises(ValueError, match="would make a"):
        read_grid(path, node_m=0.01)
    with pytest.raises(FileNotFoundError):
        read_grid(tmp_path / "absent.nc")


def test_utm_zone_of_a_point():
    assert utm_crs(LON0, LAT0) == "EPSG:32631"
    assert utm_crs(-70.5, -33.4) == "EPSG:32719"
    assert utm_crs(183.0, 10.0) == "EPSG:32601"


def test_float32_coordinates_do_not_force_a_resampling(tmp_path):
    # At UTM northings float32 keeps half a metre: 12.3 m nodes are stored up to 4 % of a node off.
    x = (430_000.0 + np.arange(50) * 12.3).astype(np.float32)
    y = (5_760_000.0 + np.arange(40) * 12.3).astype(np.float32)
    assert np.ptp(np.diff(y.astype(np.float64))) > 0.4
    z = np.random.default_rng(2).normal(500.0, 5.0, (40, 50))
    path = tmp_path / "f32.nc"
    xr.Dataset({"depth": (("y", "x"), z)}, coords={"x": x, "y": y}).to_netcdf(path)
    grid = read_grid(path)
    assert grid.shape == (40, 50) and abs(grid.node_m - 12.3) < 1e-3
    np.testing.assert_array_equal(grid.depth_m, z)


def test_soundings_on_one_line_cannot_be_gridded(tmp_path):
    path = tmp_path / "line.csv"
    path.write_text("x,y,depth\n" + "\n".join(f"{i * 5.0},0.0,{100 + i}" for i in range(10)) + "\n")
    with pytest.raises(ValueError, match="cannot be triangulated"):
        read_grid(path, node_m=5.0)


def test_bounds_read_only_a_window(tmp_path):
    nc, tif = tmp_path / "g.nc", tmp_path / "g.tif"
    lonlat_dataset(north_up=True).to_netcdf(nc)
    north_up = np.arange(60, dtype=np.float32).reshape(6, 10) + 100.0
    write_tif(tif, north_up, crs=UTM31N, transform=from_origin(430_000, 5_760_600, 100, 100))
    window = read_grid(tif, bounds=(430_200, 5_760_100, 430_500, 5_760_300), positive="down")
    # Pixel centres 430250..430450 east, 5760150..5760250 north: 2 rows (south first) x 3 columns.
    assert (window.x0_m, window.y0_m, window.shape) == (430_250.0, 5_760_150.0, (2, 3))
    np.testing.assert_array_equal(window.depth_m, north_up[::-1][1:3, 2:5])
    part = read_grid(nc, node_m=50.0, bounds=(LON0 - 0.01, LAT0 - 0.01, LON0 + 0.01, LAT0 + 0.01))
    lon, lat = node_lonlat(part)
    finite = np.isfinite(part.depth_m)
    assert finite.mean() > 0.8 and lon[finite].min() > LON0 - 0.011 and lat[finite].max() < LAT0 + 0.011
    np.testing.assert_allclose(part.depth_m[finite], -elevation_of(lon, lat)[finite], atol=1e-6)
    with pytest.raises(ValueError, match="hold 0 node"):
        read_grid(tif, bounds=(0, 0, 1, 1))
    with pytest.raises(ValueError, match="west < east"):
        read_grid(tif, bounds=(5, 0, 1, 1))


def test_longitudes_from_0_to_360_are_projected(tmp_path):
    lon = 350.0 + np.arange(41) * 0.0025  # 10 W
    lat = LAT0 + np.arange(25) * 0.0025
    # The plane shifted to 10 W (unshifted it would rise 11 km there, which the reader refuses as no sea floor).
    z = elevation_of(lon[None, :] - 360.0 + 15.5, lat[:, None])
    path = tmp_path / "east360.nc"
    xr.Dataset({"elevation": (("lat", "lon"), z)}, coords={"lon": lon, "lat": lat}).to_netcdf(path)
    grid = read_grid(path, node_m=50.0)
    assert grid.crs == "EPSG:32629"
    node_lon, node_lat = node_lonlat(grid)
    finite = np.isfinite(grid.depth_m)
    assert finite.mean() > 0.8
    np.testing.assert_allclose(grid.depth_m[finite], -elevation_of(node_lon + 15.5, node_lat)[finite], atol=1e-6)


def test_all_hole_result_is_refused(tmp_path):
    path = tmp_path / "holes.nc"
    z = np.full((3, 3), np.nan)
    xr.Dataset({"depth": (("y", "x"), z)}, coords={"x": [0.0, 10.0, 20.0], "y": [0.0, 10.0, 20.0]}).to_netcdf(path)
    for node_m in (5.0, None):  # resampled, and kept node for node
        with pytest.raises(ValueError, match="no node of the grid read from holes.nc has a depth"):
            read_grid(path, node_m=node_m, positive="down")


def test_projected_grid_to_another_projected_crs(tmp_path):
    # A plane in UTM 31N metres, read into UTM 32N: every node checked through the inverse projection.
    cols, rows = 60, 40
    west, north, step = 690_000.0, 5_770_000.0, 25.0
    x = west + (np.arange(cols) + 0.5) * step
    y = north - (np.arange(rows) + 0.5) * step
    values = (300.0 + 0.01 * (x[None, :] - west) - 0.02 * (y[:, None] - north)).astype(np.float64)
    path = tmp_path / "utm31.tif"
    write_tif(path, values, crs=UTM31N, transform=from_origin(west, north, step, step))
    grid = read_grid(path, crs="EPSG:32632", positive="down")
    assert grid.crs == "EPSG:32632" and grid.node_m == pytest.approx(25.0, rel=1e-3)
    rows_i, cols_i = np.meshgrid(np.arange(grid.shape[0]), np.arange(grid.shape[1]), indexing="ij")
    gx, gy = grid.xy(rows_i, cols_i)
    sx, sy = Transformer.from_crs("EPSG:32632", UTM31N, always_xy=True).transform(gx, gy)
    finite = np.isfinite(grid.depth_m)
    assert finite.mean() > 0.8
    np.testing.assert_allclose(grid.depth_m[finite], (300.0 + 0.01 * (sx - west) - 0.02 * (sy - north))[finite], atol=1e-6)


def test_npz_keeps_the_maps_uncertainty_layer(tmp_path):
    depth = np.arange(12.0).reshape(3, 4) + 100.0
    sigma = np.where(depth > 105.0, 0.4, 0.25)
    back = read_grid(write_npz(Grid(depth_m=depth, x0_m=0.0, y0_m=0.0, node_m=5.0, sigma_m=sigma), tmp_path / "a.npz"))
    np.testing.assert_array_equal(back.sigma_m, sigma)
    assert read_grid(write_npz(Grid(depth_m=depth, x0_m=0.0, y0_m=0.0, node_m=5.0), tmp_path / "b.npz")).sigma_m is None
