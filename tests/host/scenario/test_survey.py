"""Maps made from floors as surveys make them: gridded soundings with line-correlated errors, holes, a datum, a spread per node."""

import math

import numpy as np
import pytest

from lost.host.grid import Grid
from lost.host.scenario import MapSpec, survey_map
from lost.host.scenario.map import grid_soundings, survey_soundings
from lost.host.terrain import synthetic_terrain


def _floor(rows: int = 300, cols: int = 400, node_m: float = 5.0) -> Grid:
    return Grid(synthetic_terrain((rows, cols), seed=6, relief_m=20.0, roughness_m=2.0), 0.0, 0.0, node_m)


def test_gridding_takes_each_cells_mean_or_median_and_their_spread_and_leaves_empty_cells_holes():
    rng = np.random.default_rng(1)
    soundings = rng.normal(100.0, 2.0, (12, 9))
    soundings[0:3, 0:3] = np.nan  # a cell with no sounding
    soundings[3:6, 3:6] = np.nan
    soundings[4, 4] = 101.0  # a cell with one
    depth, sigma = grid_soundings(soundings, 3, "mean")
    median, _ = grid_soundings(soundings, 3, "median")
    assert depth.shape == sigma.shape == (4, 3)
    for r in range(4):
        for c in range(3):
            cell = soundings[3 * r : 3 * r + 3, 3 * c : 3 * c + 3]
            cell = cell[np.isfinite(cell)]
            if cell.size > 1:
                assert depth[r, c] == pytest.approx(cell.mean()) and median[r, c] == pytest.approx(np.median(cell))
                assert sigma[r, c] == pytest.approx(cell.std(ddof=1))
    assert np.isnan(depth[0, 0]) and np.isnan(sigma[0, 0]) and np.isnan(median[0, 0])
    others = [s for (r, c), s in np.ndenumerate(sigma) if (r, c) not in ((0, 0), (1, 1))]
    assert depth[1, 1] == 101.0 and sigma[1, 1] == pytest.approx(np.median(others))  # a lone sounding: the median spread
    with pytest.raises(ValueError, match="larger than the floor"):
        grid_soundings(soundings, 20)


def test_each_survey_line_has_its_own_offset_and_its_outer_beams_bend():
    floor = _floor()
    spec = MapSpec(line_spacing_m=100.0, line_azimuth_deg=0.0, line_offset_m=0.5)
    error = survey_soundings(floor, spec, np.random.default_rng(2)) - floor.depth_m
    x = np.arange(floor.shape[1]) * 5.0
    line = np.rint(x / 100.0).astype(int)
    # Lines run north: every sounding of a line shares its error; the lines' errors spread by line_offset_m.
    per_line = [error[:, line == k] for k in np.unique(line)]
    assert all(np.ptp(e) < 1e-9 for e in per_line)
    assert np.std([e[0, 0] for e in per_line]) == pytest.approx(0.5, rel=0.5)
    bent = survey_soundings(floor, MapSpec(line_spacing_m=100.0, refraction_m=0.8), np.random.default_rng(2)) - floor.depth_m
    across = np.abs(x - np.rint(x / 100.0) * 100.0)
    assert np.abs(bent[:, across == 0]).max() < 1e-9  # nadir is right
    assert np.allclose(np.abs(bent[:, across == 50.0]), 0.8)  # the swath's edge is off by refraction_m
    assert np.allclose(np.abs(bent[:, across == 25.0]), 0.2)  # quadratic across


def test_the_along_line_drift_is_correlated_along_the_lines_not_across_them():
    floor = _floor(400, 400)
    spec = MapSpec(line_spacing_m=50.0, line_azimuth_deg=90.0, line_drift_m=1.0, along_m=400.0)
    error = survey_soundings(floor, spec, np.random.default_rng(3)) - floor.depth_m
    assert np.std(error) == pytest.approx(1.0, rel=0.3)
    # Lines run east (along the rows): 40 m apart along a line the error is nearly the same; on the next line it is another.
    along = np.corrcoef(error[::10, :-8].ravel(), error[::10, 8:].ravel())[0, 1]
    across = np.corrcoef(error[:-10:10, :].ravel(), error[10::10, :].ravel())[0, 1]
    assert along > 0.9 and abs(across) < 0.3


def test_gaps_between_swaths_and_unsurveyed_patches_leave_no_soundings():
    floor = _floor()
    striped = survey_soundings(floor, MapSpec(line_spacing_m=100.0, swath_width_m=80.0), np.random.default_rng(4))
    assert np.isnan(striped).mean() == pytest.approx(0.2, abs=0.06)  # 1 - 80 / 100, within a node of each stripe edge
    patchy = survey_soundings(floor, MapSpec(hole_fraction=0.1, hole_size_m=200.0), np.random.default_rng(4))
    assert np.isnan(patchy).mean() == pytest.approx(0.1, abs=0.02)
    # In patches, not scattered: most holes have holes on all four sides.
    holes = np.isnan(patchy)
    inner = holes[1:-1, 1:-1] & holes[:-2, 1:-1] & holes[2:, 1:-1] & holes[1:-1, :-2] & holes[1:-1, 2:]
    assert inner.sum() > 0.7 * holes.sum()


