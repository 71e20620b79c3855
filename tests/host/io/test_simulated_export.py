"""The scenario `short` exported as a Kongsberg .all file, read back, and navigated with `lost run --survey`."""

from __future__ import annotations

import numpy as np
import pytest

from lost.host.io import write_npz
from lost.host.io.kongsberg_all import write_all_pings
from lost.host.io.simulated import EPOCH_S, LOCAL_FRAME_CRS, simulated_pings
from lost.host.io.survey import open_survey
from lost.host.scenario import builtin_scenario_path, load_scenario, simulate

from .survey_run import survey_run_summary


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    folder = tmp_path_factory.mktemp("short")
    scenario = load_scenario(builtin_scenario_path("short_exact_map"))  # the short tow on its floor: the map the pings were made of
    grid, crs, pings = simulated_pings(scenario)
    return scenario, write_all_pings(pings, folder / "short.all"), write_npz(grid, folder / "short_map.npz"), crs


def test_the_exported_pings_read_back_on_the_scenarios_true_track(exported):
    scenario, path, _, crs = exported
    assert crs == LOCAL_FRAME_CRS  # the scenario's own frame is local
    _, records = simulate(scenario)
    survey = open_survey(path, crs=crs)
    pings = list(survey)
    assert len(pings) == len(records) == 600 and not survey.skipped
    times = np.array([p.time_s for p in pings]) - EPOCH_S
    np.testing.assert_allclose(times, records.t_s, atol=1e-3)  # the format's millisecond
    east, north = np.array([p.east_m for p in pings]), np.array([p.north_m for p in pings])
    assert np.max(np.hypot(east - records.truth_x_m, north - records.truth_y_m)) < 0.02  # 1/20,000,000 degree and the projection
    spec = scenario.sensors["sonar"]
    assert all(p.beams == spec.beams for p in pings)
    valid = np.mean([p.valid.mean() for p in pings])
    assert abs(valid - (1 - spec.missing_beam_rate)) < 0.02
    # The swath lies across the motion: its beams as far from the track as the swath is wide.
    first = pings[300]
    spread = np.hypot(first.beam_east_m - first.east_m, first.beam_north_m - first.north_m)
    assert spread.max() == pytest.approx(max(spec.shape) * 10.0 / 2, rel=1e-3)


def test_lost_run_survey_on_the_export_converges_like_the_scenario_run(exported, tmp_path, capsys):
    _, path, map_path, _ = exported
    out = tmp_path / "run"
    summary = survey_run_summary(path, map_path, out)
    capsys.readouterr()
    pmf = summary["methods"]["pmf"]
    dead = summary["methods"]["dead_reckoning"]
    # Measured at the commit of this test: PMF 2.63 m RMS after convergence (p95 3.95 m) against 63.7 m of dead reckoning;
    # `lost run short` itself gives the PMF 1.81 m (p95 3.50 m) from its 170 m lay-back start.
    assert summary["convergence"]["converged"]
    assert pmf["rms_m"] < 4.0 and pmf["p95_m"] < 7.0
    assert dead["rms_m"] > 40.0
    assert 0.7 <= pmf["nees_in_band"] <= 1.0
