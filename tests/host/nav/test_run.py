"""The whole pipeline on the shipped short tow with the map equal to its floor (short_exact_map), with its errors asserted."""

import numpy as np
import pytest

from lost.host.nav import NavParameters, run_lost
from lost.host.report import summarize
from lost.host.scenario import builtin_scenario_path, load_scenario, simulate


@pytest.fixture(scope="module")
def short_run():
    scenario = load_scenario(builtin_scenario_path("short_exact_map"))
    grid, records = simulate(scenario)
    params = NavParameters(**scenario.navigation)
    result = run_lost(records, grid, params)
    return result, summarize(result, name=scenario.name, parameters=params.as_dict())


def test_short_scenario_converges_and_beats_the_baselines(short_run):
    result, summary = short_run
    convergence, methods = summary["convergence"], summary["methods"]
    assert convergence["initial_error_m"] > 150.0
    assert convergence["converged"] and convergence["time_s"] < 240.0
    lost, layback, dead = methods["lost"], methods["layback"], methods["dead_reckoning"]
    # The pipeline issue's goal: half a 10 m node RMS after convergence.
    assert lost["rms_m"] <= 5.0 and lost["p95_m"] < 10.0 and lost["max_m"] < 25.0
    assert layback["rms_m"] > 10 * lost["rms_m"]
    assert dead["rms_m"] > 10 * lost["rms_m"]


def test_short_scenario_uses_every_patch_and_no_range(short_run):
    result, summary = short_run
    patches = np.arange(0, len(result.t_s), 2)  # a patch every 2 s
    used = np.flatnonzero(result.mle_source == "patch")
    assert set(used) <= set(patches) and len(used) >= 0.95 * (len(patches) - 1)
    assert summary["counts"]["slant_range_corrections"] == 0
    assert summary["off_map_records"] == 0


def test_a_tow_that_leaves_the_map_dead_reckons_beyond_it():
    from lost.host.scenario import CableSpec, Scenario, SensorSpec, ShipSpec, SonarSpec, TerrainSpec

    scenario = Scenario(
        seed=12,
        duration_s=1500.0,
        # 880 m deep: the 900 m cable was shorter than the 920 m vehicle depth of the default 1000 m (clamped then, refused now).
        terrain=TerrainSpec(shape=(150, 300), roughness_m=10.0, hurst=0.5, mean_depth_m=880.0),  # ends at easting 2990 m
        ship=ShipSpec(waypoints_m=((1500.0, 750.0), (5000.0, 750.0))),
        cable=CableSpec(out_m=900.0),
        sensors={"sonar": SonarSpec(noise=0.2), "velocity": SensorSpec(noise=0.02, bias=(0.02, 0.0))},
    )
    grid, records = simulate(scenario)
    result = run_lost(records, grid, NavParameters())
    summary = summarize(result, name="edge", parameters={})
    beyond = result.truth[:, 0] > 3000.0 + 300.0  # past the edge by more than a search area
    assert beyond.sum() > 50
    assert result.off_map[beyond].all() and summary["off_map_records"] == int(result.off_map.sum())
    assert np.all(result.mle_source[result.off_map] == "")
    # Dead reckoning on a 2 cm/s velocity bias: the error grows by about that much per second, no jumps.
    error = np.hypot(*(result.estimate - result.truth).T)
    assert np.all(np.isfinite(result.estimate[beyond]))
    assert error[beyond][-1] < error[np.flatnonzero(beyond)[0]] + 0.03 * beyond.sum() + 10.0
    assert summary["convergence"]["converged"]
