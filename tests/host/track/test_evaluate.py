"""Scoring with Stone Soup's metrics on hand-made cases, and Stone Soup's GM-PHD baseline on a short run."""

import dataclasses

import numpy as np
import pytest

from lost.host.track.baseline import JPDAParameters, run_gm_phd, run_jpda
from lost.host.track.estimates import Estimate
from lost.host.track.evaluate import contact_metrics, holding, score
from lost.host.track.simulate import Truth, builtin_scenario_path, load_scenario, simulate
from lost.host.track.tracker import TrackerParameters


def straight_truth(pings=10):
    t = np.arange(pings) * 1.3
    xy = np.zeros((pings, 1, 2))
    xy[:, 0, 1] = 300.0 - 0.5 * t
    velocity = np.zeros_like(xy)
    velocity[:, 0, 1] = -0.5
    return Truth(t, xy, velocity, ("diver",), np.ones((pings, 1), bool))


def on_truth(truth, offset=(0.0, 0.0), track_id=1):
    return [[Estimate(track_id, *(truth.xy[i, 0] + offset), *truth.velocity[i, 0])] for i in range(truth.t_s.size)]


def test_a_perfect_track_scores_zero_and_locks_at_once():
    truth = straight_truth()
    s = score(on_truth(truth), truth)
    assert s.gospa_mean == pytest.approx(0.0, abs=1e-9) and s.ospa_mean == pytest.approx(0.0, abs=1e-9)
    assert s.pings_to_lock == [1] and (s.confirmed_tracks, s.false_tracks) == (1, 0)
    assert s.siap["Completeness"] == pytest.approx(1.0) and s.siap["Spuriousness"] == pytest.approx(0.0)


def test_gospa_charges_offsets_misses_and_false_contacts():
    truth = straight_truth()
    history = on_truth(truth, offset=(3.0, 4.0))  # 5 m off at every ping
    history[0] = []  # missed at the first ping: c / 2 = 25 m
    history[1] = history[1] + [Estimate(9, 400.0, 0.0, 0.0, 0.0)]  # and a false contact at the second: 25 m more
    s = score(history, truth, siap=False)
    assert s.gospa_mean == pytest.approx((25.0 + 30.0 + 8 * 5.0) / 10)
    assert s.gospa_localisation_mean == pytest.approx(9 * 5.0 / 10)
    assert s.pings_to_lock == [2] and s.false_tracks == 1 and s.confirmed_tracks == 2


def test_score_refuses_histories_of_another_length():
    with pytest.raises(ValueError, match="9 pings of reports against 10 pings of truth"):
        score(on_truth(straight_truth())[:9], straight_truth())


def test_stone_soup_gm_phd_sees_the_diver_where_the_simulator_put_it():
    scenario = load_scenario(builtin_scenario_path("one_diver"))
    scenario = dataclasses.replace(scenario, duration_s=52.0, sonar=dataclasses.replace(scenario.sonar, clutter_per_ping=1.0))
    sim = simulate(scenario)
    params = TrackerParameters(clutter_per_ping=1.0)
    history = run_gm_phd(sim.pings, sonar=scenario.sonar.sonar, tracker=params)
    assert len(history) == len(sim.pings)
    late = [min(np.hypot(*(e.xy - sim.truth.xy[i, 0])) for e in history[i]) for i in range(30, len(history)) if history[i]]
    assert len(late) > 5 and np.median(late) < 10.0


def test_stone_soup_jpda_confirms_the_diver_after_its_m_of_n_and_follows_it():
    scenario = load_scenario(builtin_scenario_path("one_diver"))
    scenario = dataclasses.replace(scenario, duration_s=40.0, sonar=dataclasses.replace(scenario.sonar, clutter_per_ping=1.0))
    sim = simulate(scenario)
    history = run_jpda(sim.pings, sonar=scenario.sonar.sonar, tracker=TrackerParameters(clutter_per_ping=1.0), jpda=JPDAParameters(min_points=4))
    assert len(history) == len(sim.pings)
    assert not any(history[:3])  # a track needs four updates before the initiator releases it
    late = [min(np.hypot(*(e.xy - sim.truth.xy[i, 0])) for e in history[i]) for i in range(15, len(history)) if history[i]]
    assert len(late) > 10 and np.median(late) < 10.0


def two_truths(pings=6, apart=20.0):
    t = np.arange(pings) * 1.3
    xy = np.zeros((pings, 2, 2))
    xy[:, :, 1] = 300.0
    xy[:, 1, 0] = apart
    return Truth(t, xy, np.zeros_like(xy), ("diver", "diver"), np.ones((pings, 2), bool))


def test_one_track_between_two_divers_holds_only_one_and_switches_are_counted():
    truth = two_truths()
    between = [[Estimate(1, 10.0, 300.0, 0.0, 0.0)] for _ in range(6)]  # within 25 m of both
    m = contact_metrics(between, truth)
    assert sorted(m["coverage"]) == [0.0, 1.0] and m["all_held"] == 0.0
    assert gospa_per_ping_of(between, truth) == pytest.approx([10.0 + 25.0] * 6)
    two = [[Estimate(1 if i < 3 else 3, 0.0, 300.0, 0, 0), Estimate(2, 20.0, 301.0, 0, 0)] for i in range(6)]
    two[0] = []
    m = contact_metrics(two, truth, after=1)
    assert m["coverage"] == [1.0, 1.0] and m["all_held"] == 1.0
    assert m["first_lock"] == [2, 2] and m["identity_switches"] == [1, 0]
    np.testing.assert_array_equal(holding(two, truth)[:, 0], [-1, 1, 1, 3, 3, 3])


def gospa_per_ping_of(history, truth):
    return score(history, truth, siap=False).gospa_per_ping
