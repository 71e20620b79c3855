"""The USBL fix (Du et al. 2018, eqs. 1-2 and the ray trace): direction from the array's phase differences,
horizontal range from the ray joining the transducer to the towfish's known depth, the ship's attitude and
lever arm, and the fix's covariance.

Conventions: the array's axes are the ship's (x forward, y starboard, z down); ``phase_x`` and ``phase_y`` are
the phase differences (rad) across the baselines along x and y, so that eq. 1 gives the direction cosines
``cos beta = lambda phase / (2 pi d)``; the travel time is one way (the interrogation's round trip less the
transponder's turnaround, halved).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .frames import body_to_ned
from .rays import ray_to_offset, solve_ray, trace_to_depth
from .sound import SoundSpeedProfile

__all__ = ["UsblArray", "UsblFix", "direction_cosines_from_phase", "phase_from_direction_cosines", "reply_from_geometry", "usbl_fix"]


@dataclass(frozen=True)
class UsblArray:
    """The USBL's array, mounting and noise (the fix's covariance is built from the noise terms, the simulator's
    replies draw from them).

    Parameters
    ----------
    frequency_hz : float
        Carrier frequency; the wavelength is the sound speed at the array over it.
    baseline_m : float
        Element spacing d of both baselines (at most half a wavelength for unambiguous phases).
    lever_arm_m : tuple
        From the GNSS antenna to the array's centre, in the ship's frame (forward, starboard, down), m.
    antenna_height_m : float
        Height of the GNSS antenna above the sea surface, m.
    phase_noise_rad, travel_time_noise_s, tilt_noise_rad, heading_noise_rad, gnss_noise_m, depth_noise_m : float
        One-sigma noise of the phase differences, the one-way travel time, the ship's roll and pitch, its heading,
        the GNSS horizontal position (per axis) and the towfish's pressure depth.
    direction_noise : float, optional
        One-sigma noise of a direction cosine, for a USBL that reports directions rather than phases; by default
        it follows from the phase noise, ``lambda phase_noise / (2 pi d)``.
    noise_growth_per_km : float
        The reply's signal weakens with range: the phase (or direction) noise is multiplied by
        ``1 + noise_growth_per_km * slant range in km``.
    turnaround_s : float
        The transponder's delay between hearing the interrogation and replying, for logs of two-way travel times.
    transponder_lever_arm_m : tuple
        From the towfish's INS (and its pressure sensor) to its transponder, in the towfish's frame (forward,
        starboard, down), m.
    """

    frequency_hz: float = 20000.0
    baseline_m: float = 0.035
    lever_arm_m: tuple[float, float, float] = (0.0, 0.0, 20.0)
    antenna_height_m: float = 15.0
    phase_noise_rad: float = 0.01
    travel_time_noise_s: float = 2e-5
    tilt_noise_rad: float = np.radians(0.02)
    heading_noise_rad: float = np.radians(0.05)
    gnss_noise_m: float = 0.5
    depth_noise_m: float = 0.5
    direction_noise: float | None = None
    noise_growth_per_km: float = 0.0
    turnaround_s: float = 0.0
    transponder_lever_arm_m: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        for name in ("frequency_hz", "baseline_m", "phase_noise_rad", "travel_time_noise_s", "gnss_noise_m", "depth_noise_m"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"UsblArray.{name} must be positive, got {getattr(self, name)}")

    def wavelength_m(self, speed_m_s: float) -> float:
        return speed_m_s / self.frequency_hz

    def range_factor(self, slant_range_m: float) -> float:
        """How much the phase (or direction) noise grows at a slant range."""
        return 1.0 + self.noise_growth_per_km * slant_range_m / 1000.0

    def phase_noise_at(self, slant_range_m: float) -> float:
        """One-sigma phase noise (rad) of a reply from a slant range."""
        return self.phase_noise_rad * self.range_factor(slant_range_m)

    def cosine_noise(self, speed_m_s: float, slant_range_m: float = 0.0) -> float:
        """One-sigma noise of a direction cosine at the array (sound speed ``speed_m_s`` there) from a slant range."""
        if self.direction_noise is not None:
            return self.direction_noise * self.range_factor(slant_range_m)
        return self.wavelength_m(speed_m_s) * self.phase_noise_at(slant_range_m) / (2.0 * np.pi * self.baseline_m)


@dataclass(frozen=True)
class UsblFix:
    """A towfish position from one USBL reply, in the local frame, with its covariance.

    ``covariance_ne`` is the 2 x 2 covariance of (north, east) in m^2; ``depth_variance_m2`` that of the depth;
    ``cross_ne_depth`` the covariances of north and east with the depth: the horizontal range comes from the ray to
    the measured depth, so a depth error moves the fix along the line of sight (by ``-cot(theta_end)`` per metre).
    ``sound_speed_jacobian_m`` is how the fix moves (north, east, down; m) per unit of fractional error in the path-mean
    sound speed: the slant range scales with it and, the depth being known, the horizontal range by ``slant^2 / horizontal``
    times as much, along the line of sight. That error is common to successive fixes, so it is not in the covariance but
    a state of the filter (:class:`lost.host.usbl.filter.SoundSpeedError`).
    """

    north_m: float
    east_m: float
    depth_m: float
    covariance_ne: np.ndarray
    depth_variance_m2: float
    slant_range_m: float
    horizontal_range_m: float
    azimuth_rad: float
    iterations: int
    cross_ne_depth: np.ndarray = field(default_factory=lambda: np.zeros(2))
    sound_speed_jacobian_m: np.ndarray = field(default_factory=lambda: np.zeros(3))

    @property
    def covariance_ned(self) -> np.ndarray:
        """The 3 x 3 covariance of (north, east, depth)."""
        covariance = np.empty((3, 3))
        covariance[:2, :2] = self.covariance_ne
        covariance[:2, 2] = covariance[2, :2] = self.cross_ne_depth
        covariance[2, 2] = self.depth_variance_m2
        return covariance


def direction_cosines_from_phase(phase_rad, wavelength_m: float, baseline_m: float) -> np.ndarray:
    """Eq. 1 solved for the direction cosine: ``cos beta = lambda phase / (2 pi d)``."""
    return wavelength_m * np.asarray(phase_rad, dtype=float) / (2.0 * np.pi * baseline_m)


def phase_from_direction_cosines(cosine, wavelength_m: float, baseline_m: float) -> np.ndarray:
    """Eq. 1: the phase difference across a baseline ``d`` for a direction cosine."""
    return 2.0 * np.pi * baseline_m / wavelength_m * np.asarray(cosine, dtype=float)


def _azimuth(cos_x: float, cos_y: float, attitude: np.ndarray) -> tuple[float, float]:
    """Azimuth and angle from the vertical (rad) of the reply's arrival direction, in the local frame."""
    down = 1.0 - cos_x * cos_x - cos_y * cos_y
    if down <= 0.0:
        raise ValueError(f"direction cosines ({cos_x:.4f}, {cos_y:.4f}) have no downward component: the phases are wrong or wrapped")
    direction = body_to_ned(*attitude) @ np.array([cos_x, cos_y, np.sqrt(down)])
    return float(np.arctan2(direction[1], direction[0])), float(np.arccos(np.clip(direction[2], -1.0, 1.0)))


