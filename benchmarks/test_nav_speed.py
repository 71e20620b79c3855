"""Navigation speed: the shipped two-hour tow (7200 records at 1 Hz, a 10 x 10 patch at every record).

Run with `make bench`. The goal of the pipeline issue is the whole two-hour tow in under 30 s with the
fast software backend; the pipeline alone is benchmarked here, and `time lost run two_hour` gives the
end-to-end figure (simulation, CSV, JSON and plots included) that the README quotes.
"""

import pytest

from lost.host.nav import NavParameters, PreparedMap, run_lost
from lost.host.report import summarize
from lost.host.scenario import builtin_scenario_path, load_scenario, simulate


@pytest.fixture(scope="module")
def two_hour():
    scenario = load_scenario(builtin_scenario_path("two_hour"))
    grid, records = simulate(scenario)
    return scenario, grid, records


def test_two_hour_tow_pipeline(benchmark, two_hour):
    scenario, grid, records = two_hour
    params = NavParameters(**scenario.navigation)
    prepared = PreparedMap.for_navigation(grid, params)
    result = benchmark.pedantic(run_lost, args=(records, grid, params), kwargs={"prepared": prepared}, rounds=3, iterations=1)
    summary = summarize(result, name=scenario.name, parameters=params.as_dict())
    assert summary["convergence"]["converged"] and summary["methods"]["lost"]["rms_m"] < 5.0


def test_two_hour_tow_simulation(benchmark, two_hour):
    scenario, _, _ = two_hour
    grid, records = benchmark.pedantic(simulate, args=(scenario,), rounds=3, iterations=1)
    assert len(records) == 7200