def test_a_surveyed_map_is_coarser_offset_holed_and_carries_its_spread():
    floor = _floor()
    spec = MapSpec(node_m=25.0, line_spacing_m=200.0, line_offset_m=0.3, sounding_noise_m=0.5, hole_fraction=0.05, offset_m=2.5)
    nav_map = survey_map(floor, spec, seed=7)
    assert nav_map.node_m == 25.0 and nav_map.shape == (60, 80) and nav_map.sigma_m.shape == nav_map.shape
    assert nav_map.xy(0, 0) == pytest.approx(floor.xy(2.0, 2.0))
    truth = floor.depth_m.reshape(60, 5, 80, 5).mean(axis=(1, 3))
    error = nav_map.depth_m - truth
    assert np.nanmean(error) == pytest.approx(2.5, abs=0.3)
    assert 0.02 < np.isnan(nav_map.depth_m).mean() < 0.09
    assert np.array_equal(np.isnan(nav_map.depth_m), np.isnan(nav_map.sigma_m))
    # The spread: the sounding noise and the relief inside each 25 m cell.
    relief = floor.depth_m.reshape(60, 5, 80, 5).std(axis=(1, 3), ddof=1)
    expected = np.sqrt(0.5**2 + relief**2)
    assert np.nanmedian(nav_map.sigma_m / expected) == pytest.approx(1.0, abs=0.1)
    np.testing.assert_array_equal(nav_map.depth_m, survey_map(floor, spec, seed=7).depth_m)
    assert not np.array_equal(nav_map.depth_m, survey_map(floor, spec, seed=8).depth_m, equal_nan=True)
    cut = survey_map(floor, MapSpec(node_m=25.0, extent_m=(0.0, 0.0, 1000.0, 800.0)), seed=7)
    assert cut.sigma_m.shape == cut.shape and cut.shape[1] < 80
    median = survey_map(floor, MapSpec(node_m=25.0, gridding="median"), seed=7)
    assert np.nanmax(np.abs(median.depth_m - truth)) < 3 * np.nanmax(relief)
    assert survey_map(floor, MapSpec(), seed=7).sigma_m is None  # the map is the floor: no gridding, no spread


def test_a_grid_carries_a_per_node_sigma_of_its_own_shape_and_never_negative():
    depth = np.full((4, 5), 100.0)
    assert Grid(depth, 0.0, 0.0, 10.0, sigma_m=np.full((4, 5), 0.2)).sigma_m.dtype == np.float64
    assert Grid(depth, 0.0, 0.0, 10.0).sigma_m is None
    with pytest.raises(ValueError, match="shape"):
        Grid(depth, 0.0, 0.0, 10.0, sigma_m=np.ones((5, 4)))
    with pytest.raises(ValueError, match="negative"):
        Grid(depth, 0.0, 0.0, 10.0, sigma_m=np.full((4, 5), -0.1))


def test_the_map_node_is_checked_against_the_floor_files_own_node(tmp_path):
    """A 75 m map of a 25 m floor file: three floor nodes a map node, not refused against the synthetic floor's 10 m."""
    from lost.host.io import write_npz
    from lost.host.scenario import load_scenario, simulate

    depth = 700.0 + synthetic_terrain((150, 300), seed=2, relief_m=20.0, roughness_m=3.0) - 1000.0
    write_npz(Grid(depth, 0.0, 0.0, 25.0), tmp_path / "floor.npz")
    text = ('duration_s = 60\n[terrain]\nfile = "floor.npz"\n[map]\nnode_m = {node}\n'
            "[ship]\nwaypoints_m = [[4000.0, 1800.0], [7000.0, 1800.0]]\n[cable]\nout_m = 900.0\n")
    (tmp_path / "good.toml").write_text(text.format(node=75.0))
    grid, records = simulate(load_scenario(tmp_path / "good.toml"))
    assert grid.node_m == 75.0 and grid.shape == (50, 100) and records.sonar[0].node_m == 75.0
    (tmp_path / "bad.toml").write_text(text.format(node=60.0))
    with pytest.raises(ValueError, match=r"whole multiple of the floor's node, 25 m"):
        simulate(load_scenario(tmp_path / "bad.toml"))


