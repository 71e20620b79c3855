"""The navigation with a USBL: the ray-traced slant range, the fix in the Bayesian filters and in the patent pipeline."""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import replace

import numpy as np
import pytest

from lost.host.grid import Grid
from lost.host.nav import NavParameters, navigate
from lost.host.nav.estimator import Estimate, Motion, Observation
from lost.host.nav.likelihood import TerrainLikelihood
from lost.host.nav.loop import RecordLoop
from lost.host.nav.mapprep import PreparedMap
from lost.host.nav.patent import PatentEstimator
from lost.host.nav.pf import ParticleFilter
from lost.host.nav.pmf import PointMassFilter
from lost.host.nav.stages import TrackFrame
from lost.host.records import NavRecords
from lost.host.report import NEES_3_SIGMA, track_nees
from lost.host.scenario import builtin_scenario_path, load_scenario, simulate, usbl_profile
from lost.host.terrain import synthetic_terrain
from lost.host.usbl.rays import slant_range_from_travel_time
from lost.host.usbl.sound import SoundSpeedProfile

NODE = 10.0
PROFILE = SoundSpeedProfile(np.array([0.0, 100.0, 2000.0]), np.array([1540.0, 1510.0, 1490.0]))


def _grid():
    return Grid(synthetic_terrain((80, 80), seed=4, roughness_m=10.0, hurst=0.5), 0.0, 0.0, NODE)


def _quiet(**changes):
    return replace(NavParameters(velocity_noise_mps=0.0, gyro_bias_rps=0.0, accel_bias_mps2=0.0, use_slant_range=False, usable_updates=1,
                                 estimate_velocity_bias=False, pmf_min_cell_m=1.0), **changes)


def _fix_observation(position, covariance, slant=np.nan, t_s=0.0, frame=None):
    return Observation(t_s=t_s, frame=frame, patch=None, ocean_depth_m=np.nan, vehicle_depth_m=500.0, slant_range_m=slant,
                       fix_position_m=np.asarray(position, float), fix_covariance_m2=np.asarray(covariance, float))


def _filter(kind, params, grid):
    likelihood = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0)
    return PointMassFilter(likelihood, params, grid=grid) if kind == "pmf" else ParticleFilter(likelihood, params, grid=grid, seed=3)


@pytest.mark.parametrize("kind", ["pmf", "pf"])
def test_a_fix_is_a_kalman_update_of_a_gaussian_prior(kind):
    grid = _grid()
    params = _quiet(initial_sigma_m=30.0, position_floor_m=0.0, position_floor_nodes=0.0, pf_particles=40_000, usbl_fix_dof=math.inf)
    f = _filter(kind, params, grid)
    start = np.array([400.0, 400.0])
    f.start(0.0, start, _fix_observation(start, np.eye(2)))  # start() ignores the fix
    prior_mean, prior_cov = f.estimate().position, f.estimate().covariance
    fix, cov = start + np.array([20.0, -10.0]), np.array([[100.0, 30.0], [30.0, 225.0]])
    f.update(_fix_observation(fix, cov))
    gain = prior_cov @ np.linalg.inv(prior_cov + cov)
    expected_mean = prior_mean + gain @ (fix - prior_mean)
    expected_cov = (np.eye(2) - gain) @ prior_cov
    answer = f.estimate()
    tolerance = 0.3 if kind == "pmf" else 1.0  # the PF's is a 40,000-particle sample
    np.testing.assert_allclose(answer.position, expected_mean, atol=tolerance)
    np.testing.assert_allclose(answer.covariance, expected_cov, rtol=0.1 if kind == "pf" else 0.02, atol=2.0)
    assert f.counts["fix_updates"] == 1 and f.counts["fix_rejected_gate"] == 0


