"""Checks of a navigation log: time order, positions, plausible readings, motion, units, and the records against their map."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..grid import Grid
from ..records import NavRecords
from .csvtable import _MISSING_WORDS, _where
from .filecheck import DEEPEST_M

#: The USBL fix columns of a log: position and covariance, all five or none.
_USBL_FIX = ("usbl_x_m", "usbl_y_m", "usbl_sxx", "usbl_syy", "usbl_sxy")


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
    hull_mounted = both.any() and np.all(cable[both] == 0)  # no cable at all: the sonar is on the ship
    if both.any() and short.sum() == both.sum() and not hull_mounted:
        raise ValueError(
            f"{path.name}: cable_out_m is shorter than vehicle_depth_m in every record (e.g. {cable[short][0]:g} m of cable at "
            f"{depth[short][0]:g} m depth): a cable in another unit, or the wrong column?"
        )
    if short.any() and not hull_mounted:
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
        _refuse_unit_change(speed[moving] / logged[moving], rows[known[1:]][moving], lines, path)
    warnings = _check_time_gaps(t, rows, lines, path, bare_clock=time_column == "time_utc") + _check_heading_unit(records)
    fast = np.flatnonzero(speed > MAX_SHIP_SPEED_MPS)
    if fast.size:
        k = int(fast[0])
        warnings.append(
            f"{fast.size} ship position step(s) faster than any ship (> {MAX_SHIP_SPEED_MPS:g} m/s), the first at "
            f"{_where(int(rows[known[k + 1]]), lines)}: {step[k]:.0f} m in {dt[k]:g} s; bad GPS fixes?"
        )
    return warnings


#: Runs of this many moving records whose position-to-velocity speed ratio changes by a unit's factor (within
#: UNIT_FACTOR_TOLERANCE) or by more than UNIT_CHANGE_GROSS mean the log changes unit part-way (metres to kilometres
#: or feet or nautical miles; seconds to milliseconds or minutes). A towed vehicle's velocity against its ship's positions
#: also changes in turns and while the cable settles, by factors of 2-3 that no unit has: those are not refused.
UNIT_CHANGE_RUN = 10
UNIT_FACTORS = (1000.0, 3.28084, 1852.0, 60.0)
UNIT_FACTOR_TOLERANCE = 0.1
UNIT_CHANGE_GROSS = 20.0


def _unit_factor(change: float) -> bool:
    """Whether a change of the speed ratio by ``change`` is a change of unit."""
    size = max(change, 1.0 / change)
    return size > UNIT_CHANGE_GROSS or any(abs(size / f - 1.0) < UNIT_FACTOR_TOLERANCE for f in UNIT_FACTORS)


#: Each side of a unit change holds steady: this share of its runs within UNIT_STEADY_FACTOR of the side's median.
UNIT_STEADY_SHARE = 0.8
UNIT_STEADY_FACTOR = 1.6


def _steady(medians: np.ndarray) -> bool:
    centre = np.median(medians)
    return medians.size >= 2 and float(np.mean(np.abs(np.log(medians / centre)) < np.log(UNIT_STEADY_FACTOR))) >= UNIT_STEADY_SHARE


def _refuse_unit_change(ratio: np.ndarray, rows: np.ndarray, lines, path: Path) -> None:
    """Refuse a log whose speed ratio steps, and stays, by a unit's factor; a ramp (the cable settling) is no step."""
    if ratio.size < 2 * UNIT_CHANGE_RUN:
        return
    # The median of each run of records: one bad fix does not move it, a unit change for the rest of the log does.
    runs = ratio[: ratio.size // UNIT_CHANGE_RUN * UNIT_CHANGE_RUN].reshape(-1, UNIT_CHANGE_RUN)
    medians = np.median(runs, axis=1)
    for k in range(2, medians.size - 1):
        before, after = medians[:k], medians[k:]
        factor = float(np.median(after) / np.median(before))
        if _unit_factor(factor) and _steady(before) and _steady(after):
            first = k * UNIT_CHANGE_RUN + int(np.argmax(np.abs(np.log(runs[k] / np.median(before))) > 0.5 * abs(np.log(factor))))
            raise ValueError(
                f"{path.name}: positions move {factor:.3g} times as fast for the logged velocity from about "
                f"{_where(int(rows[first]), lines)} on as before it: a change of unit part-way through the log (kilometres or feet "
                "for metres, another time unit)? Give one unit throughout"
            )


#: A gap between records longer than this many typical steps (and a minute) is reported.
GAP_STEPS = 60


def _check_time_gaps(t: np.ndarray, rows: np.ndarray, lines, path: Path, *, bare_clock: bool) -> list[str]:
    steps = np.diff(t)
    if steps.size < 2:
        return []
    limit = max(GAP_STEPS * float(np.median(steps)), 60.0)
    gaps = np.flatnonzero(steps > limit)
    if not gaps.size:
        return []
    k = int(gaps[0])
    for g in gaps if bare_clock else ():
        # In clock times, a gap of whole half hours, give or take two steps, is a clock moved to another zone (or daylight saving).
        shift = round(float(steps[g]) / 1800.0) * 1800.0
        if abs(steps[g] - shift) <= 2 * float(np.median(steps)):
            raise ValueError(
                f"{path.name}: time jumps by {steps[g]:g} s ({shift / 3600:g} h and {steps[g] - shift:+g} s) before {_where(int(rows[g + 1]), lines)}: "
                "a change of time zone in bare times? Give times with their zone (e.g. 2024-05-01T12:00:00+02:00) or in UTC"
            )
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
