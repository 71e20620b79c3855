"""Acoustic rays through constant-gradient layers (Du et al. 2018, eqs. 3-5).

A ray leaves the transducer at the angle ``theta0`` from the vertical and keeps Snell's constant
``p = sin(theta) / c``. In a layer where the speed changes with the constant gradient ``g`` it is an arc of a
circle, and from the layer's top (speed ``c_a``, angle ``theta_a``) to its bottom (``c_b``, ``theta_b``):

- horizontal offset (eq. 3): ``(cos theta_a - cos theta_b) / (p g)``, evaluated as
  ``p dz (c_a + c_b) / (cos theta_a + cos theta_b)`` (the same number, finite in isovelocity water);
- travel time: ``(1 / g) ln[c_b (1 + cos theta_a) / (c_a (1 + cos theta_b))]``, the exact integral of ``ds / c``
  along the arc, evaluated with ``log1p`` so that ``g -> 0`` gives ``dz / (c cos theta)``.
  (The paper's eq. 3 writes the time as the arc length over the layer's harmonic-mean speed, an approximation
  that the exact integral replaces; they agree as the layers thin.)

The inverse (eqs. 4-5): given the one-way travel time and the target's depth, find the ray. From a first angle,
the ray is traced for the travel time to its end point P; eq. 4's angle of P seen from the transducer is compared
with the angle of the point at the same distance on the target's depth, and the launch angle is moved by the
difference; this repeats until two successive end points differ by at most ``tolerance_m`` in both coordinates
(eq. 5's stopping rule). At the fixed point the ray ends on the target's depth at the measured time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .sound import SoundSpeedProfile, _log1p_ratio

__all__ = ["RayEnd", "RaySolution", "trace_to_depth", "trace_for_time", "solve_ray", "slant_range_from_travel_time"]

#: How far below the target an iteration's trial ray may be traced: the profile is held at its last speed there.
_OVERSHOOT_M = 5000.0


@dataclass(frozen=True)
class RayEnd:
    """Where a ray is at the end of a trace: horizontal offset and depth (m), travel time (s), angle from the vertical (rad)."""

    horizontal_m: float
    depth_m: float
    time_s: float
    angle_rad: float


@dataclass(frozen=True)
class RaySolution:
    """The ray joining the transducer to a target at a known depth for a measured travel time."""

    launch_angle_rad: float
    horizontal_m: float
    vertical_m: float
    slant_range_m: float
    iterations: int

    @property
    def chord_angle_rad(self) -> float:
        """Angle of the straight line transducer-target from the vertical."""
        return float(np.arctan2(self.horizontal_m, self.vertical_m))


def _segments(depth: np.ndarray, speed: np.ndarray, p: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Horizontal offset, travel time and bottom cosine of each layer for Snell's constant ``p``."""
    sine = p * speed
    if np.any(sine >= 1.0):
        where = int(np.flatnonzero(sine >= 1.0)[0])
        raise ValueError(f"the ray turns before {depth[where]:.1f} m (sin(theta) = p c reaches 1 at c = {speed[where]:.2f} m/s): "
                         "no downward ray reaches the target at this angle")
    cosine = np.sqrt(1.0 - sine * sine)
    dz = np.diff(depth)
    c_a, c_b, cos_a, cos_b = speed[:-1], speed[1:], cosine[:-1], cosine[1:]
    gradient = (c_b - c_a) / dz
    dx = p * dz * (c_a + c_b) / (cos_a + cos_b)
    k = p * p * dz * (c_a + c_b) / ((cos_a + cos_b) * (1.0 + cos_b))
    dt = dz * _log1p_ratio(gradient * dz / c_a) / c_a + k * _log1p_ratio(gradient * k)
    return dx, dt, cos_b


def _snell(profile: SoundSpeedProfile, launch_angle_rad: float, start_depth_m: float) -> float:
    if not 0.0 <= launch_angle_rad < np.pi / 2:
        raise ValueError(f"launch angle {np.degrees(launch_angle_rad):.3f} deg from the vertical is not a downward ray (0 <= theta < 90 deg)")
    return float(np.sin(launch_angle_rad) / profile.speed_at(start_depth_m))


