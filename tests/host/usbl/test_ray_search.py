"""The ray search (``solve_ray``) against an independent fine Snell integration: tropical (a surface mixed layer over
a thermocline), polar (a surface duct: speed growing with depth) and step casts, targets 100-4000 m deep, horizontal
ranges to 5 km, direct rays and rays that turn under the target; the reason named when no ray exists."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from lost.host.usbl.rays import NoRayError, ray_to_offset, solve_ray, trace_to_depth
from lost.host.usbl.sound import SoundSpeedProfile

TRANSDUCER_M = 5.0
DEPTHS_M = (100.0, 500.0, 1000.0, 2000.0, 4000.0)
NODES_M = np.arange(0.0, 5000.1, 10.0)


def _munk(z):
    eta = 2.0 * (z - 1300.0) / 1300.0
    return 1500.0 * (1.0 + 0.00737 * (eta - 1.0 + np.exp(-eta)))


def tropical() -> SoundSpeedProfile:
    """A 60 m isothermal mixed layer (speed rising with pressure) over Munk's canonical profile (axis at 1300 m)."""
    speed = np.where(NODES_M < 60.0, _munk(60.0) + 0.0165 * (NODES_M - 60.0), _munk(NODES_M))
    return SoundSpeedProfile(NODES_M, speed)


def polar() -> SoundSpeedProfile:
    """Speed rising from the surface everywhere (a surface duct), with the warm Atlantic layer's bump at 300 m."""
    return SoundSpeedProfile(NODES_M, 1437.0 + 0.0165 * NODES_M + 6.0 * np.exp(-(((NODES_M - 300.0) / 200.0) ** 2)))


def step() -> SoundSpeedProfile:
    """Isovelocity to 200 m, +40 m/s over one metre, then the deep pressure gradient."""
    depth = np.concatenate(([0.0, 200.0, 201.0], np.arange(210.0, 5000.1, 10.0)))
    return SoundSpeedProfile(depth, np.where(depth <= 200.0, 1500.0, 1540.0 + 0.0165 * (depth - 201.0)))


CASTS = {"tropical": tropical, "polar": polar, "step": step}


def reference_ray(profile: SoundSpeedProfile, p: float, top: float, target: float, turning: bool, step_m: float = 0.1) -> tuple[float, float]:
    """Horizontal offset and time of a ray by midpoint quadrature of Snell's law, independent of the layer formulas.

    Down to the target: dx = tan(theta) dz, dt = dz / (c cos theta), sin(theta) = p c(z), in steps of ``step_m``. A
    turning ray's loop under the target (down to where p c = 1, found by root search, and back) is integrated in
    u = sqrt(z_turn - z), which removes the square-root singularity at the turning point; its depth steps are at
    most ``step_m`` too.
    """
    def speed(z):
        return np.interp(z, profile.depth_m, profile.speed_m_s)

    edges = np.linspace(top, target, int(np.ceil((target - top) / step_m)) + 1)
    middle = (edges[:-1] + edges[1:]) / 2
    c = speed(middle)
    cosine = np.sqrt(1.0 - (p * c) ** 2)
    dz = np.diff(edges)
    x, t = float(np.sum(p * c / cosine * dz)), float(np.sum(dz / (c * cosine)))
    if turning and x <= 5000.0:
        grid = profile.depth_m[profile.depth_m > target]
        first = grid[np.flatnonzero(p * speed(grid) >= 1.0)[0]]
        turn = brentq(lambda z: p * speed(z) - 1.0, target, first, xtol=1e-12)
        span = np.sqrt(turn - target)
        n = int(np.ceil(2.0 * span * span / step_m))
        u = (np.arange(n) + 0.5) * span / n
        z = turn - u * u
        c = speed(z)
        cosine = np.sqrt(np.maximum(1.0 - (p * c) ** 2, 0.0))
        dz = 2.0 * u * span / n
        x += 2.0 * float(np.sum(p * c / cosine * dz))
        t += 2.0 * float(np.sum(dz / (c * cosine)))
    return x, t


