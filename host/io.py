"""Bathymetry files in, :class:`~lost.host.grid.Grid` out (and a ``.npz`` cache back out).

:func:`read_grid` reads the formats surveys and public models come in and returns a grid in a
projected metric frame, depth positive down, row 0 at the south edge:

========================  =======================================================================
file                      how it is read
========================  =======================================================================
``.xyz .txt .csv``        ASCII soundings, one per line: ``x y z`` or ``lon lat z`` (whitespace,
                          comma or semicolon separated, ``#`` comments, optional header naming the
                          columns). Scattered soundings are gridded (below).
``.nc .grd .nc4 .cdf``    GMT or GEBCO NetCDF through xarray (classic and NetCDF-4 files; also
                          GMT's pre-4.1 layout with ``x_range``, ``dimension`` and a 1-D ``z``).
``.tif .tiff``            GeoTIFF through rasterio, band 1, with its CRS, transform and nodata.
``.asc``                  ESRI ASCII grid (EMODnet ships these) through rasterio, with a ``.prj``
                          beside it for the CRS.
GMT native (any name)     GMT's ``=bf``/``=bd`` binary grids (892-byte header, then the values,
                          north row first); the integer ones (``=bs``, ``=bi``, ``=bb``) and Surfer
                          grids are refused with the command that converts them (:mod:`~lost.host.filecheck`).
``.npz``                  LOST's own cache, written by :func:`write_npz`; keys ``depth_m`` (2-D,
                          row 0 south), ``x0_m``, ``y0_m``, ``node_m`` and ``crs`` (a CRS string,
                          empty for a local frame).
========================  =======================================================================

``bounds=(west, south, east, north)``, in the file's own coordinates, reads only a window (from
NetCDF and GeoTIFF without loading the rest), so a region can be cut from a global GEBCO grid.

Binary files are recognised by content (NetCDF, HDF5, TIFF and zip signatures, GMT's native
header), so a GMT ``.grd`` that is really NetCDF reads whatever its name; text files by extension.

Damaged files
    A NetCDF file shorter than its header says (classic: every variable's extent; NetCDF-4: the HDF5
    superblock's end of file) is refused as truncated, naming both sizes; a NetCDF or GeoTIFF the
    library cannot read is named with the library's reason. Values farther from sea level than any
    sea floor (:data:`lost.host.filecheck.DEEPEST_M`) are refused, with a hint when they look like an
    undeclared nodata value (``nodata=``).

Coordinates
    A grid in geographic coordinates (longitude/latitude: CF ``degrees_east`` units, ``lon``/``lat``
    names, a geographic GeoTIFF CRS, or ``source_crs``) is projected with pyproj to ``crs``, by default
    the WGS 84 UTM zone of the grid's centre, and resampled (bilinear, scipy) onto square nodes of
    ``node_m`` aligned to multiples of ``node_m``. A projected grid is kept node for node when its nodes
    are already square and ``crs``/``node_m`` ask for nothing else; otherwise it is resampled the same
    way. ``node_m`` defaults to the file's finer node spacing in metres at the grid's centre.

Depth sign
    Grids store elevation (GEBCO, most GMT grids: negative under the sea) or depth (positive down).
    The sign is taken from, in order: the ``positive=`` argument; the CF ``positive`` attribute; the
    variable's name, standard name or long name (``depth`` means down; ``elevation``, ``height``,
    ``altitude``, ``topo`` mean up); and last the data itself (a negative median means elevation of a
    sea floor). Elevations are negated to depth. The ``lost.host.io`` logger says which: at INFO when
    metadata decided, at WARNING when the data's sign did (a guess the user should see; ``lost run``
    puts it in the run's summary). Data holding both signs in earnest (a median of zero or more
    with at least ``MIXED_SIGN_SHARE`` below zero: mostly land with some sea) are refused without
    metadata or ``positive``: the data cannot tell.

Holes
    Holes stay holes: NaN in ``Grid.depth_m`` (nodata values, NaN cells, nodes outside a reprojected
    footprint, nodes with no sounding within ``max_gap_m``). Resampling never fills them: a resampled
    node is NaN when any source node carrying interpolation weight is a hole. Making a hole-free image
    for the correlator is the map preparation's job (``lost.host.nav``), not the reader's.

Gridding scattered soundings
    Soundings are projected to the metric frame, duplicates at the same position averaged, then
    interpolated linearly over their Delaunay triangulation (scipy) onto the nodes; a node whose
    nearest sounding is farther than ``max_gap_m`` (default ``node_m``) is NaN, and so, when
    ``max_gap_m`` is not given, is a node whose triangle has a side longer than two nodes (it spans a
    hole or a concave edge of the survey): gaps between survey lines are not invented. Soundings on a regular lattice (a gridded export, ``grd2xyz``, at least
    half its nodes present) are read node for node instead, so a missing node stays a hole exactly
    (unless ``max_gap_m`` is given, which asks for the triangulation's bridging). ``node_m`` defaults to the median distance between neighbouring
    soundings. Lines whose depth is NaN (GMT writes holes so) are skipped and the count is logged.
"""

from __future__ import annotations

import logging
import math
import os
import re
from pathlib import Path

import numpy as np

from .filecheck import GMT_NATIVE_HEADER_BYTES, check_plausible, check_whole, native_format, read_gmt_native
from .grid import Grid

__all__ = ["read_grid", "write_npz", "utm_crs", "GRID_SUFFIXES"]

log = logging.getLogger(__name__)

