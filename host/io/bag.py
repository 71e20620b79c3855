"""BAG grids (Bathymetry Attributed Grid, HDF5) with their uncertainty layer, through GDAL's BAG driver (rasterio).

:func:`read_bag` returns the depth (the BAG's elevation negated: BAG elevations are positive up) and the
uncertainty (metres, one standard deviation as the producer computed it) node for node, row 0 south, holes
(BAG's 1,000,000 no-data value) as NaN in both. A BAG without an uncertainty layer is refused
(:class:`~lost.host.io.errors.MissingLayerError`) unless ``require_uncertainty=False``. ``read_grid`` reads a
``.bag`` as any other grid (the depth alone, resampled on request).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..grid import Grid
from .errors import MissingLayerError, SurveyFileError
from .filecheck import check_whole

__all__ = ["BagGrid", "read_bag"]


@dataclass(frozen=True)
class BagGrid:
    """The depth grid and its per-node uncertainty (metres, NaN holes; None when the file has none and none was required)."""

    grid: Grid
    uncertainty_m: np.ndarray | None


def read_bag(path: str | os.PathLike, *, require_uncertainty: bool = True) -> BagGrid:
    """Depth and uncertainty of a projected, square-node BAG, node for node (see the module)."""
    import rasterio
    from rasterio.errors import RasterioError

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no BAG file at {path}")
    with path.open("rb") as f:
        if f.read(8) != b"\x89HDF\r\n\x1a\n":
            raise SurveyFileError(f"{path.name} is not a BAG (an HDF5 file); its first bytes say otherwise")
    check_whole(path)
    try:
        with rasterio.open(path, driver="BAG") as src:
            layers = [d or "" for d in src.descriptions]
            if "elevation" not in layers:
                raise SurveyFileError(f"{path.name} has no elevation layer (layers: {', '.join(layers) or 'none'})")
            t = src.transform
            if t.b != 0 or t.d != 0 or abs(t.a) != abs(t.e):
                raise SurveyFileError(
                    f"{path.name} has nodes of {abs(t.a):g} x {abs(t.e):g} (or a rotation); read_bag reads square nodes node for node, read_grid resamples"
                )
            if src.crs is None or not _projected(src.crs):
                raise SurveyFileError(f"{path.name} is not in a projected CRS ({src.crs}); read its depth with read_grid, which projects it")
            elevation = src.read(layers.index("elevation") + 1, masked=True).astype(np.float64).filled(np.nan)
            uncertainty = None
            if "uncertainty" in layers:
                uncertainty = src.read(layers.index("uncertainty") + 1, masked=True).astype(np.float64).filled(np.nan)
            elif require_uncertainty:
                raise MissingLayerError(
                    f"{path.name} has no uncertainty layer (layers: {', '.join(layers)}); pass require_uncertainty=False to read the depth alone"
                )
            crs = _horizontal(src.crs)
            node = abs(t.a)
            x0, y_north = t.c + node / 2, t.f - node / 2  # the transform maps pixel corners; a value is its node's
            rows = src.height
    except RasterioError as error:
        raise SurveyFileError(f"{path.name} cannot be read as a BAG, it is truncated or damaged ({' '.join(str(error).split())})") from None
    # GDAL hands rows north first; the house's grids have row 0 south.
    depth = -elevation[::-1]
    if uncertainty is not None:
        uncertainty = uncertainty[::-1].copy()
    return BagGrid(Grid(np.ascontiguousarray(depth), float(x0), float(y_north - (rows - 1) * node), float(node), crs), uncertainty)


def _projected(crs) -> bool:
    from pyproj import CRS

    parsed = CRS.from_wkt(crs.to_wkt())
    horizontal = parsed.sub_crs_list[0] if parsed.is_compound else parsed
    return horizontal.is_projected


def _horizontal(crs) -> str:
    """The horizontal part of a BAG's CRS (GDAL reports a compound CRS with the vertical datum), as EPSG:n when it has one."""
    from pyproj import CRS

    parsed = CRS.from_wkt(crs.to_wkt())
    horizontal = parsed.sub_crs_list[0] if parsed.is_compound else parsed
    code = horizontal.to_epsg()
    return f"EPSG:{code}" if code else horizontal.to_wkt()
