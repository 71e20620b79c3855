"""Bathymetry readers: ASCII XYZ soundings (regular exports and scattered soundings, x/y or lon/lat) read back node for node."""

import logging

import numpy as np
import pytest

from lost.host.io import read_grid

from .test_grids import LAT0, LON0, UTM31N, elevation_of, node_lonlat

# ------------------------------------------------------------------ ASCII XYZ


def plane(x, y):
    return 200.0 + 0.01 * x - 0.02 * y


def test_regular_xyz_export_grids_exactly(tmp_path):
    x, y = np.meshgrid(np.arange(5) * 20.0 + 1000.0, np.arange(4) * 20.0 + 3000.0)
    lines = [f"{a:.1f} {b:.1f} {plane(a, b):.6f}" for a, b in zip(x.ravel(), y.ravel())]
    path = tmp_path / "grid.xyz"
    path.write_text("# exported by grd2xyz\n" + "\n".join(lines) + "\n")
    grid = read_grid(path, positive="down")
    assert (grid.x0_m, grid.y0_m, grid.node_m, grid.crs) == (1000.0, 3000.0, 20.0, None)
    np.testing.assert_allclose(grid.depth_m, plane(x, y), atol=1e-9)
    part = read_grid(path, positive="down", bounds=(1010.0, 3000.0, 1080.0, 3040.0))
    assert (part.x0_m, part.y0_m, part.shape) == (1020.0, 3000.0, (3, 4))
    np.testing.assert_allclose(part.depth_m, plane(x, y)[:3, 1:], atol=1e-9)


def test_scattered_soundings_leave_gaps_as_holes(tmp_path):
    rng = np.random.default_rng(5)
    # Two survey lines 200 m apart, soundings every ~5 m across a 40 m swath each.
    pts = []
    for y_line in (0.0, 200.0):
        x = rng.uniform(0, 300, 2000)
        y = y_line + rng.uniform(-20, 20, 2000)
        pts.append(np.column_stack([x, y, plane(x, y)]))
    xyz = np.vstack(pts)
    path = tmp_path / "soundings.csv"
    path.write_text("easting,northing,depth\n" + "\n".join(f"{a},{b},{c}" for a, b, c in xyz) + "\n")
    grid = read_grid(path, node_m=10.0)
    rows, cols = np.meshgrid(np.arange(grid.shape[0]), np.arange(grid.shape[1]), indexing="ij")
    gx, gy = grid.xy(rows, cols)
    between = (gy > 40) & (gy < 160)
    assert np.all(np.isnan(grid.depth_m[between]))  # no sounding within 10 m: not invented
    on_line = np.isfinite(grid.depth_m)
    near_centre = (np.abs(gy) <= 10) | (np.abs(gy - 200) <= 10)
    assert on_line[near_centre].mean() > 0.9
    np.testing.assert_allclose(grid.depth_m[on_line], plane(gx, gy)[on_line], atol=1e-6)


def test_lonlat_xyz_is_projected(tmp_path, caplog):
    lon, lat = np.meshgrid(LON0 + np.arange(20) * 0.001, LAT0 + np.arange(20) * 0.001)
    z = elevation_of(lon, lat)
    path = tmp_path / "survey.txt"
    body = "\n".join(f"{a:.6f}\t{b:.6f}\t{c:.4f}" for a, b, c in zip(lon.ravel(), lat.ravel(), z.ravel()))
    path.write_text("lon\tlat\televation\n" + body + "\n5.501\t52.001\tNaN\n")
    with caplog.at_level(logging.INFO, logger="lost.host.io"):
        grid = read_grid(path, node_m=20.0, max_gap_m=60.0)
    assert "skipped 1 of 401 soundings" in caplog.text
    assert grid.crs == UTM31N
    node_lon, node_lat = node_lonlat(grid)
    finite = np.isfinite(grid.depth_m)
    assert finite.mean() > 0.7
    # Linear interpolation over a triangulation of a plane in lon/lat, projected: close, not exact.
    np.testing.assert_allclose(grid.depth_m[finite], -elevation_of(node_lon, node_lat)[finite], atol=0.05)


def test_headerless_xyz_that_could_be_degrees_needs_a_crs(tmp_path):
    path = tmp_path / "ambiguous.xyz"
    path.write_text("5.0 52.0 -10\n5.1 52.0 -11\n5.0 52.1 -12\n5.1 52.1 -13\n")
    with pytest.raises(ValueError, match="source_crs"):
        read_grid(path)
    grid = read_grid(path, source_crs="EPSG:4326", node_m=1000.0, max_gap_m=8000.0)
    assert grid.crs == UTM31N and np.nanmin(grid.depth_m) >= 10.0


def test_xyz_missing_column_is_named(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("x,y,temperature\n0,0,1\n1,0,1\n0,1,1\n")
    with pytest.raises(ValueError, match="no z column.*found x, y, temperature"):
        read_grid(path)


def test_xyz_without_position_is_refused(tmp_path):
    path = tmp_path / "nopos.csv"
    path.write_text("x,y,depth\n0,0,1\n,0,1\n0,1,1\n1,1,1\n")
    with pytest.raises(ValueError, match="sounding 2 has no position"):
        read_grid(path)
