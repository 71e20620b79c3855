"""Simulate an INS+USBL tow: the towfish's true motion and its IMU, the ship ahead on the same track, the USBL's
replies with range-dependent noise, dropouts and bad fixes that grow in the ship's turns. The replies are traced
through the truth ocean of :mod:`lost.host.usbl.ocean` (finer than the cast, warming and heaving over the tow), not
the cast the processing is given. The output is what a recording holds (the log and IMU tables of docs/usbl.md)
plus the truth, so a simulated run goes through the same processing as a recorded one.

The truth is exactly consistent with the strapdown mechanization on the rotating Earth: at every IMU sample the
ideal angular rate is the rotation between the true attitudes of the interval's ends with the Earth's turn
over the interval added, and the ideal specific force the one that gives the true velocity change (gravity and
Coriolis included) at the interval's mid-attitude; the true position is the trapezoid of the true velocities.
With an error-free IMU, :func:`lost.host.usbl.ins.strapdown` reproduces the truth to rounding.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from .fix import reply_from_geometry
from .frames import LocalFrame, body_to_ned, euler_from_matrix, rotation_from_vector
from .ins import EarthModel
from .ocean import TruthOcean
from .scenario import DEG_PER_HOUR, MILLI_G, UsblScenario
from .sound import Cast, read_cast

__all__ = ["SimulatedTow", "simulate_tow", "LOG_COLUMNS", "IMU_COLUMNS"]

#: The recorded log's columns, one row per USBL ping (docs/usbl.md); the true_* and injected columns only in simulations.
LOG_COLUMNS = ["time_s", "ship_lat_deg", "ship_lon_deg", "ship_roll_deg", "ship_pitch_deg", "ship_heading_deg", "travel_time_s",
               "phase_x_rad", "phase_y_rad", "fish_depth_m", "fish_roll_deg", "fish_pitch_deg", "fish_heading_deg"]
TRUTH_COLUMNS = ["true_lat_deg", "true_lon_deg", "true_depth_m", "injected"]
IMU_COLUMNS = ["time_s", "fx_m_s2", "fy_m_s2", "fz_m_s2", "wx_rad_s", "wy_rad_s", "wz_rad_s"]


@dataclass(frozen=True)
class SimulatedTow:
    """A simulated recording: the log (one row per ping), the IMU table, the cast, and the truth at the IMU samples."""

    log: pd.DataFrame
    imu: pd.DataFrame
    cast: Cast
    truth_time_s: np.ndarray
    truth_position: np.ndarray
    truth_velocity: np.ndarray
    truth_attitude: np.ndarray


def _course(scenario: UsblScenario, time: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Heading (rad) and turn rate (rad/s) of the course program at the given times."""
    tow = scenario.tow
    durations = np.array([0.0] + [d for d, _ in tow.course])
    rates = np.radians([r for _, r in tow.course])
    breaks = np.cumsum(durations)
    headings = np.radians(tow.heading_deg) + np.concatenate(([0.0], np.cumsum(rates * durations[1:])))
    index = np.clip(np.searchsorted(breaks, time, side="right") - 1, 0, rates.size)
    rate = np.where(index < rates.size, np.append(rates, 0.0)[index], 0.0)
    return np.interp(time, breaks, headings), rate


