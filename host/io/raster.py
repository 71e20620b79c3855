"""GeoTIFF and ESRI ASCII grids through rasterio, and GMT's native float grids: values, coordinates and CRS."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .bounds import _window
from .crs import _agree
from .depthsign import _ascending, _sign_from_metadata, _to_depth
from .filecheck import read_gmt_native
from .uncertainty import check_sigma_layer


def _read_raster(path: Path, *, positive: str | None, source_crs: str | None, bounds, nodata):
    """Band 1 as depth, coordinates, CRS, and a BAG's uncertainty layer (None for other rasters, or a BAG without one)."""
    from rasterio.errors import RasterioError

    try:
        values, xs, ys, file_crs, description, tags, sigma = _raster_values(path, bounds)
    except (RasterioError, OSError) as error:
        # GDAL reports a cut-off strip or tile as a read error of a block: name the file and say what it means.
        raise ValueError(f"{path.name} cannot be read as a raster, it is truncated or damaged ({' '.join(str(error).split())})") from None
    file_crs = _agree(path, file_crs, source_crs)
    hint = _sign_from_metadata({"positive": tags.get("positive", ""), "long_name": description}, "")
    values = _to_depth(values, positive or hint, path.name, "band 1", nodata)
    if sigma is not None:
        sigma, _, _ = _ascending(check_sigma_layer(sigma, values, path.name, "uncertainty"), xs, ys, path.name)
    return (*_ascending(values, xs, ys, path.name), file_crs, sigma)


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
        window = Window.from_slices((sy.start, sy.stop), (sx.start, sx.stop))
        band = src.read(1, masked=True, window=window)
        # Packed rasters store integers with a scale and offset; nodata is masked before they apply.
        scale, offset = src.scales[0], src.offsets[0]
        values = np.ma.filled(band.astype(np.float64) * scale + offset, np.nan)
        file_crs = src.crs.to_string() if src.crs else None
        description = (src.descriptions[0] or "") if src.descriptions else ""
        tags = src.tags(1)
        layers = [d or "" for d in src.descriptions]
        sigma = None
        if src.driver == "BAG" and "uncertainty" in layers:
            sigma = np.ma.filled(src.read(layers.index("uncertainty") + 1, masked=True, window=window).astype(np.float64), np.nan)
    return values, xs, ys, file_crs, description, tags, sigma


def _read_gmt_native(path: Path, kind: str, *, positive, source_crs, bounds, nodata):
    values, xs, ys, header = read_gmt_native(path, kind)
    geographic = any(word in header["x_units"].lower() for word in ("degree", "lon"))
    file_crs = _agree(path, "EPSG:4326" if geographic else None, source_crs)
    if bounds is not None:
        sx, sy = _window(xs, bounds[0], bounds[2], path, "x"), _window(ys, bounds[1], bounds[3], path, "y")
        values, xs, ys = values[sy, sx], xs[sx], ys[sy]
    hint = _sign_from_metadata({"long_name": header["z_units"]}, "")
    values = _to_depth(values, positive or hint, path.name, f"the GMT native grid ({kind.split(':')[1]})", nodata)
    return (*_ascending(values, xs, ys, path.name), file_crs, None)


