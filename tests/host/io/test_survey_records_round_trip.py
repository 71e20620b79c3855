"""A simulated tow through a real format and back into the navigation's records, with the scenario run's own dead reckoning.

The records `lost run --survey`'s recorder makes of the exported `.all` file, given the scenario run's dead reckoning
(``dead_reckoning_error``), carry the scenario's times, true track and dead-reckoned track record for record to the
format's precision, over the whole run; their patches, placed by the truth, are the patches of the same pings never
written, but for the nodes a rounding moved a beam into or out of.
"""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import replace

import numpy as np
import pytest

from lost.host.cli import main
from lost.host.io import write_npz
from lost.host.io.crs import transformer
from lost.host.io.kongsberg_all import write_all_pings
from lost.host.io.simulated import simulated_pings
from lost.host.io.sonar import grid_soundings
from lost.host.io.survey import open_survey, project_ping
from lost.host.io.survey_records import SurveyRecorder, survey_records
from lost.host.nav import navigation_parameters
from lost.host.nav.loop import RecordLoop
from lost.host.scenario import builtin_scenario_path, load_scenario, simulate

#: The format's precision on a position: 1/20,000,000 degree of latitude, 1/10,000,000 of longitude, and the projection.
POSITION_M = 0.02


@pytest.fixture(scope="module")
def tow(tmp_path_factory):
    folder = tmp_path_factory.mktemp("round_trip")
    scenario = replace(load_scenario(builtin_scenario_path("short_exact_map")), duration_s=200)
    _, records = simulate(scenario)
    loop = RecordLoop(records, navigation_parameters(scenario.navigation), [], Counter())
    for n in range(len(records)):
        loop.step(n)
    grid, crs, pings = simulated_pings(scenario)
    memory = list(pings)
    path = write_all_pings(iter(memory), folder / "short.all")
    to_map = transformer("EPSG:4326", crs)
    memory = [project_ping(ping, to_map) for ping in memory]  # what open_survey does to a ping it reads
    return scenario, records, loop.dead_reckoning, memory, list(open_survey(path, crs=crs)), grid, path, write_npz(grid, folder / "map.npz")


def _scripted(records, reckoned):
    error = reckoned - np.column_stack([records.truth_x_m, records.truth_y_m])
    return lambda t: (np.interp(t, records.t_s, error[:, 0]), np.interp(t, records.t_s, error[:, 1]))


def _recorder(grid, **kw) -> SurveyRecorder:
    return SurveyRecorder(node_m=grid.node_m, patch_shape=(10, 10), interval_s=1.0, window_s=60.0, patch_centre="soundings", **kw)


def test_the_round_trip_gives_the_scenarios_times_truth_and_dead_reckoning_record_for_record(tow):
    _, records, reckoned, _, read_back, grid, _, _ = tow
    assert np.all(np.isfinite(reckoned))  # the scenario run started at its first record
    survey = survey_records(iter(read_back), _recorder(grid, dead_reckoning_error=_scripted(records, reckoned)))
    assert len(survey) == len(records) == 200
    np.testing.assert_allclose(survey.t_s, records.t_s, atol=1e-3)  # the format's millisecond
    truth = np.hypot(survey.truth_x_m - records.truth_x_m, survey.truth_y_m - records.truth_y_m)
    dead = np.hypot(survey.ship_x_m - reckoned[:, 0], survey.ship_y_m - reckoned[:, 1])
    assert truth.max() < POSITION_M and dead.max() < POSITION_M
    # The velocity the survey's navigation moves by is the scenario's dead reckoning differenced: a position's rounding per second.
    velocity = np.column_stack([survey.vel_x_mps, survey.vel_y_mps])[1:]
    np.testing.assert_allclose(velocity, np.diff(reckoned, axis=0) / np.diff(records.t_s)[:, None], atol=2 * POSITION_M)