_XYZ_SUFFIXES = (".xyz", ".txt", ".csv")
_NETCDF_SUFFIXES = (".nc", ".grd", ".nc4", ".cdf")
_TIFF_SUFFIXES = (".tif", ".tiff")
_ESRI_ASCII_SUFFIXES = (".asc",)
GRID_SUFFIXES = _XYZ_SUFFIXES + _NETCDF_SUFFIXES + _TIFF_SUFFIXES + _ESRI_ASCII_SUFFIXES + (".npz",)

# Above this many nodes a grid is almost surely a mistaken node_m (1e8 float64 nodes are 800 MB).
_MAX_NODES = 100_000_000

# Names seen in GMT, GEBCO, SRTM15+, EMODnet and GDAL-converted NetCDF files, most specific first.
_DEPTH_VARIABLES = ("elevation", "depth", "z", "Band1", "topo", "bathymetry", "height", "altitude")
_X_NAMES = ("lon", "longitude", "x", "easting", "east", "x_m")
_Y_NAMES = ("lat", "latitude", "y", "northing", "north", "y_m")
_Z_NAMES = ("z", "depth", "depth_m", "elevation", "elevation_m", "height", "altitude", "topo", "bathymetry")
_GEOGRAPHIC_NAMES = {"lon", "longitude", "lat", "latitude"}
_DOWN_WORDS = ("depth",)
_UP_WORDS = ("elevation", "height", "altitude", "topo")


def read_grid(
    path: str | os.PathLike,
    *,
    crs: str | None = None,
    node_m: float | None = None,
    source_crs: str | None = None,
    variable: str | None = None,
    positive: str | None = None,
    max_gap_m: float | None = None,
    bounds: tuple[float, float, float, float] | None = None,
    nodata: float | None = None,
) -> Grid:
    """Read a bathymetry file into a projected, square-node :class:`Grid`.

    Parameters
    ----------
    path : path-like
        The file; its format is recognised by content (binary formats) or extension (see the module
        docstring for the table).
    crs : str, optional
        The projected CRS of the result (anything ``pyproj.CRS.from_user_input`` takes). Default: the
        file's own CRS when it is projected, else the WGS 84 UTM zone of the grid's centre.
    node_m : float, optional
        Node spacing of the result, metres. Default: the file's finer spacing in metres (gridded
        files) or the median neighbour distance (soundings).
    source_crs : str, optional
        The CRS of the file's coordinates when the file does not carry one (XYZ text, NetCDF without
        grid mapping). Not allowed to contradict a CRS the file declares.
    variable : str, optional
        The NetCDF variable holding the grid; default: the first of the common names found.
    positive : {"down", "up"}, optional
        Whether the file's values are depths (positive down) or elevations (positive up). Default:
        from metadata, names, then the data's median sign (module docstring, "Depth sign").
    max_gap_m : float, optional
        Soundings only: the farthest a node may be from its nearest sounding and still get a depth.
        Default ``node_m``.
    bounds : (west, south, east, north), optional
        Read only the nodes (or soundings) inside this box, given in the file's own coordinates
        (degrees for a geographic file, as its longitudes run): a region of a global GEBCO grid without
        loading the whole file.
    nodata : float, optional
        A value of the file that marks a hole, when the file does not declare one (a 16-bit GeoTIFF
        written without a nodata tag holds -32768 there); in the file's units, before any sign change.

    Returns
    -------
    Grid
        Depth in metres, positive down, NaN holes, row 0 south.

    Raises
    ------
    ValueError
        The format is unknown, a required variable, column or key is missing (the message names what
        was found), coordinates are not monotonic, the CRS is ambiguous or contradictory, or the
        result would be empty or absurdly large; the file is truncated or unreadable (named, with the
        library's reason); it holds values farther from sea level than any sea floor (an undeclared
        nodata value: see ``nodata``); its sign is not in its metadata and its data hold both signs in
        earnest (pass ``positive``); it is a format LOST does not read (GMT's integer native grids,
        Surfer grids), named with how to convert it.
    FileNotFoundError
        The file does not exist.
    """
    grid = _read_any(
        Path(path), crs=crs, node_m=node_m, source_crs=source_crs, variable=variable, positive=positive,
        max_gap_m=max_gap_m, bounds=bounds, nodata=nodata,
    )
    if not np.isfinite(grid.depth_m).any():
        raise ValueError(
            f"no node of the grid read from {Path(path).name} has a depth: the file (or its bounds window) is all "
            "holes, max_gap_m is too small for the soundings, or the file's frame is not what it says"
        )
    return grid


