"""The towfish's inertial navigation: the paper's one-point-one-azimuth dead reckoning (eqs. 6-7) and a
strapdown mechanization of IMU samples in the local north-east-down frame.

The strapdown frame is a local tangent plane on a non-rotating Earth with constant gravity (``gsw.grav`` at the
latitude): right for the simulator's IMU and for an IMU whose output has the Earth's rate removed, not for raw
navigation-grade gyros (the Earth's 15 deg/h and the Coriolis term are not modelled; see docs/usbl.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .frames import rotation_from_vector

__all__ = ["ImuSamples", "NavState", "strapdown", "strapdown_step", "dead_reckon", "MIN_IMU_RATE_HZ"]

#: The slowest IMU the mechanization accepts (the issue's floor).
MIN_IMU_RATE_HZ = 10.0


@dataclass(frozen=True)
class ImuSamples:
    """IMU output: sample ``k`` is the mean specific force (m/s^2) and angular rate (rad/s), body frame
    (forward, starboard, down), over the interval from ``time_s[k - 1]`` to ``time_s[k]``."""

    time_s: np.ndarray
    specific_force: np.ndarray
    angular_rate: np.ndarray

    def __post_init__(self) -> None:
        time = np.asarray(self.time_s, dtype=float)
        force = np.asarray(self.specific_force, dtype=float)
        rate = np.asarray(self.angular_rate, dtype=float)
        if time.ndim != 1 or force.shape != (time.size, 3) or rate.shape != (time.size, 3):
            raise ValueError(f"IMU samples need n times and n x 3 specific forces and rates, got {time.shape}, {force.shape}, {rate.shape}")
        if time.size < 2:
            raise ValueError("IMU samples: at least two are needed")
        steps = np.diff(time)
        if np.any(steps <= 0.0):
            row = int(np.flatnonzero(steps <= 0.0)[0]) + 1
            raise ValueError(f"IMU samples: times must increase; sample {row} at {time[row]:.4f} s follows {time[row - 1]:.4f} s")
        if np.median(steps) > 1.0 / MIN_IMU_RATE_HZ + 1e-9:
            raise ValueError(f"IMU samples: median interval {np.median(steps):.4f} s is slower than {MIN_IMU_RATE_HZ:.0f} Hz")
        if not (np.all(np.isfinite(force)) and np.all(np.isfinite(rate))):
            raise ValueError("IMU samples: specific force and angular rate must be finite")
        object.__setattr__(self, "time_s", time)
        object.__setattr__(self, "specific_force", force)
        object.__setattr__(self, "angular_rate", rate)


@dataclass
class NavState:
    """Position and velocity (north, east, down; m, m/s) and attitude (body-to-NED matrix) of the INS."""

    position: np.ndarray
    velocity: np.ndarray
    attitude: np.ndarray

    def copy(self) -> NavState:
        return NavState(self.position.copy(), self.velocity.copy(), self.attitude.copy())


def strapdown_step(state: NavState, specific_force: np.ndarray, angular_rate: np.ndarray, dt: float, gravity_m_s2: float) -> NavState:
    """One step: attitude by the rotation vector ``w dt``; velocity by the specific force rotated at the interval's
    mid-attitude plus gravity; position by the trapezoid of the velocities."""
    half = state.attitude @ rotation_from_vector(angular_rate * (dt / 2.0))
    attitude = half @ rotation_from_vector(angular_rate * (dt / 2.0))
    velocity = state.velocity + (half @ specific_force + np.array([0.0, 0.0, gravity_m_s2])) * dt
    position = state.position + (state.velocity + velocity) * (dt / 2.0)
    return NavState(position, velocity, attitude)


def strapdown(imu: ImuSamples, initial: NavState, gravity_m_s2: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Integrate IMU samples from ``initial`` (the state at ``imu.time_s[0]``); returns position, velocity (n x 3)
    and attitude (n x 3 x 3) at every sample time."""
    n = imu.time_s.size
    position, velocity, attitude = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3, 3))
    state = initial.copy()
    position[0], velocity[0], attitude[0] = state.position, state.velocity, state.attitude
    for k in range(1, n):
        state = strapdown_step(state, imu.specific_force[k], imu.angular_rate[k], imu.time_s[k] - imu.time_s[k - 1], gravity_m_s2)
        position[k], velocity[k], attitude[k] = state.position, state.velocity, state.attitude
    return position, velocity, attitude


def dead_reckon(time_s, along_acceleration_m_s2, heading_rad, *, north0_m: float, east0_m: float,
                speed0_m_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One-point-one-azimuth dead reckoning (Du et al. 2018, eqs. 6-7).

    Over each interval ``t = t_i - t_(i-1)`` the along-track acceleration ``a_i`` gives the speed
    ``v_i = v_(i-1) + a_i t`` and the distance ``d_i = v_(i-1) t + a_i t^2 / 2`` (eq. 6, read recursively: the
    paper's ``v_i = a_i t`` is the speed gained in the interval); the azimuth ``alpha_i`` of the step is the
    compass heading's circular mean over the interval, and ``x_i = x_0 + sum d sin(alpha)`` (east),
    ``y_i = y_0 + sum d cos(alpha)`` (north) (eq. 7).

    Returns
    -------
    north, east, speed : numpy.ndarray
        At every time, starting from the given point and speed.
    """
    time = np.asarray(time_s, dtype=float)
    accel = np.asarray(along_acceleration_m_s2, dtype=float)
    heading = np.asarray(heading_rad, dtype=float)
    if not (time.shape == accel.shape == heading.shape) or time.ndim != 1:
        raise ValueError(f"dead reckoning needs matching 1-D times, accelerations and headings, got {time.shape}, {accel.shape}, {heading.shape}")
    if np.any(np.diff(time) <= 0.0):
        raise ValueError("dead reckoning: times must increase")
    dt = np.diff(time)
    speed = speed0_m_s + np.concatenate(([0.0], np.cumsum(accel[1:] * dt)))
    distance = speed[:-1] * dt + 0.5 * accel[1:] * dt**2
    azimuth = np.angle(np.exp(1j * heading[:-1]) + np.exp(1j * heading[1:]))
    north = north0_m + np.concatenate(([0.0], np.cumsum(distance * np.cos(azimuth))))
    east = east0_m + np.concatenate(([0.0], np.cumsum(distance * np.sin(azimuth))))
    return north, east, speed