def _true_motion(scenario: UsblScenario, time: np.ndarray, earth: EarthModel) -> tuple[np.ndarray, ...]:
    tow = scenario.tow
    heading, _ = _course(scenario, time)
    swing = 2 * np.pi / 300.0
    climb = tow.depth_swing_m * swing * np.cos(swing * time)
    velocity = np.stack([tow.speed_m_s * np.cos(heading), tow.speed_m_s * np.sin(heading), climb], axis=1)
    dt = np.diff(time)[:, None]
    position = np.concatenate([np.zeros((1, 3)), np.cumsum((velocity[1:] + velocity[:-1]) / 2 * dt, axis=0)])
    position[:, 2] += tow.depth_m
    roll = np.radians(tow.roll_swing_deg) * np.sin(2 * np.pi * time / 8.3)
    pitch = np.radians(tow.pitch_swing_deg) * np.sin(2 * np.pi * time / 11.7)
    attitude = body_to_ned(roll, pitch, heading)
    # The mechanization's step: C_k = E C_(k-1) R(w dt), E the Earth's turn over dt; so R(w dt) = C_(k-1)' E' C_k.
    interval = float(dt[0, 0])
    earth_turn = rotation_from_vector(-earth.rate_ned * interval)
    earth_half = rotation_from_vector(-earth.rate_ned * interval / 2.0)
    step = Rotation.from_matrix(np.einsum("kji,mj,kml->kil", attitude[:-1], earth_turn, attitude[1:])).as_rotvec()
    rate = step / dt
    middle = earth_half @ attitude[:-1] @ Rotation.from_rotvec(step / 2).as_matrix()
    coriolis = 2.0 * np.cross(earth.rate_ned, velocity[:-1])
    acceleration = np.diff(velocity, axis=0) / dt - earth.gravity_ned + coriolis
    force = np.einsum("kji,kj->ki", middle, acceleration)
    # Sample 0 has no interval before it; it repeats sample 1 (the mechanization never uses it).
    return position, velocity, attitude, np.vstack([force[:1], force]), np.vstack([rate[:1], rate])


def _imu_errors(scenario: UsblScenario, rng: np.random.Generator, n: int, dt: float) -> tuple[np.ndarray, np.ndarray]:
    spec = scenario.imu
    gyro_bias = rng.normal(0.0, spec.gyro_bias_deg_h * DEG_PER_HOUR, 3) + np.cumsum(
        rng.normal(0.0, spec.gyro_bias_walk_deg_h_sqrt_h * DEG_PER_HOUR / 60.0 * np.sqrt(dt), (n, 3)), axis=0)
    accel_bias = rng.normal(0.0, spec.accel_bias_mg * MILLI_G, 3) + np.cumsum(
        rng.normal(0.0, spec.accel_bias_walk_mg_sqrt_h * MILLI_G / 60.0 * np.sqrt(dt), (n, 3)), axis=0)
    noise = scenario.imu.noise()
    gyro = gyro_bias + rng.normal(0.0, noise.angle_random_walk / np.sqrt(dt), (n, 3))
    accel = accel_bias + rng.normal(0.0, noise.velocity_random_walk / np.sqrt(dt), (n, 3))
    return gyro, accel


def simulate_tow(scenario: UsblScenario) -> SimulatedTow:
    """Simulate the scenario's tow (deterministic for its seed)."""
    rng = np.random.default_rng(scenario.seed)
    cast = read_cast(scenario.cast_path())
    tow = scenario.tow
    ocean = TruthOcean.build(cast, scenario.ocean, tow.depth_m + tow.depth_swing_m + abs(scenario.usbl.transponder_lever_arm_m[2]) + 10.0)
    latitude, longitude = scenario.origin
    earth = EarthModel.at(latitude)
    dt = 1.0 / scenario.imu_rate_hz
    lead = int(round(scenario.tow.layback_m / scenario.tow.speed_m_s / dt))
    samples = int(round(scenario.duration_s / dt)) + 1
    time = np.arange(samples + lead) * dt
    position, velocity, attitude, force, rate = _true_motion(scenario, time, earth)
    gyro_error, accel_error = _imu_errors(scenario, rng, samples, dt)
    imu = pd.DataFrame(np.column_stack([time[:samples], force[:samples] + accel_error, rate[:samples] + gyro_error]), columns=IMU_COLUMNS)

    frame = LocalFrame(latitude, longitude)
    step = int(round(scenario.ping_interval_s / dt))
    rows = [_ping(scenario, rng, ocean, frame, k, time, position, attitude, lead) for k in range(step, samples, step)]
    log = pd.DataFrame(rows, columns=LOG_COLUMNS + TRUTH_COLUMNS)
    return SimulatedTow(log, imu, cast, time[:samples], position[:samples], velocity[:samples], attitude[:samples])


