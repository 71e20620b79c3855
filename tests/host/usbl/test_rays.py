"""Ray tracing (eq. 3) against an independent fine-step Snell integration and the isovelocity closed form,
the inverse iteration (eqs. 4-5), and the paper's Table 1 experiment."""

from importlib import resources
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from lost.host.usbl.rays import slant_range_from_travel_time, solve_ray, trace_for_time, trace_to_depth
from lost.host.usbl.sound import SoundSpeedProfile, read_cast

SHIPPED_CAST = Path(str(resources.files("lost.host.usbl") / "data" / "scs_june.csv"))

#: Du et al. 2018, Table 1: depth h, ray-traced distance S2, and the error of a surface-speed range (m).
PAPER_TABLE_1 = [(50.25, 65.98, 0.14), (153.91, 201.28, 0.77), (246.36, 322.42, 1.13), (352.86, 461.29, 4.33),
                 (456.35, 596.75, 8.63), (548.51, 717.03, 12.01), (651.38, 851.45, 16.74), (747.64, 976.99, 21.14),
                 (850.73, 1111.57, 24.18), (949.12, 1240.37, 30.85), (1051.18, 1373.59, 35.09)]


@pytest.fixture(scope="module")
def profile():
    return SoundSpeedProfile.from_cast(read_cast(SHIPPED_CAST))


def snell_fine_step(depth, speed, theta0, z0, z1, step=0.01):
    """Midpoint integration of dx/dz = tan(theta), dt/dz = 1 / (c cos(theta)) with sin(theta) = p c(z)."""
    edges = np.arange(z0, z1 + step / 2, step)
    mid = (edges[:-1] + edges[1:]) / 2
    c = np.interp(mid, depth, speed)
    sine = np.sin(theta0) / np.interp(z0, depth, speed) * c
    cosine = np.sqrt(1 - sine**2)
    dz = np.diff(edges)
    return float(np.sum(sine / cosine * dz)), float(np.sum(dz / (c * cosine)))


@pytest.mark.parametrize("angle_deg", [0.0, 20.0, 40.0, 55.0])
def test_trace_matches_fine_step_snell_within_a_centimetre_at_1000_m(profile, angle_deg):
    theta0 = np.radians(angle_deg)
    ray = trace_to_depth(profile, theta0, 5.0, 1000.0)
    x, t = snell_fine_step(profile.depth_m, profile.speed_m_s, theta0, 5.0, 1000.0)
    assert abs(ray.horizontal_m - x) < 0.01
    assert abs(ray.time_s - t) * 1500.0 < 0.01


@pytest.mark.parametrize("angle_deg", [0.0, 10.0, 45.0, 70.0])
def test_isovelocity_is_the_straight_line(angle_deg):
    water = SoundSpeedProfile.isovelocity(1500.0)
    theta = np.radians(angle_deg)
    ray = trace_to_depth(water, theta, 3.0, 903.0)
    assert ray.horizontal_m == pytest.approx(900.0 * np.tan(theta), rel=1e-12, abs=1e-12)
    assert ray.time_s == pytest.approx(900.0 / (1500.0 * np.cos(theta)), rel=1e-12)
    end = trace_for_time(water, theta, 3.0, ray.time_s / 2)
    assert end.depth_m == pytest.approx(453.0, abs=1e-9) and end.horizontal_m == pytest.approx(450.0 * np.tan(theta), abs=1e-9)
    solution = solve_ray(water, 3.0, 903.0, ray.time_s, tolerance_m=1e-6)
    assert solution.slant_range_m == pytest.approx(1500.0 * ray.time_s, abs=1e-6)
    assert solution.launch_angle_rad == pytest.approx(theta, abs=1e-8)


@pytest.mark.parametrize("angle_deg", [5.0, 35.0, 60.0])
def test_trace_for_time_lands_on_the_traced_ray(profile, angle_deg):
    theta0 = np.radians(angle_deg)
    ray = trace_to_depth(profile, theta0, 5.0, 777.0)
    end = trace_for_time(profile, theta0, 5.0, ray.time_s)
    assert end.depth_m == pytest.approx(777.0, abs=1e-6)
    assert end.horizontal_m == pytest.approx(ray.horizontal_m, abs=1e-6)


@pytest.mark.parametrize("angle_deg", [0.5, 25.0, 40.0, 62.0])
def test_inverse_iteration_recovers_the_ray(profile, angle_deg):
    theta0 = np.radians(angle_deg)
    ray = trace_to_depth(profile, theta0, 5.0, 1050.0)
    solution = solve_ray(profile, 5.0, 1050.0, ray.time_s)
    assert solution.horizontal_m == pytest.approx(ray.horizontal_m, abs=1e-3)
    assert 1 <= solution.iterations <= 12
    slant, horizontal = slant_range_from_travel_time(profile, ray.time_s, 5.0, 1050.0)
    assert slant == pytest.approx(np.hypot(ray.horizontal_m, 1045.0), abs=1e-3)
    assert horizontal == pytest.approx(ray.horizontal_m, abs=1e-3)


def test_inverse_refuses_impossible_inputs(profile):
    vertical = trace_to_depth(profile, 0.0, 5.0, 800.0).time_s
    with pytest.raises(ValueError, match="shorter than the vertical ray"):
        solve_ray(profile, 5.0, 800.0, vertical * 0.9)
    with pytest.raises(ValueError, match="below the sound-speed profile"):
        solve_ray(profile, 5.0, 1600.0, 2.0)
    with pytest.raises(ValueError, match="must be below the transducer"):
        solve_ray(profile, 5.0, 5.0, 1.0)
    with pytest.raises(ValueError, match="turns"):
        trace_to_depth(SoundSpeedProfile(np.array([0.0, 100.0]), np.array([1500.0, 1600.0])), np.radians(80.0), 0.0, 100.0)


def surface_speed_range_errors(profile):
    """The Table 1 experiment: for the paper's geometry, the true ray's travel time times the surface speed,
    minus the true straight-line distance."""
    errors = []
    for depth, distance, _ in PAPER_TABLE_1:
        horizontal = np.sqrt(distance**2 - depth**2)
        angle = brentq(lambda a, d=depth, h=horizontal: trace_to_depth(profile, a, 0.0, d).horizontal_m - h, 0.0, 1.5)
        time = trace_to_depth(profile, angle, 0.0, depth).time_s
        errors.append(profile.speed_at(0.0) * time - distance)
    return np.array(errors)


def test_table_1_surface_speed_error_grows_with_depth(profile):
    errors = surface_speed_range_errors(profile)
    paper = np.array([row[2] for row in PAPER_TABLE_1])
    assert np.all(np.diff(errors) > 0.0)
    assert errors[0] < 0.5
    assert 25.0 < errors[-1] < 50.0  # paper: 35.09 m at 1051.18 m on its (unpublished) profile
    assert np.all(np.abs(errors - paper) < 0.25 * errors[-1])
