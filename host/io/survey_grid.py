"""A bathymetry grid from the valid soundings of survey files (``lost grid``), and its CF NetCDF file.

:func:`grid_survey` bins every valid sounding to its nearest node (nodes at multiples of ``node_m`` in the
projected CRS, as :func:`~lost.host.io.read_grid` aligns them) and keeps per node the mean depth, the count
and the sample standard deviation (ddof 1; NaN where fewer than two soundings fell). A node no sounding
reached is a hole (NaN), never filled. Two streamed passes over the files (the extent, then the sums), so
memory holds the grid, not the soundings. Sums are taken about a reference depth (the first valid
sounding's) so that the variance of deep water keeps its digits.

:func:`write_survey_grid` writes a CF-1.8 NetCDF file: coordinates ``x``/``y`` (metres, projection
coordinates, ascending), ``depth`` (positive down, first so that GMT takes it by default), ``depth_std``
and ``count``, and a ``crs`` grid mapping with the CRS's WKT (``crs_wkt`` and GDAL's ``spatial_ref``).
``read_grid`` reads its ``depth`` back node for node; xarray and GMT read it as it is.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..grid import Grid
from .errors import NoPingsError
from .survey import Survey

__all__ = ["SurveyGrid", "grid_survey", "write_survey_grid"]

# Above this many nodes the node spacing is almost surely a mistake for the survey's size (8 bytes x 4 arrays per node).
_MAX_NODES = 100_000_000


@dataclass(frozen=True)
class SurveyGrid:
    """The gridded soundings: ``grid`` (mean depth, NaN holes), and per node ``std_m`` and ``count``; ``skipped`` as read."""

    grid: Grid
    std_m: np.ndarray
    count: np.ndarray
    skipped: dict = field(default_factory=dict)
    notes: dict = field(default_factory=dict)


def grid_survey(paths: str | os.PathLike | Iterable[str | os.PathLike], *, node_m: float, crs: str | None = None) -> SurveyGrid:
    """Mean, count and standard deviation of the valid soundings per node of ``node_m`` metres (see the module)."""
    if not (isinstance(node_m, int | float) and math.isfinite(node_m) and node_m > 0):
        raise ValueError(f"node_m must be a positive number of metres, got {node_m!r}")
    survey = Survey(paths, crs=crs)
    lo, hi, reference = np.array([math.inf, math.inf]), np.array([-math.inf, -math.inf]), math.nan
    for ping in survey:
        if ping.valid.any():
            e, n = ping.beam_east_m[ping.valid], ping.beam_north_m[ping.valid]
            lo, hi = np.minimum(lo, [e.min(), n.min()]), np.maximum(hi, [e.max(), n.max()])
            if math.isnan(reference):
                reference = float(ping.depth_m[ping.valid][0])
    if math.isnan(reference):
        names = ", ".join(p.name for p in survey.paths)
        raise NoPingsError(f"{names}: no valid sounding to grid (skipped: {dict(survey.skipped) or 'nothing'}); every beam flagged or no ping placed")
    x0, y0 = np.floor(lo[0] / node_m + 0.5) * node_m, np.floor(lo[1] / node_m + 0.5) * node_m
    cols = int(np.floor((hi[0] - x0) / node_m + 0.5)) + 1
    rows = int(np.floor((hi[1] - y0) / node_m + 0.5)) + 1
    if rows * cols > _MAX_NODES:
        raise ValueError(f"{rows} x {cols} nodes of {node_m:g} m for a survey {hi[0] - lo[0]:.0f} x {hi[1] - lo[1]:.0f} m: node_m is too small")
    count = np.zeros(rows * cols, dtype=np.int64)
    total = np.zeros(rows * cols)
    squares = np.zeros(rows * cols)
    for ping in survey:
        if not ping.valid.any():
            continue
        col = np.floor((ping.beam_east_m[ping.valid] - x0) / node_m + 0.5).astype(np.int64)
        row = np.floor((ping.beam_north_m[ping.valid] - y0) / node_m + 0.5).astype(np.int64)
        node = row * cols + col
        d = ping.depth_m[ping.valid] - reference
        count += np.bincount(node, minlength=rows * cols)
        total += np.bincount(node, weights=d, minlength=rows * cols)
        squares += np.bincount(node, weights=d * d, minlength=rows * cols)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(count > 0, total / count, np.nan)
        variance = np.where(count > 1, (squares - count * mean * mean) / (count - 1), np.nan)
    std = np.sqrt(np.maximum(variance, 0.0), where=np.isfinite(variance), out=np.full_like(variance, np.nan))
    grid = Grid((mean + reference).reshape(rows, cols), float(x0), float(y0), float(node_m), survey.crs, std.reshape(rows, cols))
    return SurveyGrid(grid, std.reshape(rows, cols), count.reshape(rows, cols), dict(survey.skipped), dict(survey.notes))


def write_survey_grid(result: SurveyGrid, path: str | os.PathLike, *, history: str = "") -> Path:
    """Write the gridded soundings as CF NetCDF (see the module); returns the path. Written whole, then renamed into place."""
    import xarray as xr

    from .crs import as_crs

    path = Path(path)
    grid = result.grid
    rows, cols = grid.shape
    x = grid.x0_m + np.arange(cols) * grid.node_m
    y = grid.y0_m + np.arange(rows) * grid.node_m
    crs = as_crs(grid.crs)
    coords = {
        "x": ("x", x, {"units": "m", "standard_name": "projection_x_coordinate", "long_name": "easting", "axis": "X"}),
        "y": ("y", y, {"units": "m", "standard_name": "projection_y_coordinate", "long_name": "northing", "axis": "Y"}),
    }
    common = {"grid_mapping": "crs"}
    ds = xr.Dataset(
        {
            "depth": (("y", "x"), grid.depth_m, {**common, "units": "m", "positive": "down", "standard_name": "sea_floor_depth_below_sea_surface",
                                                 "long_name": "mean depth of the valid soundings per node (no tide)"}),
            "depth_std": (("y", "x"), result.std_m, {**common, "units": "m", "long_name": "sample standard deviation of the soundings per node (ddof 1)"}),
            "count": (("y", "x"), result.count.astype(np.int32), {**common, "long_name": "number of valid soundings per node"}),
            "crs": ((), np.int32(0), {"crs_wkt": crs.to_wkt(), "spatial_ref": crs.to_wkt(), "epsg_code": crs.to_string()}),
        },
        coords=coords,
        attrs={"Conventions": "CF-1.8", "title": "bathymetry gridded from multibeam soundings by lost grid",
               "node_m": grid.node_m, "history": history},
    )
    encoding = {name: {"zlib": True, "complevel": 4, "_FillValue": np.nan} for name in ("depth", "depth_std")}
    encoding["count"] = {"zlib": True, "complevel": 4, "_FillValue": None}
    encoding.update({name: {"_FillValue": None} for name in ("x", "y")})
    partial = path.with_name(path.name + ".partial")
    try:
        ds.to_netcdf(partial, engine="netcdf4", format="NETCDF4", encoding=encoding)
        os.replace(partial, path)
    finally:
        partial.unlink(missing_ok=True)
    return path
