"""The multi-target tracker: PDA against a hand EKF, EM clusters, M-of-N confirmation and deletion, two divers,
an hour-free-ish of false tracks, classes, CPA, and the covariance checked against the truth (NEES)."""

import dataclasses
import math

import numpy as np
import pytest

from lost.host.consistency import nees
from lost.host.track import Ping, Sonar
from lost.host.track.cluster import fit_mixture
from lost.host.track.kalman import ContactState, measurement, pda_update, predict
from lost.host.track.metrics import pings_to_lock
from lost.host.track.simulate import TargetSpec, builtin_scenario_path, load_scenario, simulate
from lost.host.track.tracker import MultiTargetTracker, TrackerParameters, _cpa

R = np.diag([4.0, np.radians(1.5) ** 2])


def test_pda_with_one_sure_detection_is_the_extended_kalman_update():
    state = ContactState(np.array([30.0, 300.0, 0.0, -0.5]), np.diag([25.0, 25.0, 1.0, 1.0]))
    platform, heading = np.array([0.0, 0.0]), 10.0
    z = np.array([[303.0, np.radians(-4.0)]])
    updated, association = pda_update(state, z, R, platform, heading, pd=1.0, clutter_density=1e-12)
    z_hat, H = measurement(state.x, platform, heading)
    S = H @ state.P @ H.T + R
    K = state.P @ H.T @ np.linalg.inv(S)
    np.testing.assert_allclose(updated.x, state.x + K @ (z[0] - z_hat), rtol=1e-9)
    np.testing.assert_allclose(updated.P, (np.eye(4) - K @ H) @ state.P, rtol=1e-6, atol=1e-9)
    assert association.gated.tolist() == [0] and association.beta_none < 1e-6


def test_pda_ignores_detections_outside_the_gate_and_weighs_clutter_against_a_miss():
    state = ContactState(np.array([0.0, 200.0, 0.0, 0.0]), np.diag([4.0, 4.0, 0.1, 0.1]))
    far = np.array([[260.0, 0.2]])
    same, association = pda_update(state, far, R, np.zeros(2), 0.0, pd=0.9, clutter_density=0.01)
    assert association.gated.size == 0 and same is state
    near = np.array([[201.0, 0.0]])
    dense, a_dense = pda_update(state, near, R, np.zeros(2), 0.0, pd=0.9, clutter_density=10.0)
    sparse, a_sparse = pda_update(state, near, R, np.zeros(2), 0.0, pd=0.9, clutter_density=0.001)
    assert a_dense.beta_none > a_sparse.beta_none  # in dense clutter the detection may well not be the contact's
    assert abs(dense.x[1] - 200.0) < abs(sparse.x[1] - 200.0)


def test_prediction_moves_at_constant_velocity_and_grows_the_covariance():
    state = ContactState(np.array([0.0, 0.0, 1.0, -2.0]), np.eye(4))
    later = predict(state, 2.0, 0.1)
    np.testing.assert_allclose(later.x, [2.0, -4.0, 1.0, -2.0])
    assert np.all(np.diag(later.P) > np.diag(state.P))


def test_em_finds_two_clusters_with_their_shares_and_spreads():
    rng = np.random.default_rng(0)
    a = rng.normal([100.0, 200.0], [3.0, 10.0], (700, 2))
    b = rng.normal([-50.0, 300.0], [5.0, 5.0], (300, 2))
    mixture = fit_mixture(np.vstack([a, b]), np.array([[90.0, 190.0], [-40.0, 310.0], [0.0, 0.0]]), iterations=20)
    assert len(mixture) == 2  # the empty seed is dropped
    np.testing.assert_allclose(mixture.shares, [0.7, 0.3], atol=0.01)
    np.testing.assert_allclose(mixture.means, [[100.0, 200.0], [-50.0, 300.0]], atol=1.5)
    np.testing.assert_allclose(np.sqrt(mixture.covariances[0].diagonal()), [3.0, 10.0], rtol=0.15)


def test_cpa_and_time_to_reach_by_hand():
    # 100 m north, coming straight in at 1 m/s: CPA 0 in 100 s, within 10 m in 90 s.
    assert _cpa(np.array([0.0, 100.0]), np.array([0.0, -1.0]), 10.0) == pytest.approx((0.0, 100.0, 90.0))
    # Passing 30 m abeam: CPA 30 m, never within 10 m.
    cpa, t, reach = _cpa(np.array([30.0, 100.0]), np.array([0.0, -1.0]), 10.0)
    assert (cpa, t) == pytest.approx((30.0, 100.0)) and math.isnan(reach)
    # Going away: the closest point is now.
    assert _cpa(np.array([0.0, 100.0]), np.array([0.0, 1.0]), 10.0)[:2] == pytest.approx((100.0, 0.0))


def repeated_pings(n_with, n_without, where=(300.0, 5.0)):
    pings = [Ping(i, 1.3 * i, (0.0, 0.0), 0.0, [where[0]], [where[1]]) for i in range(n_with)]
    return pings + [Ping(n_with + i, 1.3 * (n_with + i), (0.0, 0.0), 0.0, [], []) for i in range(n_without)]