def _read_any(path: Path, *, crs, node_m, source_crs, variable, positive, max_gap_m, bounds, nodata) -> Grid:
    if not path.is_file():
        raise FileNotFoundError(f"no bathymetry file at {path}")
    if positive not in (None, "down", "up"):
        raise ValueError(f"positive must be 'down', 'up' or None, got {positive!r}")
    for name, value in (("node_m", node_m), ("max_gap_m", max_gap_m)):
        if value is not None and not (np.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be a positive number of metres, got {value!r}")
    if bounds is not None:
        bounds = _check_bounds(bounds)
    if nodata is not None and not (isinstance(nodata, int | float) and not isinstance(nodata, bool) and math.isfinite(nodata)):
        raise ValueError(f"nodata must be a finite number (the file's hole value), got {nodata!r}")
    kind = _format_of(path)
    if kind == "npz":
        if variable is not None or positive is not None or source_crs is not None or nodata is not None:
            raise ValueError("an .npz grid is already depth in a known frame; variable, positive, source_crs and nodata do not apply")
        grid = _read_npz(path)
        if grid.crs is None and crs is not None:
            raise ValueError(f"{path.name} is in a local frame (no CRS), so it cannot be projected to crs={crs!r}")
        if bounds is None and (crs is None or _same_crs(crs, grid.crs)) and node_m in (None, grid.node_m):
            return grid
        rows, cols = grid.shape
        ys = grid.y0_m + np.arange(rows) * grid.node_m
        xs = grid.x0_m + np.arange(cols) * grid.node_m
        values = grid.depth_m
        if bounds is not None:
            sx, sy = _window(xs, bounds[0], bounds[2], path, "x"), _window(ys, bounds[1], bounds[3], path, "y")
            values, xs, ys = values[sy, sx], xs[sx], ys[sy]
        return _regular_to_grid(values, xs, ys, grid.crs, crs=crs, node_m=node_m)
    if kind == "xyz":
        if variable is not None:
            raise ValueError("variable= names a NetCDF variable; an XYZ file has columns x, y, z")
        return _read_xyz(
            path, crs=crs, node_m=node_m, source_crs=source_crs, positive=positive, max_gap_m=max_gap_m, bounds=bounds, nodata=nodata
        )
    if max_gap_m is not None:
        raise ValueError("max_gap_m applies to scattered soundings (XYZ files), not to gridded files")
    if kind == "netcdf":
        values, xs, ys, file_crs = _read_netcdf(
            path, variable=variable, positive=positive, source_crs=source_crs, bounds=bounds, nodata=nodata
        )
    elif kind.startswith("gmt:"):
        if variable is not None:
            raise ValueError("variable= names a NetCDF variable; a GMT native binary grid holds one")
        values, xs, ys, file_crs = _read_gmt_native(path, kind, positive=positive, source_crs=source_crs, bounds=bounds, nodata=nodata)
    else:
        if variable is not None:
            raise ValueError("variable= names a NetCDF variable; a GeoTIFF or ESRI ASCII grid is read from its band 1")
        values, xs, ys, file_crs = _read_raster(path, positive=positive, source_crs=source_crs, bounds=bounds, nodata=nodata)
    return _regular_to_grid(values, xs, ys, file_crs, crs=crs, node_m=node_m)


def write_npz(grid: Grid, path: str | os.PathLike) -> Path:
    """Cache a grid as ``.npz`` (keys ``depth_m``, ``x0_m``, ``y0_m``, ``node_m``, ``crs``).

    :func:`read_grid` reads it back bit for bit. Returns the path written (``.npz`` is appended by
    NumPy when missing, so the returned path is the one to read).
    """
    path = Path(path)
    if path.suffix != ".npz":
        path = path.with_name(path.name + ".npz")
    np.savez_compressed(
        path,
        depth_m=grid.depth_m,
        x0_m=np.float64(grid.x0_m),
        y0_m=np.float64(grid.y0_m),
        node_m=np.float64(grid.node_m),
        crs=np.str_(grid.crs or ""),
    )
    return path


def utm_crs(lon_deg: float, lat_deg: float) -> str:
    """The WGS 84 UTM zone containing a point, as ``"EPSG:326zz"`` (north) or ``"EPSG:327zz"`` (south)."""
    from pyproj.aoi import AreaOfInterest
    from pyproj.database import query_utm_crs_info

    if not (-180 <= lon_deg <= 360 and -90 <= lat_deg <= 90):
        raise ValueError(f"({lon_deg}, {lat_deg}) is not a longitude/latitude in degrees")
    lon = (lon_deg + 180) % 360 - 180
    found = query_utm_crs_info(datum_name="WGS 84", area_of_interest=AreaOfInterest(lon, lat_deg, lon, lat_deg))
    if not found:
        raise ValueError(f"no WGS 84 UTM zone contains ({lon_deg}, {lat_deg}); pass crs= explicitly")
    # A point on a zone boundary lies in two zones; the list order is the database's, so pick by code.
    codes = sorted(info.code for info in found if info.code.startswith(("326", "327")))
    return f"EPSG:{codes[0]}"


# --------------------------------------------------------------------------------------------
# format recognition


def _format_of(path: Path) -> str:
    with path.open("rb") as f:
        magic = f.read(8)
    if magic.startswith(b"CDF") or magic.startswith(b"\x89HDF"):
        check_whole(path)
        return "netcdf"
    if magic[:4] in (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+"):
        check_whole(path)
        return "raster"
    if magic.startswith(b"PK"):
        if path.suffix.lower() != ".npz":
            raise ValueError(f"{path.name} is a zip archive; only .npz grids written by write_npz are read as zip")
        return "npz"
    native = native_format(path)
    if native is not None and native.startswith("gmt:"):
        return native
    if native is not None:
        raise ValueError(
            f"{path.name} is a {native.split(':', 1)[1]}, which LOST does not read; convert it to NetCDF or GeoTIFF, e.g. "
            f"gdal_translate -of netCDF '{path.name}' {path.stem}.nc, or gmt grdconvert '{path.name}=sf' {path.stem}.nc"
        )
    suffix = path.suffix.lower()
    if suffix in _XYZ_SUFFIXES:
        return "xyz"
    if suffix in _ESRI_ASCII_SUFFIXES:
        if not magic.lower().startswith(b"ncols"):
            raise ValueError(f"{path.name} has an .asc name but no ESRI ASCII grid header (it starts {magic!r})")
        return "raster"
    if suffix in _NETCDF_SUFFIXES + _TIFF_SUFFIXES + (".npz",):
        hint = ""
        if suffix == ".grd" and path.stat().st_size > GMT_NATIVE_HEADER_BYTES:
            hint = "; a GMT native binary grid (=bf, =bs, ...) is recognised by its 892-byte header, which this file's is not either"
        raise ValueError(f"{path.name} has a {suffix} name but its content is not {suffix[1:]} (first bytes {magic!r}){hint}")
    raise ValueError(f"cannot read {path.name}: unknown grid format {suffix!r}; LOST reads {', '.join(GRID_SUFFIXES)}")


# --------------------------------------------------------------------------------------------
# readers: each returns values[y, x] with ascending coordinate vectors, or a Grid


def _read_npz(path: Path) -> Grid:
    with np.load(path, allow_pickle=False) as data:
        missing = [k for k in ("depth_m", "x0_m", "y0_m", "node_m") if k not in data.files]
        if missing:
            raise ValueError(f"{path.name} lacks the key(s) {', '.join(missing)}; it has {', '.join(data.files) or 'none'}")
        crs = str(data["crs"]) if "crs" in data.files else ""
        return Grid(
            depth_m=np.array(data["depth_m"], dtype=np.float64),
            x0_m=float(data["x0_m"]),
            y0_m=float(data["y0_m"]),
            node_m=float(data["node_m"]),
            crs=crs or None,
        )


def _read_netcdf(path: Path, *, variable: str | None, positive: str | None, source_crs: str | None, bounds, nodata):
    try:
        values, xs, ys, geographic, file_crs, sign_hint, variable = _netcdf_values(path, variable, bounds)
    except (OSError, RuntimeError, KeyError, IndexError) as error:
        # netCDF4/HDF5 report a damaged file as "NetCDF: HDF error" and the like: name the file and say what it means.
        raise ValueError(f"{path.name} cannot be read as NetCDF, it is truncated or damaged ({type(error).__name__}: {error})") from None
    if geographic:
        if file_crs is not None and not _crs(file_crs).is_geographic:
            raise ValueError(f"{path.name}: coordinates are in degrees but the grid mapping says {file_crs}")
        file_crs = file_crs or "EPSG:4326"
    file_crs = _agree(path, file_crs, source_crs)
    values = _to_depth(values, positive or sign_hint, path.name, variable, nodata)
    return (*_ascending(values, xs, ys, path.name), file_crs)


def _netcdf_values(path: Path, variable: str | None, bounds):
    import xarray as xr

    with xr.open_dataset(path, engine="netcdf4", mask_and_scale=True, decode_times=False) as ds:
        two_d = [name for name, v in ds.data_vars.items() if v.ndim == 2]
        if variable is None and not two_d and _LEGACY_GMT_VARIABLES <= set(ds.variables):
            values, xs, ys, geographic, sign_hint = _legacy_gmt(ds, path)
            variable, file_crs = "z", None
            if bounds is not None:
                sx, sy = _window(xs, bounds[0], bounds[2], path, "x"), _window(ys, bounds[1], bounds[3], path, "y")
                values, xs, ys = values[sy, sx], xs[sx], ys[sy]
        else:
            values, xs, ys, geographic, file_crs, sign_hint, variable = _cf_grid(ds, path, variable, two_d, bounds)
    return values, xs, ys, geographic, file_crs, sign_hint, variable


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
            f"LOST needs the node positions in coordinate variables ({', '.join(_X_NAMES)} / {', '.join(_Y_NAMES)})"
        )
    xs = np.asarray(ds[x_name].values, dtype=np.float64)
    ys = np.asarray(ds[y_name].values, dtype=np.float64)
    x_geographic, y_geographic = _is_geographic(ds[x_name], x_name), _is_geographic(ds[y_name], y_name)
    if x_geographic != y_geographic:
        raise ValueError(f"{path.name}: one coordinate ({x_name}, {y_name}) is geographic and the other is not")
    file_crs = _netcdf_crs(ds, da)
    if bounds is not None:
        sx, sy = _window(xs, bounds[0], bounds[2], path, x_name), _window(ys, bounds[1], bounds[3], path, y_name)
        da, xs, ys = da.isel({x_dim: sx, y_dim: sy}), xs[sx], ys[sy]
    values = np.asarray(da.values, dtype=np.float64)  # the file is read here, and only the window
    return values, xs, ys, x_geographic, file_crs, _sign_from_metadata(da.attrs, variable), variable


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
    return name.lower() in _GEOGRAPHIC_NAMES or units.startswith("degree") or standard in ("longitude", "latitude")


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
                    return _crs(attrs[key]).to_string()
            if attrs.get("epsg_code"):
                return str(attrs["epsg_code"])
    return None


def _sign_from_metadata(attrs: dict, variable: str) -> str | None:
    cf_positive = str(attrs.get("positive", "")).lower()
    if cf_positive in ("down", "up"):
        return cf_positive
    words = " ".join(str(s).lower() for s in (variable, attrs.get("standard_name", ""), attrs.get("long_name", "")))
    if any(w in words for w in _DOWN_WORDS):
        return "down"
    if any(w in words for w in _UP_WORDS):
        return "up"
    return None


def _read_raster(path: Path, *, positive: str | None, source_crs: str | None, bounds, nodata):
    from rasterio.errors import RasterioError

    try:
        values, xs, ys, file_crs, description, tags = _raster_values(path, bounds)
    except (RasterioError, OSError) as error:
        # GDAL reports a cut-off strip or tile as a read error of a block: name the file and say what it means.
        raise ValueError(f"{path.name} cannot be read as a raster, it is truncated or damaged ({' '.join(str(error).split())})") from None
    file_crs = _agree(path, file_crs, source_crs)
    hint = _sign_from_metadata({"positive": tags.get("positive", ""), "long_name": description}, "")
    values = _to_depth(values, positive or hint, path.name, "band 1", nodata)
    return (*_ascending(values, xs, ys, path.name), file_crs)


def _raster_values(path: Path, bounds):
    import rasterio
    from rasterio.windows import Window

    with rasterio.open(path) as src:
        t = src.transform
        if t.b != 0 or t.d != 0:
            raise ValueError(f"{path.name} is rotated or sheared (transform {tuple(t)[:6]}); LOST reads north-up rasters only")
        # rasterio's transform maps pixel corners; a value belongs to its pixel's centre.
        xs = t.c + (np.arange(src.width) + 0.5) * t.a
        ys = t.f + (np.arange(src.height) + 0.5) * t.e
        sx, sy = slice(0, src.width), slice(0, src.height)
        if bounds is not None:
            sx, sy = _window(xs, bounds[0], bounds[2], path, "x"), _window(ys, bounds[1], bounds[3], path, "y")
            xs, ys = xs[sx], ys[sy]
        band = src.read(1, masked=True, window=Window.from_slices((sy.start, sy.stop), (sx.start, sx.stop)))
        # Packed rasters store integers with a scale and offset; nodata is masked before they apply.
        scale, offset = src.scales[0], src.offsets[0]
        values = np.ma.filled(band.astype(np.float64) * scale + offset, np.nan)
        file_crs = src.crs.to_string() if src.crs else None
        description = (src.descriptions[0] or "") if src.descriptions else ""
        tags = src.tags(1)
    return values, xs, ys, file_crs, description, tags


def _read_gmt_native(path: Path, kind: str, *, positive, source_crs, bounds, nodata):
    values, xs, ys, header = read_gmt_native(path, kind)
    geographic = any(word in header["x_units"].lower() for word in ("degree", "lon"))
    file_crs = _agree(path, "EPSG:4326" if geographic else None, source_crs)
    if bounds is not None:
        sx, sy = _window(xs, bounds[0], bounds[2], path, "x"), _window(ys, bounds[1], bounds[3], path, "y")
        values, xs, ys = values[sy, sx], xs[sx], ys[sy]
    hint = _sign_from_metadata({"long_name": header["z_units"]}, "")
    values = _to_depth(values, positive or hint, path.name, f"the GMT native grid ({kind.split(':')[1]})", nodata)
    return (*_ascending(values, xs, ys, path.name), file_crs)


def _read_xyz(path: Path, *, crs, node_m, source_crs, positive, max_gap_m, bounds, nodata) -> Grid:
    import pandas as pd

    first = _first_data_line(path)
    sep = "," if "," in first else ";" if ";" in first else r"\s+"
    tokens = [t for t in re.split(r"[\s,;]+", first.strip()) if t]
    has_header = not all(_is_number(t) for t in tokens)
    table = pd.read_csv(path, sep=sep, comment="#", header=0 if has_header else None, skip_blank_lines=True)
    if has_header:
        columns = {str(c).strip().lower(): c for c in table.columns}
        picked = []
        for role, names in (("x", _X_NAMES), ("y", _Y_NAMES), ("z", _Z_NAMES)):
            name = next((columns[n] for n in names if n in columns), None)
            if name is None:
                raise ValueError(
                    f"{path.name}: no {role} column; expected one of {', '.join(names)}, found {', '.join(map(str, table.columns))}"
                )
            picked.append(name)
        x_col, y_col, z_col = picked
        geographic = str(x_col).strip().lower() in _GEOGRAPHIC_NAMES
        sign_hint = _sign_from_metadata({}, str(z_col))
    else:
        if table.shape[1] != 3:
            raise ValueError(f"{path.name}: a headerless XYZ file has 3 columns (x y z), this one has {table.shape[1]}")
        x_col, y_col, z_col = table.columns
        geographic = None
        sign_hint = None
    try:
        x, y, z = (pd.to_numeric(table[c], errors="raise").to_numpy(np.float64) for c in (x_col, y_col, z_col))
    except (ValueError, TypeError) as exc:
        raise ValueError(f"{path.name}: a non-numeric value in the x, y, z columns ({exc})") from None
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        bad = int(np.flatnonzero(~(np.isfinite(x) & np.isfinite(y)))[0])
        raise ValueError(f"{path.name}: sounding {bad + 1} has no position (NaN or empty x/y)")
    if bounds is not None:
        inside = (x >= bounds[0]) & (x <= bounds[2]) & (y >= bounds[1]) & (y <= bounds[3])
        x, y, z = x[inside], y[inside], z[inside]
    keep = np.isfinite(z)
    if not keep.all():
        log.warning("%s: skipped %d of %d soundings with no depth (NaN)", path.name, int((~keep).sum()), z.size)
        x, y, z = x[keep], y[keep], z[keep]
    if z.size < 3:
        raise ValueError(f"{path.name}: {z.size} sounding(s) with a depth; gridding needs at least 3")

    if source_crs is not None:
        if geographic is not None and geographic != _crs(source_crs).is_geographic:
            raise ValueError(f"{path.name}: the column names say {'lon/lat' if geographic else 'x/y'}, source_crs says {source_crs}")
        file_crs = _crs(source_crs).to_string()
    elif geographic:
        file_crs = "EPSG:4326"
    elif geographic is None and np.all(np.abs(x) <= 360) and np.all(np.abs(y) <= 90):
        raise ValueError(
            f"{path.name}: a headerless file whose coordinates could be longitude/latitude or metres; "
            "name the columns (lon lat z / x y z) or pass source_crs="
        )
    else:
        file_crs = None
    z = _to_depth(z, positive or sign_hint, path.name, f"column {z_col!r}" if has_header else "the third (z) column", nodata)
    keep = np.isfinite(z)  # nodata made holes: a hole is the absence of a sounding
    x, y, z = x[keep], y[keep], z[keep]
    lattice = _lattice(x, y, z) if max_gap_m is None else None
    if lattice is not None:
        # Gridded soundings (grd2xyz): read node for node, so a missing node stays a hole, exactly, and
        # nothing lies past the data's edge. (An explicit max_gap_m asks for the triangulation's bridging.)
        return _regular_to_grid(*lattice, file_crs, crs=crs, node_m=node_m)

    target = _target_crs(file_crs, crs, x, y)
    if file_crs is not None and target is not None and not _same_crs(file_crs, target):
        x, y = _transformer(file_crs, target).transform(x, y)
        x, y = np.asarray(x), np.asarray(y)
    return _grid_soundings(x, y, z, node_m=node_m, max_gap_m=max_gap_m, crs=target, name=path.name)


def _check_bounds(bounds) -> tuple[float, float, float, float]:
    try:
        west, south, east, north = (float(v) for v in bounds)
    except (TypeError, ValueError):
        raise ValueError(f"bounds must be four numbers (west, south, east, north), got {bounds!r}") from None
    if not (np.all(np.isfinite([west, south, east, north])) and west < east and south < north):
        raise ValueError(f"bounds must be finite with west < east and south < north, got {bounds!r}")
    return west, south, east, north


def _window(coords: np.ndarray, lo: float, hi: float, path: Path, axis: str) -> slice:
    """The contiguous index range of monotonic coordinates inside [lo, hi]."""
    inside = np.flatnonzero((coords >= lo) & (coords <= hi))
    if inside.size < 2:
        raise ValueError(
            f"{path.name}: bounds {lo:g} to {hi:g} hold {inside.size} node(s) of {axis}, whose values run "
            f"{coords.min():g} to {coords.max():g}; a grid needs at least 2"
        )
    return slice(int(inside[0]), int(inside[-1]) + 1)


def _first_data_line(path: Path) -> str:
    with path.open("r", encoding="utf-8", errors="replace") as f:
        for line in f:
            if line.strip() and not line.lstrip().startswith("#"):
                return line
    raise ValueError(f"{path.name} holds no data lines")


def _is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


# --------------------------------------------------------------------------------------------
# shared steps


#: A share of values on the other side of zero from the median above which the data's sign is no guide.
MIXED_SIGN_SHARE = 0.1


def _to_depth(values: np.ndarray, positive: str | None, name: str, variable: str, nodata: float | None = None) -> np.ndarray:
    """The file's values as depth (positive down): holes for ``nodata``, implausible values refused, the sign applied."""
    if nodata is not None:
        values = np.where(values == nodata, np.nan, values)
    check_plausible(values, name, variable)
    if positive is None:
        positive = _sign_from_data(values, name, variable)
    if positive == "up":
        log.info("%s: %s is elevation (positive up); negated to depth (positive down)", name, variable)
        return -values
    return values


def _sign_from_data(values: np.ndarray, name: str, variable: str) -> str:
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        raise ValueError(f"{name}: {variable} holds no finite value")
    median = float(np.median(finite))
    below, above = float(np.mean(finite < 0)), float(np.mean(finite > 0))
    if median >= 0 and below >= MIXED_SIGN_SHARE:
        # Mostly land at +60 m with sea at -40 m, or a depth grid with much ground above its datum: the median cannot tell.
        raise ValueError(
            f"{name}: {variable} has no sign convention in its metadata and holds both signs in earnest ({above:.0%} above zero, "
            f"{below:.0%} below): elevation over mostly land or depth with dry ground, the data cannot tell; "
            "pass positive='up' (elevation, as GEBCO) or 'down' (depth), --positive on the command line"
        )
    positive = "up" if median < 0 else "down"
    # A guess from the data, so it is said at WARNING (Python prints it even when logging is not set up,
    # and the command line puts it in the run's report).
    log.warning(
        "%s: %s has no sign convention in its metadata; its median is %s, so it is read as %s "
        "(pass positive='up' or 'down', --positive on the command line, to say otherwise)",
        name, variable, f"{median:g}", "elevation (negated to depth)" if positive == "up" else "depth",
    )
    return positive


def _ascending(values: np.ndarray, xs: np.ndarray, ys: np.ndarray, name: str):
    """Flip so both coordinate vectors ascend (north-up files become row 0 south)."""
    for _axis, coords, label in ((1, xs, "x"), (0, ys, "y")):
        if coords.size > 1:
            steps = np.diff(coords)
            if not (np.all(steps > 0) or np.all(steps < 0)):
                raise ValueError(f"{name}: the {label} coordinates are not strictly monotonic")
    if xs.size > 1 and xs[1] < xs[0]:
        values, xs = values[:, ::-1], xs[::-1]
    if ys.size > 1 and ys[1] < ys[0]:
        values, ys = values[::-1, :], ys[::-1]
    return np.ascontiguousarray(values), xs, ys


def _crs(value):
    from pyproj import CRS

    try:
        return CRS.from_user_input(value)
    except Exception as exc:  # pyproj raises its own CRSError; name the input
        raise ValueError(f"not a CRS pyproj understands: {value!r} ({exc})") from None


def _same_crs(a, b) -> bool:
    if a is None or b is None:
        return a is b
    return _crs(a) == _crs(b)


def _agree(path: Path, file_crs: str | None, source_crs: str | None) -> str | None:
    if source_crs is None:
        return file_crs
    if file_crs is not None and not _same_crs(file_crs, source_crs):
        raise ValueError(f"{path.name} declares {file_crs}; source_crs={source_crs!r} contradicts it")
    return _crs(source_crs).to_string()


def _transformer(src, dst):
    from pyproj import Transformer

    return Transformer.from_crs(_crs(src), _crs(dst), always_xy=True)


def _target_crs(file_crs: str | None, crs: str | None, xs: np.ndarray, ys: np.ndarray) -> str | None:
    if crs is not None:
        target = _crs(crs)
        if not target.is_projected:
            raise ValueError(f"crs must be a projected (metric) CRS, got {crs!r}")
        if file_crs is None:
            raise ValueError("the file's coordinates have no CRS to project from; pass source_crs= as well as crs=")
        return crs if isinstance(crs, str) else target.to_string()
    if file_crs is None:
        return None
    if _crs(file_crs).is_geographic:
        lon_c = (float(np.min(xs)) + float(np.max(xs))) / 2
        lat_c = (float(np.min(ys)) + float(np.max(ys))) / 2
        return utm_crs(lon_c, lat_c)
    return file_crs


def _regular_to_grid(values, xs, ys, file_crs, *, crs, node_m) -> Grid:
    """A regular (possibly geographic, possibly non-square) grid onto square metric nodes."""
    target = _target_crs(file_crs, crs, xs, ys)
    reproject = file_crs is not None and target is not None and not _same_crs(file_crs, target)
    if xs.size < 2 or ys.size < 2:
        raise ValueError(f"a grid needs at least 2 x 2 nodes to be georeferenced, got {ys.size} x {xs.size}")
    dx, dy = (float(c[-1] - c[0]) / (c.size - 1) for c in (xs, ys))
    # Uniform when every node lies within a thousandth of a node, or a float32 rounding, of its place:
    # float32 coordinate variables (common in NetCDF) must not force a resampling.
    slack_x, slack_y = _slack(xs, dx), _slack(ys, dy)
    uniform = _off_place(xs, dx) <= slack_x and _off_place(ys, dy) <= slack_y
    if not reproject:
        # Square when one spacing, the better known of the two, puts every node of both axes within its slack.
        node = dx if slack_x / (xs.size - 1) <= slack_y / (ys.size - 1) else dy
        square = abs(node - dx) * (xs.size - 1) <= slack_x and abs(node - dy) * (ys.size - 1) <= slack_y
        if uniform and square and (node_m is None or math.isclose(node_m, node, rel_tol=1e-9)):
            return Grid(depth_m=values, x0_m=float(xs[0]), y0_m=float(ys[0]), node_m=node, crs=target)
        node_m = node_m or min(dx, dy)
        x_lo, x_hi, y_lo, y_hi = xs[0], xs[-1], ys[0], ys[-1]
        transformer = None
    else:
        transformer = _transformer(file_crs, target)
        if node_m is None:
            # The file's finer spacing, measured in metres at its centre.
            xc, yc = xs[xs.size // 2], ys[ys.size // 2]
            px, py = transformer.transform([xc, xc + dx, xc], [yc, yc, yc + dy])
            node_m = min(math.hypot(px[1] - px[0], py[1] - py[0]), math.hypot(px[2] - px[0], py[2] - py[0]))
        x_lo, y_lo, x_hi, y_hi = transformer.transform_bounds(xs[0], ys[0], xs[-1], ys[-1], densify_pts=101)
    x0 = math.ceil(x_lo / node_m - 1e-9) * node_m
    y0 = math.ceil(y_lo / node_m - 1e-9) * node_m
    cols = math.floor((x_hi - x0) / node_m + 1e-9) + 1
    rows = math.floor((y_hi - y0) / node_m + 1e-9) + 1
    if rows < 1 or cols < 1:
        raise ValueError(f"node_m={node_m} m leaves no node inside the grid's extent")
    if rows * cols > _MAX_NODES:
        raise ValueError(f"node_m={node_m:g} m would make a {rows} x {cols} grid; pass a coarser node_m")
    node_x = x0 + np.arange(cols) * node_m
    node_y = y0 + np.arange(rows) * node_m
    qx, qy = np.meshgrid(node_x, node_y)
    if transformer is not None:
        from pyproj.enums import TransformDirection

        qx, qy = transformer.transform(qx, qy, direction=TransformDirection.INVERSE)
        if _crs(file_crs).is_geographic:
            # PROJ answers longitudes in [-180, 180); a file may run 0 to 360.
            qx = xs[0] + np.mod(np.asarray(qx) - xs[0], 360.0)
    depth = _interpolate_keeping_holes(values, xs, ys, np.asarray(qx), np.asarray(qy))
    return Grid(depth_m=depth, x0_m=float(x0), y0_m=float(y0), node_m=float(node_m), crs=target)


def _slack(coords: np.ndarray, step: float) -> float:
    return max(1e-3 * abs(step), float(np.spacing(np.float32(np.max(np.abs(coords))))))


def _off_place(coords: np.ndarray, step: float) -> float:
    """How far the farthest node lies from a uniform spacing of ``step``."""
    return float(np.max(np.abs(coords - (coords[0] + np.arange(coords.size) * step))))


def _interpolate_keeping_holes(values, xs, ys, qx, qy) -> np.ndarray:
    """Bilinear interpolation; NaN wherever a hole carries weight or the point lies outside."""
    from scipy.interpolate import RegularGridInterpolator

    holes = np.isnan(values)
    filled = np.where(holes, 0.0, values)
    points = np.stack([qy.ravel(), qx.ravel()], axis=-1)
    depth = RegularGridInterpolator((ys, xs), filled, bounds_error=False, fill_value=np.nan)(points)
    if holes.any():
        hole_weight = RegularGridInterpolator((ys, xs), holes.astype(np.float64), bounds_error=False, fill_value=1.0)(points)
        depth[hole_weight > 1e-9] = np.nan
    return depth.reshape(qx.shape)


def _lattice(x: np.ndarray, y: np.ndarray, z: np.ndarray):
    """``(values, xs, ys)`` when the soundings sit on a regular lattice (a gridded export), holes NaN; else None."""
    xs, ys = np.unique(x), np.unique(y)
    if xs.size < 2 or ys.size < 2:
        return None
    dx, dy = float(np.min(np.diff(xs))), float(np.min(np.diff(ys)))
    col, row = (x - xs[0]) / dx, (y - ys[0]) / dy
    on_lattice = np.allclose(col, np.round(col), rtol=0, atol=1e-3) and np.allclose(row, np.round(row), rtol=0, atol=1e-3)
    cols, rows = int(round((xs[-1] - xs[0]) / dx)) + 1, int(round((ys[-1] - ys[0]) / dy)) + 1
    # Mostly full, or scattered soundings written with few decimals would pass for a fine lattice.
    if not on_lattice or x.size < 0.5 * rows * cols or rows * cols > _MAX_NODES:
        return None
    r, c = np.round(row).astype(np.int64), np.round(col).astype(np.int64)
    sums, counts = np.zeros((rows, cols)), np.zeros((rows, cols))
    np.add.at(sums, (r, c), z)
    np.add.at(counts, (r, c), 1)  # repeated soundings of a node: their mean
    with np.errstate(invalid="ignore"):
        values = np.where(counts > 0, sums / counts, np.nan)
    return values, xs[0] + np.arange(cols) * dx, ys[0] + np.arange(rows) * dy


def _grid_soundings(x, y, z, *, node_m, max_gap_m, crs, name) -> Grid:
    import pandas as pd
    from scipy.interpolate import LinearNDInterpolator
    from scipy.spatial import Delaunay, QhullError, cKDTree
    from threadpoolctl import threadpool_limits

    # Repeated positions would make a degenerate triangulation; their mean is the honest depth.
    merged = pd.DataFrame({"x": x, "y": y, "z": z}).groupby(["x", "y"], sort=False, as_index=False)["z"].mean()
    x, y, z = (merged[c].to_numpy() for c in ("x", "y", "z"))
    if z.size < 3:
        raise ValueError(f"{name}: soundings at {z.size} distinct position(s); gridding needs at least 3")
    tree = cKDTree(np.column_stack([x, y]))
    if node_m is None:
        node_m = float(np.median(tree.query(np.column_stack([x, y]), k=2)[0][:, 1]))
    # By default a triangle may not bridge more than two nodes; an explicit max_gap_m is the user's one rule.
    longest_side_m = 2 * node_m if max_gap_m is None else math.inf
    max_gap_m = node_m if max_gap_m is None else max_gap_m
    x0 = math.ceil(x.min() / node_m - 1e-9) * node_m
    y0 = math.ceil(y.min() / node_m - 1e-9) * node_m
    cols = math.floor((x.max() - x0) / node_m + 1e-9) + 1
    rows = math.floor((y.max() - y0) / node_m + 1e-9) + 1
    if rows * cols > _MAX_NODES:
        raise ValueError(f"{name}: node_m={node_m:g} m would make a {rows} x {cols} grid; pass a coarser node_m")
    qx, qy = np.meshgrid(x0 + np.arange(cols) * node_m, y0 + np.arange(rows) * node_m)
    # Only nodes with a sounding within max_gap_m get a depth; the others stay holes, never interpolated.
    gap = tree.query(np.column_stack([qx.ravel(), qy.ravel()]), k=1, distance_upper_bound=max_gap_m * (1 + 1e-9))[0]
    near = np.isfinite(gap).reshape(qx.shape)
    depth = np.full(qx.shape, np.nan)
    try:
        # Delaunay's barycentric transforms call LAPACK once per triangle, where BLAS threads only
        # contend (20 times slower on a busy 2-core machine).
        with threadpool_limits(limits=1, user_api="blas"):
            triangles = Delaunay(np.column_stack([x, y]))
            # A triangle with a side longer than two nodes spans a hole or a concave edge of the survey:
            # the nodes it covers are not bridged, even when one of its corners is near.
            corners = triangles.points[triangles.simplices]
            longest = np.max(np.hypot(*(corners - np.roll(corners, 1, axis=1)).transpose(2, 0, 1)), axis=1)
            within = triangles.find_simplex(np.column_stack([qx[near], qy[near]]))
            bridged = np.zeros(qx.shape, dtype=bool)
            bridged[near] = (within >= 0) & (longest[within] <= longest_side_m * (1 + 1e-9))
            depth[bridged] = LinearNDInterpolator(triangles, z)(qx[bridged], qy[bridged])
    except QhullError:
        raise ValueError(f"{name}: the soundings cannot be triangulated (are they all on one line?)") from None
    return Grid(depth_m=depth, x0_m=float(x0), y0_m=float(y0), node_m=float(node_m), crs=crs)