def usbl_fix(profile: SoundSpeedProfile, array: UsblArray, *, travel_time_s: float, roll_rad: float, pitch_rad: float, heading_rad: float,
             antenna_north_m: float, antenna_east_m: float, target_depth_m: float, phase_x_rad: float | None = None,
             phase_y_rad: float | None = None, direction_cosines: tuple[float, float] | None = None) -> UsblFix:
    """One USBL fix of a towfish at a known depth, from the reply's phases or its direction cosines (array frame).

    The direction (eqs. 1-2) gives the azimuth, rotated by the ship's attitude into the local frame; the range is
    the ray joining the transducer to the towfish's depth for the travel time (eqs. 3-5, started at the measured
    angle). The covariance propagates the array's noise terms: azimuth noise across the line of sight (its
    Jacobian on the phases and the attitude taken numerically), travel-time and depth noise along it (through the
    ray's angle at the towfish), and the GNSS noise on both axes.

    Raises
    ------
    ValueError
        The phases give no downward direction, the travel time cannot reach the depth, or the ray does not converge.
    """
    attitude = np.array([roll_rad, pitch_rad, heading_rad])
    transducer = np.array([antenna_north_m, antenna_east_m, -array.antenna_height_m]) + body_to_ned(*attitude) @ np.asarray(array.lever_arm_m)
    speed = float(profile.speed_at(max(transducer[2], 0.0)))
    wavelength = array.wavelength_m(speed)
    phases = [phase for phase in (phase_x_rad, phase_y_rad) if phase is not None]
    if (direction_cosines is None and len(phases) < 2) or (direction_cosines is not None and phases):
        raise ValueError("a USBL fix needs either both phases (phase_x_rad, phase_y_rad) or direction_cosines, not both or neither")
    if direction_cosines is None:
        cos_x, cos_y = direction_cosines_from_phase([phase_x_rad, phase_y_rad], wavelength, array.baseline_m)
    else:
        cos_x, cos_y = (float(c) for c in direction_cosines)
    azimuth, angle = _azimuth(cos_x, cos_y, attitude)
    top = max(transducer[2], 0.0)
    ray = solve_ray(profile, top, target_depth_m, travel_time_s, initial_angle_rad=angle)
    horizontal = ray.horizontal_m
    north = transducer[0] + horizontal * np.cos(azimuth)
    east = transducer[1] + horizontal * np.sin(azimuth)

    # Along the line of sight: the ray's angle at the towfish turns time and depth noise into horizontal range.
    end_angle = ray.arrival_angle_rad
    end_speed = float(profile.speed_at(target_depth_m))
    sine = max(np.sin(end_angle), 1e-3)
    along_var = (end_speed / sine * array.travel_time_noise_s) ** 2 + (np.cos(end_angle) / sine * array.depth_noise_m) ** 2
    cosine_noise = array.cosine_noise(speed, ray.slant_range_m)
    jacobian = _azimuth_jacobian(cos_x, cos_y, attitude)
    azimuth_var = float(jacobian @ np.diag([cosine_noise**2, cosine_noise**2, array.tilt_noise_rad**2,
                                            array.tilt_noise_rad**2, array.heading_noise_rad**2]) @ jacobian)
    along = np.array([np.cos(azimuth), np.sin(azimuth)])
    across = np.array([-np.sin(azimuth), np.cos(azimuth)])
    covariance = along_var * np.outer(along, along) + horizontal**2 * azimuth_var * np.outer(across, across) + array.gnss_noise_m**2 * np.eye(2)
    cross = -np.cos(end_angle) / sine * array.depth_noise_m**2 * along
    speed_jacobian = np.append(ray.slant_range_m**2 / max(horizontal, 1.0) * along, 0.0)
    return UsblFix(float(north), float(east), float(target_depth_m), covariance, array.depth_noise_m**2, ray.slant_range_m, horizontal,
                  azimuth, ray.iterations, cross, speed_jacobian)