def _cases(name: str):
    """Rays of the cast to every depth: direct ones from the vertical to near grazing (fractions of the grazing
    Snell constant), and turning ones (flatter than the direct ray can be); only those within 5 km."""
    profile = CASTS[name]()
    for target in DEPTHS_M:
        c_max = profile.layers(TRANSDUCER_M, target)[1].max()
        for fraction in (0.2, 0.5, 0.8, 0.95, 0.99, 0.999, 0.99999):
            yield name, target, fraction / c_max, False
        below = profile.layers(target, profile.bottom_m)[1].max()
        if below > c_max:
            for fraction in (0.3, 0.7, 0.95, 0.99, 0.999):
                yield name, target, (1.0 / below + fraction * (1.0 / c_max - 1.0 / below)), True


@pytest.fixture(scope="module")
def measured():
    """For every case: the reference offset, the solver's ray and the reference time (both casts' profiles built once)."""
    rows = []
    for name in CASTS:
        profile = CASTS[name]()
        for _, target, p, turning in _cases(name):
            x, t = reference_ray(profile, p, TRANSDUCER_M, target, turning)
            if x > 5000.0:
                continue
            launch = float(np.arcsin(p * profile.speed_at(TRANSDUCER_M)))
            # The USBL's measured direction, off by 0.05 deg, chooses among rays of the same time.
            solution = solve_ray(profile, TRANSDUCER_M, target, t, initial_angle_rad=launch + np.radians(0.05))
            rows.append((name, target, p, turning, x, t, solution))
    return rows


def test_every_ray_within_5_km_is_found_to_a_centimetre(measured):
    errors = np.array([abs(solution.horizontal_m - x) for *_, x, _, solution in measured])
    assert len(measured) >= 60
    assert errors.max() < 0.01, max(zip(errors, [row[:4] for row in measured]))


def test_the_cases_reach_5_km_low_elevations_and_turning_rays(measured):
    offsets = np.array([row[4] for row in measured])
    assert offsets.max() > 3000.0 and offsets.min() < 100.0
    turned = [row for row in measured if row[3]]
    assert turned and all(row[6].turning_depth_m is not None and row[6].turning_depth_m > row[1] for row in turned)
    assert all(row[6].arrival_angle_rad > np.pi / 2 for row in turned)
    assert all(row[6].turning_depth_m is None for row in measured if not row[3])
    # Under the mixed layer: the tropical cast's 100 m target at elevations below 10 deg (from the horizontal).
    low = [row for row in measured if row[0] == "tropical" and row[1] == 100.0 and row[6].launch_angle_rad > np.radians(80.0)]
    assert len(low) >= 3


@pytest.mark.parametrize("name", list(CASTS))
def test_the_forward_search_and_the_tracer_agree_with_the_reference(name):
    profile = CASTS[name]()
    for target in (100.0, 1000.0):
        for offset in (50.0, 800.0, 2500.0):
            try:
                angle = ray_to_offset(profile, TRANSDUCER_M, target, offset)
            except NoRayError as error:
                assert "reaches" in str(error)
                continue
            p = np.sin(angle) / profile.speed_at(TRANSDUCER_M)
            x, t = reference_ray(profile, float(p), TRANSDUCER_M, target, False, step_m=0.01)  # 1 cm: some are near grazing
            assert abs(x - offset) < 0.01
            assert abs(trace_to_depth(profile, angle, TRANSDUCER_M, target).time_s - t) * 1500.0 < 0.01


def test_a_time_no_ray_takes_names_the_limiting_ray():
    profile = tropical()  # no ray turns back up to 100 m within 5 km: the deep speed exceeds the mixed layer's only below 4 km
    c_max = profile.layers(TRANSDUCER_M, 100.0)[1].max()
    _, longest = reference_ray(profile, 0.99999 / c_max, TRANSDUCER_M, 100.0, False)
    with pytest.raises(NoRayError, match=r"no ray reaches 100.00 m in .* s: the flattest direct ray \(launched 8\d\.\d+ deg from the vertical, "
                                         r"grazing the speed maximum 15\d\d\.\d\d m/s at 60\.0 m\) arrives in .* a ray trapped above 60\.0 m"):
        solve_ray(profile, TRANSDUCER_M, 100.0, longest * 1.2)
    step_cast = step()
    with pytest.raises(NoRayError, match=r"under the target the speed stays below"):
        solve_ray(SoundSpeedProfile(step_cast.depth_m[:5], step_cast.speed_m_s[:5]), TRANSDUCER_M, 220.0, 2.0)
