"""Sonar detections in and out: the documented CSV layout, read with named errors and counted skips.

The detection log
    A CSV file with a header row, one row per detection, ``#`` comment lines allowed; column names
    are matched without regard to case or surrounding spaces.

    ===================  ========  ===========================================================
    column               required  meaning
    ===================  ========  ===========================================================
    ``ping``             yes       ping number (integer); the rows of one ping are consecutive
    ``t_s``              yes       time of the ping, seconds, strictly increasing from ping to
                                   ping, equal on every row of a ping
    ``platform_x_m``     one pair  sonar (platform GPS) easting, metres, equal within a ping
    ``platform_y_m``     of these  sonar northing, metres, equal within a ping
    ``platform_lat``     or these  or latitude and longitude, degrees (WGS 84), projected with
    ``platform_lon``               pyproj to ``crs`` (default: the UTM zone of the first fix)
    ``heading_deg``      yes       sonar axis (platform heading), degrees clockwise from north
                                   (grid north with x/y; true north with lat/lon, turned to grid
                                   north by the meridian convergence at each fix)
    ``range_m``          yes       detection range, metres
    ``bearing_deg``      yes       detection bearing from the sonar's axis, degrees, positive to
                                   starboard (clockwise)
    ``strength_db``      no        detection strength, dB above the detection threshold (the
                                   tracker's amplitude model weighs it; NaN where not given)
    ===================  ========  ===========================================================

    A ping with no detection is one row whose ``range_m`` and ``bearing_deg`` are both empty: a
    quiet ping still moves the platform and still counts as a ping the filters step through.

Errors and skips
    A missing file or column (a position pair counts as one), a non-numeric or empty required cell
    (other than the quiet-ping pair), a latitude or longitude out of range, a ping number that goes
    back or repeats after another ping, rows of one ping disagreeing on time or platform, or time not
    increasing from ping to ping raise ``ValueError`` naming the file, the
    column and the line. Detections outside the sonar's sector (beyond ``max_range_m``, negative
    range, or a bearing beyond ``half_fov_deg``) are dropped and counted in the :class:`DetectionReport`
    by reason, never silently.
"""

from __future__ import annotations

import csv
import dataclasses
import math
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .geometry import Sonar, polar_to_world

__all__ = ["Ping", "DetectionReport", "read_detections", "write_detections", "DETECTION_COLUMNS", "WRITTEN_COLUMNS"]

_REQUIRED = ("ping", "t_s", "heading_deg", "range_m", "bearing_deg")
_POSITIONS = (("platform_x_m", "platform_y_m"), ("platform_lat", "platform_lon"))
_OPTIONAL = ("strength_db",)
DETECTION_COLUMNS = ("ping", "t_s", *_POSITIONS[0], *_POSITIONS[1], "heading_deg", "range_m", "bearing_deg", *_OPTIONAL)
#: The columns write_detections writes (metric positions).
WRITTEN_COLUMNS = ("ping", "t_s", *_POSITIONS[0], "heading_deg", "range_m", "bearing_deg", *_OPTIONAL)
_PER_PING = ("t_s", "x", "y", "heading_deg")
#: The unit checks judge logs of at least this many detections (fewer cannot tell a unit from a narrow scene).
UNIT_CHECK_MIN = 20


