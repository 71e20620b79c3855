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
    depth, positive down). Each record's soundings are gridded by :func:`lost.host.sonar.grid_soundings`
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
    value: an example survey to run the command line on.

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

import functools
import os
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .filecheck import DEEPEST_M
from .grid import Grid
from .records import NavRecords, SonarPatch
from .sonar import _check_shape, grid_soundings, soundings_centre

__all__ = ["LoadReport", "read_navlog", "write_navlog", "check_against_map", "NAVLOG_COLUMNS", "PATCH_CENTRES", "SONAR_COLUMNS",
           "MAX_SHIP_SPEED_MPS"]

_TIME_COLUMNS = ("t_s", "time_utc")
_SINGLE_REQUIRED = ("ship_heading_deg", "vehicle_depth_m", "altitude_m", "cable_out_m")
_POSITION_FORMS = (("x_m", "y_m"), ("lat", "lon"))
_VELOCITY_FORMS = (("vel_x_mps", "vel_y_mps"), ("speed_mps", "course_deg"))
_TRUTH_FORMS = (("truth_x_m", "truth_y_m"), ("truth_lat", "truth_lon"))
_PATCH_CENTRE_FORMS = (("patch_east_m", "patch_north_m"),)
_PATCH_AGE = "patch_age_s"
_USBL_FIX = ("usbl_x_m", "usbl_y_m", "usbl_sxx", "usbl_syy", "usbl_sxy")
_OPTIONAL = ("slant_range_m", "usbl_travel_time_s", *_USBL_FIX)
NAVLOG_COLUMNS = (
    _TIME_COLUMNS + _SINGLE_REQUIRED + sum(_POSITION_FORMS, ()) + sum(_VELOCITY_FORMS, ()) + _OPTIONAL + sum(_TRUTH_FORMS, ())
    + sum(_PATCH_CENTRE_FORMS, ()) + (_PATCH_AGE,)
)
#: Where a record's sonar patch is centred when the log has no patch_east_m/patch_north_m for it.
PATCH_CENTRES = ("vehicle", "soundings")
SONAR_COLUMNS = ("t_s", "time_utc", "record", "east_m", "north_m", "depth_m")