def test_a_scenario_refines_a_coarse_file_into_a_finer_floor_and_surveys_it(tmp_path):
    from lost.host.io import write_npz
    from lost.host.scenario import load_scenario, scenario_floor, simulate

    coarse = 700.0 + synthetic_terrain((60, 120), seed=2, relief_m=20.0, roughness_m=3.0) - 1000.0
    write_npz(Grid(coarse, 0.0, 0.0, 50.0), tmp_path / "dem.npz")
    (tmp_path / "fine.toml").write_text(
        'duration_s = 30\n[terrain]\nfile = "dem.npz"\nrefine_node_m = 10.0\ndetail_m = 0.5\n[map]\nnode_m = 50.0\n'
        "[ship]\nwaypoints_m = [[4000.0, 1500.0], [5500.0, 1500.0]]\n[cable]\nout_m = 900.0\n")
    scenario = load_scenario(tmp_path / "fine.toml")
    floor = scenario_floor(scenario)
    assert floor.node_m == 10.0 and floor.shape == (296, 596)
    assert np.std(floor.depth_m[::5, ::5] - coarse) == pytest.approx(0.5, rel=0.2)
    grid, _ = simulate(scenario)
    assert grid.node_m == 50.0 and grid.sigma_m is not None
    (tmp_path / "odd.toml").write_text('[terrain]\nfile = "dem.npz"\nrefine_node_m = 15.0\n[cable]\nout_m = 900.0\n')
    with pytest.raises(ValueError, match=r"refine_node_m \(15 m\) must divide the node of dem.npz \(50 m\)"):
        scenario_floor(load_scenario(tmp_path / "odd.toml"))


def test_a_scenario_file_lays_out_a_shelf_with_a_canyon(tmp_path):
    from lost.host.scenario import load_scenario, scenario_floor

    path = tmp_path / "shelf.toml"
    path.write_text(
        "[terrain]\nshape = [200, 300]\nnode_m = 10.0\nmean_depth_m = 200.0\nrelief_m = 0.0\nroughness_m = 0.3\ngradient = 0.01\n"
        "downslope_deg = 90.0\n[[terrain.features]]\nkind = \"canyon\"\nheight_m = 50.0\nwidth_m = 60.0\n"
        "path_m = [[0.0, 1000.0], [3000.0, 1000.0]]\n[[terrain.features]]\nkind = \"seamount\"\nheight_m = 80.0\nwidth_m = 200.0\n"
        "at_m = [2000.0, 1600.0]\n[cable]\nout_m = 600.0\n")
    scenario = load_scenario(path)
    assert [f.kind for f in scenario.terrain.features] == ["canyon", "seamount"]
    floor = scenario_floor(scenario).depth_m
    assert floor[100, 150] - floor[50, 150] == pytest.approx(50.0, abs=3.0)  # the canyon's floor below the shelf
    assert floor[50, 250] - floor[50, 50] == pytest.approx(20.0, abs=3.0)  # 1 % deeper over 2 km eastward
    assert floor[160, 200] < floor[160, 100] - 60.0  # the seamount
    path.write_text('[terrain]\n[[terrain.features]]\nkind = "trench"\nheight_m = 5.0\nwidth_m = 5.0\n')
    with pytest.raises(ValueError, match=r"terrain.features\[0\].kind"):
        load_scenario(path)
    path.write_text('[terrain]\nfile = "x.nc"\ngradient = 0.01\n[cable]\nout_m = 2000.0\n')
    with pytest.raises(ValueError, match="shape the synthetic floor, not a grid file"):
        load_scenario(path)
    path.write_text('[terrain]\nrefine_node_m = 5.0\n')
    with pytest.raises(ValueError, match="refine a grid file"):
        load_scenario(path)
    assert math.isfinite(floor.sum())


REALISTIC = ("coarse_map", "shelf_canyon", "seamount_ridges")


@pytest.mark.parametrize("name", REALISTIC)
def test_the_shipped_realistic_map_scenarios_survey_a_floor_three_to_ten_times_finer(name):
    from lost.host.scenario import builtin_scenario_path, load_scenario

    scenario = load_scenario(builtin_scenario_path(name))
    spec = scenario.map
    assert 3 <= spec.node_m / scenario.terrain.node_m <= 10
    assert spec.line_spacing_m and spec.line_offset_m > 0 and spec.line_drift_m > 0 and spec.refraction_m > 0
    assert spec.sounding_noise_m > 0 and spec.hole_fraction > 0 and abs(spec.offset_m) >= 2.0


def test_the_shelf_canyon_map_shows_the_canyon_and_its_walls_spread_more_than_the_shelf():
    from lost.host.scenario import builtin_scenario_path, load_scenario, scenario_floor, survey_map

    scenario = load_scenario(builtin_scenario_path("shelf_canyon"))
    floor = scenario_floor(scenario)
    nav_map = survey_map(floor, scenario.map, seed=1)
    assert nav_map.shape == (180, 340) and 0.005 < np.isnan(nav_map.depth_m).mean() < 0.06
    # Across the track's row (2.2 km north), the canyon is the deepest 50 m; its walls have the largest spread.
    row = nav_map.depth_m[88]
    shelf = np.nanmedian(row)
    assert np.nanmax(row) - shelf > 40.0
    walls = np.nanmax(nav_map.sigma_m[88]) / np.nanmedian(nav_map.sigma_m[88])
    assert walls > 5.0
    # The shelf itself is smooth: within a few metres over kilometres, its sigma the sounding noise and a little relief.
    assert np.nanmedian(nav_map.sigma_m) == pytest.approx(0.3, abs=0.1)
