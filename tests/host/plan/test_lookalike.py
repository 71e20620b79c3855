"""The planner's look-alikes: the runner-up per ring against a placement-by-placement search, periodic terrain against
rough, the lock along a route lost over look-alike ground and regained on informative terrain, and accuracy.nc's layers."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from scipy import ndimage

from lost.host.cli import EXIT_OK, main
from lost.host.grid import Grid
from lost.host.io import write_npz
from lost.host.plan import RouteModel, SonarModel, lookalike_grid, predict_along
from lost.host.plan.ambiguity import EXCLUSION_NODES
from lost.host.plan.route import false_lock_probability


def _rough(shape=(50, 70), seed=1, relief=40.0) -> Grid:
    depth = 500.0 + relief * ndimage.gaussian_filter(np.random.default_rng(seed).normal(size=shape), 2.0)
    return Grid(depth_m=depth, x0_m=0.0, y0_m=0.0, node_m=10.0)


def _direct(depth: np.ndarray, row: int, col: int, shape, reach: int, edges_nodes: np.ndarray, noise_var: float) -> dict[int, tuple[float, float]]:
    """Every placement within ``reach`` written out: the smallest n D / s^2 per ring and its distance (nodes)."""
    h, w = shape
    patch = depth[row - h // 2: row - h // 2 + h, col - w // 2: col - w // 2 + w]
    best: dict[int, tuple[float, float]] = {}
    for di in range(-reach, reach + 1):
        for dj in range(-reach, reach + 1):
            radius = float(np.hypot(di, dj))
            i, j = row - h // 2 + di, col - w // 2 + dj
            if max(abs(di), abs(dj)) <= EXCLUSION_NODES or radius > reach or i < 0 or j < 0 or i + h > depth.shape[0] or j + w > depth.shape[1]:
                continue
            other = depth[i: i + h, j: j + w]
            if not np.isfinite(other).all():
                continue
            diff = patch - other
            value = diff.size * (np.mean(diff**2) - np.mean(diff) ** 2) / noise_var
            ring = int(np.searchsorted(edges_nodes, radius, side="left"))
            if ring not in best or value < best[ring][0]:
                best[ring] = (value, radius)
    return best


def test_the_runner_up_per_ring_equals_a_placement_by_placement_search():
    grid = _rough()
    depth = grid.depth_m.copy()
    depth[30, 50] = np.nan  # a hole: placements touching it are no look-alikes, patches touching it have none
    grid = Grid(depth_m=depth, x0_m=0.0, y0_m=0.0, node_m=10.0)
    sonar = SonarModel(shape=(6, 8), noise_m=0.4)
    found = lookalike_grid(grid, sonar, 0.3, radius_m=120.0)
    edges = found.ring_edges_m / grid.node_m
    for row, col in ((20, 30), (8, 9), (40, 60), (25, 45)):
        direct = _direct(depth, row, col, sonar.shape, 12, edges, 0.4**2 + 0.3**2)
        assert sorted(direct) == [k for k in range(len(edges)) if np.isfinite(found.snr[k, row, col])]
        for ring, (value, radius) in direct.items():
            assert found.snr[ring, row, col] == pytest.approx(value, rel=1e-7)
            assert found.distance_m[ring, row, col] == pytest.approx(radius * grid.node_m)
    assert np.isnan(found.snr[:, 28:33, 47:54]).all() and np.isnan(found.snr[:, :2]).all()


def test_periodic_terrain_is_a_false_lock_and_rough_terrain_is_not():
    y, x = np.mgrid[0:60, 0:80] * 10.0
    ridges = Grid(depth_m=400.0 + 5.0 * np.sin(2 * np.pi * x / 80.0), x0_m=0.0, y0_m=0.0, node_m=10.0)  # sand waves: every 80 m alike
    alike = false_lock_probability(lookalike_grid(ridges, SonarModel(), 0.1, radius_m=200.0, work=3e6))
    rough = false_lock_probability(lookalike_grid(_rough((60, 80)), SonarModel(), 0.1, radius_m=200.0, work=3e6))
    assert np.nanmin(alike) > 0.99 and np.nanmax(rough) < 0.01


def test_a_repeated_tile_is_as_many_look_alikes_as_its_repeats():
    tile = 20.0 * ndimage.gaussian_filter(np.random.default_rng(3).normal(size=(10, 10)), 1.5, mode="wrap")
    repeated = Grid(depth_m=500.0 + np.tile(tile, (7, 7)), x0_m=0.0, y0_m=0.0, node_m=10.0)  # a 100 m tile repeated
    found = lookalike_grid(repeated, SonarModel(shape=(8, 8), noise_m=0.3), 0.1, radius_m=150.0, work=3e6)
    # the ring to 150 m holds the 4 repeats at 100 m and the 4 at 141 m: each a chance of 1/2 to win a patch
    assert np.nanmin(found.snr[-1]) < 1e-6
    assert np.allclose(found.rivals[-1, 25:45, 25:45], 4.0, atol=0.05)  # where every repeat is on the map
    rough = lookalike_grid(_rough((70, 70)), SonarModel(shape=(8, 8), noise_m=0.3), 0.1, radius_m=150.0, work=3e6)
    assert np.nanmax(rough.rivals[-1]) < 0.05


def test_the_lock_is_lost_over_look_alike_ground_and_regained_on_informative_terrain():
    rng = np.random.default_rng(4)
    y, x = np.mgrid[0:50, 0:240] * 10.0
    depth = 400.0 + 5.0 * (np.sin(2 * np.pi * x / 80.0) + np.sin(2 * np.pi * y / 80.0)) + 0.02 * rng.normal(size=x.shape)
    rough = 30.0 * ndimage.gaussian_filter(rng.normal(size=x.shape), 2.0)
    depth[:, 160:] += rough[:, 160:]  # sand waves to 1600 m, rough ground beyond
    grid = Grid(depth_m=depth, x0_m=0.0, y0_m=0.0, node_m=10.0)
    sonar = SonarModel(noise_m=0.3)
    from lost.host.plan import accuracy_grid

    accuracy, lookalike = accuracy_grid(grid, sonar, 0.1), lookalike_grid(grid, sonar, 0.1, radius_m=200.0, work=3e6)
    t = np.arange(0.0, 1500.0, 3.0)
    xy = np.column_stack([100.0 + 1.5 * t, np.full(t.size, 250.0)])
    model = RouteModel(speed_mps=1.5, interval_s=3.0, initial_sigma_m=100.0, usable_sigma_m=10.0, floor_m=1.0, patch_length_m=100.0,
                       acquisitions_per_patch=10.0)
    route = predict_along(accuracy, t, xy, model, lookalike)
    waves, beyond = xy[:, 0] < 1500.0, xy[:, 0] > 1800.0
    # where every 80 m looks alike only the map's 2 cm of noise tells the placements apart: the search goes on
    assert route["unlocked"][xy[:, 0] < 600.0].min() > 0.99 and route["unlocked"][waves].min() > 0.7
    assert route["unlocked"][beyond][-1] < 0.01 and route["predicted_m"][beyond][-1] < 5.0
    assert route["predicted_m"][waves].min() > 50.0  # the error is the search's, not the bound's
    locked = predict_along(accuracy, t, xy, model)  # without look-alikes: the bound alone, locked from the start
    assert "unlocked" not in locked and locked["predicted_m"][waves][-1] < 10.0


def test_lost_plan_writes_the_look_alike_layers(tmp_path):
    y, x = np.mgrid[0:40, 0:60] * 10.0
    grid = Grid(depth_m=400.0 + 5.0 * (np.sin(2 * np.pi * x / 80.0) + np.sin(2 * np.pi * y / 80.0)), x0_m=0.0, y0_m=0.0, node_m=10.0)
    write_npz(grid, tmp_path / "map.npz")
    out = tmp_path / "plan"
    assert main(["plan", str(tmp_path / "map.npz"), "--out", str(out), "--lookalike-radius-m", "150"]) == EXIT_OK
    with xr.open_dataset(out / "accuracy.nc") as data:
        assert set(data.data_vars) == {"accuracy_m", "false_lock_probability", "lookalike_separation", "lookalike_distance_m"}
        inner = data["false_lock_probability"].values[10:30, 10:50]
        assert np.all(inner > 0.99) and np.isnan(data["false_lock_probability"].values[:3]).all()
        assert np.nanmin(data["lookalike_distance_m"].values) >= 30.0  # beyond the truth's own two nodes


def test_a_search_ends_on_rough_ground_and_a_search_over_a_hole_becomes_a_wrong_lock():
    from lost.host.plan import accuracy_grid

    grid = _rough((40, 200), seed=7)
    depth = grid.depth_m.copy()
    depth[:, 90:110] = np.nan  # an unsurveyed patch across the route
    grid = Grid(depth_m=depth, x0_m=0.0, y0_m=0.0, node_m=10.0)
    sonar = SonarModel(noise_m=0.3)
    accuracy, lookalike = accuracy_grid(grid, sonar, 0.1), lookalike_grid(grid, sonar, 0.1, radius_m=150.0, work=3e6)
    model = RouteModel(speed_mps=1.5, interval_s=2.0, initial_sigma_m=100.0, usable_sigma_m=10.0, floor_m=1.0, patch_length_m=100.0)
    t = np.arange(0.0, 1200.0, 2.0)
    xy = np.column_stack([60.0 + 1.5 * t, np.full(t.size, 200.0)])
    route = predict_along(accuracy, t, xy, model, lookalike)
    before, after = (xy[:, 0] > 300.0) & (xy[:, 0] < 800.0), xy[:, 0] > 1150.0
    assert route["unlocked"][before].max() < 1e-3  # found within a few patch lengths of rough ground
    assert route["unlocked"][after].max() < 1e-3  # and held through the hole: no search's tail carried over it
    started_in_hole = predict_along(accuracy, t[t < 200.0], np.column_stack([950.0 + 0.3 * t[t < 200.0], np.full((t < 200.0).sum(), 200.0)]),
                                    model, lookalike)
    assert started_in_hole["unlocked"][-1] > 0.99 and started_in_hole["predicted_m"][-1] > 50.0  # no terrain: a search or a wrong lock


def test_the_wrong_place_beyond_the_nearest_look_alike_is_the_search_densitys_tail():
    from lost.host.plan.route import _wrong_place_ms

    # the search's density about the truth, 60 m an axis: its mean square distance beyond 100 m, by sampling
    offsets = np.random.default_rng(11).normal(scale=60.0, size=(400_000, 2))
    squared = np.sum(offsets**2, axis=1)
    assert _wrong_place_ms(2 * 60.0**2, 100.0) == pytest.approx(squared[squared > 100.0**2].mean(), rel=0.02)
    assert _wrong_place_ms(2 * 60.0**2, 0.0) == pytest.approx(squared.mean(), rel=0.01)


def test_a_search_on_a_repeated_tile_narrows_over_a_hole_onto_a_copy_beyond_the_nearest():
    from lost.host.plan import accuracy_grid

    tile = 20.0 * ndimage.gaussian_filter(np.random.default_rng(5).normal(size=(10, 10)), 1.5, mode="wrap")
    depth = 500.0 + np.tile(tile, (6, 40))  # a 100 m tile repeated over 600 m x 4 km at 10 m nodes
    depth[:, 120:250] = np.nan  # a hole of 1.3 km across the route: several patch lengths
    grid = Grid(depth_m=depth, x0_m=0.0, y0_m=0.0, node_m=10.0)
    sonar = SonarModel(shape=(8, 8), noise_m=0.3)
    accuracy, lookalike = accuracy_grid(grid, sonar, 0.1), lookalike_grid(grid, sonar, 0.1, radius_m=150.0, work=3e6)
    model = RouteModel(speed_mps=1.5, interval_s=2.0, initial_sigma_m=60.0, velocity_noise_mps=1e-6, usable_sigma_m=10.0, floor_m=1.0,
                       patch_length_m=80.0)
    t = np.arange(0.0, 1600.0, 2.0)
    xy = np.column_stack([200.0 + 1.5 * t, np.full(t.size, 300.0)])
    route = predict_along(accuracy, t, xy, model, lookalike)
    tiles, hole_end = xy[:, 0] < 1100.0, (xy[:, 0] > 2300.0) & (xy[:, 0] < 2450.0)
    assert route["unlocked"][tiles].min() > 0.99 and route["predicted_m"][tiles].max() == pytest.approx(np.sqrt(2) * 60.0, rel=0.01)
    # the copies lie every 100 m (100 and 141 m in the outer ring, its best one of them): the truth's placement gone,
    # the wrong place is in the search density's tail beyond it
    last = int(np.flatnonzero(tiles)[-1])
    nearest = lookalike.distance_m[-1, 30, int(round(xy[last, 0] / 10.0))]
    assert nearest == pytest.approx(100.0) or nearest == pytest.approx(100.0 * np.sqrt(2))
    assert route["unlocked"][hole_end].min() > 0.99
    assert route["predicted_m"][hole_end][-1] == pytest.approx(np.sqrt(nearest**2 + 2 * 60.0**2), rel=0.02)


def test_the_first_terrain_update_weighs_all_the_track_run_before_it():
    """The filters temper a patch by the track run since their last terrain update, the first wholly: a first update
    that waits for the patch to fill ends the search as a patch length of updates would, not as one update's share."""
    from lost.host.plan import Sweep, accuracy_grid

    grid = _rough((60, 200), seed=3, relief=5.0)
    sonar = SonarModel(noise_m=0.3)
    accuracy, lookalike = accuracy_grid(grid, sonar, 0.1), lookalike_grid(grid, sonar, 0.1, radius_m=150.0, work=3e6)
    model = RouteModel(speed_mps=1.5, interval_s=1.0, initial_sigma_m=100.0, usable_sigma_m=10.0, floor_m=1.0, patch_length_m=100.0,
                       patch_lag_m=70.0, sweep=Sweep(shape=(10, 10), node_m=10.0), min_valid_fraction=0.5)
    t = np.arange(0.0, 300.0, 1.0)
    xy = np.column_stack([500.0 + 1.5 * t, np.full(t.size, 300.0)])
    route = predict_along(accuracy, t, xy, model, lookalike)
    first = int(np.flatnonzero(np.isfinite(route["bound_m"]))[0])
    assert first > 10 and route["unlocked"][first - 1] == 1.0  # no update while the patch is under half full
    assert route["unlocked"][first] < 0.01  # the first update, a whole patch's evidence, ends the search (one share: 0.7)
