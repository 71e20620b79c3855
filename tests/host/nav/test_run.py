"""The whole pipeline on the shipped short scenario, with its errors asserted."""

import numpy as np
import pytest

from lost.host.nav import NavParameters, run_lost
from lost.host.report import summarize
from lost.host.scenario import builtin_scenario_path, load_scenario, simulate


@pytest.fixture(scope="module")
def short_run():
    scenario = load_scenario(builtin_scenario_path("short"))
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
    assert lost["rms_m"] < 7.0 and lost["p95_m"] < 15.0 and lost["max_m"] < 25.0
    assert layback["rms_m"] > 10 * lost["rms_m"]
    assert dead["rms_m"] > 10 * lost["rms_m"]


def test_short_scenario_uses_every_patch_and_no_range(short_run):
    result, summary = short_run
    patches = np.arange(0, len(result.t_s), 2)  # a patch every 2 s
    used = np.flatnonzero(result.mle_source == "patch")
    assert set(used) <= set(patches) and len(used) >= 0.95 * (len(patches) - 1)
    assert summary["counts"]["slant_range_corrections"] == 0
    assert summary["off_map_records"] == 0