@pytest.mark.parametrize("kind", ["pmf", "pf"])
def test_a_fix_far_off_pulls_less_than_a_gaussian_would_and_one_near_about_as_much(kind):
    grid = _grid()
    start, cov = np.array([400.0, 400.0]), 9.0 * np.eye(2)  # a 3 m fix on a 3 m density
    outcome = {}
    for dof in (math.inf, 6.0):
        for offset in (2.0, 8.0, 12.0):  # the innovation's NIS 0.2, 3.6 and 8 against the stated variance: inside its gate
            f = _filter(kind, _quiet(initial_sigma_m=3.0, position_floor_m=0.0, position_floor_nodes=0.0, pf_particles=40_000,
                                     usbl_fix_dof=dof), grid)
            f.start(0.0, start, _fix_observation(start, np.eye(2)))
            f.update(_fix_observation(start + np.array([offset, 0.0]), cov))
            outcome[dof, offset] = float(f.estimate().position[0] - start[0]), f.counts["fix_updates"]
    assert all(outcome[math.inf, offset][1] == 1 for offset in (2.0, 8.0, 12.0))  # the Gaussian takes all three, half way
    assert abs(outcome[6.0, 2.0][0] - outcome[math.inf, 2.0][0]) < 0.1 * outcome[math.inf, 2.0][0]
    assert outcome[6.0, 8.0][1] == 1 and outcome[6.0, 8.0][0] < 0.93 * outcome[math.inf, 8.0][0]
    # Four sigmas off, the t's update moves the mean by more than the little it narrows allows: its NIS refuses it.
    assert outcome[6.0, 12.0][1] == 0


@pytest.mark.parametrize("kind", ["pmf", "pf"])
def test_a_usable_filter_gates_fixes_by_what_the_fixes_showed(kind):
    grid = _grid()
    f = _filter(kind, _quiet(initial_sigma_m=3.0, position_floor_m=0.0, position_floor_nodes=0.0), grid)
    start = np.array([400.0, 400.0])
    f.start(0.0, start, _fix_observation(start, np.eye(2)))
    for _ in range(60):
        f._trust.note_fix_innovation(0.35)  # fixes four times as good as stated: the gate's scale is a quarter
    outlier = start + np.array([15.0, 0.0])  # NIS 8.6 against the stated variance: under gate_nis (13.8), over a quarter of it
    f._trust.usable = False
    f.update(_fix_observation(outlier, 16.0 * np.eye(2)))
    assert f.counts["fix_updates"] == 1  # while acquiring the stated gate stands
    f = _filter(kind, _quiet(initial_sigma_m=3.0, position_floor_m=0.0, position_floor_nodes=0.0), grid)
    f.start(0.0, start, _fix_observation(start, np.eye(2)))
    for _ in range(60):
        f._trust.note_fix_innovation(0.35)
    f._trust.usable = True
    f.update(_fix_observation(outlier, 16.0 * np.eye(2)))
    assert f.counts["fix_rejected_gate"] == 1 and f.counts["fix_updates"] == 0


@pytest.mark.parametrize("kind", ["pmf", "pf"])
def test_a_used_fix_restarts_the_ins_error_growth_and_a_refused_one_does_not(kind):
    """Eq. 6.2's growth runs from the last position fix: 600 s off the map it is about 24 m (1-sigma)."""
    grid = _grid()
    f = _filter(kind, _quiet(initial_sigma_m=10.0, gyro_bias_rps=4.8e-8, accel_bias_mps2=1e-4), grid)
    start = np.array([400.0, 400.0])
    f.start(0.0, start, _fix_observation(start, np.eye(2)))
    f._trust.since_update_s = 600.0
    f.update(_fix_observation(start + 500.0, np.eye(2)))  # far outside the gate: refused
    assert f.counts["fix_rejected_gate"] == 1 and f._trust.since_update_s == 600.0
    f.update(_fix_observation(start + 1.0, 25.0 * np.eye(2)))
    assert f.counts["fix_updates"] == 1 and f._trust.since_update_s == 0.0
    assert f._trust.growth_variance(1.0) < 1e-3