@dataclass(frozen=True)
class LoadReport:
    """What reading a navigation log (and its sonar side file) kept, skipped and why.

    Attributes
    ----------
    path : str
        The navigation log.
    rows : int
        Data rows in the log.
    records : int
        Records kept (``rows`` less the skipped ones).
    nan_counts : dict[str, int]
        Missing readings (empty or NaN cells) per column read, kept rows only.
    skipped_rows : tuple of (int, str)
        ``(data row, reason)`` for each row left out; data rows count from 0 after the header.
    unknown_columns : tuple of str
        Columns not in the documented layout, not read.
    warnings : tuple of str
        Implausible readings found and kept (position jumps faster than any ship); the command line
        puts them in the run's report.
    notes : tuple of str
        Decisions worth knowing: projections, north conversion, absent optional columns, ignored
        duplicate forms.
    sonar_path : str or None
        The sonar side file, if one was read.
    soundings : int
        Rows of the sonar file.
    soundings_used : int
        Soundings gridded into a patch.
    soundings_implausible : int
        Soundings whose depth no sea floor has (more than ``SOUNDING_ABOVE_SURFACE_M`` above the
        surface, deeper than ``lost.host.filecheck.DEEPEST_M``).
    soundings_without_value : int
        Soundings with an empty or NaN time/record, offset or depth.
    soundings_unmatched : int
        Soundings whose time or record index matches no row of the log.
    soundings_of_skipped_records : int
        Soundings belonging to a skipped row.
    soundings_outside_patch : int
        Soundings farther from the vehicle than the patch reaches.
    records_with_sonar : int
        Records that got a patch.
    """

    path: str
    rows: int
    records: int
    nan_counts: dict[str, int]
    skipped_rows: tuple[tuple[int, str], ...] = ()
    unknown_columns: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    sonar_path: str | None = None
    soundings: int = 0
    soundings_used: int = 0
    soundings_without_value: int = 0
    soundings_implausible: int = 0
    soundings_unmatched: int = 0
    soundings_of_skipped_records: int = 0
    soundings_outside_patch: int = 0
    records_with_sonar: int = 0

    def summary(self) -> str:
        """A few lines of plain text for the command line."""
        lines = [f"{self.path}: {self.rows} rows, {self.records} records kept"]
        if self.skipped_rows:
            reasons = Counter(reason for _, reason in self.skipped_rows)
            for reason, count in reasons.items():
                rows = [str(r) for r, why in self.skipped_rows if why == reason]
                shown = ", ".join(rows[:5]) + (", ..." if len(rows) > 5 else "")
                lines.append(f"  skipped {count} row(s), {reason}: data row(s) {shown}")
        missing = {c: n for c, n in self.nan_counts.items() if n}
        if missing:
            lines.append("  missing readings (kept as NaN): " + ", ".join(f"{c} {n}" for c, n in missing.items()))
        if self.unknown_columns:
            lines.append("  unknown columns, not read: " + ", ".join(self.unknown_columns))
        lines += [f"  note: {n}" for n in self.notes]
        lines += [f"  warning: {w}" for w in self.warnings]
        if self.sonar_path is not None:
            lines.append(
                f"{self.sonar_path}: {self.soundings} soundings, {self.soundings_used} gridded into "
                f"{self.records_with_sonar} patch(es)"
            )
            for label, count in (
                ("without a value (empty or NaN)", self.soundings_without_value),
                ("with a depth no sea floor has", self.soundings_implausible),
                ("matching no record", self.soundings_unmatched),
                ("of skipped records", self.soundings_of_skipped_records),
                ("beyond the patch", self.soundings_outside_patch),
            ):
                if count:
                    lines.append(f"  not used: {count} {label}")
        return "\n".join(lines)


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
    # An empty patch centre or age is no missing reading: the record's patch (if any) is centred by patch_centre, aged 0.
    nan_counts = {layout.columns[c]: int(np.isnan(values[c]).sum()) for c in layout.columns
                  if c in layout.used and c not in (*sum(_PATCH_CENTRE_FORMS, ()), _PATCH_AGE)}
    if "slant_range_m" not in layout.columns:
        values["slant_range_m"] = np.full(kept_rows.size, np.nan)
        notes.append("no slant_range_m column: slant range is NaN (not measured) for every record")

    impossible = _impossible_readings(values, kept_rows, lines, path)
    geographic = layout.position == ("lat", "lon")
    usbl = _usbl_columns(values, layout.columns, kept_rows, lines, path, geographic, notes)
    ship_x, ship_y, convergence = _ship_positions(values, geographic, crs, path, kept_rows, lines, notes)
    vel_x, vel_y = _grid_velocity(values, layout.velocity, convergence)
    truth_x, truth_y = _truth_positions(values, layout.truth, crs, path, kept_rows, lines, notes)
    sonar_patches: tuple[SonarPatch | None, ...] = ()
    sonar_stats: dict = {}
    if sonar is not None:
        sonar_patches, sonar_stats = _read_sonar(
            Path(sonar), record_times=values["t_s"], epoch=epoch, convergence_deg=convergence, kept_rows=kept_rows, rows=len(table),
            patch_shape=h_w, node_m=float(node_m), time_tolerance_s=time_tolerance_s, patch_centre=patch_centre,
            centre_east=values.get("patch_east_m"), centre_north=values.get("patch_north_m"), age_s=values.get(_PATCH_AGE),
        )

    records = NavRecords(
        t_s=values["t_s"], ship_x_m=ship_x, ship_y_m=ship_y, ship_heading_deg=_wrap(values["ship_heading_deg"] + convergence),
        vehicle_depth_m=values["vehicle_depth_m"], altitude_m=values["altitude_m"], vel_x_mps=vel_x, vel_y_mps=vel_y,
        slant_range_m=values["slant_range_m"], cable_out_m=values["cable_out_m"], sonar=sonar_patches,
        truth_x_m=truth_x, truth_y_m=truth_y, **usbl,
    )
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


