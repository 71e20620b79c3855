"""The towfish's inertial navigation: the paper's one-point-one-azimuth dead reckoning (eqs. 6-7) and a
strapdown mechanization of IMU samples in the local north-east-down frame.

The strapdown frame is the Earth-fixed local tangent plane (north, east, down at the run's origin): the gyros
sense the Earth's rotation as well as the vehicle's, and the velocity feels the Coriolis acceleration, both
mechanized; gravity is the constant plumb-line gravity of the origin (``gsw.grav``), whose direction is taken
as the same over the few kilometres of a run (a 1 km offset tilts it by 0.16 mrad; see docs/usbl.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .frames import rotation_from_vector

__all__ = ["EarthModel", "ImuSamples", "NavState", "strapdown", "strapdown_step", "dead_reckon", "MIN_IMU_RATE_HZ", "EARTH_RATE_RAD_S"]

#: The slowest IMU the mechanization accepts (the issue's floor).
MIN_IMU_RATE_HZ = 10.0

#: WGS 84's rotation rate of the Earth.
EARTH_RATE_RAD_S = 7.292115e-5


@dataclass(frozen=True)
class EarthModel:
    """Gravity (m/s^2, down) and the Earth's rotation (rad/s, north-east-down) on the local tangent plane."""

    gravity_m_s2: float
    rate_ned: np.ndarray

    @classmethod
    def at(cls, latitude_deg: float, *, rotating: bool = True) -> EarthModel:
        """The Earth at a latitude: ``gsw.grav`` at the surface and ``Omega (cos L, 0, -sin L)``; ``rotating=False``
        gives a non-rotating Earth (for an IMU whose output has the Earth's rate removed)."""
        import gsw

        latitude = np.radians(latitude_deg)
        rate = EARTH_RATE_RAD_S * np.array([np.cos(latitude), 0.0, -np.sin(latitude)]) if rotating else np.zeros(3)
        return cls(float(gsw.grav(latitude_deg, 0.0)), rate)

    @property
    def gravity_ned(self) -> np.ndarray:
        return np.array([0.0, 0.0, self.gravity_m_s2])


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


def strapdown_step(state: NavState, specific_force: np.ndarray, angular_rate: np.ndarray, dt: float, earth: EarthModel) -> NavState:
    """One step: attitude by the body rotation ``w dt`` less the Earth's ``Omega dt`` (in halves, so the velocity
    update sees the interval's mid-attitude); velocity by the rotated specific force, gravity and the Coriolis
    term at the step's first velocity; position by the trapezoid of the velocities."""
    body_half = rotation_from_vector(angular_rate * (dt / 2.0))
    earth_half = rotation_from_vector(-earth.rate_ned * (dt / 2.0))
    half = earth_half @ state.attitude @ body_half
    attitude = earth_half @ half @ body_half
    coriolis = 2.0 * np.cross(earth.rate_ned, state.velocity)
    velocity = state.velocity + (half @ specific_force + earth.gravity_ned - coriolis) * dt
    position = state.position + (state.velocity + velocity) * (dt / 2.0)
    return NavState(position, velocity, attitude)


def strapdown(imu: ImuSamples, initial: NavState, earth: EarthModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Integrate IMU samples from ``initial`` (the state at ``imu.time_s[0]``); returns position, velocity (n x 3)
    and attitude (n x 3 x 3) at every sample time."""
    n = imu.time_s.size
    position, velocity, attitude = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3, 3))
    state = initial.copy()
    position[0], velocity[0], attitude[0] = state.position, state.velocity, state.attitude
    for k in range(1, n):
        state = strapdown_step(state, imu.specific_force[k], imu.angular_rate[k], imu.time_s[k] - imu.time_s[k - 1], earth)
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