@dataclass(frozen=True, eq=False)
class Ping:
    """One transmit/receive cycle: where the sonar was and what it detected.

    Attributes
    ----------
    index : int
        Ping number.
    t_s : float
        Time, seconds.
    platform_xy : ndarray, shape (2,)
        Sonar position, east and north, metres.
    heading_deg : float
        Sonar axis, degrees clockwise from north.
    range_m, bearing_deg : ndarray, shape (n,)
        The detections (bearing from the axis, positive to starboard).
    strength_db : ndarray, shape (n,)
        Detection strengths, NaN where not given.
    """

    index: int
    t_s: float
    platform_xy: np.ndarray
    heading_deg: float
    range_m: np.ndarray
    bearing_deg: np.ndarray
    strength_db: np.ndarray = field(default_factory=lambda: np.empty(0))

    def __post_init__(self) -> None:
        object.__setattr__(self, "platform_xy", np.asarray(self.platform_xy, dtype=float).reshape(2))
        for name in ("range_m", "bearing_deg"):
            object.__setattr__(self, name, np.asarray(getattr(self, name), dtype=float).reshape(-1))
        if self.range_m.shape != self.bearing_deg.shape:
            raise ValueError(f"Ping {self.index}: {self.range_m.size} ranges but {self.bearing_deg.size} bearings.")
        strength = np.asarray(self.strength_db, dtype=float).reshape(-1)
        object.__setattr__(self, "strength_db", strength if strength.size else np.full(self.range_m.size, np.nan))

    @property
    def detections(self) -> int:
        """How many detections the ping holds."""
        return int(self.range_m.size)

    def detections_xy(self) -> np.ndarray:
        """The detections' world positions, shape (n, 2), metres."""
        return polar_to_world(self.platform_xy, self.heading_deg, self.range_m, self.bearing_deg)


@dataclass(frozen=True)
class DetectionReport:
    """What reading a detection log kept and what it dropped, by reason."""

    path: str
    rows: int
    pings: int
    detections: int
    beyond_range: int = 0
    negative_range: int = 0
    outside_field_of_view: int = 0
    unknown_columns: tuple[str, ...] = ()
    crs: str = ""

    @property
    def dropped(self) -> int:
        """Detections dropped for lying outside the sector."""
        return self.beyond_range + self.negative_range + self.outside_field_of_view

    def summary(self) -> str:
        """A few lines of plain text for the command line."""
        lines = [f"{self.path}: {self.rows} rows, {self.pings} pings, {self.detections} detections kept"]
        for label, count in (
            ("beyond the sonar's range", self.beyond_range),
            ("at a negative range", self.negative_range),
            ("outside the field of view", self.outside_field_of_view),
        ):
            if count:
                lines.append(f"  dropped {count} detection(s) {label}")
        if self.unknown_columns:
            lines.append("  unknown columns, not read: " + ", ".join(self.unknown_columns))
        if self.crs:
            lines.append(f"  note: latitude/longitude projected to {self.crs}; headings turned from true to grid north")
        return "\n".join(lines)


