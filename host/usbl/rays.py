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

The inverse: given the one-way travel time and the target's depth, find the ray. Du et al.'s eqs. 4-5 iterate the
launch angle from the angle at which a trial ray's end point is seen; that iteration can step into rays that never
reach the target (under a surface mixed layer at low elevation). Here the launch angle is bracketed instead: along
the direct rays (those that reach the target's depth going down) the travel time grows with Snell's constant from
the vertical ray to the one grazing the speed maximum between transducer and target, so a root bracket on the time
finds the one direct ray; rays that pass the target's depth, turn where ``p c = 1`` below it and come back up are
bracketed by sampling. When none takes the measured time, the error names the limiting ray.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .sound import SoundSpeedProfile, _log1p_ratio

__all__ = ["NoRayError", "RayEnd", "RaySolution", "trace_to_depth", "trace_for_time", "solve_ray", "ray_to_offset", "slant_range_from_travel_time"]

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
    """The ray joining the transducer to a target at a known depth for a measured travel time: its launch angle, the
    offsets of the target, the traces it took, its angle from the downward vertical at the target (above 90 deg for a ray
    that turned under the target and arrives from below) and, for such a ray, the depth where it turned."""

    launch_angle_rad: float
    horizontal_m: float
    vertical_m: float
    slant_range_m: float
    iterations: int
    arrival_angle_rad: float = 0.0
    turning_depth_m: float | None = None

    @property
    def chord_angle_rad(self) -> float:
        """Angle of the straight line transducer-target from the vertical."""
        return float(np.arctan2(self.horizontal_m, self.vertical_m))


def _terms(dz, c_a, c_b, p, *, turning: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Horizontal offset, travel time and bottom cosine of layers of thickness ``dz`` from speed ``c_a`` to ``c_b``
    for Snell's constant ``p`` (element by element, broadcasting: a column of constants traces many rays at once);
    ``turning``: each layer's bottom is its ray's turning point (cosine exactly 0, not the rounding of ``1 - (p c)^2``)."""
    cos_a = np.sqrt(np.maximum(1.0 - (p * c_a) ** 2, 0.0))
    cos_b = np.zeros(np.broadcast(p, c_b).shape) if turning else np.sqrt(np.maximum(1.0 - (p * c_b) ** 2, 0.0))
    gradient = (c_b - c_a) / dz
    dx = p * dz * (c_a + c_b) / (cos_a + cos_b)
    k = p * p * dz * (c_a + c_b) / ((cos_a + cos_b) * (1.0 + cos_b))
    dt = dz * _log1p_ratio(gradient * dz / c_a) / c_a + k * _log1p_ratio(gradient * k)
    return dx, dt, cos_b


def _segments(depth: np.ndarray, speed: np.ndarray, p: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Horizontal offset, travel time and bottom cosine of each layer for Snell's constant ``p``."""
    sine = p * speed
    if np.any(sine >= 1.0):
        where = int(np.flatnonzero(sine >= 1.0)[0])
        raise ValueError(f"the ray turns before {depth[where]:.1f} m (sin(theta) = p c reaches 1 at c = {speed[where]:.2f} m/s): "
                         "no downward ray reaches the target at this angle")
    return _terms(np.diff(depth), speed[:-1], speed[1:], p)


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


def _direct_many(profile: SoundSpeedProfile, p: np.ndarray, top: float, bottom: float) -> tuple[np.ndarray, np.ndarray]:
    """Offsets and times of the direct rays of Snell constants ``p`` (each below 1 / the speed maximum) from ``top`` to ``bottom``."""
    depth, speed = profile.layers(top, bottom)
    dx, dt, _ = _terms(np.diff(depth), speed[:-1], speed[1:], np.asarray(p, dtype=float)[:, None])
    return dx.sum(axis=1), dt.sum(axis=1)


def _dives(profile: SoundSpeedProfile, p: np.ndarray, target: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Offsets and times of the loops of rays of Snell constants ``p`` under the target (down to where ``p c = 1`` and back
    up), and their turning depths; NaN for a ray that does not turn within the profile."""
    p = np.asarray(p, dtype=float)
    nan = np.full(p.shape, np.nan)
    if target >= profile.bottom_m:
        return nan, nan, nan
    depth, speed = profile.layers(target, profile.bottom_m)
    reached = p[:, None] * speed[None, :] >= 1.0
    turns = reached.any(axis=1) & ~reached[:, 0]
    if not turns.any():
        return nan, nan, nan
    q = p[turns]
    k = np.argmax(reached[turns], axis=1)  # the first node beyond the turning point; the ray turns inside layer k - 1
    c_turn = 1.0 / q
    turn = depth[k - 1] + (c_turn - speed[k - 1]) / (speed[k] - speed[k - 1]) * (depth[k] - depth[k - 1])
    whole = np.arange(depth.size - 1)[None, :] < (k - 1)[:, None]  # the layers crossed entirely
    with np.errstate(divide="ignore", invalid="ignore"):  # the layers beyond a ray's turning point, masked out below
        dx, dt, _ = _terms(np.diff(depth), speed[:-1], speed[1:], q[:, None])
        part_dx, part_dt, _ = _terms(turn - depth[k - 1], speed[k - 1], c_turn, q, turning=True)
    offsets, times, depths = nan.copy(), nan.copy(), nan.copy()
    offsets[turns] = 2.0 * (np.where(whole, dx, 0.0).sum(axis=1) + np.where(turn > depth[k - 1], part_dx, 0.0))
    times[turns] = 2.0 * (np.where(whole, dt, 0.0).sum(axis=1) + np.where(turn > depth[k - 1], part_dt, 0.0))
    depths[turns] = turn
    return offsets, times, depths


def _speed_maximum(profile: SoundSpeedProfile, top: float, bottom: float) -> tuple[float, float]:
    """The highest speed between two depths and the depth where it is (the rays' turning limit)."""
    depth, speed = profile.layers(top, bottom)
    k = int(np.argmax(speed))
    return float(speed[k]), float(depth[k])


class NoRayError(ValueError):
    """No ray joins the transducer and the target for the given travel time or offset; the message says why."""


def ray_to_offset(profile: SoundSpeedProfile, start_depth_m: float, target_depth_m: float, horizontal_m: float) -> float:
    """Launch angle (rad from the vertical) of the direct ray from ``start_depth_m`` to a point ``horizontal_m`` away at
    ``target_depth_m``: a root bracket (Brent) on the traced offset over Snell's constant, from the vertical ray to the one
    grazing the speed maximum between the two depths (the flattest that still reaches the target going down).

    Raises
    ------
    NoRayError
        The offset lies beyond the grazing ray's (a direct ray cannot reach it); the message gives that limit.
    """
    from scipy.optimize import brentq

    if horizontal_m <= 0.0:
        return 0.0
    c_top = float(profile.speed_at(start_depth_m))
    c_max, z_max = _speed_maximum(profile, start_depth_m, target_depth_m)
    p_high = (1.0 - _GRAZING) / c_max
    reach = float(_direct_many(profile, [p_high], start_depth_m, target_depth_m)[0][0])
    if horizontal_m > reach:
        raise NoRayError(f"no direct ray reaches {horizontal_m:.1f} m off at {target_depth_m:.2f} m: the flattest, grazing the speed maximum "
                         f"{c_max:.2f} m/s at {z_max:.1f} m, reaches {reach:.1f} m")
    p = brentq(lambda q: _direct_many(profile, [q], start_depth_m, target_depth_m)[0][0] - horizontal_m, 0.0, p_high, xtol=1e-20,
               rtol=4 * np.finfo(float).eps)
    return float(np.arcsin(min(1.0, p * c_top)))


#: How close to grazing (p c_max = 1) the flattest direct ray is traced: its sine is 1 - this.
_GRAZING = 1e-12
#: Snell constants sampled to bracket the rays that turn below the target (each bracket is then solved by Brent).
_TURNING_SAMPLES = 64


def _turning_rays(profile: SoundSpeedProfile, top: float, target: float, travel_time_s: float, p_low: float, p_high: float,
                  solve) -> list[tuple[float, float, float | None, int]]:
    """The rays that pass the target's depth, turn under it and come back up to it in ``travel_time_s`` (sampled brackets)."""
    def turning(p) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        offset, time = _direct_many(profile, p, top, target)
        loop_offset, loop_time, turn = _dives(profile, p, target)
        return offset + loop_offset, time + loop_time - travel_time_s, turn

    found = []
    grid = np.linspace(p_low, p_high, _TURNING_SAMPLES + 1)[1:]
    values = turning(grid)[1]
    for k in np.flatnonzero(np.isfinite(values[:-1]) & np.isfinite(values[1:]) & (np.sign(values[:-1]) != np.sign(values[1:]))):
        p, calls = solve(lambda q: float(turning(np.array([q]))[1][0]), grid[k], grid[k + 1])
        offset, _, turn = turning(np.array([p]))
        found.append((p, float(offset[0]), float(turn[0]), calls + _TURNING_SAMPLES))
    return found


def _no_ray(profile: SoundSpeedProfile, top: float, target: float, travel_time_s: float, p_high: float, c_top: float, c_max: float,
            z_max: float, c_below: float, longest: float) -> str:
    """Why no ray takes ``travel_time_s``: the limiting direct ray, and whether any ray turns under the target."""
    below = ("no ray that turns under the target takes that time" if c_below > c_max else
             f"under the target the speed stays below {c_max:.2f} m/s down to the profile's {profile.bottom_m:.0f} m, so no ray turns back up to it")
    return (f"no ray reaches {target:.2f} m in {travel_time_s:.5f} s: the flattest direct ray (launched "
            f"{np.degrees(np.arcsin(min(1.0, p_high * c_top))):.3f} deg from the vertical, grazing the speed maximum {c_max:.2f} m/s "
            f"at {z_max:.1f} m) arrives in {longest:.5f} s at {_direct_many(profile, [p_high], top, target)[0][0]:.1f} m; a longer time needs "
            f"a ray trapped above {z_max:.1f} m (surface-reflected paths are not modelled), and {below}")


def _chosen_ray(profile: SoundSpeedProfile, found: list[tuple[float, float, float | None, int]], top: float, target: float,
                travel_time_s: float, initial_angle_rad: float | None, tolerance_m: float, max_iterations: int) -> RaySolution:
    """Of the rays found (Snell constant, offset, turning depth, traces), the one closest to the measured angle."""
    c_top = float(profile.speed_at(top))
    launch = lambda p: float(np.arcsin(min(1.0, p * c_top)))  # noqa: E731
    if initial_angle_rad is not None:
        p, horizontal, turn, calls = min(found, key=lambda ray: abs(launch(ray[0]) - initial_angle_rad))
    else:
        p, horizontal, turn, calls = found[0]
    c_end = float(profile.speed_at(target))
    residual = abs(_direct_many(profile, [p], top, target)[1][0] + (_dives(profile, np.array([p]), target)[1][0] if turn is not None else 0.0)
                   - travel_time_s)
    if residual * c_end > tolerance_m:
        raise ValueError(f"the ray search did not converge to {tolerance_m} m in {max_iterations} traces "
                         f"(travel time {travel_time_s:.5f} s, target depth {target:.2f} m)")
    arrival = float(np.arcsin(min(1.0, p * c_end)))
    vertical = target - top
    return RaySolution(launch(p), horizontal, vertical, float(np.hypot(horizontal, vertical)), calls,
                       np.pi - arrival if turn is not None else arrival, turn)


def solve_ray(profile: SoundSpeedProfile, start_depth_m: float, target_depth_m: float, travel_time_s: float, *,
              tolerance_m: float = 1e-3, max_iterations: int = 100, initial_angle_rad: float | None = None) -> RaySolution:
    """The ray from the transducer to a target at a known depth for a measured one-way travel time.

    Every ray that exists is found: the travel time to the target's depth grows with Snell's constant ``p`` along the
    direct rays (those that reach the target going down), from the vertical ray to the one grazing the speed maximum
    between the two depths, so one root bracket (Brent) over ``p`` finds the direct ray; rays that pass the target's
    depth, turn below it (where ``p c = 1``) and come back up to it are bracketed by sampling ``p`` and solved the same
    way. Of several rays with the travel time, the one whose launch angle is closest to ``initial_angle_rad`` (the
    USBL's measured direction) is returned; without it, the direct ray. Rays reflected at the surface or the floor are
    not modelled.

    Parameters
    ----------
    profile : SoundSpeedProfile
        The sound-speed layers; must reach ``target_depth_m`` (and, for turning rays, their turning depth).
    start_depth_m, target_depth_m : float
        Depths of the transducer and the target (m, positive down; the target below the transducer).
    travel_time_s : float
        One-way travel time along the ray, s.
    tolerance_m : float
        The solution's travel time must match to ``tolerance_m`` of path at the target's speed.
    max_iterations : int
        Brent's limit of traces per bracket.
    initial_angle_rad : float, optional
        The measured arrival angle from the vertical at the transducer, to choose among several rays.

    Raises
    ------
    NoRayError
        The travel time is too short for the target's depth, or no ray takes that time (the message says which ray
        limits it: the grazing one, and whether any ray turns below the target).
    ValueError
        The target is not below the transducer or lies below the profile.
    """
    from scipy.optimize import brentq

    vertical = target_depth_m - start_depth_m
    if not vertical > 0.0:
        raise ValueError(f"the target at {target_depth_m:.2f} m must be below the transducer at {start_depth_m:.2f} m")
    if target_depth_m > profile.bottom_m:
        raise ValueError(f"the target at {target_depth_m:.2f} m is below the sound-speed profile's last sample at {profile.bottom_m:.2f} m")
    top, target = start_depth_m, target_depth_m
    vertical_time = float(_direct_many(profile, [0.0], top, target)[1][0])
    if travel_time_s < vertical_time - 1e-9:
        raise NoRayError(f"travel time {travel_time_s:.5f} s is shorter than the vertical ray's {vertical_time:.5f} s to "
                         f"{target_depth_m:.2f} m: the depth or the time is wrong")
    if travel_time_s <= vertical_time:
        return RaySolution(0.0, 0.0, vertical, vertical, 0, 0.0)
    c_top = float(profile.speed_at(top))
    c_max, z_max = _speed_maximum(profile, top, target)
    p_high = (1.0 - _GRAZING) / c_max
    found: list[tuple[float, float, float | None, int]] = []  # Snell constant, offset, turning depth, traces

    def solve(function, low: float, high: float) -> tuple[float, int]:
        # On p squared: near the vertical the time grows as p^2, which Brent would meet as a double root.
        square, result = brentq(lambda q: function(np.sqrt(q)), low**2, high**2, xtol=1e-24, rtol=4 * np.finfo(float).eps,
                                maxiter=max_iterations, full_output=True, disp=False)
        return float(np.sqrt(square)), int(result.function_calls)

    def direct_time(p: float) -> float:
        return float(_direct_many(profile, [p], top, target)[1][0]) - travel_time_s

    longest = direct_time(p_high) + travel_time_s
    if longest >= travel_time_s:
        p, calls = solve(direct_time, 0.0, p_high)
        found.append((p, float(_direct_many(profile, [p], top, target)[0][0]), None, calls))
    c_below = _speed_maximum(profile, target, profile.bottom_m)[0] if target < profile.bottom_m else c_max
    if c_below > c_max:  # rays flatter than 1 / c_below turn under the target and come back up to it
        found += _turning_rays(profile, top, target, travel_time_s, 1.0 / c_below, p_high, solve)
    if not found:
        raise NoRayError(_no_ray(profile, top, target, travel_time_s, p_high, c_top, c_max, z_max, c_below, longest))
    return _chosen_ray(profile, found, top, target, travel_time_s, initial_angle_rad, tolerance_m, max_iterations)


def slant_range_from_travel_time(profile: SoundSpeedProfile, travel_time_s: float, transducer_depth_m: float,
                                 target_depth_m: float) -> tuple[float, float]:
    """Straight-line slant range and horizontal range (m) of a target at a known depth from a one-way travel time.

    The call the navigation makes for a ray-traced range (LOST's slant-range corrector, the terrain filters).
    """
    solution = solve_ray(profile, transducer_depth_m, target_depth_m, travel_time_s)
    return solution.slant_range_m, solution.horizontal_m
