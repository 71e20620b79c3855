"""The 15-state INS+USBL filter: prediction on a perfect IMU, the update and its gate, and a short tow's NEES."""

import numpy as np
import pytest
from scipy.stats import chi2

from lost.host.usbl.filter import ImuNoise, InsUsblFilter
from lost.host.usbl.fix import UsblFix
from lost.host.usbl.frames import body_to_ned
from lost.host.usbl.ins import EarthModel, NavState, strapdown
from lost.host.usbl.pipeline import UsblConfig, process
from lost.host.usbl.scenario import ImuSpec
from lost.host.usbl.simulate import simulate_tow

GRAVITY = 9.785
STILL_EARTH = EarthModel(GRAVITY, np.zeros(3))


def _filter(position=(0.0, 0.0, 500.0), sigma_m=5.0) -> InsUsblFilter:
    covariance = np.diag([sigma_m**2] * 3 + [0.01] * 3 + [1e-6] * 3 + [1e-12] * 3 + [1e-8] * 3)
    state = NavState(np.array(position, float), np.array([1.0, 0.0, 0.0]), np.eye(3))
    return InsUsblFilter(state, covariance, ImuNoise(), STILL_EARTH, gate_probability=0.999)


def _fix(north, east, depth=500.0, sigma=2.0) -> UsblFix:
    return UsblFix(north, east, depth, np.eye(2) * sigma**2, 0.25, 0.0, 0.0, 0.0, 1)


def test_prediction_moves_the_state_and_grows_the_covariance():
    filt = _filter()
    before = filt.covariance.copy()
    for _ in range(100):
        filt.predict(np.array([0.0, 0.0, -GRAVITY]), np.zeros(3), 0.1)
    np.testing.assert_allclose(filt.state.position, [10.0, 0.0, 500.0], atol=1e-9)
    assert np.all(np.diag(filt.covariance)[:6] > np.diag(before)[:6])
    np.testing.assert_allclose(filt.covariance, filt.covariance.T, atol=1e-12)


def test_update_pulls_toward_the_fix_and_shrinks_the_covariance():
    filt = _filter(sigma_m=5.0)
    accepted, nis = filt.update(_fix(4.0, -3.0, sigma=5.0))
    assert accepted
    # Equal variances: the estimate goes half way, the variance halves.
    np.testing.assert_allclose(filt.state.position[:2], [2.0, -1.5], atol=1e-9)
    np.testing.assert_allclose(np.diag(filt.covariance)[:2], [12.5, 12.5], rtol=1e-9)
    assert nis == pytest.approx((16 + 9) / 50 + 0.0, rel=1e-9)


def test_gate_rejects_a_wild_fix_and_leaves_the_state_alone():
    filt = _filter(sigma_m=2.0)
    before = filt.state.position.copy()
    accepted, nis = filt.update(_fix(60.0, 0.0))
    assert not accepted and nis > chi2.ppf(0.999, 3) == pytest.approx(filt.gate)
    np.testing.assert_array_equal(filt.state.position, before)


def test_truth_is_the_strapdown_of_an_ideal_imu(short_scenario, imu_samples):
    quiet = ImuSpec(gyro_bias_deg_h=0.0, accel_bias_mg=0.0, angle_random_walk_deg_sqrt_h=0.0, velocity_random_walk_mg_sqrt_hz=0.0,
                    gyro_bias_walk_deg_h_sqrt_h=0.0, accel_bias_walk_mg_sqrt_h=0.0)
    sim = simulate_tow(short_scenario(imu=quiet, duration_s=120.0))
    start = NavState(sim.truth_position[0], sim.truth_velocity[0], sim.truth_attitude[0])
    position, velocity, attitude = strapdown(imu_samples(sim.imu), start, EarthModel.at(18.0))
    np.testing.assert_allclose(attitude, sim.truth_attitude, atol=1e-9)
    np.testing.assert_allclose(velocity, sim.truth_velocity, atol=1e-9)
    np.testing.assert_allclose(position, sim.truth_position, atol=1e-6)