def write_navlog(records: NavRecords, path: str | os.PathLike, *, sonar: str | os.PathLike | None = None) -> None:
    """Write records in the documented layout (and their sonar patches as a side file).

    Parameters
    ----------
    records : NavRecords
    path : path-like
        The navigation-log CSV to write.
    sonar : path-like, optional
        The sonar side file to write; required when the records carry sonar patches, refused otherwise.
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


def _read_table(path: Path):
    import pandas as pd

    if not path.is_file():
        raise FileNotFoundError(f"no file at {path}")
    header = _header_line(path)
    sep = _separator(header)
    _refuse_duplicates([name.strip() for name in header.split(sep)], path)
    try:
        # The C parser makes clean columns float64 at once; a column with a stray word stays text, and
        # _numeric then names the cell. Only these words (and empty cells) are missing readings.
        return pd.read_csv(
            path, sep=sep, comment="#", skipinitialspace=True, keep_default_na=False,
            na_values=["", "nan", "NaN", "NAN", "NA", "n/a", "N/A", "null", "NULL", "NaT"],
        )
    except pd.errors.EmptyDataError:
        raise ValueError(f"{path.name} is empty; a header row naming the columns is needed") from None
    except pd.errors.ParserError as exc:
        raise ValueError(f"{path.name} is not a well-formed CSV: {' '.join(str(exc).split())}") from None
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path.name} is not UTF-8 text (a byte {exc.object[exc.start]:#04x} at {exc.start}); is it a binary file?") from None


def _header_line(path: Path) -> str:
    try:
        with path.open("r", encoding="utf-8") as stream:
            for line in stream:
                if line.strip() and not line.lstrip().startswith("#"):
                    return line.rstrip("\r\n").lstrip("\ufeff")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path.name} is not UTF-8 text (a byte {exc.object[exc.start]:#04x} at {exc.start}); is it a binary file?") from None
    raise ValueError(f"{path.name} is empty; a header row naming the columns is needed")


def _separator(header: str) -> str:
    """Comma, semicolon or tab: whichever separates the header's names (the most frequent of the three)."""
    counts = {sep: header.count(sep) for sep in (",", ";", "\t")}
    best = max(counts, key=counts.get)
    return best if counts[best] else ","


def _refuse_duplicates(names: list[str], path: Path) -> None:
    seen: dict[str, int] = {}
    for index, name in enumerate(names):
        key = name.lower()
        if key in seen:
            raise ValueError(
                f"{path.name}: the column name {name!r} appears twice (columns {seen[key] + 1} and {index + 1}, "
                f"names compared without case: {names[seen[key]]!r}); which one is meant cannot be guessed, rename or drop one"
            )
        seen[key] = index


class _Lines:
    """File line (1-based) of each data row, for error messages; counted only when one is raised."""

    def __init__(self, path: Path, rows: int) -> None:
        self._path, self._rows = path, rows

    @functools.cached_property
    def numbers(self) -> np.ndarray | None:
        numbers = []
        with self._path.open("r", encoding="utf-8", errors="replace") as f:
            for number, line in enumerate(f, start=1):
                if line.strip() and not line.lstrip().startswith("#"):
                    numbers.append(number)
        numbers = numbers[1:]  # the header
        # A quoted cell spanning lines would shift the count: then name the data row only.
        return np.asarray(numbers) if len(numbers) == self._rows else None


def _where(row: int, lines: _Lines) -> str:
    numbers = lines.numbers
    return f"data row {row}" + (f" (line {int(numbers[row])})" if numbers is not None else "")


_MISSING_WORDS = ("nan", "na", "n/a", "null")


def _numeric(column, name: str, path: Path, lines: _Lines) -> np.ndarray:
    import pandas as pd

    if pd.api.types.is_bool_dtype(column.dtype):
        raise ValueError(f"{path.name}: {name} holds true/false, not numbers, from {_where(0, lines)}: {column.iloc[0]!r}")
    if pd.api.types.is_numeric_dtype(column.dtype):
        return column.to_numpy(np.float64)
    number = pd.to_numeric(column, errors="coerce").to_numpy(np.float64)
    # Only cells that did not parse are looked at again: empty or a missing word is a missing reading.
    unparsed = np.flatnonzero(np.isnan(number))
    if unparsed.size:
        text = column.iloc[unparsed].astype(str).str.strip().str.lower()
        bad = unparsed[~(column.iloc[unparsed].isna() | (text == "") | text.isin(_MISSING_WORDS)).to_numpy()]
        if bad.size:
            row = int(bad[0])
            raise ValueError(f"{path.name}: {name} is not a number at {_where(row, lines)}: {column.iloc[row]!r}")
    return number


def _seconds(column, name: str, path: Path, lines, *, epoch):
    """ISO 8601 timestamps to seconds from ``epoch`` (default: the first timestamp); NaN where empty."""
    import pandas as pd

    text = column.astype(str).str.strip()
    empty = column.isna() | (text == "") | text.str.lower().isin(_MISSING_WORDS + ("nat",))
    stamps = pd.to_datetime(text.where(~empty), utc=True, errors="coerce", format="ISO8601")
    bad = np.flatnonzero(stamps.isna().to_numpy() & ~empty.to_numpy())
    if bad.size:
        row = int(bad[0])
        raise ValueError(f"{path.name}: {name} is not an ISO 8601 time at {_where(row, lines)}: {column.iloc[row]!r}")
    if epoch is None:
        known = stamps.dropna()
        if known.empty:
            return np.full(len(stamps), np.nan), None
        epoch = known.iloc[0]
    return (stamps - epoch).dt.total_seconds().to_numpy(np.float64, na_value=np.nan), epoch