def _azimuth_jacobian(cos_x: float, cos_y: float, attitude: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """d azimuth / d (cos_x, cos_y, roll, pitch, heading), by central differences (cheap: no ray trace)."""
    inputs = np.array([cos_x, cos_y, *attitude])
    jacobian = np.empty(5)
    for k in range(5):
        up, down = inputs.copy(), inputs.copy()
        up[k] += step
        down[k] -= step
        difference = _azimuth(up[0], up[1], up[2:])[0] - _azimuth(down[0], down[1], down[2:])[0]
        jacobian[k] = np.angle(np.exp(1j * difference)) / (2.0 * step)
    return jacobian


def reply_from_geometry(profile: SoundSpeedProfile, array: UsblArray, *, roll_rad: float, pitch_rad: float, heading_rad: float,
                        antenna_north_m: float, antenna_east_m: float, target_north_m: float, target_east_m: float,
                        target_depth_m: float) -> tuple[float, float, float]:
    """The noise-free reply a USBL measures of a target: one-way travel time and the two phase differences (rad).

    The inverse of :func:`usbl_fix`, for the simulator and the tests: the ray joining the transducer to the target
    (the direct one: :func:`lost.host.usbl.rays.ray_to_offset`), its arrival direction in the
    array's frame, and eq. 1.
    """
    attitude = np.array([roll_rad, pitch_rad, heading_rad])
    rotation = body_to_ned(*attitude)
    transducer = np.array([antenna_north_m, antenna_east_m, -array.antenna_height_m]) + rotation @ np.asarray(array.lever_arm_m)
    top = max(transducer[2], 0.0)
    offset = np.array([target_north_m - transducer[0], target_east_m - transducer[1]])
    horizontal = float(np.hypot(*offset))
    angle = ray_to_offset(profile, top, target_depth_m, horizontal) if horizontal >= 1e-6 else 0.0
    time = trace_to_depth(profile, angle, top, target_depth_m).time_s
    azimuth = np.arctan2(offset[1], offset[0])
    direction = rotation.T @ np.array([np.sin(angle) * np.cos(azimuth), np.sin(angle) * np.sin(azimuth), np.cos(angle)])
    wavelength = array.wavelength_m(float(profile.speed_at(top)))
    phase_x, phase_y = phase_from_direction_cosines(direction[:2], wavelength, array.baseline_m)
    return float(time), float(phase_x), float(phase_y)
