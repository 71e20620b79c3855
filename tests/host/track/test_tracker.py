"""The multi-target tracker: PDA against a hand EKF, EM clusters, confirmation and deletion by existence, two divers,
an hour-free-ish of false tracks, classes, CPA, and the covariance checked against the truth (NEES)."""

import dataclasses
import itertools
import math

import numpy as np
import pytest

from lost.host.consistency import nees
from lost.host.track import Ping, Sonar
from lost.host.track.cluster import fit_mixture
from lost.host.track.kalman import ContactState, measurement, pda_update, predict
from lost.host.track.metrics import pings_to_lock
from lost.host.track.simulate import PlatformSpec, TargetSpec, TrackScenario, builtin_scenario_path, load_scenario, simulate
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


def _steady_return(pd: float) -> tuple[list, MultiTargetTracker]:
    params = TrackerParameters(particles=2000, pd=pd)
    tracker = MultiTargetTracker(sonar=Sonar(), parameters=params, rng=np.random.default_rng(0))
    return [tracker.step(p) for p in repeated_pings(12, 20)], tracker


def test_a_steady_return_is_confirmed_by_its_existence_and_deleted_when_it_stops():
    history, tracker = _steady_return(0.9)
    ids = {r.track_id for reports in history for r in reports}
    assert len(ids) == 1
    born = next(i for i, reports in enumerate(history) if reports)
    existence = [reports[0].existence for reports in history if reports]
    assert existence[0] == tracker.parameters.birth_existence
    confirmed = next(i for i, reports in enumerate(history) if reports and reports[0].status == "confirmed")
    assert born <= 3 and 1 <= confirmed - born <= 4
    assert np.all(np.diff(existence[: confirmed - born + 1]) > 0)  # every detection raises it
    after = existence[12 - born:]
    assert np.all(np.diff(after) < 0)  # every miss lowers it
    assert tracker.deleted[-1].confirmed and tracker.deleted[-1].existence < tracker.parameters.delete_confirmed_existence


def test_a_contact_seldom_detected_survives_more_misses():
    """The misses a deletion takes follow from pd: a miss says less against a contact detected 6 times in 10."""
    last = {}
    for pd in (0.9, 0.6):
        history, _ = _steady_return(pd)
        last[pd] = max(i for i, reports in enumerate(history) if reports)
    assert last[0.9] - 11 <= 6
    assert last[0.6] - 11 >= 2 * (last[0.9] - 11)


@pytest.fixture(scope="module")
def two_divers():
    sim = simulate(load_scenario(builtin_scenario_path("two_divers")))
    tracker = MultiTargetTracker(sonar=sim.scenario.sonar.sonar, parameters=TrackerParameters(particles=1000), rng=np.random.default_rng(0))
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
    """Once a track's speed is known its class is right; a track re-born at the sector's edge is "unknown" until then."""
    sim, history = two_divers
    classes: dict[int, list[str]] = {}
    for reports in history[60:]:
        for r in reports:
            if r.status == "confirmed":
                classes.setdefault(nearest_truth(sim, r)[0], []).append(r.classification)
    for target, kind in enumerate(("diver", "diver", "drifting")):
        known = [c for c in classes[target] if c != "unknown"]
        assert len(known) / len(classes[target]) > 0.6
        assert known.count(kind) / len(known) > 0.95


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
        scenario = dataclasses.replace(load_scenario(builtin_scenario_path("one_diver")), seed=10 + seed, duration_s=300.0)
        sim = simulate(scenario)
        # The filter's process noise is the simulator's, so NEES should average its degrees of freedom (4).
        # A small search cloud: it only finds the diver; the covariance is the filtered track's.
        params = TrackerParameters(particles=300, em_points=300, accel_sigma=scenario.targets[0].accel_sigma)
        tracker = MultiTargetTracker(sonar=scenario.sonar.sonar, parameters=params, rng=np.random.default_rng(seed))
        for i, ping in enumerate(sim.pings):
            for r in tracker.step(ping):
                if r.status == "confirmed" and sim.truth.in_sector[i, 0] and i > 30:
                    truth = np.r_[sim.truth.xy[i, 0], sim.truth.velocity[i, 0]]
                    errors.append(np.array([r.x_m, r.y_m, r.vx_mps, r.vy_mps]) - truth)
                    covariances.append(r.covariance)
    e, P = np.array(errors), np.array(covariances)
    assert len(e) > 450
    assert 2.5 < nees(e, P).mean() < 6.0
    assert np.mean(nees(e[:, :2], P[:, :2, :2]) < 9.21) > 0.93  # the 99 % position ellipse holds the diver