def _pick_pair(columns: dict, forms, what: str, notes: list, *, required: bool):
    present = [form for form in forms if all(c in columns for c in form)]
    partial = [c for form in forms for c in form if c in columns and form not in present]
    if partial and not present:
        form = next(f for f in forms if any(c in columns for c in f))
        lacking = [c for c in form if c not in columns]
        raise ValueError(f"the {what} column {', '.join(c for c in form if c in columns)} needs {', '.join(lacking)} too")
    if not present:
        if required:
            alternatives = " or ".join("/".join(form) for form in forms)
            raise ValueError(f"the {what} is missing: the log needs the columns {alternatives}; it has {', '.join(columns.values())}")
        return None
    unread = [c for form in forms if form != present[0] for c in form if c in columns]
    if unread:
        notes.append(f"{'/'.join(present[0])} used for the {what}; {', '.join(unread)} not read")
    return present[0]


def _check_time(t: np.ndarray, rows: np.ndarray, lines, path: Path) -> None:
    steps = np.diff(t)
    bad = np.flatnonzero(steps <= 0)
    if bad.size:
        k = int(bad[0])
        verb = "goes backwards" if steps[k] < 0 else "repeats"
        raise ValueError(
            f"{path.name}: time {verb} at {_where(int(rows[k + 1]), lines)}: t_s={float(t[k + 1])} after "
            f"{float(t[k])} ({bad.size} such row(s)); records must be in strictly increasing time"
        )


def _project(lat, lon, crs, path: Path, rows, lines, label: str):
    """Project WGS 84 lat/lon to ``crs``; also the grid bearing of true north there (degrees)."""
    from pyproj import CRS, Transformer

    try:
        target = CRS.from_user_input(crs)
    except Exception as exc:
        raise ValueError(f"crs={crs!r} is not a CRS pyproj understands ({exc})") from None
    if not target.is_projected:
        raise ValueError(f"crs must be the map's projected (metric) CRS, got {crs!r}")
    out_of_range = np.flatnonzero((np.abs(lat) > 90) | (lon < -180) | (lon > 360))
    if out_of_range.size:
        r = int(out_of_range[0])
        raise ValueError(
            f"{path.name}: {label} ({lat[r]}, {lon[r]}) is not a latitude/longitude in degrees at {_where(int(rows[r]), lines)}"
        )
    transformer = Transformer.from_crs("EPSG:4326", target, always_xy=True)
    x, y = (np.asarray(a, dtype=np.float64) for a in transformer.transform(lon, lat))
    # True north's grid bearing: the direction a small step north takes on the map.
    step_deg = 1e-5
    xn, yn = (np.asarray(a, dtype=np.float64) for a in transformer.transform(lon, np.minimum(lat + step_deg, 90.0)))
    convergence = np.degrees(np.arctan2(xn - x, yn - y))
    known = np.isfinite(convergence)
    if known.any() and not known.all():
        # A record without a fix still needs its heading turned; convergence varies slowly, so interpolate.
        index = np.arange(convergence.size)
        convergence = np.interp(index, index[known], convergence[known])
    elif not known.any():
        convergence = np.zeros_like(convergence)
    return x, y, convergence


def _wrap(angle_deg: np.ndarray) -> np.ndarray:
    return np.mod(angle_deg, 360.0)