def test_short_tow_is_consistent(short_tow, short_scenario, imu_samples):
    scenario = short_scenario()
    run = process(short_tow.log, imu_samples(short_tow.imu), short_tow.cast, UsblConfig(array=scenario.usbl, imu=scenario.imu))
    error = run.fused.position - run.truth[run.start_index:]
    nees = np.einsum("ki,ki->k", error, np.linalg.solve(run.fused.covariance, error[..., None])[..., 0])
    assert 1.5 < nees.mean() < 5.0  # chi-square, 3 dof: mean 3 (strongly correlated epochs: a loose bound)
    assert np.all(np.isfinite(run.fused.position))
    raw = np.array([[f.north_m - t[0], f.east_m - t[1]] for f, t in zip(run.fixes, run.truth) if f is not None])
    assert np.sqrt(np.mean(np.sum(error[:, :2] ** 2, axis=1))) < 0.5 * np.sqrt(np.mean(np.sum(raw**2, axis=1)))


def test_a_depth_alone_updates_only_through_its_correlations():
    filt = _filter(sigma_m=5.0)
    filt.covariance[2, 2] = 1.0
    accepted, nis = filt.update_depth(501.0, 1.0)
    assert accepted and nis == pytest.approx(0.5)
    assert filt.state.position[2] == pytest.approx(500.5)
    np.testing.assert_allclose(filt.state.position[:2], [0.0, 0.0], atol=1e-12)  # no correlation yet: north and east stay
    assert filt.covariance[2, 2] == pytest.approx(0.5)
    assert not filt.update_depth(520.0, 0.01)[0]  # 28 sigma: gated


def test_the_transponder_lever_arm_enters_through_the_attitude():
    filt = _filter(sigma_m=1.0)
    filt.transponder_lever_arm_m = np.array([2.0, 0.0, -1.0])
    filt.covariance[6:9, 6:9] = np.eye(3) * 0.01**2
    # A fix exactly where the transponder is predicted: no innovation, nothing moves.
    predicted = filt.state.position + filt.state.attitude @ filt.transponder_lever_arm_m
    before = filt.state.position.copy()
    accepted, nis = filt.update(_fix(*predicted))
    assert accepted and nis == pytest.approx(0.0, abs=1e-18)
    np.testing.assert_allclose(filt.state.position, before, atol=1e-12)
    # A fix off by the lever arm's rotation under a yaw error: the update moves heading as well as position.
    yaw = 0.005
    rotated = filt.state.position + body_to_ned(0.0, 0.0, yaw) @ filt.transponder_lever_arm_m
    heading_before = np.arctan2(filt.state.attitude[1, 0], filt.state.attitude[0, 0])
    filt.update(_fix(*rotated))
    assert np.arctan2(filt.state.attitude[1, 0], filt.state.attitude[0, 0]) - heading_before > 0.0


def test_a_short_tow_with_a_transponder_lever_arm(short_scenario, imu_samples):
    import dataclasses

    scenario = short_scenario()
    scenario = dataclasses.replace(scenario, usbl=dataclasses.replace(scenario.usbl, transponder_lever_arm_m=(3.0, 1.0, -2.0)))
    sim = simulate_tow(scenario)
    config = UsblConfig(array=scenario.usbl, imu=scenario.imu)
    run = process(sim.log, imu_samples(sim.imu), sim.cast, config)
    error = run.fused.position - run.truth[run.start_index:]
    nees = np.einsum("ki,ki->k", error, np.linalg.solve(run.fused.covariance, error[..., None])[..., 0])
    assert 1.5 < nees.mean() < 5.0
    ignoring = process(sim.log, imu_samples(sim.imu), sim.cast, UsblConfig(array=dataclasses.replace(scenario.usbl, transponder_lever_arm_m=(0.0, 0.0, 0.0)),
                                                                           imu=scenario.imu))
    wrong = ignoring.fused.position - run.truth[run.start_index:]
    assert np.sqrt(np.mean(np.sum(error[:, :2] ** 2, axis=1))) < 0.5 * np.sqrt(np.mean(np.sum(wrong[:, :2] ** 2, axis=1)))
