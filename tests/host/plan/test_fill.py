"""The route model's real-time patch fill (lost.host.plan.fill) against geometry and against the simulator's patches."""

import dataclasses

import numpy as np
import pytest

from lost.host.grid import Grid
from lost.host.plan import RouteModel, Sweep, patch_fill, predict_along


def _north(seconds: int, speed: float = 1.5) -> np.ndarray:
    return np.column_stack([np.zeros(seconds), speed * np.arange(seconds)])


def test_a_straight_line_fills_its_first_patch_then_holds_it_whole():
    sweep = Sweep(shape=(10, 10), node_m=30.0)
    fill = patch_fill(_north(600), 1.0, sweep)
    assert fill[0] == pytest.approx(0.1)  # one ping: one row of the patch
    assert np.all(np.diff(fill[:100]) >= 0)
    assert 0.45 <= fill[100] <= 0.6  # the patch stays on the start until the vehicle is half a diagonal from it
    assert np.all(fill[400:] == 1.0)


def test_a_swath_narrower_than_the_patch_leaves_its_sides_empty_and_a_turn_fills_them():
    sweep = Sweep(shape=(10, 10), node_m=50.0, swath_width_m=300.0)
    line = patch_fill(_north(900), 1.0, sweep)
    assert line[-1] == pytest.approx(0.7)  # 300 m across 50 m nodes touches 7 of 10 columns
    turn = np.vstack([_north(450), _north(450)[:, ::-1] + (0.0, 1.5 * 449)])  # north, then east
    assert patch_fill(turn, 1.0, sweep)[450:].max() > 0.75  # the patch over the corner holds both legs


def test_the_fill_is_the_simulators():
    from lost.host.campaign.run import scenario_with
    from lost.host.scenario import builtin_scenario_path, load_scenario, simulate

    scenario = scenario_with(load_scenario(builtin_scenario_path("demo")), {"duration_s": 240.0})
    grid, records = simulate(scenario)
    spec = scenario.sensors["sonar"]
    simulated = np.array([np.isfinite(patch.depth_m).mean() for patch in records.sonar])
    xy = np.column_stack([records.truth_x_m, records.truth_y_m])
    modelled = patch_fill(xy, spec.interval_s, Sweep(shape=tuple(spec.shape), node_m=grid.node_m, swath_width_m=spec.swath_width_m))
    assert np.mean(np.abs(modelled - simulated)) < 0.01 and np.max(np.abs(modelled - simulated)) < 0.1


def test_no_terrain_update_while_the_patch_is_under_the_navigations_share():
    grid = Grid(depth_m=np.random.default_rng(0).normal(100.0, 5.0, (200, 200)), x0_m=-3000.0, y0_m=-300.0, node_m=30.0)
    accuracy = dataclasses.replace(grid, depth_m=np.full(grid.shape, 3.0))
    xy = _north(300)
    base = RouteModel(speed_mps=1.5, patch_length_m=300.0, patch_lag_m=212.0, sweep=Sweep(shape=(10, 10), node_m=30.0))
    before = predict_along(accuracy, np.arange(300.0), xy, base)
    after = predict_along(accuracy, np.arange(300.0), xy, dataclasses.replace(base, min_valid_fraction=0.5))
    thin = patch_fill(xy, 1.0, base.sweep) < 0.5
    assert thin[:30].all() and not thin[-1]
    assert np.all(np.isfinite(before["bound_m"][thin]))
    assert np.all(np.isinf(after["bound_m"][thin])) and np.all(np.isfinite(after["bound_m"][~thin]))


@pytest.mark.parametrize("field, value", [("shape", (0, 10)), ("node_m", -1.0), ("swath_width_m", float("nan")), ("max_window_s", 0.0)])
def test_a_sweep_refuses_a_bad_field(field, value):
    with pytest.raises(ValueError, match=field if field != "shape" else "rows and columns"):
        Sweep(**{"shape": (10, 10), "node_m": 30.0, field: value})