def test_a_steady_return_is_confirmed_after_m_of_n_and_deleted_after_its_misses():
    params = TrackerParameters(particles=2000)
    tracker = MultiTargetTracker(sonar=Sonar(), parameters=params, rng=np.random.default_rng(0))
    history = [tracker.step(p) for p in repeated_pings(12, 10)]
    ids = {r.track_id for reports in history for r in reports}
    assert len(ids) == 1
    born = next(i for i, reports in enumerate(history) if reports)
    confirmed = next(i for i, reports in enumerate(history) if reports and reports[0].status == "confirmed")
    assert born <= 2 and confirmed - born == params.confirm_m - 1
    last = max(i for i, reports in enumerate(history) if reports)
    assert last == 11 + params.delete_misses - 1  # gone on its sixth ping without a detection
    assert tracker.deleted[-1].confirmed


@pytest.fixture(scope="module")
def two_divers():
    sim = simulate(load_scenario(builtin_scenario_path("two_divers")))
    tracker = MultiTargetTracker(sonar=sim.scenario.sonar.sonar, parameters=TrackerParameters(), rng=np.random.default_rng(0))
    return sim, [tracker.step(p) for p in sim.pings]


def nearest_truth(sim, report):
    d = np.hypot(*(sim.truth.xy[report.ping] - [report.x_m, report.y_m]).T)
    return int(np.nanargmin(d)), float(np.nanmin(d))


def test_two_divers_give_two_confirmed_tracks_that_keep_their_identities(two_divers):
    sim, history = two_divers
    owners: dict[int, set[int]] = {}
    for reports in history:
        for r in reports:
            if r.status == "confirmed":
                target, distance = nearest_truth(sim, r)
                assert distance < 30.0  # no confirmed track away from every target
                owners.setdefault(target, set()).add(r.track_id)
    assert len(owners[0]) == 1 and len(owners[1]) == 1 and owners[0] != owners[1]
    for target in (0, 1):
        errors = np.full(len(history), np.nan)
        for i, reports in enumerate(history):
            mine = [r for r in reports if r.track_id in owners[target]]
            if mine:
                errors[i] = math.hypot(mine[0].x_m - sim.truth.xy[i, target, 0], mine[0].y_m - sim.truth.xy[i, target, 1])
        lock = pings_to_lock(errors, sim.truth.in_sector[:, target])
        assert lock is not None and lock <= 8
        assert np.nanmedian(errors) < 5.0


def test_divers_and_the_drifting_object_are_classed_by_speed(two_divers):
    sim, history = two_divers
    classes: dict[int, list[str]] = {}
    for reports in history[60:]:
        for r in reports:
            if r.status == "confirmed":
                classes.setdefault(nearest_truth(sim, r)[0], []).append(r.classification)
    for target, kind in enumerate(("diver", "diver", "drifting")):
        assert classes[target].count(kind) / len(classes[target]) > 0.8


def test_a_fast_animal_is_classed_as_one():
    scenario = load_scenario(builtin_scenario_path("one_diver"))
    scenario = dataclasses.replace(scenario, duration_s=80.0, targets=(TargetSpec(kind="animal", start_range_m=400.0, speed_mps=3.0),))
    sim = simulate(scenario)
    tracker = MultiTargetTracker(sonar=sim.scenario.sonar.sonar, parameters=TrackerParameters(particles=2000), rng=np.random.default_rng(1))
    last = [tracker.step(p) for p in sim.pings][-1]
    assert [r.classification for r in last if r.status == "confirmed"] == ["fast animal"]


def test_no_false_track_in_ten_minutes_of_clutter():
    scenario = dataclasses.replace(load_scenario(builtin_scenario_path("clutter_hour")), duration_s=600.0)
    sim = simulate(scenario)
    tracker = MultiTargetTracker(sonar=sim.scenario.sonar.sonar, parameters=TrackerParameters(particles=2000), rng=np.random.default_rng(2))
    confirmed = {r.track_id for p in sim.pings for r in tracker.step(p) if r.status == "confirmed"}
    assert confirmed == set()
    assert tracker.deleted  # tentative tracks were born and rejected, so the test could have failed


def test_track_covariance_is_consistent_with_the_truth():
    errors, covariances = [], []
    for seed in range(3):
        scenario = dataclasses.replace(load_scenario(builtin_scenario_path("one_diver")), seed=10 + seed)
        sim = simulate(scenario)
        # The filter's process noise is the simulator's, so NEES should average its degrees of freedom (4).
        params = TrackerParameters(particles=2000, accel_sigma=scenario.targets[0].accel_sigma)
        tracker = MultiTargetTracker(sonar=scenario.sonar.sonar, parameters=params, rng=np.random.default_rng(seed))
        for i, ping in enumerate(sim.pings):
            for r in tracker.step(ping):
                if r.status == "confirmed" and sim.truth.in_sector[i, 0] and i > 30:
                    truth = np.r_[sim.truth.xy[i, 0], sim.truth.velocity[i, 0]]
                    errors.append(np.array([r.x_m, r.y_m, r.vx_mps, r.vy_mps]) - truth)
                    covariances.append(r.covariance)
    e, P = np.array(errors), np.array(covariances)
    assert len(e) > 600
    assert 2.5 < nees(e, P).mean() < 6.0
    assert np.mean(nees(e[:, :2], P[:, :2, :2]) < 9.21) > 0.93  # the 99 % position ellipse holds the diver


def test_pings_out_of_time_order_are_refused():
    tracker = MultiTargetTracker(sonar=Sonar(), parameters=TrackerParameters(particles=100), rng=np.random.default_rng(0))
    tracker.step(Ping(0, 5.0, (0.0, 0.0), 0.0, [], []))
    with pytest.raises(ValueError, match="Ping 1 at t = 5.0 s does not come after ping 0 at 5.0 s"):
        tracker.step(Ping(1, 5.0, (0.0, 0.0), 0.0, [], []))