def test_pings_out_of_time_order_are_refused():
    tracker = MultiTargetTracker(sonar=Sonar(), parameters=TrackerParameters(particles=100), rng=np.random.default_rng(0))
    tracker.step(Ping(0, 5.0, (0.0, 0.0), 0.0, [], []))
    with pytest.raises(ValueError, match="Ping 1 at t = 5.0 s does not come after ping 0 at 5.0 s"):
        tracker.step(Ping(1, 5.0, (0.0, 0.0), 0.0, [], []))


def test_two_divers_twenty_metres_apart_are_two_tracks():
    """Side by side at 350 m (20 m is about two bearing sigmas there): JIPDA keeps one detection from feeding both."""
    targets = tuple(TargetSpec(start_range_m=350.0, start_bearing_deg=b, speed_mps=0.5, course_deg=180.0) for b in (-1.637, 1.637))
    scenario = dataclasses.replace(load_scenario(builtin_scenario_path("one_diver")), seed=7, duration_s=100.0, targets=targets)
    assert _both_held_after(simulate(scenario), TrackerParameters(), 7, radius_m=15.0) >= 0.9


def _both_held_after(sim, parameters: TrackerParameters, seed: int, after: int = 20, radius_m: float = 25.0) -> float:
    """Share of the pings after ``after`` at which two distinct confirmed tracks hold one diver each."""
    tracker = MultiTargetTracker(sonar=sim.scenario.sonar.sonar, parameters=parameters, rng=np.random.default_rng(seed))
    both = []
    for i, ping in enumerate(sim.pings):
        confirmed = [r for r in tracker.step(ping) if r.status == "confirmed"]
        if i >= after:
            near = [{k for k in (0, 1) if math.hypot(r.x_m - sim.truth.xy[i, k, 0], r.y_m - sim.truth.xy[i, k, 1]) <= radius_m} for r in confirmed]
            both.append(any(0 in a and 1 in b for a, b in itertools.permutations(near, 2)))
    return float(np.mean(both))


@pytest.mark.parametrize("seed", [0])
def test_jpda_star_keeps_two_divers_fifteen_metres_apart_as_two_tracks(seed):
    """15 m apart at 350 m (1.6 bearing sigmas): with every joint event the tracks coalesce and one is lost; with JPDA*'s both stay."""
    half = math.degrees(7.5 / 350.0)
    targets = tuple(TargetSpec(start_range_m=350.0, start_bearing_deg=b, speed_mps=0.5, course_deg=180.0) for b in (-half, half))
    sim = simulate(TrackScenario(name="fifteen_apart", seed=seed, duration_s=80.0, targets=targets,
                                 platform=PlatformSpec(yaw_amplitude_deg=8.0, yaw_period_s=90.0)))
    assert _both_held_after(sim, TrackerParameters(), seed) >= 0.9
    assert _both_held_after(sim, TrackerParameters(permutation_pruning=False), seed) < 0.8


def test_one_cloud_cluster_over_two_contacts_starts_a_track_at_each_of_its_detections(monkeypatch):
    """EM found one cluster over two contacts 20 m apart: each of its detections starts a track; clutter outside it none."""
    import lost.host.track.tracker as tracker_module
    from lost.host.track.cluster import Mixture

    sonar = Sonar(max_range_m=500.0, half_fov_deg=45.0, ping_interval_s=1.3)
    tracker = MultiTargetTracker(sonar=sonar, parameters=TrackerParameters(particles=1000), rng=np.random.default_rng(1))
    ping = Ping(0, 0.0, np.zeros(2), 0.0, np.array([350.0, 350.0, 200.0]), np.array([-1.637, 1.637, -30.0]))
    contacts = ping.detections_xy()[:2]
    cluster = Mixture(np.array([0.9]), contacts.mean(axis=0)[None], np.diag([12.0**2, 4.0**2])[None])
    monkeypatch.setattr(tracker_module, "fit_mixture", lambda points, seeds: cluster)
    tracker.cloud.xy = np.zeros((1000, 2))
    tracker._births(ping, np.ones(3, dtype=bool))
    born = np.array([t.state.x[:2] for t in tracker.tracks])
    assert len(born) == 2
    np.testing.assert_allclose(born[np.argsort(born[:, 0])], contacts[np.argsort(contacts[:, 0])], atol=1e-9)
    assert all(t.existence == TrackerParameters().birth_existence and not t.confirmed for t in tracker.tracks)