def trace_to_depth(profile: SoundSpeedProfile, launch_angle_rad: float, start_depth_m: float, end_depth_m: float) -> RayEnd:
    """Trace a downward ray from ``start_depth_m`` at ``launch_angle_rad`` from the vertical to ``end_depth_m`` (eq. 3).

    Raises
    ------
    ValueError
        The end is not below the start, lies below the profile, or the ray turns before reaching it.
    """
    p = _snell(profile, launch_angle_rad, start_depth_m)
    depth, speed = profile.layers(start_depth_m, end_depth_m)
    dx, dt, cos_b = _segments(depth, speed, p)
    return RayEnd(float(dx.sum()), float(end_depth_m), float(dt.sum()), float(np.arccos(cos_b[-1])))


def trace_for_time(profile: SoundSpeedProfile, launch_angle_rad: float, start_depth_m: float, time_s: float,
                   *, extend_below: bool = False) -> RayEnd:
    """Trace a downward ray for ``time_s`` seconds; ``extend_below`` holds the last speed below the profile.

    Raises
    ------
    ValueError
        The time runs out below the profile (without ``extend_below``), or the ray turns first.
    """
    if extend_below:
        profile = SoundSpeedProfile(np.append(profile.depth_m, profile.bottom_m + _OVERSHOOT_M), np.append(profile.speed_m_s, profile.speed_m_s[-1]))
    p = _snell(profile, launch_angle_rad, start_depth_m)
    depth, speed = profile.layers(start_depth_m, profile.bottom_m)
    turning = np.flatnonzero(p * speed >= 1.0)
    if turning.size:  # only the layers above the ray's turning depth can be crossed
        depth, speed = depth[: max(turning[0], 2)], speed[: max(turning[0], 2)]
    dx, dt, _ = _segments(depth, speed, p)
    elapsed = np.concatenate(([0.0], np.cumsum(dt)))
    if time_s > elapsed[-1]:
        raise ValueError(f"a ray at {np.degrees(launch_angle_rad):.3f} deg leaves the profile (bottom {profile.bottom_m:.1f} m) "
                         f"after {elapsed[-1]:.4f} s, before the travel time {time_s:.4f} s")
    layer = int(np.clip(np.searchsorted(elapsed, time_s) - 1, 0, dx.size - 1))
    top, offset = depth[layer], float(dx[:layer].sum())
    remaining = time_s - elapsed[layer]

    def part(bottom: float) -> tuple[float, float]:
        if bottom <= top:
            return 0.0, 0.0
        seg_dx, seg_dt, _ = _segments(np.array([top, bottom]), np.interp([top, bottom], depth, speed), p)
        return float(seg_dx[0]), float(seg_dt[0])

    end = min(_depth_after(top, speed[layer], (speed[layer + 1] - speed[layer]) / (depth[layer + 1] - top), p, max(remaining, 0.0)),
              depth[layer + 1])
    seg_dx, _ = part(end)
    cos_end = np.sqrt(1.0 - (p * np.interp(end, depth, speed)) ** 2)
    return RayEnd(offset + seg_dx, float(end), float(time_s), float(np.arccos(cos_end)))


def _depth_after(top: float, speed: float, gradient: float, p: float, time: float) -> float:
    """Depth a ray reaches ``time`` seconds after crossing ``top`` inside a constant-gradient layer, in closed form.

    Along the arc ``tan(theta / 2)`` grows as ``exp(g t)``, so with ``u = tan(theta_top / 2)`` the speed is
    ``c = c_top e^(gt) (1 + u^2) / (1 + u^2 e^(2gt))`` and the depth ``top + (c - c_top) / g``, written as
    ``c_top t (expm1(gt) / gt) (1 - u^2 e^(gt)) / (1 + u^2 e^(2gt))`` so that ``g -> 0`` gives ``c t cos(theta)``.
    """
    sine = p * speed
    u2 = (sine / (1.0 + np.sqrt(1.0 - sine * sine))) ** 2
    x = gradient * time
    growth = np.exp(x)
    ratio = 1.0 + x / 2.0 if abs(x) < 1e-12 else np.expm1(x) / x
    return float(top + speed * time * ratio * (1.0 - u2 * growth) / (1.0 + u2 * growth * growth))


