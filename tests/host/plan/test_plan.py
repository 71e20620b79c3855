"""The planner: the bound against a direct Fisher-matrix computation, its behaviour on planes, features and holes, the
route's growth and fusion, and `lost plan`'s files read back."""

from __future__ import annotations

import json

import numpy as np
import pytest

from lost.host.cli import EXIT_ERROR, EXIT_OK, main
from lost.host.grid import Grid
from lost.host.io import read_grid, write_npz
from lost.host.plan import RouteModel, SonarModel, accuracy_grid, map_sigma, predict_route, read_route


def _rough(shape=(60, 80), seed=1) -> Grid:
    rng = np.random.default_rng(seed)
    from scipy import ndimage

    depth = 500.0 + 8.0 * ndimage.gaussian_filter(rng.normal(size=shape), 2.0) / 0.1
    return Grid(depth_m=depth, x0_m=1000.0, y0_m=2000.0, node_m=10.0)


def _direct_bound(grid: Grid, sonar: SonarModel, row: int, col: int, map_sigma: float) -> float:
    """The Cramer-Rao bound of one patch written out beam by beam: Fisher matrix of (x, y, offset), inverted."""
    gy, gx = np.gradient(grid.depth_m, grid.node_m)
    h, w = sonar.shape
    rows = range(row - h // 2, row - h // 2 + h)
    cols = range(col - w // 2, col - w // 2 + w)
    fisher = np.zeros((3, 3))
    for r in rows:
        for c in cols:
            jac = np.array([gx[r, c], gy[r, c], 1.0])
            fisher += np.outer(jac, jac) / (sonar.noise_m**2 + map_sigma**2)
    cov = np.linalg.inv(fisher)
    return float(np.sqrt(cov[0, 0] + cov[1, 1]))


@pytest.mark.parametrize(("shape", "map_sigma"), [((10, 10), 0.0), ((6, 9), 0.7)])
def test_the_bound_equals_the_fisher_matrix_written_out(shape, map_sigma):
    grid, sonar = _rough(), SonarModel(shape=shape, noise_m=0.4)
    accuracy = accuracy_grid(grid, sonar, map_sigma)
    for row, col in ((30, 40), (12, 20), (47, 66)):
        assert accuracy.depth_m[row, col] == pytest.approx(_direct_bound(grid, sonar, row, col, map_sigma), rel=1e-9)


def test_a_plane_fixes_nothing_and_a_feature_fixes_more_than_a_shelf():
    y, x = np.mgrid[0:80, 0:120] * 10.0
    plane = Grid(depth_m=300.0 + 0.05 * x + 0.02 * y, x0_m=0.0, y0_m=0.0, node_m=10.0)
    assert np.isinf(accuracy_grid(plane, SonarModel()).depth_m).all()
    rng = np.random.default_rng(3)
    shelf = 300.0 + 0.02 * x + 0.05 * rng.normal(size=x.shape)  # a smooth shelf with a little relief
    seamount = 120.0 * np.exp(-((x - 900.0) ** 2 + (y - 400.0) ** 2) / (2 * 60.0**2))
    bound = accuracy_grid(Grid(depth_m=shelf - seamount, x0_m=0.0, y0_m=0.0, node_m=10.0), SonarModel(noise_m=0.3)).depth_m
    assert np.median(bound[35:45, 80:100]) * 5 < np.median(bound[35:45, 10:30])


def test_a_patch_touching_a_hole_or_the_edge_has_no_bound():
    grid = _rough()
    depth = grid.depth_m.copy()
    depth[30, 40] = np.nan
    bound = accuracy_grid(Grid(depth_m=depth, x0_m=0.0, y0_m=0.0, node_m=10.0), SonarModel()).depth_m
    assert np.isinf(bound[26:35, 36:45]).all() and np.isfinite(bound[30, 50])
    assert np.isinf(bound[:5]).all() and np.isinf(bound[:, -4:]).all()


def test_bad_uncertainty_and_sonar_are_named():
    with pytest.raises(ValueError, match="uncertainty must be a finite, non-negative"):
        accuracy_grid(_rough(), SonarModel(), -1.0)
    with pytest.raises(ValueError, match="at least 2 x 2"):
        SonarModel(shape=(1, 10))
    with pytest.raises(ValueError, match="positive number of metres"):
        SonarModel(noise_m=0.0)


def test_the_error_grows_where_the_terrain_says_too_little_and_shrinks_where_it_fixes():
    bound = np.full((40, 200), 1.0)
    bound[:, 80:140] = np.inf  # a stretch with no fix
    accuracy = Grid(depth_m=bound, x0_m=0.0, y0_m=0.0, node_m=10.0)
    model = RouteModel(speed_mps=2.0, interval_s=1.0, velocity_noise_mps=0.2, initial_sigma_m=100.0, usable_sigma_m=5.0, floor_m=0.5)
    route = predict_route(accuracy, np.array([[0.0, 200.0], [1990.0, 200.0]]), model)
    column = np.rint(route["east_m"] / 10.0)
    blind = (column >= 80) & (column < 140)
    assert np.array_equal(route["usable"], ~blind)
    assert np.all(np.diff(route["predicted_m"][blind]) > 0)
    assert route["predicted_m"][0] < 1.0  # the first patch is wholly new: fused at once
    before = route["predicted_m"][np.flatnonzero(blind)[0] - 1]  # then each update adds the new share of its patch: a steady level
    assert route["predicted_m"][-1] == pytest.approx(before, rel=0.02)
    assert route["predicted_m"][blind].max() > 3 * route["predicted_m"][0]
    assert route["predicted_m"].min() >= 0.5 - 1e-12  # the filters' floor


def test_lost_plan_writes_a_grid_read_grid_reads_back_node_for_node(tmp_path):
    grid = _rough()
    write_npz(grid, tmp_path / "map.npz")
    (tmp_path / "route.csv").write_text("east_m,north_m\n1200,2300\n1600,2300\n")
    out = tmp_path / "plan"
    assert main(["plan", str(tmp_path / "map.npz"), "--route", str(tmp_path / "route.csv"), "--out", str(out), "--lookalike-radius-m", "100"]) == EXIT_OK
    expected = accuracy_grid(grid, SonarModel(), map_sigma(grid)).depth_m
    back = read_grid(out / "accuracy.nc", variable="accuracy_m")
    assert back.shape == grid.shape and (back.x0_m, back.y0_m, back.node_m) == (1000.0, 2000.0, 10.0)
    np.testing.assert_allclose(back.depth_m, np.where(np.isfinite(expected), expected, np.nan), rtol=1e-12)
    summary = json.loads((out / "summary.json").read_text())
    assert len(read_route(tmp_path / "route.csv")) == 2 and summary["warnings"] == []
    assert summary["route"]["updates"] == 267  # 400 m at 1.5 m/s, one a second from t = 0
    assert {p.name for p in out.iterdir()} >= {"accuracy.nc", "accuracy.png", "route.csv", "route.png", "summary.json"}


@pytest.mark.parametrize(("text", "message"), [("x,y\n1,2\n3,4\n", "needs the columns east_m and north_m"),
                                               ("east_m,north_m\n1,2\n", "at least two finite waypoints"),
                                               ("east_m,north_m\n1,2\nthree,4\n", "line 3: east_m and north_m must be numbers")])
def test_a_bad_route_is_named(tmp_path, capsys, text, message):
    write_npz(_rough(), tmp_path / "map.npz")
    (tmp_path / "route.csv").write_text(text)
    assert main(["plan", str(tmp_path / "map.npz"), "--route", str(tmp_path / "route.csv"), "--out", str(tmp_path / "p")]) == EXIT_ERROR
    assert message in capsys.readouterr().err and not (tmp_path / "p").exists()


def test_the_map_error_is_the_filters_own_and_a_grid_layer_wins():
    from lost.host.nav.maperror import node_variance

    grid = _rough()
    assert np.allclose(map_sigma(grid, 0.3) ** 2, node_variance(grid.depth_m, grid.node_m, 0.3))
    layered = Grid(depth_m=grid.depth_m, x0_m=0.0, y0_m=0.0, node_m=10.0, sigma_m=np.full(grid.shape, 2.0))
    assert np.allclose(map_sigma(layered, 0.3) ** 2, node_variance(grid.depth_m, grid.node_m, 2.0))
    assert np.all(accuracy_grid(layered, SonarModel(), map_sigma(layered)).depth_m[20:40, 20:60]
                  > accuracy_grid(grid, SonarModel(), map_sigma(grid, 0.3)).depth_m[20:40, 20:60])


def test_the_route_model_takes_the_navigations_search_noise_and_floor():
    from lost.host.nav import NavParameters

    params = NavParameters(initial_sigma_m=250.0, velocity_noise_mps=0.1, usable_sigma_nodes=2.0)
    model = RouteModel.from_navigation(params, 25.0, patch_nodes=8.0, speed_mps=2.0)
    assert (model.initial_sigma_m, model.velocity_noise_mps, model.usable_sigma_m, model.patch_length_m, model.speed_mps) == (250.0, 0.1, 50.0, 200.0, 2.0)
    assert model.floor_m == pytest.approx(np.hypot(params.position_floor_nodes * 25.0, params.position_floor_tracking_m))
    assert RouteModel.from_navigation(params, 25.0, initial_sigma_m=40.0).initial_sigma_m == 40.0
    assert (model.velocity_bias_sigma_mps, model.velocity_bias_walk_mps, model.bias_learning_updates) == (
        params.velocity_bias_sigma_mps, params.velocity_bias_walk_mps, params.bias_learning_updates)
    assert RouteModel.from_navigation(NavParameters(estimate_velocity_bias=False), 25.0).velocity_bias_sigma_mps == 0.0


def test_lost_plan_takes_a_real_time_patch_and_its_lag_from_a_scenario():
    import argparse

    from lost.host.cli import plan as plan_cli
    from lost.host.scenario import builtin_scenario_path

    args = argparse.Namespace(config=builtin_scenario_path("demo"), sonar_noise_m=None, speed_mps=None, initial_error_m=None, lookalike_radius_m=None)
    sonar, model, _ = plan_cli._models(args, 30.0)
    assert sonar.realtime and sonar.binned  # demo's swath, gathered ping by ping
    assert model.patch_lag_m == pytest.approx(np.hypot(10, 10) * 30.0 / 2.0)
    assert plan_cli._models(argparse.Namespace(config=None, sonar_noise_m=None, speed_mps=None, initial_error_m=None,
                                                     lookalike_radius_m=None), 30.0)[1].patch_lag_m == 0.0


def test_a_scenario_gives_the_route_model_its_velocity_sensors_errors_and_the_start_is_an_option():
    import argparse
    import dataclasses

    from lost.host.cli.plan import _models, scenario_motion
    from lost.host.scenario import builtin_scenario_path, load_scenario

    demo = load_scenario(builtin_scenario_path("demo"))
    motion = scenario_motion(demo)
    assert motion["sensor_velocity_bias_mps"] == (0.02, -0.015) and motion["sensor_velocity_noise_mps"] == 0.03
    assert motion["interval_s"] == 1.0 and motion["speed_mps"] == pytest.approx(3.0 * 1852.0 / 3600.0)
    towed_blind = dataclasses.replace(demo, vehicle=dataclasses.replace(demo.vehicle, has_velocity_sensor=False))
    assert "sensor_velocity_bias_mps" not in scenario_motion(towed_blind)  # the ship's velocity: no sensor's errors
    assert "sweep" not in motion and scenario_motion(demo, 30.0)["sweep"].shape == (10, 10)  # a real-time swath, on a map's nodes
    assert motion["slant_range"] and "slant_range" not in scenario_motion(load_scenario(builtin_scenario_path("short")))  # short has none
    args = argparse.Namespace(config=builtin_scenario_path("demo"), sonar_noise_m=None, speed_mps=None, initial_error_m=180.0,
                              lookalike_radius_m=None)
    _, model, _ = _models(args, 30.0)
    assert model.initial_error_m == 180.0 and model.sensor_velocity_bias_mps == (0.02, -0.015)