@pytest.mark.parametrize("kind", ["pmf", "pf"])
def test_a_fix_outside_the_gate_is_refused_and_counted_and_the_range_is_used_instead(kind):
    grid = _grid()
    params = _quiet(initial_sigma_m=10.0, use_slant_range=True, reference_depth_m=0.0, slant_range_sigma_m=5.0)
    f = _filter(kind, params, grid)
    start = np.array([400.0, 400.0])
    f.start(0.0, start, _fix_observation(start, np.eye(2)))
    before = f.estimate().position
    ship = TrackFrame(400.0, 700.0, 90.0)
    slant = float(np.hypot(300.0, 500.0))  # consistent with the start: the range update is accepted
    f.update(_fix_observation(start + 200.0, 25.0 * np.eye(2), slant=slant, frame=ship))
    assert f.counts["fix_rejected_gate"] == 1 and f.counts["fix_updates"] == 0
    assert f.counts["range_updates"] == 1 and f.counts["range_in_fix"] == 0
    assert "fix_gate" in f.estimate().rejected
    assert np.linalg.norm(f.estimate().position - before) < 3.0


def test_an_accepted_fix_takes_the_place_of_the_same_pings_range():
    grid = _grid()
    params = _quiet(initial_sigma_m=10.0, use_slant_range=True)
    f = _filter("pmf", params, grid)
    start = np.array([400.0, 400.0])
    f.start(0.0, start, _fix_observation(start, np.eye(2)))
    f.update(_fix_observation(start, 25.0 * np.eye(2), slant=600.0, frame=TrackFrame(400.0, 700.0, 90.0)))
    assert f.counts["fix_updates"] == 1 and f.counts["range_in_fix"] == 1 and f.counts["range_updates"] == 0


# ------------------------------------------------------------------ the record loop's slant range


class _Recorder:
    """An estimator that keeps what the loop hands it."""

    name = "recorder"

    def __init__(self):
        self.counts, self.seen = Counter(), []

    def start(self, t_s, position, observation):
        self.seen.append(observation)

    def predict(self, motion: Motion):
        pass

    def update(self, observation):
        self.seen.append(observation)

    def estimate(self):
        return Estimate(position=np.zeros(2), covariance=np.eye(2), usable=False, stage="dead_reckoning")


def _records(travel, straight, depth=800.0, **usbl):
    n = len(travel)
    full = np.full(n, 1.0)
    return NavRecords(t_s=np.arange(n, dtype=float), ship_x_m=full * 0, ship_y_m=full * 0, ship_heading_deg=full * 90, vehicle_depth_m=full * depth,
                      altitude_m=full * 50, vel_x_mps=full, vel_y_mps=full * 0, slant_range_m=np.asarray(straight, float), cable_out_m=full * 1500,
                      usbl_travel_time_s=np.asarray(travel, float), **usbl)


def _loop(records, profile, **changes):
    recorder, counts = _Recorder(), Counter()
    loop = RecordLoop(records, NavParameters(reference_depth_m=5.0, **changes), [recorder], counts, profile)
    for n in range(len(records)):
        loop.step(n)
    return [o.slant_range_m for o in recorder.seen], counts


def test_the_ray_traced_range_wins_over_the_straight_one_and_is_counted():
    travel = [0.9, np.nan, 0.75, 0.8]
    slants, counts = _loop(_records(travel, [1000.0, 1001.0, np.nan, 1003.0]), PROFILE)
    expected = [slant_range_from_travel_time(PROFILE, t, 5.0, 800.0)[0] for t in (0.9, 0.75, 0.8)]
    np.testing.assert_allclose([slants[0], slants[2], slants[3]], expected, rtol=1e-12)
    assert slants[1] == 1001.0  # no reply: the straight range of the record
    assert counts["slant_range_ray_traced"] == 3 and counts["slant_range_ray_over_straight"] == 2


