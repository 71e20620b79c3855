"""A recorded (or simulated) INS+USBL tow from its tables to the fused track: the log and IMU readers, the USBL
fixes, the alignment, the filter, and the comparison methods (raw USBL, free INS, eqs. 6-7 dead reckoning).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pandas as pd
from scipy.stats import theilslopes

from ..config import NonNegativeFloat, PositiveFloat
from .checks import check_replies
from .filter import SOUND, STATES, FusionResult, InsUsblFilter, SoundSpeedError, fuse
from .fix import UsblArray, UsblFix, usbl_fix
from .frames import LocalFrame, body_to_ned
from .ins import EarthModel, ImuSamples, NavState, dead_reckon, strapdown
from .scenario import DEG_PER_HOUR, MILLI_G, ImuSpec, OpenFraction
from .simulate import IMU_COLUMNS, LOG_COLUMNS
from .sound import Cast, CastError, SoundSpeedProfile, extend_cast

__all__ = ["UsblConfig", "UsblRun", "read_log", "read_imu", "process"]


@dataclass(frozen=True)
class UsblConfig:
    """What processing needs beyond the recordings: the USBL's array and noise, the IMU's error model, the gate,
    and the alignment window (the first ``align_window_s`` of fixes give the start position and velocity);
    ``earth_rotation=False`` for an IMU whose rates have the Earth's rotation removed already.

    A cast that stops above the towfish's transponder: with ``cast_below_vehicle = "extend"`` it is continued below its
    last sample by :func:`lost.host.usbl.sound.extend_cast` (the last temperature and salinity held, TEOS-10), at most
    ``cast_extension_limit_m`` below it, and the replies from below the cast are counted in the summary; with
    ``"refuse"``, or deeper than the limit, the run stops with an error that names the cast.

    The sound speed's uncertainty (a state of the filter, :class:`lost.host.usbl.filter.SoundSpeedError`): the
    path-mean speed's error ``sound_speed_sigma_m_s`` (the cast's own, internal waves), and a surface layer drifting by
    ``surface_speed_drift_m_s_per_h`` since the cast was taken (``cast_age_h`` before the log's first ping), seen through
    its share of the path (e-folding depth ``surface_layer_m``); correlated over ``sound_speed_correlation_s``."""

    array: UsblArray = field(default_factory=UsblArray)
    imu: ImuSpec = field(default_factory=ImuSpec)
    gate_probability: OpenFraction = 0.999
    align_window_s: PositiveFloat = 40.0
    earth_rotation: bool = True
    cast_below_vehicle: Literal["extend", "refuse"] = "extend"
    cast_extension_limit_m: NonNegativeFloat = 500.0
    sound_speed_sigma_m_s: NonNegativeFloat = 0.2
    cast_age_h: NonNegativeFloat = 0.0
    surface_speed_drift_m_s_per_h: NonNegativeFloat = 0.75
    surface_layer_m: PositiveFloat = 30.0
    sound_speed_correlation_s: PositiveFloat = 600.0


@dataclass(frozen=True)
class UsblRun:
    """Everything a run produces, in the local frame of ``frame`` (north, east, down)."""

    frame: LocalFrame
    profile: SoundSpeedProfile
    time_s: np.ndarray
    fixes: list[UsblFix | None]
    fix_failures: dict[int, str]
    fused: FusionResult
    start_index: int
    ins_position: np.ndarray
    dead_reckoning: np.ndarray
    truth: np.ndarray | None
    injected: np.ndarray | None
    ship: np.ndarray
    usbl_position: np.ndarray  # each fix moved from the transponder to the INS by the logged attitude (NaN without one)
    cast: dict[str, Any] = field(default_factory=dict)  # the cast's source and depth, and what was done below it


def _read_table(path: str | Path, kind: str, required: list[str]) -> pd.DataFrame:
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{kind} file {path} does not exist")
    try:
        table = pd.read_csv(path, comment="#", skipinitialspace=True, keep_default_na=True)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as error:
        raise ValueError(f"{kind} file {path}: not a readable CSV ({error})") from error
    table.columns = [str(c).strip().lower() for c in table.columns]
    missing = [c for c in required if c not in table.columns]
    if missing:
        raise ValueError(f"{kind} file {path}: missing column(s) {missing}; has {list(table.columns)}")
    return table


def _numeric(table: pd.DataFrame, column: str, source: str, *, allow_empty: bool = False) -> np.ndarray:
    raw = table[column]
    values = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float)
    bad = ~np.isfinite(values) & (raw.notna().to_numpy() if allow_empty else True)
    if np.any(bad):
        row = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{source}: column {column!r} row {row + 1}: {raw.iloc[row]!r} is not a number")
    return values


#: A reply's direction: the phase differences (rad) or the direction cosines, across the array's x and y baselines.
DIRECTION_COLUMNS = (("phase_x_rad", "phase_y_rad"), ("dir_x", "dir_y"))
#: The reply's travel time: one way, or the interrogation's round trip (halved after the transponder's turnaround).
TRAVEL_COLUMNS = ("travel_time_s", "two_way_travel_time_s")
REQUIRED_LOG_COLUMNS = [c for c in LOG_COLUMNS if c not in DIRECTION_COLUMNS[0] and c != TRAVEL_COLUMNS[0]]


def read_log(path: str | Path, *, turnaround_s: float = 0.0) -> pd.DataFrame:
    """Read the USBL log CSV (docs/usbl.md): one row per ping; empty travel time and direction for a ping without a reply.

    A log with ``two_way_travel_time_s`` gets the one-way ``travel_time_s = (two way - turnaround_s) / 2``.

    Raises
    ------
    ValueError
        A column is missing, a value is not a number, times do not increase, or a reply is half there.
    """
    table = _read_table(path, "USBL log", REQUIRED_LOG_COLUMNS)
    source = f"USBL log {path}"
    pairs = [pair for pair in DIRECTION_COLUMNS if set(pair) <= set(table.columns)]
    if len(pairs) != 1:
        raise ValueError(f"{source}: needs the reply's direction as phase_x_rad, phase_y_rad or as dir_x, dir_y (exactly one pair); "
                         f"has {list(table.columns)}")
    travel = [c for c in TRAVEL_COLUMNS if c in table.columns]
    if len(travel) != 1:
        raise ValueError(f"{source}: needs exactly one of travel_time_s (one way) and two_way_travel_time_s; has {list(table.columns)}")
    table.attrs["direction_columns"] = pairs[0]
    table.attrs["source"] = source
    optional_empty = {travel[0], *pairs[0]}
    for column in REQUIRED_LOG_COLUMNS + list(pairs[0]) + travel:
        table[column] = _numeric(table, column, source, allow_empty=column in optional_empty)
    if travel[0] == "two_way_travel_time_s":
        one_way = (table["two_way_travel_time_s"] - turnaround_s) / 2.0
        if (one_way <= 0.0).any():
            row = int(np.flatnonzero((one_way <= 0.0).to_numpy())[0]) + 1
            raise ValueError(f"{source}: row {row}: two-way travel time {table['two_way_travel_time_s'].iloc[row - 1]} s is not longer "
                             f"than the turnaround {turnaround_s} s")
        table["travel_time_s"] = one_way
    for column in ("true_lat_deg", "true_lon_deg", "true_depth_m"):
        if column in table.columns:
            table[column] = _numeric(table, column, source, allow_empty=True)
    if len(table) < 2:
        raise ValueError(f"{source}: needs at least two pings, has {len(table)}")
    steps = np.diff(table["time_s"].to_numpy())
    if np.any(steps <= 0.0):
        row = int(np.flatnonzero(steps <= 0.0)[0]) + 2
        raise ValueError(f"{source}: time_s must increase; row {row} does not")
    present = table[sorted(optional_empty)].notna()
    half = present.any(axis=1) & ~present.all(axis=1)
    if half.any():
        row = int(np.flatnonzero(half.to_numpy())[0]) + 1
        raise ValueError(f"{source}: row {row} has some of {', '.join(sorted(optional_empty))} but not all")
    if "injected" in table.columns:
        table["injected"] = table["injected"].fillna("").astype(str)
    return table


def read_imu(path: str | Path) -> ImuSamples:
    """Read the IMU CSV (docs/usbl.md): time, specific force (m/s^2) and angular rate (rad/s), body frame."""
    table = _read_table(path, "IMU", IMU_COLUMNS)
    source = f"IMU file {path}"
    values = {c: _numeric(table, c, source) for c in IMU_COLUMNS}
    try:
        return ImuSamples(values["time_s"], np.column_stack([values[c] for c in IMU_COLUMNS[1:4]]),
                          np.column_stack([values[c] for c in IMU_COLUMNS[4:7]]))
    except ValueError as error:
        raise ValueError(f"{source}: {error}") from error


def _fixes(log: pd.DataFrame, profile: SoundSpeedProfile, array: UsblArray, frame: LocalFrame) -> tuple[list, dict, np.ndarray]:
    north, east = frame.to_local(log["ship_lat_deg"].to_numpy(), log["ship_lon_deg"].to_numpy())
    fixes: list[UsblFix | None] = []
    failures: dict[int, str] = {}
    first, second = log.attrs.get("direction_columns", DIRECTION_COLUMNS[0])
    # The ray ends at the transponder: the pressure depth plus the lever arm's vertical share at the towfish's attitude.
    transponder_depth = _transponder_depths(log, array)
    for i, row in enumerate(log.itertuples(index=False)):
        if not np.isfinite(row.travel_time_s):
            fixes.append(None)
            continue
        a, b = getattr(row, first), getattr(row, second)
        direction = dict(phase_x_rad=a, phase_y_rad=b) if first == "phase_x_rad" else dict(direction_cosines=(a, b))
        try:
            fixes.append(usbl_fix(profile, array, travel_time_s=row.travel_time_s, **direction,
                                  roll_rad=np.radians(row.ship_roll_deg), pitch_rad=np.radians(row.ship_pitch_deg),
                                  heading_rad=np.radians(row.ship_heading_deg), antenna_north_m=float(north[i]), antenna_east_m=float(east[i]),
                                  target_depth_m=float(transponder_depth[i])))
        except ValueError as error:
            fixes.append(None)
            failures[i] = str(error)
    return fixes, failures, np.column_stack([north, east])


def _transponder_depths(log: pd.DataFrame, array: UsblArray) -> np.ndarray:
    # The ray ends at the transponder: the pressure depth plus the lever arm's vertical share at the towfish's attitude.
    fish_attitude = body_to_ned(*np.radians(log[["fish_roll_deg", "fish_pitch_deg", "fish_heading_deg"]].to_numpy().T))
    return log["fish_depth_m"].to_numpy() + fish_attitude[:, 2, :] @ np.asarray(array.transponder_lever_arm_m)


#: How far below the deepest reply an extended cast reaches.
_EXTENSION_MARGIN_M = 100.0


def _cast_below_vehicle(cast: Cast, log: pd.DataFrame, config: UsblConfig) -> tuple[Cast, dict[str, Any]]:
    """The cast the rays need (extended below its last sample by the policy of ``config``) and what was done, for the summary."""
    bottom = float(cast.depth_m[-1])
    depth = _transponder_depths(log, config.array)[np.isfinite(log["travel_time_s"].to_numpy())]
    below = int(np.sum(depth > bottom))
    report = {"source": cast.source, "bottom_m": bottom, "policy": config.cast_below_vehicle, "replies_below_cast": below,
              "extended_to_m": None}
    if below == 0:
        return cast, report
    deepest = float(depth.max())
    if config.cast_below_vehicle == "refuse":
        raise CastError(f"cast {cast.source} stops at {bottom:.1f} m, above the towfish: {below} of {depth.size} replies come from below it "
                        f"(the deepest at {deepest:.1f} m); take a deeper cast, or set cast_below_vehicle = \"extend\"")
    if deepest - bottom > config.cast_extension_limit_m:
        raise CastError(f"cast {cast.source} stops at {bottom:.1f} m, {deepest - bottom:.1f} m above the deepest reply's transponder "
                        f"({deepest:.1f} m; {below} of {depth.size} replies come from below the cast); extending a cast (its last "
                        f"temperature and salinity held) is trusted to cast_extension_limit_m = {config.cast_extension_limit_m:g} m: take a deeper cast")
    extended = extend_cast(cast, deepest + _EXTENSION_MARGIN_M)
    report["extended_to_m"] = float(extended.depth_m[-1])
    return extended, report


def _sound_speed_error(profile: SoundSpeedProfile, log: pd.DataFrame, config: UsblConfig) -> SoundSpeedError:
    """The filter's model of the path-mean sound speed's error: the surface drift weighted by the surface layer's
    share of the path to the towfish's median depth, ``(L / D)(1 - exp(-D / L))``."""
    top = max(config.array.lever_arm_m[2] - config.array.antenna_height_m, 0.0)
    depth = max(float(np.nanmedian(log["fish_depth_m"].to_numpy())) - top, 1.0)
    share = config.surface_layer_m / depth * -np.expm1(-depth / config.surface_layer_m)
    speed = profile.harmonic_mean_m_s(top, min(top + depth, profile.bottom_m))
    return SoundSpeedError(config.sound_speed_sigma_m_s, config.surface_speed_drift_m_s_per_h * share, config.cast_age_h,
                           config.sound_speed_correlation_s, speed)


def _align(time: np.ndarray, row_time: np.ndarray, fixes: list, log: pd.DataFrame, config: UsblConfig,
           sound_speed: SoundSpeedError) -> tuple[int, NavState, np.ndarray]:
    """Start state and covariance at the row time of the first fix: position and velocity from a robust line through
    the first ``align_window_s`` of fixes (at their epochs ``time``), attitude from the INS's columns of that row. The
    fixes share the sound speed's error, so the start position carries it: the covariance holds their correlation."""
    valid = [i for i, f in enumerate(fixes) if f is not None]  # five or more (_check_enough_fixes)
    first = valid[0]
    window = [i for i in valid if time[i] - time[first] <= config.align_window_s]
    if len(window) < 5:
        window = valid[:5]
    t = time[window] - row_time[first]
    points = np.array([[fixes[i].north_m, fixes[i].east_m, fixes[i].depth_m] for i in window])
    # The fixes place the transponder; the INS is the lever arm away from it, at each row's attitude.
    attitudes = body_to_ned(*np.radians(log[["fish_roll_deg", "fish_pitch_deg", "fish_heading_deg"]].to_numpy()[window].T))
    points -= attitudes @ np.asarray(config.array.transponder_lever_arm_m, dtype=float)
    # Theil-Sen finds the line despite a bad fix; least squares on the fixes near it gives the estimate whose
    # variance the covariance below states.
    inliers = np.ones(t.size, dtype=bool)
    for axis in range(3):
        slope, intercept, _, _ = theilslopes(points[:, axis], t)
        residual = points[:, axis] - intercept - slope * t
        spread = 1.4826 * np.median(np.abs(residual)) + 1e-6
        inliers &= np.abs(residual) <= 4.0 * spread
    velocity, position = np.polyfit(t[inliers], points[inliers], 1)
    horizontal = np.mean([fixes[i].covariance_ne for i in window], axis=0)
    n, span = int(inliers.sum()), max(float(np.ptp(t[inliers])), 1.0)  # the fit's origin lies within a travel time of its first point
    # Line fit at its first point: intercept variance about 4 sigma^2 / n, slope variance 12 sigma^2 / (n span^2).
    variance = np.array([horizontal[0, 0], horizontal[1, 1], fixes[first].depth_variance_m2])
    covariance = np.zeros((STATES, STATES))
    covariance[0:3, 0:3] = np.diag(4.0 * variance / n)
    covariance[0:2, 0:2] = 4.0 * horizontal / n
    covariance[3:6, 3:6] = np.diag(12.0 * variance / (n * span**2))
    spec = config.imu
    covariance[6:8, 6:8] = np.eye(2) * np.radians(spec.alignment_tilt_deg) ** 2
    covariance[8, 8] = np.radians(spec.alignment_heading_deg) ** 2
    covariance[9:12, 9:12] = np.eye(3) * (spec.gyro_bias_deg_h * DEG_PER_HOUR) ** 2
    covariance[12:15, 12:15] = np.eye(3) * (spec.accel_bias_mg * MILLI_G) ** 2
    # The fit's position is off by the fixes' mean sound-speed displacement J b; the error state is -b (the estimate is 0).
    jacobian = np.mean([fixes[i].sound_speed_jacobian_m for i in window], axis=0)
    sound_speed_variance = sound_speed.variance(row_time[first] - row_time[0])
    covariance[SOUND, SOUND] = sound_speed_variance
    covariance[0:3, 0:3] += np.outer(jacobian, jacobian) * sound_speed_variance
    covariance[0:3, SOUND] = covariance[SOUND, 0:3] = -jacobian * sound_speed_variance
    row = log.iloc[first]
    attitude = body_to_ned(np.radians(row.fish_roll_deg), np.radians(row.fish_pitch_deg), np.radians(row.fish_heading_deg))
    return first, NavState(position, velocity, attitude), covariance


def _check_enough_fixes(log: pd.DataFrame, fixes: list, failures: dict[int, str]) -> None:
    """The alignment's five fixes, or an error that says why the replies gave none (the first failure's reason)."""
    valid = sum(fix is not None for fix in fixes)
    if valid >= 5:
        return
    replies = int(np.isfinite(log["travel_time_s"].to_numpy()).sum())
    why = f"; {len(failures)} replies gave no fix, the first (row {min(failures) + 1}): {failures[min(failures)]}" if failures else ""
    raise ValueError(f"{log.attrs.get('source', 'USBL log')}: the alignment needs at least five USBL fixes; {replies} of {len(log)} pings "
                     f"have a reply and {valid} of them a fix{why}")


def _trim(imu: ImuSamples, start_s: float) -> ImuSamples:
    """The IMU from the sample at or just before ``start_s`` (whose time becomes the start)."""
    first = max(int(np.searchsorted(imu.time_s, start_s, side="right")) - 1, 0)
    time = imu.time_s[first:].copy()
    time[0] = start_s
    return ImuSamples(time, imu.specific_force[first:], imu.angular_rate[first:])


def process(log: pd.DataFrame, imu: ImuSamples, cast: Cast, config: UsblConfig) -> UsblRun:
    """Fixes, alignment, the fused track and the comparison methods of one tow.

    Raises
    ------
    ValueError
        The IMU does not cover the log's pings after alignment, or too few fixes to align.
    """
    cast, cast_report = _cast_below_vehicle(cast, log, config)
    profile = SoundSpeedProfile.from_cast(cast, tolerance_m_s=0.05)
    check_replies(log, profile, config.array)
    frame = LocalFrame(float(log["ship_lat_deg"].iloc[0]), float(log["ship_lon_deg"].iloc[0]))
    # A fix places the towfish when it replied, one travel time before the ship heard it.
    travel = log["travel_time_s"].to_numpy()
    time = log["time_s"].to_numpy() - np.where(np.isfinite(travel), travel, 0.0)
    if np.any(np.diff(time) <= 0.0):
        row = int(np.flatnonzero(np.diff(time) <= 0.0)[0]) + 2
        raise ValueError(f"USBL log: the reply at row {row} ({time[row - 1]:.3f} s) does not come after the one before; pings overlap")
    fixes, failures, ship = _fixes(log, profile, config.array, frame)
    _check_enough_fixes(log, fixes, failures)
    row_time = log["time_s"].to_numpy()
    sound_speed = _sound_speed_error(profile, log, config)
    first, state, covariance = _align(time, row_time, fixes, log, config, sound_speed)
    # The filter starts at the first fix's row time and reports from the next ping on.
    start, begin = first + 1, row_time[first]
    if start >= time.size:
        raise ValueError("the log ends at its first fix: nothing to fuse after the alignment")
    if imu.time_s[0] > begin or imu.time_s[-1] < time[-1]:
        raise ValueError(f"the IMU ({imu.time_s[0]:.2f} to {imu.time_s[-1]:.2f} s) must cover the pings from {begin:.2f} to {time[-1]:.2f} s")
    earth = EarthModel.at(frame.latitude0_deg, rotating=config.earth_rotation)
    trimmed = _trim(imu, begin)
    filt = InsUsblFilter(state.copy(), covariance, config.imu.noise(), earth, config.gate_probability,
                         transponder_lever_arm_m=np.asarray(config.array.transponder_lever_arm_m, dtype=float), sound_speed=sound_speed,
                         elapsed_s=float(begin - log["time_s"].iloc[0]))
    fused = fuse(trimmed, time[start:], fixes[start:], filt, depths_m=log["fish_depth_m"].to_numpy()[start:],
                 depth_variance_m2=config.array.depth_noise_m**2)
    free_position, _, _ = strapdown(trimmed, state, earth)
    ins = np.column_stack([np.interp(time[start:], trimmed.time_s, free_position[:, k]) for k in range(3)])
    dead = _dead_reckoning(np.concatenate(([begin], time[start:])), trimmed, log.iloc[[first, *range(start, time.size)]], state,
                          earth.gravity_m_s2)[1:]
    truth = injected = None
    if {"true_lat_deg", "true_lon_deg", "true_depth_m"} <= set(log.columns):
        north, east = frame.to_local(log["true_lat_deg"].to_numpy(), log["true_lon_deg"].to_numpy())
        truth = np.column_stack([north, east, log["true_depth_m"].to_numpy()])
    if "injected" in log.columns:
        injected = log["injected"].to_numpy() != ""
    return UsblRun(frame, profile, time, fixes, failures, fused, start, ins, dead, truth, injected, ship, _usbl_positions(fixes, log, config),
                   cast_report)


def _usbl_positions(fixes: list, log: pd.DataFrame, config: UsblConfig) -> np.ndarray:
    attitude = body_to_ned(*np.radians(log[["fish_roll_deg", "fish_pitch_deg", "fish_heading_deg"]].to_numpy().T))
    lever = attitude @ np.asarray(config.array.transponder_lever_arm_m, dtype=float)
    raw = np.array([[f.north_m, f.east_m, f.depth_m] if f is not None else [np.nan] * 3 for f in fixes])
    return raw - lever


def _dead_reckoning(time: np.ndarray, imu: ImuSamples, log: pd.DataFrame, start: NavState, gravity: float) -> np.ndarray:
    """Eqs. 6-7 at the pings: the along-track acceleration is the IMU's forward specific force plus gravity's share at
    the logged pitch, averaged over each ping interval; the azimuth is the logged compass heading."""
    pitch = np.radians(log["fish_pitch_deg"].to_numpy())
    forward = np.interp(time, imu.time_s, imu.specific_force[:, 0]) - gravity * np.sin(pitch)
    sums = np.concatenate(([0.0], np.cumsum(imu.specific_force[1:, 0] * np.diff(imu.time_s))))
    mean = np.diff(np.interp(time, imu.time_s, sums)) / np.diff(time) - gravity * np.sin(pitch[1:])
    along = np.concatenate(([forward[0]], mean))
    speed0 = float(np.hypot(start.velocity[0], start.velocity[1]))
    north, east, _ = dead_reckon(time, along, np.radians(log["fish_heading_deg"].to_numpy()), north0_m=start.position[0],
                                 east0_m=start.position[1], speed0_m_s=speed0)
    return np.column_stack([north, east, log["fish_depth_m"].to_numpy()])