def solve_ray(profile: SoundSpeedProfile, start_depth_m: float, target_depth_m: float, travel_time_s: float, *,
              tolerance_m: float = 1e-3, max_iterations: int = 50, initial_angle_rad: float | None = None) -> RaySolution:
    """The ray from the transducer to a target at a known depth for a measured one-way travel time (eqs. 4-5).

    Parameters
    ----------
    profile : SoundSpeedProfile
        The sound-speed layers; must reach ``target_depth_m``.
    start_depth_m, target_depth_m : float
        Depths of the transducer and the target (m, positive down; the target below the transducer).
    travel_time_s : float
        One-way travel time along the ray, s.
    tolerance_m : float
        Eq. 5's thresholds (the same for both coordinates): stop when two successive end points differ by no more.
    max_iterations : int
        Give up (``ValueError``) after this many traces.
    initial_angle_rad : float, optional
        First launch angle (e.g. the USBL's measured one); by default the chord angle of a straight ray at the
        harmonic-mean speed.

    Raises
    ------
    ValueError
        The travel time is too short to reach the target's depth, the ray turns, or the iteration does not converge.
    """
    vertical = target_depth_m - start_depth_m
    if not vertical > 0.0:
        raise ValueError(f"the target at {target_depth_m:.2f} m must be below the transducer at {start_depth_m:.2f} m")
    if target_depth_m > profile.bottom_m:
        raise ValueError(f"the target at {target_depth_m:.2f} m is below the sound-speed profile's last sample at {profile.bottom_m:.2f} m")
    vertical_time = trace_to_depth(profile, 0.0, start_depth_m, target_depth_m).time_s
    if travel_time_s < vertical_time - 1e-9:
        raise ValueError(f"travel time {travel_time_s:.5f} s is shorter than the vertical ray's {vertical_time:.5f} s to "
                         f"{target_depth_m:.2f} m: the depth or the time is wrong")
    if travel_time_s <= vertical_time:
        return RaySolution(0.0, 0.0, vertical, vertical, 0)
    if initial_angle_rad is None:
        straight = profile.harmonic_mean_m_s(start_depth_m, target_depth_m) * travel_time_s
        initial_angle_rad = float(np.arccos(min(1.0, vertical / straight)))
    angle, previous = initial_angle_rad, None
    for iteration in range(1, max_iterations + 1):
        end = trace_for_time(profile, angle, start_depth_m, travel_time_s, extend_below=True)
        down = end.depth_m - start_depth_m
        distance = float(np.hypot(end.horizontal_m, down))
        seen = float(np.arctan2(end.horizontal_m, down))  # eq. 4
        wanted = float(np.arccos(min(1.0, vertical / distance)))
        if previous is not None and abs(end.horizontal_m - previous.horizontal_m) <= tolerance_m \
                and abs(end.depth_m - previous.depth_m) <= tolerance_m:  # eq. 5
            horizontal = trace_to_depth(profile, angle, start_depth_m, target_depth_m).horizontal_m
            return RaySolution(angle, horizontal, vertical, float(np.hypot(horizontal, vertical)), iteration)
        angle = float(np.clip(angle + wanted - seen, 0.0, np.pi / 2 - 1e-9))
        previous = end
    raise ValueError(f"the ray iteration did not converge to {tolerance_m} m in {max_iterations} traces "
                     f"(travel time {travel_time_s:.5f} s, target depth {target_depth_m:.2f} m)")


def slant_range_from_travel_time(profile: SoundSpeedProfile, travel_time_s: float, transducer_depth_m: float,
                                 target_depth_m: float) -> tuple[float, float]:
    """Straight-line slant range and horizontal range (m) of a target at a known depth from a one-way travel time.

    The call the navigation makes for a ray-traced range (LOST's slant-range corrector, the terrain filters).
    """
    solution = solve_ray(profile, transducer_depth_m, target_depth_m, travel_time_s)
    return solution.slant_range_m, solution.horizontal_m