def _ping(scenario: UsblScenario, rng: np.random.Generator, ocean: TruthOcean, frame: LocalFrame, k: int, time: np.ndarray,
          position: np.ndarray, attitude: np.ndarray, lead: int) -> list:
    tow, array, faults = scenario.tow, scenario.usbl, scenario.faults
    t = time[k]
    profile = ocean.profile_at(float(t))
    ship = position[k + lead, :2]
    ship_heading = float(np.arctan2(attitude[k + lead, 1, 0], attitude[k + lead, 0, 0]))
    ship_roll = np.radians(tow.ship_roll_swing_deg) * np.sin(2 * np.pi * t / 9.1)
    ship_pitch = np.radians(tow.ship_pitch_swing_deg) * np.sin(2 * np.pi * t / 6.7)
    _, ship_turn = _course(scenario, np.array([t + lead * (time[1] - time[0])]))
    turning = min(1.0, abs(float(np.degrees(ship_turn[0]))) / faults.turn_rate_full_deg_s)
    fish = position[k]
    fish_attitude = np.degrees(euler_from_matrix(attitude[k]))

    travel, phase_x, phase_y, injected = np.nan, np.nan, np.nan, ""
    if rng.random() >= faults.dropout_rate + faults.dropout_rate_turning * turning:
        # The reply left the towfish one travel time before the ship heard it (the time estimated at the harmonic-mean
        # speed: within a millisecond, a couple of millimetres of towfish motion).
        depth_now = position[k, 2]
        distance = np.hypot(np.hypot(*(ship - position[k, :2])), depth_now - array.lever_arm_m[2] + array.antenna_height_m)
        before = t - distance / profile.harmonic_mean_m_s(0.0, depth_now)
        fish = np.array([np.interp(before, time, position[:, axis]) for axis in range(3)])
        transponder = fish + attitude[int(round(before / (time[1] - time[0])))] @ np.asarray(array.transponder_lever_arm_m)
        travel, phase_x, phase_y = reply_from_geometry(profile, array, roll_rad=ship_roll, pitch_rad=ship_pitch, heading_rad=ship_heading,
                                                       antenna_north_m=ship[0], antenna_east_m=ship[1], target_north_m=transponder[0],
                                                       target_east_m=transponder[1], target_depth_m=transponder[2])
        travel += rng.normal(0.0, array.travel_time_noise_s)
        phase_noise = array.phase_noise_at(float(distance))
        phase_x += rng.normal(0.0, phase_noise)
        phase_y += rng.normal(0.0, phase_noise)
        if rng.random() < faults.bad_fix_rate + faults.bad_fix_rate_turning * turning:
            if rng.random() < 0.5:
                injected = "phase"
                error = rng.choice([-1.0, 1.0]) * rng.uniform(*faults.bad_phase_rad)
                phase_x, phase_y = (phase_x + error, phase_y) if rng.random() < 0.5 else (phase_x, phase_y + error)
            else:
                injected = "delay"
                travel += rng.uniform(*faults.bad_delay_s)
    antenna = ship + rng.normal(0.0, array.gnss_noise_m, 2)
    lat, lon = frame.to_geographic(antenna[0], antenna[1])
    true_lat, true_lon = frame.to_geographic(fish[0], fish[1])
    return [t, float(lat), float(lon),
            np.degrees(ship_roll + rng.normal(0.0, array.tilt_noise_rad)), np.degrees(ship_pitch + rng.normal(0.0, array.tilt_noise_rad)),
            np.degrees(ship_heading + rng.normal(0.0, array.heading_noise_rad)) % 360.0,
            travel, phase_x, phase_y, fish[2] + rng.normal(0.0, array.depth_noise_m),
            fish_attitude[0] + rng.normal(0.0, scenario.imu.alignment_tilt_deg), fish_attitude[1] + rng.normal(0.0, scenario.imu.alignment_tilt_deg),
            (fish_attitude[2] + rng.normal(0.0, scenario.imu.alignment_heading_deg)) % 360.0,
            float(true_lat), float(true_lon), fish[2], injected]