def test_without_a_profile_travel_times_are_counted_unused():
    slants, counts = _loop(_records([0.9, 0.9], [1000.0, np.nan]), None)
    assert slants[0] == 1000.0 and np.isnan(slants[1])
    assert counts["usbl_travel_time_without_profile"] == 2 and counts["slant_range_ray_traced"] == 0


def test_a_travel_time_too_short_for_the_depth_falls_back_and_is_counted():
    slants, counts = _loop(_records([0.3, 0.9], [1000.0, 1001.0]), PROFILE)
    assert slants[0] == 1000.0 and counts["usbl_ray_failed"] == 1 and counts["slant_range_ray_traced"] == 1


def test_the_loop_hands_the_fix_with_its_covariance():
    fix = dict(usbl_x_m=[-700.0, np.nan], usbl_y_m=[10.0, np.nan], usbl_sxx=[25.0, np.nan], usbl_syy=[100.0, np.nan], usbl_sxy=[5.0, np.nan])
    recorder, counts = _Recorder(), Counter()
    loop = RecordLoop(_records([np.nan, np.nan], [np.nan, np.nan], **{k: np.array(v) for k, v in fix.items()}), NavParameters(), [recorder],
                       counts)
    loop.step(0)
    loop.step(1)
    first, second = recorder.seen
    np.testing.assert_array_equal(first.fix_position_m, [-700.0, 10.0])
    np.testing.assert_array_equal(first.fix_covariance_m2, [[25.0, 5.0], [5.0, 100.0]])
    assert second.fix_position_m is None and second.fix_covariance_m2 is None


# ------------------------------------------------------------------ the patent pipeline


def _patent(**changes):
    grid = _grid()
    params = _quiet(cat_restart_s=30.0, initial_sigma_m=50.0, **changes)
    estimator = PatentEstimator(PreparedMap(grid=grid), params, Counter())
    estimator.start(0.0, np.array([400.0, 400.0]), _fix_observation([0, 0], np.eye(2)))
    return estimator


def _step(estimator, t, fix, cov=25.0):
    estimator.predict(Motion(dt_s=1.0, velocity_mps=np.zeros(2)))
    estimator.update(_fix_observation(fix, cov * np.eye(2), t_s=t))
    return estimator.estimate()


def test_the_patent_pipeline_takes_a_fix_only_after_cat_restart_s_without_a_match():
    estimator = _patent()
    fix = np.array([420.0, 390.0])
    for t in range(1, 31):
        answer = _step(estimator, float(t), fix)
        assert answer.stage == "dead_reckoning"
        np.testing.assert_array_equal(answer.position, [400.0, 400.0])
    answer = _step(estimator, 31.0, fix)
    assert answer.stage == "usbl_fix" and not answer.usable
    # The start's 50 m spread against the fix's 5 m: the first fix is taken nearly whole (weight 2500 / 2530).
    spread = 50.0**2 + _quiet().position_floor_m**2
    np.testing.assert_allclose(answer.position, [400.0, 400.0] + spread / (spread + 25.0) * (fix - [400.0, 400.0]), rtol=1e-12)
    assert estimator.counts["usbl_fix_recentred"] == 1


def test_the_patent_pipeline_averages_successive_fixes_through_its_dead_reckoning():
    estimator = _patent()
    rng = np.random.default_rng(5)
    truth = np.array([430.0, 380.0])
    fixes = truth + rng.normal(0.0, 5.0, (200, 2))
    positions = np.array([_step(estimator, float(t), fixes[t - 1]).position for t in range(1, 201)])
    settled = positions[60:]
    # The position floor (2.3 m) keeps a weight of at least 0.17 on each 5 m fix: the scatter at least halves.
    assert np.sqrt(np.mean(np.sum((settled - truth) ** 2, axis=1))) < 0.5 * np.sqrt(np.mean(np.sum((fixes[60:] - truth) ** 2, axis=1)))