def test_the_patches_of_the_file_are_those_of_the_pings_never_written_to_the_formats_precision(tow):
    _, _, _, memory, read_back, grid, _, _ = tow
    from_file = survey_records(iter(read_back), _recorder(grid)).sonar
    from_memory = survey_records(iter(memory), _recorder(grid)).sonar
    assert len(from_file) == len(from_memory) == 200
    differences, emptied = [], 0
    for a, b in zip(from_file, from_memory):
        both = np.isfinite(a.depth_m) & np.isfinite(b.depth_m)
        emptied += int(np.sum(np.isfinite(a.depth_m) != np.isfinite(b.depth_m)))
        differences.append(np.abs(a.depth_m - b.depth_m)[both])
        # The patch's centre is the soundings' middle: it moves by their rounding (5 mm of position, 0.005 degree of heading).
        assert a.centre_offset_m == pytest.approx(b.centre_offset_m, abs=POSITION_M)
        assert a.age_s == pytest.approx(b.age_s, abs=0.1)
    differences = np.concatenate(differences)
    # A node's mean is the float32 depths' mean (0.1 mm at 800 m) unless a rounding moved a beam over its edge, which changes
    # it by that sounding's share (measured: 2.6 % of the nodes, 99th percentile 2.6 cm; a node emptied or filled: 1 in 18,000).
    assert np.median(differences) < 1e-4
    assert np.mean(differences > 1e-3) < 0.05 and np.percentile(differences, 99) < 0.05
    assert emptied / differences.size < 0.001


def test_lost_run_survey_takes_the_scenarios_navigation_parameters_with_config(tow, tmp_path, capsys):
    scenario, _, _, memory, _, _, _, map_path = tow
    path = write_all_pings(iter(memory[:40]), tmp_path / "first_40_s.all")  # the parameters, not the navigation, are checked
    out = tmp_path / "run"
    code = main(["run", "--survey", str(path), "--bathy", str(map_path), "--config", str(builtin_scenario_path("short_exact_map")),
                 "--record-s", "2", "--window-s", "60", "--patch-centre", "soundings", "--estimator", "pmf", "--out", str(out)])
    assert code == 0
    capsys.readouterr()
    used = json.loads((out / "summary.json").read_text())["parameters"]
    for name, value in scenario.navigation.items():
        assert used[name] == (list(value) if isinstance(value, tuple | list) else value), name


def test_full_window_withholds_the_patches_until_the_window_of_pings_is_full_and_counts_them(tow):
    _, _, _, _, read_back, grid, _, _ = tow
    full = _recorder(grid, full_window=True)
    withheld = survey_records(iter(read_back), full)
    every = survey_records(iter(read_back), _recorder(grid))
    early = withheld.t_s < 60.0
    assert early.sum() == 60 and all(patch is None for patch, e in zip(withheld.sonar, early) if e)
    assert full.skipped["record before its window of pings was full (kept without a patch)"] == 60
    for a, b, e in zip(withheld.sonar, every.sonar, early):
        if not e:
            np.testing.assert_array_equal(a.depth_m, b.depth_m)
    np.testing.assert_array_equal(withheld.ship_x_m, every.ship_x_m)


def test_a_scripted_dead_reckoning_is_refused_beside_a_bias_or_when_it_gives_no_position(tow):
    _, _, _, _, read_back, grid, _, _ = tow
    with pytest.raises(ValueError, match="either dead_reckoning_error or dr_bias_mps and start_offset_m"):
        _recorder(grid, dead_reckoning_error=lambda t: (0.0, 0.0), dr_bias_mps=(0.1, 0.0))
    with pytest.raises(ValueError, match=r"dead_reckoning_error\(t\) must be two finite numbers"):
        survey_records(iter(read_back[:5]), _recorder(grid, dead_reckoning_error=lambda t: (float("nan"), 0.0)))


def test_each_patch_carries_the_soundings_it_was_gridded_from_placed_as_the_dead_reckoning_placed_them(tow):
    _, records, reckoned, _, read_back, grid, _, _ = tow
    survey = survey_records(iter(read_back), _recorder(grid, dead_reckoning_error=_scripted(records, reckoned)))
    checked = 0
    for patch in survey.sonar[60::20]:
        east, north, depth, age = patch.soundings.arrays()
        assert east.size == north.size == depth.size == age.size > 1000 and 0 <= age.min() and age.max() < 60.0
        again = grid_soundings(east, north, depth, patch_shape=(10, 10), node_m=grid.node_m, centre_m=patch.centre_offset_m, age_s=age)
        np.testing.assert_array_equal(again.patch.depth_m, patch.depth_m)
        assert again.patch.age_s == patch.age_s
        checked += 1
    assert checked == 7
