"""INS: strapdown against analytic motions, eqs. 6-7 dead reckoning, IMU sample checks."""

import numpy as np
import pytest

from lost.host.usbl.frames import body_to_ned
from lost.host.usbl.ins import EarthModel, ImuSamples, NavState, dead_reckon, strapdown

GRAVITY = 9.79
STILL_EARTH = EarthModel(GRAVITY, np.zeros(3))


def test_strapdown_flies_a_coordinated_circle():
    speed, rate, hz = 2.0, 0.02, 20.0
    time = np.arange(0.0, 2 * np.pi / rate + 1e-9, 1 / hz)
    n = time.size
    imu = ImuSamples(time, np.tile([0.0, speed * rate, -GRAVITY], (n, 1)), np.tile([0.0, 0.0, rate], (n, 1)))
    start = NavState(np.zeros(3), np.array([speed, 0.0, 0.0]), np.eye(3))
    position, velocity, attitude = strapdown(imu, start, STILL_EARTH)
    radius = speed / rate
    # heading psi = rate t, turning right: centre at (0, radius)
    expected = np.stack([radius * np.sin(rate * time), radius * (1 - np.cos(rate * time)), np.zeros(n)], axis=1)
    assert np.max(np.linalg.norm(position - expected, axis=1)) < 0.02
    assert np.max(np.abs(np.linalg.norm(velocity, axis=1) - speed)) < 1e-4
    np.testing.assert_allclose(attitude[-1], body_to_ned(0.0, 0.0, rate * time[-1]), atol=1e-9)


def test_strapdown_at_rest_when_tilted():
    rotation = body_to_ned(np.radians(5.0), np.radians(-3.0), np.radians(120.0))
    force = rotation.T @ np.array([0.0, 0.0, -GRAVITY])
    time = np.arange(0.0, 60.0, 0.1)
    imu = ImuSamples(time, np.tile(force, (time.size, 1)), np.zeros((time.size, 3)))
    position, velocity, _ = strapdown(imu, NavState(np.zeros(3), np.zeros(3), rotation), STILL_EARTH)
    assert np.max(np.abs(position)) < 1e-9 and np.max(np.abs(velocity)) < 1e-10


def test_an_accelerometer_bias_drifts_as_half_b_t_squared():
    time = np.arange(0.0, 100.0 + 1e-9, 0.1)
    bias = 1e-3
    imu = ImuSamples(time, np.tile([bias, 0.0, -GRAVITY], (time.size, 1)), np.zeros((time.size, 3)))
    position, _, _ = strapdown(imu, NavState(np.zeros(3), np.zeros(3), np.eye(3)), STILL_EARTH)
    assert position[-1, 0] == pytest.approx(0.5 * bias * 100.0**2, rel=1e-9)


def test_imu_samples_are_checked():
    with pytest.raises(ValueError, match="slower than 10 Hz"):
        ImuSamples(np.arange(0.0, 10.0, 0.5), np.zeros((20, 3)), np.zeros((20, 3)))
    with pytest.raises(ValueError, match="sample 2 at"):
        ImuSamples(np.array([0.0, 0.1, 0.1]), np.zeros((3, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="n x 3"):
        ImuSamples(np.array([0.0, 0.1]), np.zeros((2, 2)), np.zeros((2, 3)))


def test_dead_reckoning_is_exact_for_constant_acceleration_on_a_line():
    time = np.linspace(0.0, 50.0, 101)
    north, east, speed = dead_reckon(time, np.full(101, 0.02), np.full(101, np.radians(60.0)), north0_m=10.0, east0_m=-5.0, speed0_m_s=1.0)
    distance = 1.0 * time + 0.5 * 0.02 * time**2
    np.testing.assert_allclose(north, 10.0 + distance * np.cos(np.radians(60.0)), atol=1e-9)
    np.testing.assert_allclose(east, -5.0 + distance * np.sin(np.radians(60.0)), atol=1e-9)
    np.testing.assert_allclose(speed, 1.0 + 0.02 * time, atol=1e-12)


def test_dead_reckoning_follows_a_turn_through_north():
    time = np.arange(0.0, 200.0, 1.0)
    heading = np.radians(-90.0) + 0.01 * time  # through north (0) without a jump problem in the mean
    north, east, _ = dead_reckon(time, np.zeros(time.size), heading, north0_m=0.0, east0_m=0.0, speed0_m_s=2.0)
    radius = 200.0
    exact_north = radius * (np.sin(heading) - np.sin(heading[0]))
    exact_east = -radius * (np.cos(heading) - np.cos(heading[0]))
    assert np.max(np.hypot(north - exact_north, east - exact_east)) < 0.05


def test_at_rest_on_the_rotating_earth_the_gyros_see_its_rate():
    earth = EarthModel.at(45.0)
    rotation = body_to_ned(np.radians(2.0), np.radians(1.0), np.radians(30.0))
    time = np.arange(0.0, 600.0, 0.1)
    rates = np.tile(rotation.T @ earth.rate_ned, (time.size, 1))
    forces = np.tile(rotation.T @ -earth.gravity_ned, (time.size, 1))
    position, velocity, attitude = strapdown(ImuSamples(time, forces, rates), NavState(np.zeros(3), np.zeros(3), rotation), earth)
    assert np.max(np.abs(position)) < 1e-6 and np.max(np.abs(attitude[-1] - rotation)) < 1e-10
    assert np.linalg.norm(earth.rate_ned) * 3600 == pytest.approx(np.radians(15.041), rel=1e-3)


def test_coriolis_turns_a_moving_vehicle_without_forces():
    earth = EarthModel(GRAVITY, np.array([0.0, 0.0, -1e-3]))  # an exaggerated vertical rate: Coriolis swings v to the right
    time = np.arange(0.0, 100.0 + 1e-9, 0.01)
    rates = np.tile(earth.rate_ned, (time.size, 1))  # a body turning with the Earth: no rotation relative to it
    forces = np.tile([0.0, 0.0, -GRAVITY], (time.size, 1))
    _, velocity, _ = strapdown(ImuSamples(time, forces, rates), NavState(np.zeros(3), np.array([1.0, 0.0, 0.0]), np.eye(3)), earth)
    angle = 2e-3 * time[-1]  # v' = -2 Omega x v rotates v about down at 2 |Omega|
    np.testing.assert_allclose(velocity[-1, :2], [np.cos(angle), np.sin(angle)], atol=1e-3)
