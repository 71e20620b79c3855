"""The USBL fix: exact on noise-free replies, its covariance against Monte Carlo noise, the local frame."""

from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from lost.host.usbl.fix import UsblArray, direction_cosines_from_phase, phase_from_direction_cosines, reply_from_geometry, usbl_fix
from lost.host.usbl.frames import LocalFrame, body_to_ned, euler_from_matrix
from lost.host.usbl.sound import SoundSpeedProfile, read_cast

SHIPPED_CAST = Path(str(resources.files("lost.host.usbl") / "data" / "scs_june.csv"))
SHIP = dict(roll_rad=np.radians(2.0), pitch_rad=np.radians(-1.0), heading_rad=np.radians(30.0), antenna_north_m=100.0, antenna_east_m=-50.0)


@pytest.fixture(scope="module")
def profile():
    return SoundSpeedProfile.from_cast(read_cast(SHIPPED_CAST), tolerance_m_s=0.05)


def test_eq1_round_trip():
    cosine = np.array([-0.7, 0.0, 0.33])
    phase = phase_from_direction_cosines(cosine, 0.075, 0.035)
    assert phase[2] == pytest.approx(2 * np.pi * 0.035 / 0.075 * 0.33)
    np.testing.assert_allclose(direction_cosines_from_phase(phase, 0.075, 0.035), cosine)


@pytest.mark.parametrize(("bearing_deg", "offset_m", "depth_m"), [(200.0, 700.0, 1000.0), (45.0, 300.0, 150.0), (300.0, 1200.0, 1400.0), (10.0, 5.0, 500.0)])
def test_noise_free_reply_gives_the_target_back(profile, bearing_deg, offset_m, depth_m):
    array = UsblArray()
    rotation = body_to_ned(SHIP["roll_rad"], SHIP["pitch_rad"], SHIP["heading_rad"])
    transducer = np.array([100.0, -50.0, -15.0]) + rotation @ np.array(array.lever_arm_m)
    north = transducer[0] + offset_m * np.cos(np.radians(bearing_deg))
    east = transducer[1] + offset_m * np.sin(np.radians(bearing_deg))
    time, phase_x, phase_y = reply_from_geometry(profile, array, **SHIP, target_north_m=north, target_east_m=east, target_depth_m=depth_m)
    fix = usbl_fix(profile, array, travel_time_s=time, phase_x_rad=phase_x, phase_y_rad=phase_y, **SHIP, target_depth_m=depth_m)
    assert fix.north_m == pytest.approx(north, abs=2e-3)
    assert fix.east_m == pytest.approx(east, abs=2e-3)
    assert fix.horizontal_range_m == pytest.approx(offset_m, abs=2e-3)
    assert fix.slant_range_m == pytest.approx(np.hypot(offset_m, depth_m - transducer[2]), abs=2e-3)


def test_fix_covariance_matches_monte_carlo(profile):
    array = UsblArray(phase_noise_rad=0.015, travel_time_noise_s=1e-4, gnss_noise_m=0.3, depth_noise_m=1.0, noise_growth_per_km=0.5)
    truth = dict(target_north_m=-600.0, target_east_m=-400.0, target_depth_m=1000.0)
    time, phase_x, phase_y = reply_from_geometry(profile, array, **SHIP, **truth)
    slant = usbl_fix(profile, array, travel_time_s=time, phase_x_rad=phase_x, phase_y_rad=phase_y, **SHIP, target_depth_m=1000.0).slant_range_m
    rng = np.random.default_rng(1)
    errors, nees, errors3 = [], [], []
    for _ in range(300):
        noisy = dict(roll_rad=SHIP["roll_rad"] + rng.normal(0, array.tilt_noise_rad), pitch_rad=SHIP["pitch_rad"] + rng.normal(0, array.tilt_noise_rad),
                     heading_rad=SHIP["heading_rad"] + rng.normal(0, array.heading_noise_rad),
                     antenna_north_m=SHIP["antenna_north_m"] + rng.normal(0, array.gnss_noise_m),
                     antenna_east_m=SHIP["antenna_east_m"] + rng.normal(0, array.gnss_noise_m))
        phase_noise = array.phase_noise_at(slant)
        fix = usbl_fix(profile, array, travel_time_s=time + rng.normal(0, array.travel_time_noise_s),
                       phase_x_rad=phase_x + rng.normal(0, phase_noise), phase_y_rad=phase_y + rng.normal(0, phase_noise),
                       target_depth_m=truth["target_depth_m"] + rng.normal(0, array.depth_noise_m), **noisy)
        error = np.array([fix.north_m - truth["target_north_m"], fix.east_m - truth["target_east_m"]])
        errors.append(error)
        nees.append(error @ np.linalg.solve(fix.covariance_ne, error))
        errors3.append([*error, fix.depth_m - truth["target_depth_m"]])
    errors = np.array(errors)
    assert np.all(np.abs(errors.mean(axis=0)) < 3 * np.sqrt(np.diag(fix.covariance_ne) / len(errors)) + 0.05)
    assert 1.7 < np.mean(nees) < 2.3  # chi-square with 2 dof: mean 2, standard error 0.115 over 300 draws
    np.testing.assert_allclose(np.cov(errors.T), fix.covariance_ne, rtol=0.25, atol=0.05 * np.trace(fix.covariance_ne))
    # The depth error moves the fix along the line of sight: the 3 x 3 covariance holds the correlation.
    empirical = np.cov(np.array(errors3).T)
    np.testing.assert_allclose(empirical[:2, 2], fix.covariance_ned[:2, 2], rtol=0.3, atol=0.05)
    assert np.all(np.linalg.eigvalsh(fix.covariance_ned) > 0.0)