def _read_sonar(path: Path, *, record_times, epoch, convergence_deg, kept_rows, rows, patch_shape, node_m, time_tolerance_s,
                patch_centre, centre_east, centre_north, age_s=None):
    table = _read_table(path)
    columns = {c.strip().lower(): c for c in table.columns}
    # Soundings are keyed the way the log keeps time (or by record index, which works with either).
    time_key = "t_s" if epoch is None else "time_utc"
    missing = [c for c in ("east_m", "north_m", "depth_m") if c not in columns]
    if time_key not in columns and "record" not in columns:
        other = "time_utc" if time_key == "t_s" else "t_s"
        also = f" ({other} cannot be matched: the log's time is {time_key})" if other in columns else ""
        missing.insert(0, f"{time_key} or record{also}")
    if missing:
        raise ValueError(f"{path.name} lacks the sonar column(s) {', '.join(missing)}; it has {', '.join(table.columns)}")
    key = "record" if "record" in columns else time_key
    lines = _Lines(path, len(table))
    v = {c: _numeric(table[columns[c]], c, path, lines) for c in (key, "east_m", "north_m", "depth_m") if c != "time_utc"}
    if key == "time_utc":
        v["t_s"], _ = _seconds(table[columns["time_utc"]], "time_utc", path, lines, epoch=epoch)
        key = "t_s"
    finite = np.isfinite(v[key]) & np.isfinite(v["east_m"]) & np.isfinite(v["north_m"]) & np.isfinite(v["depth_m"])
    # A sounding above the surface or deeper than any sea is no sounding: counted, not gridded.
    implausible = finite & ((v["depth_m"] < -SOUNDING_ABOVE_SURFACE_M) | (v["depth_m"] > DEEPEST_M))
    finite &= ~implausible

    # Which kept record (index into record_times) each sounding belongs to; -1 none, -2 a skipped row.
    owner = np.full(len(table), -1, dtype=np.int64)
    if key == "record":
        index = v["record"]
        whole = finite & (index == np.round(index))
        if np.any(finite & ~whole):
            r = int(np.flatnonzero(finite & ~whole)[0])
            raise ValueError(f"{path.name}: record must be a whole data-row index, got {index[r]} at {_where(r, lines)}")
        position_of_row = np.full(rows, -2, dtype=np.int64)
        position_of_row[kept_rows] = np.arange(kept_rows.size)
        valid_index = whole & (index >= 0) & (index < rows)
        owner[valid_index] = position_of_row[index[valid_index].astype(np.int64)]
    elif record_times.size:
        t = np.where(finite, v["t_s"], np.inf)
        # The nearest record time on either side of each sounding's time.
        after = np.clip(np.searchsorted(record_times, t), 0, record_times.size - 1)
        before = np.clip(after - 1, 0, record_times.size - 1)
        nearest = np.where(np.abs(t - record_times[before]) <= np.abs(t - record_times[after]), before, after)
        matched = finite & (np.abs(t - record_times[nearest]) <= time_tolerance_s)
        owner[matched] = nearest[matched]

    n_records = record_times.size
    patches: list[SonarPatch | None] = [None] * n_records
    used = outside = 0
    usable = finite & (owner >= 0)
    order = np.argsort(owner[usable], kind="stable")
    idx = np.flatnonzero(usable)[order]
    owners = owner[idx]
    bounds = np.flatnonzero(np.diff(owners)) + 1
    for group in np.split(idx, bounds) if idx.size else []:
        # Offsets logged beside lat/lon are true east/north: turn them to grid axes like the velocities.
        record = int(owner[group[0]])
        gamma = np.radians(convergence_deg[record])

        def to_grid(east, north, gamma=gamma):
            if not gamma:
                return east, north
            return east * np.cos(gamma) + north * np.sin(gamma), -east * np.sin(gamma) + north * np.cos(gamma)

        east, north = to_grid(v["east_m"][group], v["north_m"][group])
        if centre_east is not None and np.isfinite(centre_east[record]) and np.isfinite(centre_north[record]):
            centre = to_grid(centre_east[record], centre_north[record])
        elif patch_centre == "soundings":
            centre = soundings_centre(east, north)
        else:
            centre = (0.0, 0.0)
        age = float(age_s[record]) if age_s is not None and np.isfinite(age_s[record]) else 0.0
        gridded = grid_soundings(east, north, v["depth_m"][group], patch_shape=patch_shape, node_m=node_m, centre_m=centre, age_s=age)
        used += gridded.used
        outside += gridded.outside
        if gridded.used:
            patches[record] = gridded.patch
    stats = dict(
        sonar_path=str(path),
        soundings=len(table),
        soundings_used=used,
        soundings_without_value=int((~finite).sum()) - int(implausible.sum()),
        soundings_implausible=int(implausible.sum()),
        soundings_unmatched=int((finite & (owner == -1)).sum()),
        soundings_of_skipped_records=int((finite & (owner == -2)).sum()),
        soundings_outside_patch=outside,
        records_with_sonar=sum(p is not None for p in patches),
    )
    assert used + outside + sum(stats[k] for k in ("soundings_without_value", "soundings_implausible", "soundings_unmatched",
                                                   "soundings_of_skipped_records")) == len(table)
    return tuple(patches), stats


# --------------------------------------------------------------------------------------------
# plausibility

#: A sounding more than this far above the sea surface (a negative depth) is not of the sea floor (drying banks are a few metres).
SOUNDING_ABOVE_SURFACE_M = 20.0
#: Faster than any ship that tows a vehicle (about 50 kn): a position step this fast is a bad fix.
MAX_SHIP_SPEED_MPS = 25.0
_ZONE = r"(Z|[+-]\d{2}(?::?\d{2})?)$"


