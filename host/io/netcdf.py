"""NetCDF grids (GMT, GEBCO, CF, GMT's pre-4.1 layout) through xarray: values, coordinates, CRS and sign hints."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .bounds import _window
from .crs import GEOGRAPHIC_NAMES, X_NAMES, Y_NAMES, _agree, as_crs
from .depthsign import _ascending, _sign_from_metadata, _to_depth
from .errors import UncertaintyLayerError
from .uncertainty import check_sigma_layer, check_units, sigma_variable

# Names seen in GMT, GEBCO, SRTM15+, EMODnet and GDAL-converted NetCDF files, most specific first.
_DEPTH_VARIABLES = ("elevation", "depth", "z", "Band1", "topo", "bathymetry", "height", "altitude")


def _read_netcdf(path: Path, *, variable: str | None, positive: str | None, source_crs: str | None, bounds, nodata):
    """Depth values, coordinates, CRS and the uncertainty layer (None when the file has none; see :mod:`.uncertainty`)."""
    try:
        values, xs, ys, geographic, file_crs, sign_hint, variable, sigma = _netcdf_values(path, variable, bounds)
    except (OSError, RuntimeError, KeyError, IndexError) as error:
        # netCDF4/HDF5 report a damaged file as "NetCDF: HDF error" and the like: name the file and say what it means.
        raise ValueError(f"{path.name} cannot be read as NetCDF, it is truncated or damaged ({type(error).__name__}: {error})") from None
    if geographic:
        if file_crs is not None and not as_crs(file_crs).is_geographic:
            raise ValueError(f"{path.name}: coordinates are in degrees but the grid mapping says {file_crs}")
        file_crs = file_crs or "EPSG:4326"
    file_crs = _agree(path, file_crs, source_crs)
    values = _to_depth(values, positive or sign_hint, path.name, variable, nodata)
    if sigma is not None:
        sigma_name, sigma = sigma
        sigma, _, _ = _ascending(check_sigma_layer(sigma, values, path.name, sigma_name), xs, ys, path.name)
    return (*_ascending(values, xs, ys, path.name), file_crs, sigma)


def _netcdf_values(path: Path, variable: str | None, bounds):
    import xarray as xr

    with xr.open_dataset(path, engine="netcdf4", mask_and_scale=True, decode_times=False) as ds:
        two_d = [name for name, v in ds.data_vars.items() if v.ndim == 2]
        sigma = None
        if variable is None and not two_d and _LEGACY_GMT_VARIABLES <= set(ds.variables):
            values, xs, ys, geographic, sign_hint = _legacy_gmt(ds, path)
            variable, file_crs = "z", None
            if bounds is not None:
                sx, sy = _window(xs, bounds[0], bounds[2], path, "x"), _window(ys, bounds[1], bounds[3], path, "y")
                values, xs, ys = values[sy, sx], xs[sx], ys[sy]
        else:
            values, xs, ys, geographic, file_crs, sign_hint, variable, sigma = _cf_grid(ds, path, variable, two_d, bounds)
    return values, xs, ys, geographic, file_crs, sign_hint, variable, sigma


def _cf_grid(ds, path: Path, variable: str | None, two_d: list[str], bounds):
    """A COARDS/CF grid (GMT 4.1+, GEBCO, GDAL): a 2-D variable on 1-D coordinate variables."""
    if variable is None:
        variable = next((n for n in _DEPTH_VARIABLES if n in two_d), None)
        if variable is None and len(two_d) == 1:
            variable = two_d[0]
        if variable is None:
            raise ValueError(
                f"{path.name}: no depth or elevation variable among the common names "
                f"({', '.join(_DEPTH_VARIABLES)}); its 2-D variables are {', '.join(two_d) or 'none'} "
                f"(all variables: {', '.join(map(str, ds.variables)) or 'none'}); pass variable="
            )
    elif variable not in ds.data_vars:
        raise ValueError(f"{path.name} has no variable {variable!r}; it has {', '.join(map(str, ds.data_vars)) or 'none'}")
    da = ds[variable]
    if da.ndim != 2:
        raise ValueError(f"{path.name}: {variable!r} has dimensions {da.dims}; a grid has two")
    y_dim, x_dim = da.dims
    x_name, y_name = _coordinate(ds, x_dim), _coordinate(ds, y_dim)
    if x_name is None or y_name is None:
        raise ValueError(
            f"{path.name}: {variable!r} has dimensions {da.dims} without coordinate values; "
            f"LOST needs the node positions in coordinate variables ({', '.join(X_NAMES)} / {', '.join(Y_NAMES)})"
        )
    xs = np.asarray(ds[x_name].values, dtype=np.float64)
    ys = np.asarray(ds[y_name].values, dtype=np.float64)
    x_geographic, y_geographic = _is_geographic(ds[x_name], x_name), _is_geographic(ds[y_name], y_name)
    if x_geographic != y_geographic:
        raise ValueError(f"{path.name}: one coordinate ({x_name}, {y_name}) is geographic and the other is not")
    file_crs = _netcdf_crs(ds, da)
    sigma_name = sigma_variable(ds, variable)
    sigma_da = None if sigma_name is None else ds[sigma_name]
    if sigma_da is not None:
        check_units(sigma_da.attrs, path.name, sigma_name)
        if sigma_da.dims != da.dims:
            shape = " x ".join(str(n) for n in sigma_da.shape)
            raise UncertaintyLayerError(f"{path.name}: the uncertainty layer {sigma_name!r} has dimensions {sigma_da.dims} ({shape} nodes) but the "
                                        f"depth {variable!r} {da.dims} ({' x '.join(str(n) for n in da.shape)}); a layer must match its depth node for node")
    if bounds is not None:
        sx, sy = _window(xs, bounds[0], bounds[2], path, x_name), _window(ys, bounds[1], bounds[3], path, y_name)
        da, xs, ys = da.isel({x_dim: sx, y_dim: sy}), xs[sx], ys[sy]
        sigma_da = None if sigma_da is None else sigma_da.isel({x_dim: sx, y_dim: sy})
    values = np.asarray(da.values, dtype=np.float64)  # the file is read here, and only the window
    sigma = None if sigma_da is None else (sigma_name, np.asarray(sigma_da.values, dtype=np.float64))
    return values, xs, ys, x_geographic, file_crs, _sign_from_metadata(da.attrs, variable), variable, sigma


_LEGACY_GMT_VARIABLES = {"x_range", "y_range", "spacing", "dimension", "z"}


def _legacy_gmt(ds, path: Path):
    """GMT's pre-4.1 NetCDF layout: a 1-D ``z`` stored north row first, its frame in range variables."""
    nx, ny = (int(v) for v in ds["dimension"].values)
    x_min, x_max = (float(v) for v in ds["x_range"].values)
    y_min, y_max = (float(v) for v in ds["y_range"].values)
    z = np.asarray(ds["z"].values, dtype=np.float64)
    if z.size != nx * ny:
        raise ValueError(f"{path.name}: z holds {z.size} values for dimension {nx} x {ny}")
    # Pixel registration (node_offset 1) puts values at cell centres, half a spacing inside the range.
    pixel = int(ds["z"].attrs.get("node_offset", 0)) == 1
    dx = (x_max - x_min) / (nx if pixel else nx - 1)
    dy = (y_max - y_min) / (ny if pixel else ny - 1)
    xs = x_min + (np.arange(nx) + 0.5 * pixel) * dx
    ys = y_max - (np.arange(ny) + 0.5 * pixel) * dy
    units = str(ds["x_range"].attrs.get("units", "")).lower()
    geographic = "degree" in units or "lon" in units
    return z.reshape(ny, nx), xs, ys, geographic, _sign_from_metadata(ds["z"].attrs, "z")


def _coordinate(ds, dim: str) -> str | None:
    if dim in ds.coords or dim in ds.variables:
        return dim
    return None


def _is_geographic(coord, name: str) -> bool:
    units = str(coord.attrs.get("units", "")).lower()
    standard = str(coord.attrs.get("standard_name", "")).lower()
    return name.lower() in GEOGRAPHIC_NAMES or units.startswith("degree") or standard in ("longitude", "latitude")


def _netcdf_crs(ds, da) -> str | None:
    # CF grid mapping (GDAL writes crs_wkt / spatial_ref on it); GMT 6 writes no mapping for lon/lat.
    mapping = da.attrs.get("grid_mapping") or da.encoding.get("grid_mapping")
    candidates = [mapping] if mapping else []
    candidates += ["crs", "spatial_ref", "transverse_mercator"]
    for name in candidates:
        if name in ds.variables:
            attrs = ds[name].attrs
            for key in ("crs_wkt", "spatial_ref"):
                if key in attrs:
                    return as_crs(attrs[key]).to_string()
            if attrs.get("epsg_code"):
                return str(attrs["epsg_code"])
    return None
