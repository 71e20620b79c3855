"""Coordinate reference systems: the UTM zone of a point, parsing, comparison, the target CRS of a grid; small local
offsets between geographic positions in metres."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

# Coordinate names seen in XYZ headers and NetCDF files.
X_NAMES = ("lon", "longitude", "x", "easting", "east", "x_m")
Y_NAMES = ("lat", "latitude", "y", "northing", "north", "y_m")
GEOGRAPHIC_NAMES = {"lon", "longitude", "lat", "latitude"}


#: The sphere of small local offsets between geographic positions (seconds of motion, a swath's width): its error
#: against the ellipsoid, under 0.5 %, is far below what such offsets are used for.
EARTH_RADIUS_M = 6_371_000.0


def offset_metres(dlat_deg, dlon_deg, lat_deg: float):
    """North and east metres of a small latitude and longitude difference at ``lat_deg`` (arrays or scalars)."""
    north = np.radians(dlat_deg) * EARTH_RADIUS_M
    east = np.radians(dlon_deg) * EARTH_RADIUS_M * math.cos(math.radians(lat_deg))
    return north, east


def offset_degrees(north_m, east_m, lat_deg: float):
    """Latitude and longitude differences of a small north and east offset at ``lat_deg`` (arrays or scalars)."""
    dlat = np.degrees(np.asarray(north_m, dtype=float) / EARTH_RADIUS_M)
    dlon = np.degrees(np.asarray(east_m, dtype=float) / (EARTH_RADIUS_M * max(math.cos(math.radians(lat_deg)), 1e-6)))
    return dlat, dlon


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
def as_crs(value):
    """``value`` (an EPSG code, WKT, PROJ string or pyproj CRS) as a pyproj CRS; a ValueError naming it when pyproj cannot read it."""
    from pyproj import CRS

    try:
        return CRS.from_user_input(value)
    except Exception as exc:  # pyproj raises its own CRSError; name the input
        raise ValueError(f"not a CRS pyproj understands: {value!r} ({exc})") from None


def _same_crs(a, b) -> bool:
    if a is None or b is None:
        return a is b
    return as_crs(a) == as_crs(b)


def _agree(path: Path, file_crs: str | None, source_crs: str | None) -> str | None:
    if source_crs is None:
        return file_crs
    if file_crs is not None and not _same_crs(file_crs, source_crs):
        raise ValueError(f"{path.name} declares {file_crs}; source_crs={source_crs!r} contradicts it")
    return as_crs(source_crs).to_string()


def transformer(src, dst):
    from pyproj import Transformer

    return Transformer.from_crs(as_crs(src), as_crs(dst), always_xy=True)


def _target_crs(file_crs: str | None, crs: str | None, xs: np.ndarray, ys: np.ndarray) -> str | None:
    if crs is not None:
        target = as_crs(crs)
        if not target.is_projected:
            raise ValueError(f"crs must be a projected (metric) CRS, got {crs!r}")
        if file_crs is None:
            raise ValueError("the file's coordinates have no CRS to project from; pass source_crs= as well as crs=")
        return crs if isinstance(crs, str) else target.to_string()
    if file_crs is None:
        return None
    if as_crs(file_crs).is_geographic:
        lon_c = (float(np.min(xs)) + float(np.max(xs))) / 2
        lat_c = (float(np.min(ys)) + float(np.max(ys))) / 2
        return utm_crs(lon_c, lat_c)
    return file_crs