def test_the_patent_pipeline_gates_an_outlier_fix_and_gives_in_after_reinit_after():
    estimator = _patent(reinit_after=3)
    for t in range(1, 32):
        _step(estimator, float(t), [400.0, 400.0])
    outlier = [400.0, 600.0]
    for t in range(32, 35):
        assert _step(estimator, float(t), outlier).stage == "dead_reckoning"
    assert estimator.counts["usbl_fix_gated"] == 3
    answer = _step(estimator, 35.0, outlier)
    assert answer.stage == "usbl_fix" and estimator.counts["usbl_fix_forced"] == 1


def test_the_patent_pipeline_ignores_fixes_when_told():
    estimator = _patent(use_usbl_fix=False)
    for t in range(1, 40):
        answer = _step(estimator, float(t), [420.0, 390.0])
    assert answer.stage == "dead_reckoning" and estimator.counts["usbl_fix_recentred"] == 0


# ------------------------------------------------------------------ whole runs


@pytest.fixture(scope="module", name="usbl_tow")
def usbl_tow(tmp_path_factory):
    """Four minutes of the shipped usbl_nav tow, cut before the map ends."""
    scenario = replace(load_scenario(builtin_scenario_path("usbl_nav")), duration_s=300.0)
    grid, records = simulate(scenario)
    return scenario, grid, records


def test_records_without_usbl_navigate_bit_for_bit_as_before(usbl_tow):
    scenario, grid, records = usbl_tow
    plain = replace(records, usbl_travel_time_s=None, usbl_x_m=None, usbl_y_m=None, usbl_sxx=None, usbl_syy=None, usbl_sxy=None)
    params = NavParameters(**scenario.navigation)
    without = navigate(plain, grid, params)
    # A profile with nothing to trace, and fixes switched off, change nothing either.
    with_profile = navigate(plain, grid, params, profile=usbl_profile(scenario))
    fixes_off = navigate(replace(records, usbl_travel_time_s=None), grid, replace(params, use_usbl_fix=False))
    for other in (with_profile, fixes_off):
        for name, track in without.tracks.items():
            np.testing.assert_array_equal(track.position, other.tracks[name].position)
            np.testing.assert_array_equal(track.covariance, other.tracks[name].covariance)


def test_with_the_fix_the_filters_stay_consistent_and_beat_the_raw_fixes(usbl_tow):
    scenario, grid, records = usbl_tow
    result = navigate(records, grid, NavParameters(**scenario.navigation), estimators=("pmf", "pf"), profile=usbl_profile(scenario))
    truth = result.truth
    fixed = np.isfinite(records.usbl_x_m)
    raw = np.hypot(records.usbl_x_m - records.truth_x_m, records.usbl_y_m - records.truth_y_m)[fixed]
    for name in ("pmf", "pf"):
        track = result.tracks[name]
        assert track.counts["fix_updates"] > 100
        value = track_nees(track, truth)[60:]  # after the first minute
        value = value[np.isfinite(value)]
        # Never overconfident; wide at most for the acquisition floor's minutes (the PF, its bias learned
        # at once, is 1.1 m off against that floor's 2.5 m: 0.85 in band, the rest all below it).
        assert np.mean(value >= 7.38) < 0.025
        assert np.mean((value > 0.051) & (value < 7.38)) > 0.8
        error = np.hypot(*(track.position - truth).T)[60:]
        assert np.sqrt(np.mean(error**2)) < 0.5 * np.sqrt(np.mean(raw**2))


# ------------------------------------------------------------------ lost run --svp