def _number(text: str, column: str, where: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{where}: {column} is not a number: {text!r}") from None
    if not math.isfinite(value):
        raise ValueError(f"{where}: {column} must be a finite number, got {text!r}")
    return value


def _header(reader: Iterable[list[str]], path: Path) -> tuple[dict[str, int], tuple[str, ...], bool, int]:
    """Column indices, unknown columns, whether positions are latitude/longitude, and the header's width."""
    for line in reader:
        if line and not line[0].lstrip().startswith("#"):
            names = [name.strip().lower() for name in line]
            break
    else:
        raise ValueError(f"{path}: no header row (expected columns {', '.join(_REQUIRED)} and a position pair)")
    missing = [name for name in _REQUIRED if name not in names]
    pairs = [pair for pair in _POSITIONS if all(name in names for name in pair)]
    if not pairs:
        missing.append("platform_x_m/platform_y_m (or platform_lat/platform_lon)")
    if missing:
        raise ValueError(f"{path} lacks the required column(s) {', '.join(missing)} (layout: lost.host.track.detections)")
    geographic = pairs[0] == _POSITIONS[1]  # x/y first when both are given
    unknown = tuple(name for name in names if name not in DETECTION_COLUMNS)
    columns = {name: names.index(name) for name in DETECTION_COLUMNS if name in names}
    x, y = ("platform_lon", "platform_lat") if geographic else pairs[0]  # x east, y north
    columns["x"], columns["y"] = columns[x], columns[y]
    return columns, unknown, geographic, len(names)


def _project(pings: list[Ping], crs: str | None, path: Path) -> tuple[list[Ping], str]:
    """Latitude/longitude (stored in platform_xy as lon, lat) to a metric CRS; headings to grid north."""
    from pyproj import CRS, Proj, Transformer
    from pyproj.aoi import AreaOfInterest
    from pyproj.database import query_utm_crs_info

    lon = np.array([p.platform_xy[0] for p in pings])
    lat = np.array([p.platform_xy[1] for p in pings])
    if crs is None:
        aoi = AreaOfInterest(lon[0], lat[0], lon[0], lat[0])
        crs = f"EPSG:{query_utm_crs_info(datum_name='WGS 84', area_of_interest=aoi)[0].code}"
    target = CRS.from_user_input(crs)
    if not target.is_projected:
        raise ValueError(f"{path}: crs {crs!r} is not a projected (metric) CRS")
    x, y = Transformer.from_crs("EPSG:4326", target, always_xy=True).transform(lon, lat)
    convergence = Proj(target).get_factors(lon, lat).meridian_convergence  # grid north is this far east of true north
    projected = [dataclasses.replace(p, platform_xy=np.array([x[i], y[i]]), heading_deg=float(p.heading_deg - convergence[i]))
                 for i, p in enumerate(pings)]
    return projected, crs


class _PingBuilder:
    """Collects the rows of one ping and checks they agree on time and platform."""

    def __init__(self, index: int, values: dict[str, float], where: str, columns: dict[str, str]) -> None:
        self.index, self.values, self.where, self.columns = index, values, where, columns
        self.detections: list[tuple[float, float, float]] = []

    def add(self, values: dict[str, float], where: str) -> None:
        for name in _PER_PING:
            if values[name] != self.values[name]:
                column = self.columns.get(name, name)
                raise ValueError(f"{where}: {column} {values[name]!r} differs from {self.values[name]!r} on the first row of ping {self.index} ({self.where})")

    def build(self) -> Ping:
        rows = np.array(self.detections, dtype=float).reshape(-1, 3)
        v = self.values
        return Ping(self.index, v["t_s"], (v["x"], v["y"]), v["heading_deg"], rows[:, 0], rows[:, 1], rows[:, 2])


def _check_units(pings: Sequence[Ping], sonar: Sonar, path: Path) -> None:
    """Refuse bearings in radians and ranges in kilometres (module docstring, Units)."""
    bearings = np.concatenate([p.bearing_deg for p in pings])
    ranges = np.concatenate([p.range_m for p in pings])
    if bearings.size < UNIT_CHECK_MIN:
        return
    half_fov_rad = math.radians(sonar.half_fov_deg)
    if np.max(np.abs(bearings)) <= half_fov_rad:
        raise ValueError(
            f"{path}: bearing_deg: all {bearings.size} bearings lie within +/-{half_fov_rad:.3g}, the sonar's +/-{sonar.half_fov_deg:g} deg "
            "in radians: are the bearings in radians? give degrees (or, for a sector truly that narrow, its half field of view)"
        )
    if np.max(ranges) <= sonar.max_range_m / 1000.0:
        raise ValueError(
            f"{path}: range_m: all {ranges.size} ranges lie within {sonar.max_range_m / 1000.0:g}, the sonar's {sonar.max_range_m:g} m "
            "in kilometres: are the ranges in kilometres? give metres (or, for a sonar truly that short, its maximum range)"
        )


def _add_detection(current: _PingBuilder, cells: dict[str, str], where: str, sonar: Sonar, counts: dict[str, int]) -> None:
    """One detection row into its ping, or counted by the reason it lies outside the sector."""
    range_m = _number(cells["range_m"], "range_m", where)
    bearing_deg = _number(cells["bearing_deg"], "bearing_deg", where)
    strength = _number(cells["strength_db"], "strength_db", where) if cells.get("strength_db") else math.nan
    if range_m < 0:
        counts["negative_range"] += 1
    elif range_m > sonar.max_range_m:
        counts["beyond_range"] += 1
    elif abs(bearing_deg) > sonar.half_fov_deg:
        counts["outside_field_of_view"] += 1
    else:
        current.detections.append((range_m, bearing_deg, strength))


def read_detections(path: str | os.PathLike, *, sonar: Sonar | None = None, crs: str | None = None) -> tuple[list[Ping], DetectionReport]:
    """Read a detection log (layout in the module docstring) into pings and a report.

    Parameters
    ----------
    path : path-like
        The CSV file.
    sonar : Sonar, optional
        The sector detections must lie in (default: the paper's 500 m, +/-45 degrees).
    crs : str, optional
        The projected CRS latitude/longitude positions go to (default: the UTM zone of the first fix);
        unused with x/y positions.

    Returns
    -------
    pings : list of Ping
        In time order, quiet pings included.
    report : DetectionReport
        Rows read, detections kept, detections dropped by reason.

    Raises
    ------
    ValueError
        On a missing column, a bad cell, pings out of order, or bearings in radians or ranges in kilometres
        (see the module docstring).
    FileNotFoundError
        When the file does not exist.
    """
    path = Path(path)
    sonar = sonar or Sonar()
    counts = {"beyond_range": 0, "negative_range": 0, "outside_field_of_view": 0}
    pings: list[Ping] = []
    current: _PingBuilder | None = None
    seen: set[int] = set()
    rows = 0
    with path.open(newline="") as handle:
        reader = csv.reader(handle)
        columns, unknown, geographic, width = _header(reader, path)
        names = {"x": "platform_lon" if geographic else "platform_x_m", "y": "platform_lat" if geographic else "platform_y_m"}
        for line in reader:
            if not line or not "".join(line).strip() or line[0].lstrip().startswith("#"):
                continue
            rows += 1
            where = f"{path}, line {reader.line_num}"
            if len(line) > width:
                raise ValueError(f"{where}: {len(line)} cells but the header names {width} columns")
            cells = {name: (line[i].strip() if i < len(line) else "") for name, i in columns.items()}
            values = {name: _number(cells[name], names.get(name, name), where) for name in ("ping", "t_s", "x", "y", "heading_deg")}
            if geographic and not (-90 <= values["y"] <= 90 and -180 <= values["x"] <= 360):
                raise ValueError(f"{where}: platform_lat/platform_lon {values['y']!r}, {values['x']!r} are not a latitude and longitude")
            ping = int(values["ping"])
            if ping != values["ping"]:
                raise ValueError(f"{where}: ping must be an integer, got {cells['ping']!r}")
            if current is None or ping != current.index:
                if ping in seen:
                    raise ValueError(f"{where}: ping {ping} appears again after other pings (the rows of a ping must be consecutive)")
                if current is not None:
                    if ping < current.index:
                        raise ValueError(f"{where}: ping {ping} comes after ping {current.index} (ping numbers must increase)")
                    if values["t_s"] <= current.values["t_s"]:
                        raise ValueError(f"{where}: t_s {values['t_s']!r} of ping {ping} does not increase on ping {current.index}'s {current.values['t_s']!r}")
                    pings.append(current.build())
                seen.add(ping)
                current = _PingBuilder(ping, values, where, names)
            else:
                current.add(values, where)
            if cells["range_m"] == "" and cells["bearing_deg"] == "":
                continue  # a quiet ping
            _add_detection(current, cells, where, sonar, counts)
    if current is not None:
        pings.append(current.build())
    if not pings:
        raise ValueError(f"{path} holds a header but no ping")
    _check_units(pings, sonar, path)
    projected_to = ""
    if geographic:
        pings, projected_to = _project(pings, crs, path)
    kept = sum(p.detections for p in pings)
    return pings, DetectionReport(str(path), rows, len(pings), kept, unknown_columns=unknown, crs=projected_to, **counts)


def write_detections(path: str | os.PathLike, pings: Sequence[Ping]) -> Path:
    """Write pings in the documented layout (a quiet ping as one row with empty range and bearing)."""
    path = Path(path)
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(WRITTEN_COLUMNS)
        for ping in pings:
            head = [ping.index, repr(ping.t_s), repr(float(ping.platform_xy[0])), repr(float(ping.platform_xy[1])), repr(ping.heading_deg)]
            if ping.detections == 0:
                writer.writerow([*head, "", "", ""])
            for r, b, s in zip(ping.range_m, ping.bearing_deg, ping.strength_db):
                writer.writerow([*head, repr(float(r)), repr(float(b)), "" if math.isnan(s) else repr(float(s))])
    return path
