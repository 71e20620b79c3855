"""Bathymetry grid files in, :class:`~lost.host.grid.Grid` out (and a ``.npz`` cache back out).

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
``.bag``                  BAG (HDF5) through GDAL's BAG driver: the elevation layer as depth;
                          :func:`lost.host.io.bag.read_bag` reads its uncertainty layer too.
GMT native (any name)     GMT's ``=bf``/``=bd`` binary grids (892-byte header, then the values,
                          north row first); the integer ones (``=bs``, ``=bi``, ``=bb``) and Surfer
                          grids are refused with the command that converts them (:mod:`~lost.host.io.filecheck`).
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
    sea floor (:data:`lost.host.io.filecheck.DEEPEST_M`) are refused, with a hint when they look like an
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
from pathlib import Path

import numpy as np

from ..grid import Grid
from .bounds import _check_bounds, _window
from .crs import _same_crs
from .filecheck import GMT_NATIVE_HEADER_BYTES, check_whole, native_format
from .gridding import _regular_to_grid
from .netcdf import _read_netcdf
from .raster import _read_gmt_native, _read_raster
from .xyz import _read_xyz

__all__ = ["read_grid", "write_npz", "GRID_SUFFIXES"]

log = logging.getLogger(__name__)

_XYZ_SUFFIXES = (".xyz", ".txt", ".csv")
_NETCDF_SUFFIXES = (".nc", ".grd", ".nc4", ".cdf")
_TIFF_SUFFIXES = (".tif", ".tiff")
_ESRI_ASCII_SUFFIXES = (".asc",)
_BAG_SUFFIXES = (".bag",)
GRID_SUFFIXES = _XYZ_SUFFIXES + _NETCDF_SUFFIXES + _TIFF_SUFFIXES + _ESRI_ASCII_SUFFIXES + _BAG_SUFFIXES + (".npz",)


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
        values, sigma = grid.depth_m, grid.sigma_m
        if bounds is not None:
            sx, sy = _window(xs, bounds[0], bounds[2], path, "x"), _window(ys, bounds[1], bounds[3], path, "y")
            values, xs, ys = values[sy, sx], xs[sx], ys[sy]
            sigma = None if sigma is None else sigma[sy, sx]
        return _regular_to_grid(values, xs, ys, grid.crs, crs=crs, node_m=node_m, sigma=sigma)
    if kind == "xyz":
        if variable is not None:
            raise ValueError("variable= names a NetCDF variable; an XYZ file has columns x, y, z")
        return _read_xyz(
            path, crs=crs, node_m=node_m, source_crs=source_crs, positive=positive, max_gap_m=max_gap_m, bounds=bounds, nodata=nodata
        )
    if max_gap_m is not None:
        raise ValueError("max_gap_m applies to scattered soundings (XYZ files), not to gridded files")
    if kind == "netcdf":
        values, xs, ys, file_crs, sigma = _read_netcdf(
            path, variable=variable, positive=positive, source_crs=source_crs, bounds=bounds, nodata=nodata
        )
    elif kind.startswith("gmt:"):
        if variable is not None:
            raise ValueError("variable= names a NetCDF variable; a GMT native binary grid holds one")
        values, xs, ys, file_crs, sigma = _read_gmt_native(path, kind, positive=positive, source_crs=source_crs, bounds=bounds, nodata=nodata)
    else:
        if variable is not None:
            raise ValueError("variable= names a NetCDF variable; a GeoTIFF or ESRI ASCII grid is read from its band 1")
        values, xs, ys, file_crs, sigma = _read_raster(path, positive=positive, source_crs=source_crs, bounds=bounds, nodata=nodata)
    return _regular_to_grid(values, xs, ys, file_crs, crs=crs, node_m=node_m, sigma=sigma)


def write_npz(grid: Grid, path: str | os.PathLike) -> Path:
    """Cache a grid as ``.npz`` (keys ``depth_m``, ``x0_m``, ``y0_m``, ``node_m``, ``crs``, and ``sigma_m`` when it has one).

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
        **({} if getattr(grid, "sigma_m", None) is None else {"sigma_m": grid.sigma_m}),
    )
    return path


# format recognition


def _format_of(path: Path) -> str:
    with path.open("rb") as f:
        magic = f.read(8)
    if magic.startswith(b"\x89HDF") and path.suffix.lower() == ".bag":
        check_whole(path)
        return "raster"  # GDAL's BAG driver: band 1 is the elevation, named so (its sign follows)
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
    if suffix in _NETCDF_SUFFIXES + _TIFF_SUFFIXES + _BAG_SUFFIXES + (".npz",):
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
            sigma_m=np.array(data["sigma_m"], dtype=np.float64) if "sigma_m" in data.files else None,
        )
