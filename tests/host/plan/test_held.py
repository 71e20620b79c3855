"""The error of a held lock: the map's error against the sonar's patch (a binned swath against a point-sampled patch), one
patch's bound of it rather than the filters' density, and its growth where there is no fix."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from lost.host.grid import Grid
from lost.host.nav.maperror import node_variance
from lost.host.plan import RouteModel, SonarModel, accuracy_grid, held_sigma, predict_along


def _plane_with_layer(spread: float = 0.0) -> Grid:
    """A tilted plane whose sigma layer is its soundings' spread in a cell: the plane's own (slope * L / sqrt(12) an
    axis) plus ``spread`` of independent noise."""
    rows, cols = np.mgrid[0:30, 0:40]
    node = 20.0
    depth = 800.0 + 0.2 * cols * node + 0.1 * rows * node
    plane = node_variance(depth, node, 0.0)
    return Grid(depth_m=depth, x0_m=0.0, y0_m=0.0, node_m=node, sigma_m=np.sqrt(plane + spread**2))


def test_a_binned_swath_sees_the_spread_a_plane_does_not_explain_a_point_sampled_patch_the_whole():
    grid = _plane_with_layer(spread=0.3)
    binned = held_sigma(grid, SonarModel(binned=True))
    points = held_sigma(grid, SonarModel(binned=False))
    inside = (slice(2, -2), slice(2, -2))  # the plane's second differences are exact away from the edges
    assert np.allclose(binned[inside], 0.3, atol=1e-9)
    assert np.allclose(points, grid.sigma_m)
    assert np.all(points[inside] > 3 * binned[inside])


def test_a_map_without_a_layer_takes_the_survey_sigma_and_the_relief():
    depth = 500.0 + 30.0 * ndimage.gaussian_filter(np.random.default_rng(3).normal(size=(40, 50)), 2.0)
    grid = Grid(depth_m=depth, x0_m=0.0, y0_m=0.0, node_m=10.0)
    held = held_sigma(grid, SonarModel(), 0.4)
    full = node_variance(depth, 10.0, 0.4)
    assert np.all(held >= 0.4 - 1e-12) and np.all(held**2 <= full + 1e-9)
    assert np.any(held**2 < full - 1e-3)  # the slope term is the filters' allowance, not the held error


def test_the_held_error_is_one_patchs_bound_below_the_density_floor_and_grows_through_a_hole():
    bound = np.full((40, 200), 1.0)
    bound[:, 80:140] = np.inf  # no fix here
    accuracy = Grid(depth_m=bound, x0_m=0.0, y0_m=0.0, node_m=10.0)
    held = Grid(depth_m=np.where(np.isfinite(bound), 0.6, np.inf), x0_m=0.0, y0_m=0.0, node_m=10.0)
    model = RouteModel(speed_mps=2.0, interval_s=1.0, velocity_noise_mps=0.2, initial_sigma_m=100.0, usable_sigma_m=5.0, floor_m=3.0)
    t = np.arange(0.0, 990.0)
    xy = np.column_stack([2.0 * t, np.full(t.size, 200.0)])
    density = predict_along(accuracy, t, xy, model)
    route = predict_along(accuracy, t, xy, model, held=held)
    column = np.rint(route["east_m"] / 10.0)
    blind = (column >= 80) & (column < 140)
    assert np.allclose(route["predicted_m"][~blind & (column > 5)], 0.6)  # not the floor's 3 m: that is the density's width
    assert np.all(density["predicted_m"] >= 3.0 - 1e-12)
    grown = route["predicted_m"][blind]
    assert np.all(np.diff(grown) > 0) and grown[-1] > 2 * 0.6
    # it grows as the density does from the last fix: the same increase of the mean square
    assert grown[-1] ** 2 - 0.6**2 == pytest.approx(density["predicted_m"][blind][-1] ** 2 - density["predicted_m"][np.flatnonzero(blind)[0] - 1] ** 2,
                                                    rel=1e-6)


def test_the_held_bound_on_rough_ground_is_below_the_filters_bound():
    depth = 500.0 + 40.0 * ndimage.gaussian_filter(np.random.default_rng(5).normal(size=(50, 60)), 2.0)
    grid = Grid(depth_m=depth, x0_m=0.0, y0_m=0.0, node_m=10.0)
    sonar = SonarModel(noise_m=0.3)
    filters = accuracy_grid(grid, sonar, np.sqrt(node_variance(depth, 10.0, 0.5))).depth_m
    held = accuracy_grid(grid, sonar, held_sigma(grid, sonar, 0.5)).depth_m
    ok = np.isfinite(filters)
    assert ok.any() and np.all(held[ok] <= filters[ok] + 1e-12)
