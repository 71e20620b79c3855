"""Hostile input to the planner's look-alikes and to a campaign of another system: named errors or rows, never a wrong
grid or a lost campaign."""

from __future__ import annotations

import numpy as np
import pytest

from lost.host.campaign import run_task
from lost.host.campaign.spec import RunTask
from lost.host.cli import main
from lost.host.grid import Grid
from lost.host.io import write_npz
from lost.host.plan import RouteModel, SonarModel, held_grid, lookalike_grid


def _grid(depth: np.ndarray) -> Grid:
    return Grid(depth_m=depth, x0_m=0.0, y0_m=0.0, node_m=10.0)


@pytest.mark.parametrize("radius", [0.0, -5.0, float("nan")])
def test_a_search_radius_that_is_no_distance_is_named(radius):
    with pytest.raises(ValueError, match="look-alike search radius must be a positive number of metres"):
        lookalike_grid(_grid(np.zeros((20, 20))), SonarModel(), radius_m=radius)


def test_a_map_of_holes_or_smaller_than_a_patch_has_no_look_alikes():
    holes = lookalike_grid(_grid(np.full((30, 30), np.nan)), SonarModel(), radius_m=100.0)
    small = lookalike_grid(_grid(np.random.default_rng(1).normal(size=(8, 8))), SonarModel(), radius_m=100.0)
    assert np.isnan(holes.snr).all() and np.isnan(holes.rivals).all() and np.isnan(small.snr).all()


def test_lost_plan_refuses_a_radius_that_is_no_distance(tmp_path, capsys):
    write_npz(_grid(np.random.default_rng(2).normal(size=(30, 30))), tmp_path / "map.npz")
    with pytest.raises(SystemExit) as stopped:  # the command line's own check, before anything is written
        main(["plan", str(tmp_path / "map.npz"), "--out", str(tmp_path / "p"), "--lookalike-radius-m", "-3"])
    assert stopped.value.code != 0 and "--lookalike-radius-m: expected a positive number" in capsys.readouterr().err
    assert not (tmp_path / "p").exists()


def test_a_navigation_field_in_a_usbl_run_is_a_row_with_its_error():
    (row,) = run_task(RunTask(case="u", scenario="usbl_turns", seed=0, values={"map.noise_m": 0.5}, estimators=("fused",), system="usbl"))
    assert row["estimator"] is None and "map.noise_m: 'map' names no field" in row["error"] and row["system"] == "usbl"


def test_a_scenario_the_system_does_not_ship_is_a_row_with_its_error():
    (row,) = run_task(RunTask(case="t", scenario="no_such_diver", seed=0, values={}, estimators=("ours",), system="track"))
    assert row["estimator"] is None and "no_such_diver" in row["error"]



@pytest.mark.parametrize("bad", [-0.1, float("nan"), float("inf")])
def test_a_held_error_that_is_no_sigma_is_named(bad):
    depth = np.random.default_rng(3).normal(size=(20, 20))
    errors = np.full(depth.shape, 0.3)
    errors[5, 5] = bad
    with pytest.raises(ValueError, match="map's error against the patch must be a finite, non-negative"):
        held_grid(_grid(depth), SonarModel(shape=(4, 4)), 0.5, errors)
    with pytest.raises(ValueError, match="map's uncertainty must be a finite, non-negative"):
        held_grid(_grid(depth), SonarModel(shape=(4, 4)), errors, 0.5)


@pytest.mark.parametrize("field", ["patch_lag_m", "velocity_bias_sigma_mps", "velocity_bias_walk_mps"])
@pytest.mark.parametrize("bad", [-1.0, float("nan")])
def test_a_route_model_of_no_lag_or_bias_is_named(field, bad):
    with pytest.raises(ValueError, match=f"{field} must be a non-negative number"):
        RouteModel(**{field: bad})


@pytest.mark.parametrize("bad", [0, 2.5, True])
def test_a_route_model_learning_the_bias_after_no_whole_number_of_fixes_is_named(bad):
    with pytest.raises(ValueError, match="bias_learning_updates must be a whole number of at least 1"):
        RouteModel(bias_learning_updates=bad)


@pytest.mark.parametrize("bad", [-0.1, 1.5, float("nan")])
def test_a_route_model_needing_an_impossible_share_of_the_patch_is_named(bad):
    with pytest.raises(ValueError, match="min_valid_fraction must lie in"):
        RouteModel(min_valid_fraction=bad)