def _check_zones(column, lines, notes: list) -> list[str]:
    """A warning when some timestamps carry a zone and some do not; a note for several zones (all converted to UTC)."""
    text = column.astype(str).str.strip()
    stamped = ~(column.isna() | (text == "") | text.str.lower().isin(_MISSING_WORDS + ("nat",)))
    # A zone follows the time of day: look only past the 'T' (or the space) so a date's dashes are not taken for one.
    zones = text.str.split(r"[T ]", n=1, regex=True).str[-1].str.extract(_ZONE, expand=False).fillna("")
    zones = zones[stamped.to_numpy()]
    with_zone = zones != ""
    kinds = sorted(set(zones[with_zone]))
    if len(kinds) > 1:
        notes.append(f"time_utc holds several time zones ({', '.join(kinds)}); every time converted to UTC")
    if with_zone.any() and not with_zone.all():
        row = int(zones.index[(~with_zone).to_numpy()][0] if with_zone.iloc[0] else zones.index[with_zone.to_numpy()][0])
        return [
            f"time_utc mixes times with a zone and without one (the first change at {_where(row, lines)}: {column.iloc[row]!r}); "
            "a bare time is read as UTC, check that it is"
        ]
    return []


#: The longest one-way travel time believed (about 15 km of water; the longest-range USBLs reach about 11 km).
MAX_USBL_TRAVEL_TIME_S = 10.0

#: Readings no tow can give: (column, test of the impossible values, why). Such a reading is set to missing and counted.
_IMPOSSIBLE = (
    ("altitude_m", lambda v: v < 0, "a negative height above the floor"),
    ("altitude_m", lambda v: v > DEEPEST_M, "higher above the floor than any sea is deep"),
    ("vehicle_depth_m", lambda v: v < -1.0, "the vehicle more than 1 m above the surface"),
    ("vehicle_depth_m", lambda v: v > DEEPEST_M, "deeper than any sea"),
    ("cable_out_m", lambda v: v < 0, "a negative cable length"),
    ("slant_range_m", lambda v: v < 0, "a negative range"),
    ("usbl_travel_time_s", lambda v: v <= 0, "a travel time not after the ping"),
    ("usbl_travel_time_s", lambda v: v > MAX_USBL_TRAVEL_TIME_S, f"longer than {MAX_USBL_TRAVEL_TIME_S:g} s, beyond any USBL's reach"),
)


def _usbl_columns(values: dict, columns: dict, rows: np.ndarray, lines, path: Path, geographic: bool, notes: list) -> dict:
    """The USBL series for NavRecords (absent ones stay None): the fix's five columns come together, each row whole."""
    found = {}
    if "usbl_travel_time_s" in columns:
        found["usbl_travel_time_s"] = values["usbl_travel_time_s"]
    present = [c for c in _USBL_FIX if c in columns]
    if not present:
        return found
    if len(present) < len(_USBL_FIX):
        raise ValueError(f"{path.name} has the USBL fix column(s) {', '.join(present)} but lacks "
                         f"{', '.join(c for c in _USBL_FIX if c not in columns)}: a fix needs all five")
    if geographic:
        raise ValueError(f"{path.name} gives ship positions as lat/lon but the USBL fix as usbl_x_m/usbl_y_m; give the log in x_m/y_m "
                         "(the map's CRS), where the fix and its covariance are in the same axes")
    fix = np.stack([values[c] for c in _USBL_FIX])
    given = np.isfinite(fix)
    partial = np.flatnonzero(given.any(axis=0) & ~given.all(axis=0))
    if partial.size:
        k = int(partial[0])
        empty = [c for c, ok in zip(_USBL_FIX, given[:, k]) if not ok]
        raise ValueError(f"{path.name}: the USBL fix at {_where(int(rows[k]), lines)} lacks {', '.join(empty)} ({partial.size} such row(s)); "
                         "a row has all five fix values or none")
    sxx, syy, sxy = fix[2:]
    with np.errstate(invalid="ignore"):
        bad = np.flatnonzero(given.all(axis=0) & ~((sxx > 0) & (syy > 0) & (sxy * sxy < sxx * syy)))
    if bad.size:
        k = int(bad[0])
        raise ValueError(f"{path.name}: the USBL fix at {_where(int(rows[k]), lines)} has no covariance (usbl_sxx={sxx[k]:g}, "
                         f"usbl_syy={syy[k]:g}, usbl_sxy={sxy[k]:g} m**2): variances must be positive and usbl_sxy**2 < usbl_sxx * usbl_syy")
    notes.append(f"{int(given.all(axis=0).sum())} USBL fix(es) read")
    return found | {c: values[c] for c in _USBL_FIX}