def _recorded(tmp_path, usbl_tow):
    from lost.host.io import write_npz
    from lost.host.io.navlog import write_navlog

    _, grid, records = usbl_tow
    write_navlog(records, tmp_path / "nav.csv", sonar=tmp_path / "sonar.csv")
    write_npz(grid, tmp_path / "map.npz")
    return ["run", "--log", str(tmp_path / "nav.csv"), "--sonar", str(tmp_path / "sonar.csv"), "--bathy", str(tmp_path / "map.npz"),
            "--estimator", "pmf", "--set", "reference_depth_m=5.0"]


def test_lost_run_svp_ray_traces_a_logs_travel_times(tmp_path, usbl_tow, capsys):
    import json

    from lost.host.cli import main
    from lost.host.usbl.scenario import shipped_cast_path

    command = _recorded(tmp_path, usbl_tow)
    assert main([*command, "--svp", str(shipped_cast_path("scs_june")), "--out", str(tmp_path / "with")]) == 0
    summary = json.loads((tmp_path / "with" / "summary.json").read_text())
    pings = int(np.isfinite(usbl_tow[2].usbl_travel_time_s).sum())
    assert summary["counts"]["slant_range_ray_traced"] == pings and summary["sound_speed_profile"].endswith("scs_june.csv")
    assert summary["methods"]["pmf"]["counts"]["fix_updates"] > 100
    assert main([*command, "--out", str(tmp_path / "without")]) == 0
    summary = json.loads((tmp_path / "without" / "summary.json").read_text())
    assert summary["counts"]["usbl_travel_time_without_profile"] == pings
    assert any("USBL travel times but no sound-speed profile" in w for w in summary["warnings"])


def test_lost_run_svp_names_a_bad_cast(tmp_path, usbl_tow, capsys):
    from lost.host.cli import main

    (tmp_path / "cast.csv").write_text("depth_m,sound_speed_m_s\n0,1540\n100,1530\n")
    assert main([*_recorded(tmp_path, usbl_tow), "--svp", str(tmp_path / "cast.csv"), "--out", str(tmp_path / "o")]) == 1
    assert "cast.csv: the cast's position is unknown" in capsys.readouterr().err


def test_lost_run_on_a_usbl_scenario_says_what_the_usbl_did_and_warns_of_a_wrong_transducer_depth(tmp_path, capsys):
    import json

    from lost.host.cli import main

    text = builtin_scenario_path("usbl_nav").read_text().replace("duration_s = 1800", "duration_s = 120")
    (tmp_path / "u.toml").write_text(text)
    assert main(["run", str(tmp_path / "u.toml"), "--estimator", "pmf", "--set", "reference_depth_m=0", "--out", str(tmp_path / "o")]) == 0
    printed = capsys.readouterr().out
    assert "USBL: " in printed and "slant ranges ray-traced ([sensors.usbl] cast scs_june)" in printed and "fixes used: pmf" in printed
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert any("reference_depth_m (0 m) is not the USBL transducer's depth" in w for w in summary["warnings"])


def test_without_its_usbl_the_point_mass_filter_makes_no_false_fix_while_it_learns_its_velocity_bias(usbl_tow):
    """The tow's velocity reads 5 and -4 cm/s off. Before the bias carried a variance, the PMF sat 5-7 m off with a
    1.3 m covariance through its first minutes (229 false fixes on the whole tow): the patches were misplaced by the
    unlearned bias times their age, and nothing in the density said so."""
    scenario, grid, records = usbl_tow
    none = replace(records, slant_range_m=np.full(len(records), np.nan), usbl_travel_time_s=None, usbl_x_m=None, usbl_y_m=None,
                   usbl_sxx=None, usbl_syy=None, usbl_sxy=None)
    track = navigate(none, grid, NavParameters(**scenario.navigation), estimators=("pmf",)).tracks["pmf"]
    truth = np.column_stack([records.truth_x_m, records.truth_y_m])
    value = track_nees(track, truth)
    assert track.usable[150:].mean() > 0.8  # it is usable while it learns, not silenced
    assert np.count_nonzero(track.usable & (value > NEES_3_SIGMA)) == 0