def test_wrapped_phases_are_refused(profile):
    with pytest.raises(ValueError, match="no downward component"):
        usbl_fix(profile, UsblArray(), travel_time_s=1.0, phase_x_rad=3.0, phase_y_rad=3.0, **SHIP, target_depth_m=800.0)


def test_local_frame_round_trips_and_has_unit_scale():
    frame = LocalFrame(18.0, 115.5)
    north, east = frame.to_local([18.0, 18.01], [115.5, 115.5])
    assert north[0] == pytest.approx(0.0, abs=1e-6) and east[0] == pytest.approx(0.0, abs=1e-6)
    assert north[1] == pytest.approx(1106.9, abs=1.0)  # one hundredth of a degree of latitude at 18 deg N
    lat, lon = frame.to_geographic(north, east)
    np.testing.assert_allclose(lat, [18.0, 18.01], atol=1e-10)
    easting, northing = frame.to_utm(north, east)
    assert frame.utm_crs.to_epsg() == 32650
    assert northing[1] - northing[0] == pytest.approx(1106.9 * 0.9996, abs=1.0)
    with pytest.raises(ValueError, match="out of range"):
        LocalFrame(95.0, 0.0)


def test_euler_round_trip():
    angles = np.radians([[3.0, -2.0, 170.0], [0.0, 10.0, -45.0]])
    np.testing.assert_allclose(euler_from_matrix(body_to_ned(*angles.T)), angles, atol=1e-12)


def test_direction_cosines_give_the_same_fix_as_phases(profile):
    array = UsblArray()
    time, phase_x, phase_y = reply_from_geometry(profile, array, **SHIP, target_north_m=-500.0, target_east_m=200.0, target_depth_m=900.0)
    by_phase = usbl_fix(profile, array, travel_time_s=time, phase_x_rad=phase_x, phase_y_rad=phase_y, **SHIP, target_depth_m=900.0)
    rotation = body_to_ned(SHIP["roll_rad"], SHIP["pitch_rad"], SHIP["heading_rad"])
    depth = (np.array([100.0, -50.0, -15.0]) + rotation @ np.array(array.lever_arm_m))[2]
    cosines = direction_cosines_from_phase([phase_x, phase_y], array.wavelength_m(float(profile.speed_at(depth))), array.baseline_m)
    by_direction = usbl_fix(profile, array, travel_time_s=time, direction_cosines=tuple(cosines), **SHIP, target_depth_m=900.0)
    assert by_direction.north_m == pytest.approx(by_phase.north_m, abs=1e-9)
    np.testing.assert_allclose(by_direction.covariance_ne, by_phase.covariance_ne, rtol=1e-6)
    with pytest.raises(ValueError, match="either both phases"):
        usbl_fix(profile, array, travel_time_s=time, phase_x_rad=phase_x, direction_cosines=tuple(cosines), **SHIP, target_depth_m=900.0)


def test_phase_noise_grows_with_range():
    array = UsblArray(phase_noise_rad=0.01, noise_growth_per_km=1.0)
    assert array.phase_noise_at(2000.0) == pytest.approx(0.03)
    assert array.cosine_noise(1500.0, 2000.0) == pytest.approx(3 * array.cosine_noise(1500.0, 0.0))