def _impossible_readings(values: dict, rows: np.ndarray, lines, path: Path) -> list[str]:
    """Set physically impossible readings to missing (NaN) and say how many; refuse a cable always shorter than the depth."""
    warnings = []
    for column, test, why in _IMPOSSIBLE:
        if column not in values:  # an optional column the log does not have
            continue
        with np.errstate(invalid="ignore"):
            bad = np.flatnonzero(test(values[column]))
        if bad.size:
            values[column] = values[column].copy()
            values[column][bad] = np.nan
            warnings.append(f"{bad.size} {column} reading(s) set to missing, {why} (the first at {_where(int(rows[bad[0]]), lines)})")
    cable, depth = values["cable_out_m"], values["vehicle_depth_m"]
    both = np.isfinite(cable) & np.isfinite(depth)
    short = both & (cable < depth)
    if both.any() and short.sum() == both.sum():
        raise ValueError(
            f"{path.name}: cable_out_m is shorter than vehicle_depth_m in every record (e.g. {cable[short][0]:g} m of cable at "
            f"{depth[short][0]:g} m depth): a cable in another unit, or the wrong column?"
        )
    if short.any():
        first = int(rows[np.flatnonzero(short)[0]])
        warnings.append(f"{int(short.sum())} record(s) with less cable out than the vehicle's depth, the first at {_where(first, lines)}: "
                        "their lay-back is taken as zero")
    return warnings


def _check_motion(records: NavRecords, rows: np.ndarray, lines, path: Path, time_column: str, geographic: bool) -> list[str]:
    """Refuse a log whose positions and velocities disagree by a factor of a thousand; list position jumps."""
    t, x, y = records.t_s, records.ship_x_m, records.ship_y_m
    known = np.flatnonzero(np.isfinite(x) & np.isfinite(y))
    if known.size < 3:
        return []
    dt = np.diff(t[known])
    step = np.hypot(np.diff(x[known]), np.diff(y[known]))
    speed = step / dt
    logged = np.hypot(records.vel_x_mps, records.vel_y_mps)
    logged = logged[known[1:]]
    # Moving by either measure (a unit error makes one of them tiny); a zero velocity is a dropout, not a ratio.
    moving = np.isfinite(logged) & np.isfinite(speed) & (logged > 0) & (np.maximum(logged, speed) > 0.3)
    if moving.sum() >= 3:
        ratio = float(np.median(speed[moving] / logged[moving]))
        if not 1e-2 < ratio < 1e2:
            raise ValueError(_unit_suspect(ratio, float(np.median(dt)), time_column, geographic, path))
    warnings = _check_time_gaps(t, rows, lines) + _check_heading_unit(records)
    fast = np.flatnonzero(speed > MAX_SHIP_SPEED_MPS)
    if fast.size:
        k = int(fast[0])
        warnings.append(
            f"{fast.size} ship position step(s) faster than any ship (> {MAX_SHIP_SPEED_MPS:g} m/s), the first at "
            f"{_where(int(rows[known[k + 1]]), lines)}: {step[k]:.0f} m in {dt[k]:g} s; bad GPS fixes?"
        )
    return warnings


#: A gap between records longer than this many typical steps (and a minute) is reported.
GAP_STEPS = 60


def _check_time_gaps(t: np.ndarray, rows: np.ndarray, lines) -> list[str]:
    steps = np.diff(t)
    if steps.size < 2:
        return []
    limit = max(GAP_STEPS * float(np.median(steps)), 60.0)
    gaps = np.flatnonzero(steps > limit)
    if not gaps.size:
        return []
    k = int(gaps[0])
    return [f"{gaps.size} gap(s) in time longer than {limit:g} s, the first {steps[k]:g} s before {_where(int(rows[k + 1]), lines)}: "
            "the navigation dead-reckons across them"]


def _check_heading_unit(records: NavRecords) -> list[str]:
    """Headings all within [0, 2 pi] while the ship's course turns through more than 20 degrees: radians."""
    heading = records.ship_heading_deg[np.isfinite(records.ship_heading_deg)]
    course = np.degrees(np.arctan2(records.vel_x_mps, records.vel_y_mps))
    course = course[np.isfinite(course) & (np.hypot(records.vel_x_mps, records.vel_y_mps) > 0.3)]
    if heading.size < 3 or course.size < 3 or np.max(np.abs(heading)) > 2 * np.pi:
        return []
    # The spread of the course about its circular mean.
    mean = np.angle(np.mean(np.exp(1j * np.radians(course))), deg=True)
    if np.max(np.abs((course - mean + 180.0) % 360.0 - 180.0)) > 20.0 or abs(mean) > 20.0:
        return [f"ship_heading_deg stays within 0 to {2 * np.pi:.2f} while the ship's course is not near north: "
                "are the headings in radians? give degrees"]
    return []


