"""Recorded surveys in: a navigation-log CSV (and a sonar side file) to :class:`NavRecords`.

The navigation log
    A CSV file with a header row, one row per record, ``#`` comment lines allowed. Column names are
    matched without regard to case or surrounding spaces; a cell left empty, or ``NaN``, is a missing
    reading: it stays NaN in the records and is counted per column in the :class:`LoadReport` (so are
    the trailing cells of a row cut short; a row with more cells than the header is an error).

    ==========================  ===========  ===================================================
    column(s)                   required     meaning
    ==========================  ===========  ===================================================
    ``t_s``                     one of the   time, seconds, strictly increasing; a row without a
                                time two     time is skipped and reported
    ``time_utc``                             or an ISO 8601 timestamp (a zone suffix is honoured,
                                             none means UTC); ``t_s`` then counts from the first
    ``x_m``, ``y_m``            one of the   ship GPS easting, northing (metres, the map's CRS)
    ``lat``, ``lon``            two pairs    or latitude, longitude (degrees, WGS 84), projected
                                             with pyproj to ``crs`` (the map's CRS)
    ``ship_heading_deg``        yes          degrees clockwise from north
    ``vehicle_depth_m``         yes          pressure depth of the vehicle, metres
    ``altitude_m``              yes          altimeter height above the sea floor, metres
    ``vel_x_mps``, ``vel_y_mps`` one of the  velocity over ground, east and north, m/s
    ``speed_mps``, ``course_deg`` two pairs  or speed over ground and course (clockwise from north)
    ``cable_out_m``             yes          cable paid out, metres
    ``slant_range_m``           no           ship to vehicle, metres (all NaN when absent)
    ``usbl_travel_time_s``      no           one-way USBL travel time, ship transducer to the
                                             vehicle's transponder, seconds; with a sound-speed
                                             profile (``lost run --svp``) the navigation ray-traces
                                             it into the slant range, which then wins over
                                             ``slant_range_m``
    ``usbl_x_m``, ``usbl_y_m``, no (all      the USBL fix of the vehicle (easting, northing in the
    ``usbl_sxx``, ``usbl_syy``, five or      map's CRS, metres) and its covariance (east variance,
    ``usbl_sxy``                none)        north variance, covariance; m**2); a row has all five or
                                             none; only in an ``x_m``/``y_m`` log
    ``truth_x_m``, ``truth_y_m`` no          the vehicle's true position (trials with a
                                             reference, simulations); ``truth_lat``/``truth_lon``
                                             in degrees are projected like the ship's
    ``patch_east_m``,           no           the sonar patch centre's offset from the vehicle,
    ``patch_north_m``                        metres, like the sonar offsets (a patch gathered in
                                             real time lies behind the vehicle); empty: see
                                             ``patch_centre``
    ``patch_age_s``             no           how long before the record the patch's soundings
                                             were taken, on average, seconds (negative: after
                                             it); the filters move a patch by their velocity-
                                             bias estimate times this age. Empty: 0
    ==========================  ===========  ===================================================

    North: with ``x_m``/``y_m`` positions, headings, courses and velocities are in grid axes (grid
    north). With ``lat``/``lon`` they are taken as true (geographic) and turned to grid north by the
    meridian convergence at each record's position, measured with pyproj (up to a few degrees in a
    UTM zone, enough to shift a kilometre of lay-back by tens of metres); so are the sonar offsets.

    Columns outside this table are reported as unknown, not read. When both forms of a pair are
    present, ``x_m``/``y_m`` and ``vel_x_mps``/``vel_y_mps`` are used, and the report says so.

The sonar side file
    A CSV with a header, one sounding per row: ``t_s`` or ``time_utc``, whichever the log has (the time
    of the record it belongs to, matched within ``time_tolerance_s``), or ``record`` (0-based index of the navigation log's data row),
    ``east_m`` and ``north_m`` (offset from the vehicle, metres; grid axes, or true east/north in a
    lat/lon log, see North) and ``depth_m`` (sea-floor
    depth, positive down). Each record's soundings are gridded by :func:`lost.host.io.sonar.grid_soundings`
    into a ``patch_shape`` patch of ``node_m`` nodes around the record's ``patch_east_m``/``patch_north_m``
    or, without them, around the vehicle (``patch_centre="vehicle"``) or the middle of the record's
    soundings (``"soundings"``, for a swath gathered behind the vehicle); a record without soundings
    gets ``None``.
    Soundings matching no record, belonging to a skipped record, lacking a value, or falling beyond
    the patch are counted in the report, never dropped silently.

Writing
    :func:`write_navlog` writes records (a simulated tow, say) in this layout, positions as ``x_m``/``y_m``
    and sonar patches as one sounding per seen node keyed by ``record`` (with ``patch_east_m``/``patch_north_m``
    when a patch is not centred on the vehicle), so :func:`read_navlog` reads them back value for
    value: an example survey to run the command line on. A ``cable_out_m`` of 0 in every record is a
    sonar on the ship itself (a hull-mounted survey, ``lost run --survey``'s records): no lay-back, noted.

Errors
    A missing file, a missing required column, a column named twice (compared without case), a file
    that is not UTF-8 text, a non-numeric cell, latitude/longitude out of range or time not
    increasing raise ``ValueError`` naming the column, data row and file line. So do positions and
    logged velocities that disagree by more than a factor of 100 (times in milliseconds, positions in
    kilometres, a velocity in another unit) and a cable shorter than the depth in every record.

Plausibility
    Comma, semicolon and tab separated files are read (the separator splits the header). Readings no
    tow can give (a negative altitude, cable or range; the vehicle more than 1 m above the surface)
    are set to missing and counted; ship position steps faster than any ship (``MAX_SHIP_SPEED_MPS``),
    records with less cable than depth and ``time_utc`` columns mixing zoned and bare times are
    reported: each is a line of :attr:`LoadReport.warnings`. :func:`check_against_map` checks records
    against the map they are to be navigated on (patch node spacing, positions near the map, with a
    diagnosis of swapped or kilometre positions).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..records import NavRecords
from .csvtable import _Lines, _numeric, _pick_pair, _read_table, _seconds
from .navlog_checks import (
    _USBL_FIX,
    MAX_SHIP_SPEED_MPS,
    _check_motion,
    _check_time,
    _check_zones,
    _impossible_readings,
    _project,
    _usbl_columns,
    _wrap,
    check_against_map,
)
from .navlog_report import LoadReport
from .navlog_sonar import _read_sonar
from .sonar import _check_shape

__all__ = ["LoadReport", "read_navlog", "write_navlog", "check_against_map", "NAVLOG_COLUMNS", "PATCH_CENTRES", "SONAR_COLUMNS",
           "MAX_SHIP_SPEED_MPS"]

_TIME_COLUMNS = ("t_s", "time_utc")
_SINGLE_REQUIRED = ("ship_heading_deg", "vehicle_depth_m", "altitude_m", "cable_out_m")
_POSITION_FORMS = (("x_m", "y_m"), ("lat", "lon"))
_VELOCITY_FORMS = (("vel_x_mps", "vel_y_mps"), ("speed_mps", "course_deg"))
_TRUTH_FORMS = (("truth_x_m", "truth_y_m"), ("truth_lat", "truth_lon"))
_PATCH_CENTRE_FORMS = (("patch_east_m", "patch_north_m"),)
_PATCH_AGE = "patch_age_s"
_OPTIONAL = ("slant_range_m", "usbl_travel_time_s", *_USBL_FIX)
NAVLOG_COLUMNS = (
    _TIME_COLUMNS + _SINGLE_REQUIRED + sum(_POSITION_FORMS, ()) + sum(_VELOCITY_FORMS, ()) + _OPTIONAL + sum(_TRUTH_FORMS, ())
    + sum(_PATCH_CENTRE_FORMS, ()) + (_PATCH_AGE,)
)
#: Where a record's sonar patch is centred when the log has no patch_east_m/patch_north_m for it.
PATCH_CENTRES = ("vehicle", "soundings")
SONAR_COLUMNS = ("t_s", "time_utc", "record", "east_m", "north_m", "depth_m")


def read_navlog(
    path: str | os.PathLike,
    *,
    sonar: str | os.PathLike | None = None,
    crs: str | None = None,
    patch_shape: tuple[int, int] = (10, 10),
    node_m: float | None = None,
    time_tolerance_s: float = 1e-3,
    patch_centre: str = "vehicle",
) -> tuple[NavRecords, LoadReport]:
    """Read a navigation log (and optionally its sonar side file) into records and a report.

    Parameters
    ----------
    path : path-like
        The navigation-log CSV (layout in the module docstring).
    sonar : path-like, optional
        The sonar soundings CSV.
    crs : str, optional
        The map's projected CRS; needed when the log gives positions as ``lat``/``lon``.
    patch_shape : (h, w)
        Sonar patch nodes, north by east.
    node_m : float, optional
        Sonar patch node spacing, metres (the map's); needed with ``sonar``.
    time_tolerance_s : float
        How far a sounding's ``t_s`` may be from its record's time.
    patch_centre : {"vehicle", "soundings"}
        Where a record's patch is centred when the log gives no ``patch_east_m``/``patch_north_m``
        for it: on the vehicle, or on the middle of the record's soundings.

    Returns
    -------
    (NavRecords, LoadReport)

    Raises
    ------
    ValueError
        Missing required columns (named), non-numeric cells, coordinates out of range, time not
        increasing (data row and line named), a lat/lon log without ``crs``, sonar without ``node_m``.
    FileNotFoundError
        A file does not exist.
    """
    path = Path(path)
    h_w = _check_shape(patch_shape)
    _check_options(sonar, node_m, patch_centre, time_tolerance_s)
    table = _read_table(path)
    notes: list[str] = []
    layout = _layout(table, path, notes)
    lines = _Lines(path, len(table))
    values, epoch, zone_warnings = _read_values(table, layout, path, lines, notes)
    values, kept_rows, skipped = _drop_timeless(values, layout.time_column, path, lines)
    nan_counts = _missing_readings(values, layout, notes)
    impossible = _impossible_readings(values, kept_rows, lines, path)
    _note_platform(values, notes)
    geographic = layout.position == ("lat", "lon")
    series, convergence = _motion(values, layout, crs, path, kept_rows, lines, notes)
    sonar_patches, sonar_stats = (), {}
    if sonar is not None:
        sonar_patches, sonar_stats = _read_sonar(
            Path(sonar), record_times=values["t_s"], epoch=epoch, convergence_deg=convergence, kept_rows=kept_rows, rows=len(table),
            patch_shape=h_w, node_m=float(node_m), time_tolerance_s=time_tolerance_s, patch_centre=patch_centre,
            centre_east=values.get("patch_east_m"), centre_north=values.get("patch_north_m"), age_s=values.get(_PATCH_AGE),
        )
    records = NavRecords(**series, sonar=sonar_patches)
    warnings = zone_warnings + impossible + _check_motion(records, kept_rows, lines, path, layout.time_column, geographic)
    report = LoadReport(path=str(path), warnings=tuple(warnings), rows=len(table), records=len(records), nan_counts=nan_counts,
                        skipped_rows=skipped, unknown_columns=layout.unknown, notes=tuple(notes), **sonar_stats)
    return records, report


def _check_options(sonar, node_m, patch_centre: str, time_tolerance_s: float) -> None:
    """The reader's own arguments, each named when wrong."""
    if sonar is not None and (node_m is None or not (np.isfinite(node_m) and node_m > 0)):
        raise ValueError(f"gridding sonar soundings needs node_m, the map's node spacing in metres (got {node_m!r})")
    if patch_centre not in PATCH_CENTRES:
        raise ValueError(f"patch_centre must be one of {PATCH_CENTRES}, got {patch_centre!r}")
    if not (np.isfinite(time_tolerance_s) and time_tolerance_s >= 0):
        raise ValueError(f"time_tolerance_s must be a non-negative number of seconds, got {time_tolerance_s!r}")


@dataclass(frozen=True)
class _Layout:
    """Which of a log's columns say what: each quantity's form, the time column, what is read, what is not known."""

    columns: dict  # lower-cased, stripped name -> the header as written
    position: tuple[str, str]
    velocity: tuple[str, str]
    truth: tuple[str, str] | None
    time_column: str
    used: frozenset
    unknown: tuple[str, ...]


def _layout(table, path: Path, notes: list[str]) -> _Layout:
    """The log's layout from its header; the required columns missing are named together."""
    columns = {c.strip().lower(): c for c in table.columns}
    position = _pick_pair(columns, _POSITION_FORMS, "ship position", notes, required=True)
    velocity = _pick_pair(columns, _VELOCITY_FORMS, "velocity", notes, required=True)
    truth = _pick_pair(columns, _TRUTH_FORMS, "truth position", notes, required=False)
    patch_centre = _pick_pair(columns, _PATCH_CENTRE_FORMS, "sonar patch centre", notes, required=False)
    time_column = next((c for c in _TIME_COLUMNS if c in columns), None)
    missing = ([] if time_column else ["t_s (or time_utc)"]) + [c for c in _SINGLE_REQUIRED if c not in columns]
    if time_column == "t_s" and "time_utc" in columns:
        notes.append("t_s used for the time; time_utc not read")
    if missing:
        raise ValueError(f"{path.name} lacks the required column(s) {', '.join(missing)}; it has {', '.join(table.columns)}")
    used = frozenset(set(_SINGLE_REQUIRED) | set(position) | set(velocity) | set(truth or ()) | set(patch_centre or ())
                     | {c for c in (*_OPTIONAL, _PATCH_AGE) if c in columns})
    unknown = tuple(columns[c] for c in columns if c not in NAVLOG_COLUMNS)
    return _Layout(columns, position, velocity, truth, time_column, used, unknown)


def _read_values(table, layout: _Layout, path: Path, lines: _Lines, notes: list[str]) -> tuple[dict, object, list]:
    """Every used column as numbers, and ``t_s`` (from ``time_utc`` if need be, with its epoch and zone warnings)."""
    columns = layout.columns
    values = {c: _numeric(table[columns[c]], c, path, lines) for c in layout.used}
    epoch, zone_warnings = None, []
    if layout.time_column == "t_s":
        values["t_s"] = _numeric(table[columns["t_s"]], "t_s", path, lines)
    else:
        values["t_s"], epoch = _seconds(table[columns["time_utc"]], "time_utc", path, lines, epoch=None)
        zone_warnings = _check_zones(table[columns["time_utc"]], lines, notes)
        if epoch is not None:
            notes.append(f"t_s counts seconds from time_utc {epoch.isoformat()}")
    return values, epoch, zone_warnings


def _drop_timeless(values: dict, time_column: str, path: Path, lines: _Lines) -> tuple[dict, np.ndarray, tuple]:
    """A row without a time cannot be placed in the sequence: skipped and said so; the rest must run forward."""
    t = values["t_s"]
    keep = np.isfinite(t)
    skipped = tuple((int(r), f"no time ({time_column} empty or NaN)") for r in np.flatnonzero(~keep))
    if not keep.any():
        raise ValueError(f"{path.name} has no record with a time ({len(t)} data row(s)); there is nothing to navigate")
    kept_rows = np.flatnonzero(keep)
    values = {c: v[keep] for c, v in values.items()}
    _check_time(values["t_s"], kept_rows, lines, path)
    return values, kept_rows, skipped


def _missing_readings(values: dict, layout: _Layout, notes: list[str]) -> dict[str, int]:
    """Missing readings per column read (an empty patch centre or age is none: the patch is centred by patch_centre,
    aged 0); a log without ``slant_range_m`` gets NaN throughout, said in the notes."""
    counts = {layout.columns[c]: int(np.isnan(values[c]).sum()) for c in layout.columns
              if c in layout.used and c not in (*sum(_PATCH_CENTRE_FORMS, ()), _PATCH_AGE)}
    if "slant_range_m" not in layout.columns:
        values["slant_range_m"] = np.full(values["t_s"].size, np.nan)
        notes.append("no slant_range_m column: slant range is NaN (not measured) for every record")
    return counts


def _note_platform(values: dict, notes: list[str]) -> None:
    """A cable of 0 in every record is a sonar on the ship itself (a hull-mounted survey): said, not refused."""
    cable = values["cable_out_m"]
    if np.isfinite(cable).any() and np.all(cable[np.isfinite(cable)] == 0):
        notes.append("cable_out_m is 0 in every record: the sonar is on the ship (a hull-mounted survey), no lay-back")


def _motion(values: dict, layout: _Layout, crs: str | None, path: Path, kept_rows: np.ndarray, lines: _Lines,
            notes: list[str]) -> tuple[dict, np.ndarray]:
    """Every series of :class:`NavRecords` but the sonar, on the grid (positions projected, angles and velocities turned
    to grid north), and the meridian convergence at each record (degrees, 0 for a log already on the grid)."""
    geographic = layout.position == ("lat", "lon")
    usbl = _usbl_columns(values, layout.columns, kept_rows, lines, path, geographic, notes)
    ship_x, ship_y, convergence = _ship_positions(values, geographic, crs, path, kept_rows, lines, notes)
    vel_x, vel_y = _grid_velocity(values, layout.velocity, convergence)
    truth_x, truth_y = _truth_positions(values, layout.truth, crs, path, kept_rows, lines, notes)
    series = dict(
        t_s=values["t_s"], ship_x_m=ship_x, ship_y_m=ship_y, ship_heading_deg=_wrap(values["ship_heading_deg"] + convergence),
        vehicle_depth_m=values["vehicle_depth_m"], altitude_m=values["altitude_m"], vel_x_mps=vel_x, vel_y_mps=vel_y,
        slant_range_m=values["slant_range_m"], cable_out_m=values["cable_out_m"], truth_x_m=truth_x, truth_y_m=truth_y, **usbl,
    )
    return series, convergence


def _ship_positions(values: dict, geographic: bool, crs: str | None, path: Path, kept_rows: np.ndarray, lines: _Lines,
                    notes: list[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The ship's grid position and the meridian convergence (degrees, 0 for a log already on the grid)."""
    if not geographic:
        return values["x_m"], values["y_m"], np.zeros_like(values["x_m"])
    if crs is None:
        raise ValueError(f"{path.name} gives positions as lat/lon; pass crs= (the map's projected CRS) to project them")
    ship_x, ship_y, convergence = _project(values["lat"], values["lon"], crs, path, kept_rows, lines, "lat/lon")
    finite = convergence[np.isfinite(convergence)]
    if finite.size:
        notes.append(
            f"positions projected from WGS 84 lat/lon to {crs}; headings, courses and velocities turned from "
            f"true to grid north by the meridian convergence ({finite.min():+.3f} to {finite.max():+.3f} deg)"
        )
    return ship_x, ship_y, convergence


def _grid_velocity(values: dict, velocity: tuple[str, str], convergence: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """East and north velocity on the grid, from components or speed and course, turned by the convergence."""
    if velocity == ("vel_x_mps", "vel_y_mps"):
        vx, vy = values["vel_x_mps"], values["vel_y_mps"]
        c, s = np.cos(np.radians(convergence)), np.sin(np.radians(convergence))
        return vx * c + vy * s, -vx * s + vy * c
    course = np.radians(values["course_deg"] + convergence)
    return values["speed_mps"] * np.sin(course), values["speed_mps"] * np.cos(course)


def _truth_positions(values: dict, truth: tuple[str, str] | None, crs: str | None, path: Path, kept_rows: np.ndarray,
                     lines: _Lines, notes: list[str]) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The reference track on the grid, or None when the log has none (said in the notes)."""
    if truth == ("truth_x_m", "truth_y_m"):
        return values["truth_x_m"], values["truth_y_m"]
    if truth is None:
        notes.append("no truth position columns: the log has no reference track")
        return None, None
    if crs is None:
        raise ValueError(f"{path.name} gives the truth as truth_lat/truth_lon; pass crs= to project it")
    truth_x, truth_y, _ = _project(values["truth_lat"], values["truth_lon"], crs, path, kept_rows, lines, "truth_lat/truth_lon")
    return truth_x, truth_y


def write_navlog(records: NavRecords, path: str | os.PathLike, *, sonar: str | os.PathLike | None = None,
                 epoch_utc_s: float | None = None) -> None:
    """Write records in the documented layout (and their sonar patches as a side file).

    Records of a hull-mounted survey (:mod:`lost.host.io.survey_records`) are written as they are: ``cable_out_m``
    0 in every record (read back as a sonar on the ship, no lay-back), ``slant_range_m`` empty, the first
    record's velocity empty when the survey had no earlier ping to difference.

    Parameters
    ----------
    records : NavRecords
    path : path-like
        The navigation-log CSV to write.
    sonar : path-like, optional
        The sonar side file to write; required when the records carry sonar patches, refused otherwise.
    epoch_utc_s : float, optional
        The POSIX time (UTC) at which ``t_s`` is 0 (a survey's first ping): a ``time_utc`` column is written beside
        ``t_s`` (to the microsecond, for the reader of the file; :func:`read_navlog` takes ``t_s``).
    """
    import pandas as pd

    has_sonar = any(p is not None for p in records.sonar)
    if has_sonar and sonar is None:
        raise ValueError("the records carry sonar patches; pass sonar= to write them, or they would be lost")
    if sonar is not None and not has_sonar:
        raise ValueError("sonar= was given but the records carry no sonar patch")
    names = {
        "t_s": "t_s", "x_m": "ship_x_m", "y_m": "ship_y_m", "ship_heading_deg": "ship_heading_deg",
        "vehicle_depth_m": "vehicle_depth_m", "altitude_m": "altitude_m", "vel_x_mps": "vel_x_mps",
        "vel_y_mps": "vel_y_mps", "slant_range_m": "slant_range_m", "cable_out_m": "cable_out_m",
    }
    if records.has_truth:
        names |= {"truth_x_m": "truth_x_m", "truth_y_m": "truth_y_m"}
    if records.has_usbl:
        names |= {name: name for name in ("usbl_travel_time_s", *_USBL_FIX)}
    table = pd.DataFrame({column: getattr(records, attribute) for column, attribute in names.items()})
    if epoch_utc_s is not None:
        table.insert(1, "time_utc", pd.to_datetime(epoch_utc_s + records.t_s, unit="s", utc=True).strftime("%Y-%m-%dT%H:%M:%S.%fZ"))
    if any(patch is not None and patch.centre_offset_m != (0.0, 0.0) for patch in records.sonar):
        centres = np.array([patch.centre_offset_m if patch is not None else (np.nan, np.nan) for patch in records.sonar])
        table["patch_east_m"], table["patch_north_m"] = centres[:, 0], centres[:, 1]
    if any(patch is not None and patch.age_s != 0.0 for patch in records.sonar):
        table[_PATCH_AGE] = [patch.age_s if patch is not None else np.nan for patch in records.sonar]
    # pandas writes float64 with repr precision, so the text reads back to the same numbers.
    table.to_csv(path, index=False, na_rep="")
    if sonar is not None:
        parts = []
        for index, patch in enumerate(records.sonar):
            if patch is None:
                continue
            h, w = patch.depth_m.shape
            k, l = np.nonzero(np.isfinite(patch.depth_m))
            east, north = patch.centre_offset_m
            parts.append(pd.DataFrame({
                "record": index,
                "east_m": east + (l - (w - 1) / 2) * patch.node_m,
                "north_m": north + (k - (h - 1) / 2) * patch.node_m,
                "depth_m": patch.depth_m[k, l],
            }))
        pd.concat(parts, ignore_index=True).to_csv(sonar, index=False)


# --------------------------------------------------------------------------------------------