def _unit_suspect(ratio: float, median_step: float, time_column: str, geographic: bool, path: Path) -> str:
    said = f"{path.name}: the ship moves {ratio:.3g} times as fast by its positions as by its logged velocity"
    if ratio < 1:
        if time_column == "t_s" and median_step >= 50:
            return f"{said}, and records are {median_step:g} s apart: t_s looks like milliseconds; give seconds"
        if not geographic:
            return f"{said}: x_m/y_m look like kilometres (or t_s like milliseconds); give metres and seconds"
        return f"{said}: are the times in milliseconds, or the velocity in another unit than m/s?"
    return f"{said}: is the velocity in another unit than m/s (knots, cm/s), or are the times in another unit than seconds?"


def check_against_map(records: NavRecords, grid: Grid) -> list[str]:
    """Refuse records that cannot belong to ``grid``; return warnings for doubtful ones.

    Sonar patches must have the map's node spacing (the correlator compares node with node). At
    least one ship position must lie within reach of the map (the largest cable out, at least
    2 km); when none does, the message says whether the positions fit the map swapped (latitude for
    longitude, x for y) or multiplied by a thousand (kilometres).

    Raises
    ------
    ValueError
        A patch node spacing differs from the map's, or no ship position comes near the map.
    """
    sizes = sorted({float(p.node_m) for p in records.sonar if p is not None})
    wrong = [size for size in sizes if not np.isclose(size, grid.node_m, rtol=1e-9)]
    if wrong:
        raise ValueError(
            f"the sonar patches have {', '.join(f'{v:g}' for v in wrong)} m nodes but the map has {grid.node_m:g} m nodes: the correlator "
            f"compares node with node, so no patch could match; grid the soundings at the map's node (read_navlog node_m={grid.node_m:g}) "
            "or resample the map (read_grid node_m=, lost run --node-m)"
        )
    x, y = records.ship_x_m, records.ship_y_m
    finite = np.isfinite(x) & np.isfinite(y)
    if not finite.any():
        raise ValueError("no record has a ship position; there is nothing to navigate from")
    reach = max(2000.0, float(np.nanmax(records.cable_out_m)) if np.isfinite(records.cable_out_m).any() else 0.0)
    near = _near(grid, x[finite], y[finite], reach)
    if near.any():
        if near.mean() < 0.5:
            return [f"only {near.mean():.0%} of the ship positions lie within {reach:g} m of the map"]
        return []
    raise ValueError(
        f"no ship position lies within {reach:g} m of the map (map x {grid.x0_m:.0f} to {grid.x0_m + (grid.shape[1] - 1) * grid.node_m:.0f}, "
        f"y {grid.y0_m:.0f} to {grid.y0_m + (grid.shape[0] - 1) * grid.node_m:.0f}; the log's first position is "
        f"({x[finite][0]:.1f}, {y[finite][0]:.1f})): {_diagnose(grid, x[finite], y[finite], reach)}"
    )


def _near(grid: Grid, x: np.ndarray, y: np.ndarray, reach: float) -> np.ndarray:
    rows, cols = grid.shape
    dx = np.maximum(0.0, np.maximum(grid.x0_m - x, x - (grid.x0_m + (cols - 1) * grid.node_m)))
    dy = np.maximum(0.0, np.maximum(grid.y0_m - y, y - (grid.y0_m + (rows - 1) * grid.node_m)))
    return np.hypot(dx, dy) <= reach


def _diagnose(grid: Grid, x: np.ndarray, y: np.ndarray, reach: float) -> str:
    if _near(grid, x * 1000.0, y * 1000.0, reach).mean() > 0.5:
        return "multiplied by 1000 they would be on it: the positions look like kilometres; give metres"
    if _near(grid, y, x, reach).mean() > 0.5:
        return "with x and y swapped they would be on it: swap the x_m and y_m columns"
    if grid.crs is not None:
        from pyproj import Transformer

        try:
            to_lonlat = Transformer.from_crs(grid.crs, "EPSG:4326", always_xy=True)
            lon, lat = to_lonlat.transform(x, y)
            sx, sy = to_lonlat.transform(np.asarray(lat), np.asarray(lon), direction="INVERSE")
            if np.all(np.isfinite(sx)) and _near(grid, np.asarray(sx), np.asarray(sy), reach).mean() > 0.5:
                return "with latitude and longitude swapped they would be on it: swap the lat and lon columns"
        except Exception:  # noqa: BLE001  (a failed projection only means no diagnosis)
            pass
    return "is the log in the map's CRS, and is it the right map?"
