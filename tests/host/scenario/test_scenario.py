"""The tow simulator: scenario files, physics and sensors."""

import math
from dataclasses import replace

import numpy as np
import pytest

from lost.host.scenario import (
    KNOT_MPS,
    CableSpec,
    CurrentSpec,
    Scenario,
    SensorSpec,
    ShipSpec,
    SonarSpec,
    TerrainSpec,
    builtin_descriptions,
    builtin_scenario_path,
    builtin_scenarios,
    exact_map,
    load_scenario,
    simulate,
)


def test_the_shipped_scenarios_load():
    names = builtin_scenarios()
    assert {"demo", "short", "two_hour"} <= set(names)
    for name in names:
        scenario = load_scenario(builtin_scenario_path(name))
        assert scenario.name == name and scenario.duration_s > 0


def test_every_shipped_scenario_navigates_on_a_survey_map_but_the_named_map_equals_floor_one():
    for name in builtin_scenarios():
        scenario = load_scenario(builtin_scenario_path(name))
        if name == "short_exact_map":
            assert not scenario.map.surveyed
            continue
        spec = scenario.map
        node = spec.node_m / scenario.terrain.node_m
        assert 3 <= node <= 10 and spec.line_spacing_m and spec.line_offset_m > 0 and spec.sounding_noise_m > 0 and spec.offset_m != 0, name
    descriptions = builtin_descriptions()
    assert set(descriptions) == set(builtin_scenarios()) and all(descriptions.values())
    assert "map = floor" in descriptions["short_exact_map"]


def test_short_exact_map_is_the_short_tow_on_its_floor_and_short_a_survey_of_it():
    short = load_scenario(builtin_scenario_path("short"))
    exact_grid, exact = simulate(load_scenario(builtin_scenario_path("short_exact_map")))
    grid, records = simulate(exact_map(short))
    np.testing.assert_array_equal(grid.depth_m, exact_grid.depth_m)
    np.testing.assert_array_equal(records.truth_x_m, exact.truth_x_m)
    assert grid.sigma_m is None and grid.node_m == short.terrain.node_m
    survey_grid, surveyed = simulate(short)
    np.testing.assert_array_equal(surveyed.truth_x_m, exact.truth_x_m)  # the same tow; only the map and the patch's node differ
    assert survey_grid.node_m == 3 * grid.node_m and survey_grid.sigma_m is not None and np.isnan(survey_grid.depth_m).any()
    patch = next(p for p in surveyed.sonar if p is not None)
    assert patch.node_m == survey_grid.node_m
    # The survey's map departs from the floor's block means by its line errors and datum, not by metres of noise.
    rows, cols = survey_grid.shape
    means = grid.depth_m[: rows * 3, : cols * 3].reshape(rows, 3, cols, 3).mean(axis=(1, 3))
    error = survey_grid.depth_m - means
    assert abs(np.nanmedian(error) - short.map.offset_m) < 0.2 and 0.2 < np.nanstd(error) < 1.5


def test_an_unknown_field_is_an_error(tmp_path):
    path = tmp_path / "typo.toml"
    path.write_text("[ship]\nspeed_knots = 3\n")
    with pytest.raises(ValueError, match=r"\[ship\] has unknown field\(s\) \['speed_knots'\]"):
        load_scenario(path)
    path.write_text("[sensors.sonr]\nnoise = 1\n")
    with pytest.raises(ValueError, match="unknown sensor"):
        load_scenario(path)
    path.write_text("durations = 3\n")
    with pytest.raises(ValueError, match="unknown top-level"):
        load_scenario(path)


def test_bad_values_are_errors(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text("[sensors.gps]\ndropout_rate = 1.5\n")
    with pytest.raises(ValueError, match="sensors.gps.dropout_rate: Input should be less than or equal to 1, got 1.5"):
        load_scenario(path)
    path.write_text("[ship]\nwaypoints_m = [[0, 0]]\n")
    with pytest.raises(ValueError, match="two waypoints"):
        load_scenario(path)
    path.write_text("this is = not toml [\n")
    with pytest.raises(ValueError, match="not valid TOML"):
        load_scenario(path)
    with pytest.raises(ValueError, match="no built-in scenario"):
        builtin_scenario_path("atlantis")


def _quiet(**changes):
    """A straight eastward tow with perfect sensors."""
    base = Scenario(
        seed=3,
        duration_s=900.0,
        terrain=TerrainSpec(shape=(200, 500), roughness_m=5.0),
        ship=ShipSpec(waypoints_m=((1800.0, 1000.0), (4800.0, 1000.0)), speed_kn=3.0),
        cable=CableSpec(out_m=1200.0, catenary_factor=0.9),
        sensors={"sonar": SonarSpec(shape=(5, 7), interval_s=3.0)},
    )
    return replace(base, **changes)


def test_a_cross_current_sets_the_vehicle_off_the_track_by_the_water_angle():
    scenario = _quiet(current=CurrentSpec(speed_kn=0.5, toward_deg=0.0))
    grid, records = simulate(scenario)
    v, c = 3.0 * KNOT_MPS, 0.5 * KNOT_MPS
    depth = records.vehicle_depth_m[-1]
    layback = 0.9 * math.sqrt(1200.0**2 - depth**2)
    offset = records.truth_y_m[-1] - records.ship_y_m[-1]
    assert offset == pytest.approx(layback * c / math.hypot(v, c), rel=1e-3)
    behind = records.ship_x_m[-1] - records.truth_x_m[-1]
    assert behind == pytest.approx(layback * v / math.hypot(v, c), rel=1e-3)


def test_perfect_sensors_read_the_truth():
    grid, records = simulate(_quiet())
    truth = np.column_stack([records.truth_x_m, records.truth_y_m])
    velocity = np.gradient(truth, 1.0, axis=0)
    assert np.allclose(records.vel_x_mps, velocity[:, 0]) and np.allclose(records.vel_y_mps, velocity[:, 1])
    ship_range = np.hypot(records.ship_x_m - truth[:, 0], records.ship_y_m - truth[:, 1])
    assert np.allclose(records.slant_range_m, np.hypot(ship_range, records.vehicle_depth_m))
    # Altimeter + pressure depth is the sea floor under the vehicle: the map interpolated at the truth.
    from scipy.interpolate import RegularGridInterpolator

    floor = RegularGridInterpolator((np.arange(grid.shape[0]) * 10.0, np.arange(grid.shape[1]) * 10.0), grid.depth_m)
    assert np.allclose(records.vehicle_depth_m + records.altitude_m, floor(np.column_stack([truth[:, 1], truth[:, 0]])))
    # Patches every 3 s, 5 x 7, centred on the vehicle, rows northward.
    present = [n for n, p in enumerate(records.sonar) if p is not None]
    assert present == list(range(0, 900, 3))
    patch = records.sonar[30].depth_m
    assert patch.shape == (5, 7)
    x, y = truth[30]
    assert patch[2, 3] == pytest.approx(floor([[y, x]])[0])
    assert patch[4, 3] == pytest.approx(floor([[y + 20.0, x]])[0])
    assert patch[2, 0] == pytest.approx(floor([[y, x - 30.0]])[0])


def test_the_same_seed_gives_the_same_tow_and_noise_has_its_rates():
    noisy = _quiet(sensors={
        "altimeter": SensorSpec(noise=0.3, dropout_rate=0.1, outlier_rate=0.05, outlier=30.0),
        "sonar": SonarSpec(noise=0.2, missing_beam_rate=0.2, bias=1.0),
    })
    _, a = simulate(noisy)
    _, b = simulate(noisy)
    assert np.array_equal(a.altitude_m, b.altitude_m, equal_nan=True)
    dropped = np.isnan(a.altitude_m).mean()
    assert 0.07 < dropped < 0.13
    missing = np.mean([np.isnan(p.depth_m).mean() for p in a.sonar if p is not None])
    assert 0.17 < missing < 0.23


def test_no_slant_range_when_disabled_and_ship_velocity_without_ins():
    from lost.host.scenario import SlantRangeSpec, VehicleSpec

    scenario = _quiet(sensors={"slant_range": SlantRangeSpec(enabled=False)}, vehicle=VehicleSpec(has_velocity_sensor=False))
    _, records = simulate(scenario)
    assert np.isnan(records.slant_range_m).all()
    ship_velocity = np.gradient(np.column_stack([records.ship_x_m, records.ship_y_m]), 1.0, axis=0)
    assert np.allclose(records.vel_x_mps, ship_velocity[:, 0])


def test_the_ship_turns_at_its_rate_through_the_waypoints():
    scenario = _quiet(ship=ShipSpec(waypoints_m=((1800.0, 500.0), (3000.0, 500.0), (3000.0, 1500.0)), turn_rate_dps=1.0))
    _, records = simulate(scenario)
    turn = np.abs((np.diff(records.ship_heading_deg) + 180.0) % 360.0 - 180.0)
    assert turn.max() <= 1.0 + 1e-9
    final = records.ship_heading_deg[-1]
    assert records.ship_heading_deg[0] == pytest.approx(90.0) and min(final, 360.0 - final) < 0.1  # east, then north


def test_a_grid_file_replaces_the_synthetic_floor(tmp_path):
    from lost.host.grid import Grid
    from lost.host.io import write_npz

    depth = np.full((150, 400), 700.0) + np.arange(400)[None, :] * 0.1
    write_npz(Grid(depth, 500.0, 0.0, 10.0), tmp_path / "floor.npz")
    path = tmp_path / "file.toml"
    path.write_text(
        'duration_s = 60\n[terrain]\nfile = "floor.npz"\n'
        "[ship]\nwaypoints_m = [[3000.0, 700.0], [4400.0, 700.0]]\n[cable]\nout_m = 800.0\n"
    )
    grid, records = simulate(load_scenario(path))
    assert grid.x0_m == 500.0 and np.array_equal(grid.depth_m, depth)
    expected = 700.0 + (records.truth_x_m - 500.0) / 10.0 * 0.1
    assert np.allclose(records.vehicle_depth_m + records.altitude_m, expected)


def test_a_gps_dropout_loses_both_coordinates():
    _, records = simulate(_quiet(sensors={"gps": SensorSpec(noise=1.0, dropout_rate=0.2)}))
    assert np.array_equal(np.isnan(records.ship_x_m), np.isnan(records.ship_y_m))
    assert 0.15 < np.isnan(records.ship_x_m).mean() < 0.25
    assert not np.isnan(records.ship_heading_deg).any()


def test_a_swath_binned_by_dead_reckoning_makes_the_gridded_patch(tmp_path):
    from lost.host.grid import Grid
    from lost.host.io import write_npz

    plane = 500.0 + 0.05 * np.arange(500)[None, :] + 0.03 * np.arange(200)[:, None]
    write_npz(Grid(plane, 0.0, 0.0, 10.0), tmp_path / "plane.npz")
    on_plane = replace(_quiet(), base_dir=tmp_path, terrain=TerrainSpec(file="plane.npz"))
    _, from_swath = simulate(replace(on_plane, sensors={"sonar": SonarSpec(mode="swath", beams=64, shape=(6, 6), interval_s=5.0)}))
    _, from_nodes = simulate(replace(on_plane, sensors={"sonar": SonarSpec(shape=(6, 6), interval_s=5.0)}))
    # From 30 s on, the pings behind the vehicle cover the patch (earlier, its back is still empty).
    compared = 0
    for a, b in zip(from_swath.sonar[30:], from_nodes.sonar[30:-30]):
        if a is None:
            assert b is None
            continue
        assert np.isfinite(a.depth_m).all()
        # Each node holds the mean of the soundings on it: within the plane's rise over half a node.
        assert np.max(np.abs(a.depth_m - b.depth_m)) < 0.5 * 10.0 * 0.06
        compared += 1
    assert compared > 100


def test_a_realtime_swath_patch_uses_no_later_ping_and_lies_behind_the_vehicle(tmp_path):
    from lost.host.grid import Grid
    from lost.host.io import write_npz

    plane = 500.0 + 0.05 * np.arange(500)[None, :] + 0.03 * np.arange(200)[:, None]
    write_npz(Grid(plane, 0.0, 0.0, 10.0), tmp_path / "plane.npz")
    sonar = SonarSpec(mode="swath", realtime=True, beams=64, shape=(6, 6), interval_s=5.0)
    on_plane = replace(_quiet(), base_dir=tmp_path, terrain=TerrainSpec(file="plane.npz"), sensors={"sonar": sonar})
    _, full = simulate(on_plane)
    _, cut = simulate(replace(on_plane, duration_s=600.0))
    # Causal: ending the tow earlier changes no patch (the post-processing patch near the end would change).
    for a, b in zip(full.sonar[: len(cut)], cut.sonar):
        assert (a is None) == (b is None)
        if a is not None:
            np.testing.assert_array_equal(a.depth_m, b.depth_m)
            assert a.centre_offset_m == b.centre_offset_m
    _, post = simulate(replace(on_plane, duration_s=600.0, sensors={"sonar": replace(sonar, realtime=False)}))
    _, post_full = simulate(replace(on_plane, sensors={"sonar": replace(sonar, realtime=False)}))
    assert not np.array_equal(post.sonar[595].depth_m, post_full.sonar[595].depth_m, equal_nan=True)
    # Behind the eastward-moving vehicle by at least half the patch diagonal, and full once the swath reaches back.
    half_diagonal = math.hypot(6, 6) * 10.0 / 2
    checked = 0
    for n, patch in enumerate(full.sonar):
        if patch is None or n < 60:
            continue
        east, north = patch.centre_offset_m
        assert east < 0 and math.hypot(east, north) >= half_diagonal and abs(north) < 1.0
        assert np.isfinite(patch.depth_m).all()
        # Each node holds the plane's depth at its place, within the rise over half a node.
        rows = (full.truth_y_m[n] + north + (np.arange(6) - 2.5) * 10.0) / 10.0
        cols = (full.truth_x_m[n] + east + (np.arange(6) - 2.5) * 10.0) / 10.0
        expected = 500.0 + 0.05 * cols[None, :] + 0.03 * rows[:, None]
        assert np.max(np.abs(patch.depth_m - expected)) < 0.5 * 10.0 * 0.08
        checked += 1
    assert checked > 100


def test_swath_settings_are_validated():
    with pytest.raises(ValueError, match="mode must be"):
        Scenario(sensors={"sonar": SonarSpec(mode="sidescan")})
    with pytest.raises(ValueError, match="at least 2 beams"):
        Scenario(sensors={"sonar": SonarSpec(mode="swath", beams=1)})
    with pytest.raises(ValueError, match="realtime applies to mode = 'swath'"):
        Scenario(sensors={"sonar": SonarSpec(realtime=True)})


def test_the_map_is_surveyed_from_a_finer_floor_by_block_means_noise_offset_and_extent():
    from lost.host.scenario import FaultSpec, MapSpec, scenario_floor, survey_map

    scenario = _quiet(terrain=TerrainSpec(shape=(200, 500), node_m=5.0, roughness_m=5.0), map=MapSpec(node_m=50.0))
    floor = scenario_floor(scenario)
    nav_map = survey_map(floor, scenario.map, seed=1)
    assert nav_map.node_m == 50.0 and nav_map.shape == (20, 50)
    assert nav_map.depth_m[3, 7] == pytest.approx(floor.depth_m[30:40, 70:80].mean())
    # A map node stands at the centre of the floor nodes it averages.
    assert nav_map.xy(3, 7) == pytest.approx(floor.xy(34.5, 74.5))
    noisy = survey_map(floor, MapSpec(node_m=50.0, noise_m=1.0, offset_m=3.0), seed=1)
    difference = noisy.depth_m - nav_map.depth_m
    assert difference.mean() == pytest.approx(3.0, abs=0.1) and difference.std() == pytest.approx(1.0, rel=0.1)
    cut = survey_map(floor, MapSpec(node_m=50.0, extent_m=(0.0, 0.0, 1000.0, 2000.0)), seed=1)
    x, y = cut.xy(np.array(cut.shape) - 1, np.array(cut.shape) - 1)
    assert cut.x0_m == nav_map.x0_m and float(x[1]) <= 1000.0 + 50.0 and cut.shape[1] < nav_map.shape[1]
    # The sonar sees the floor, the navigation gets the map; without [map] they are one grid.
    grid, records = simulate(replace(scenario, fault=FaultSpec()))
    assert grid.node_m == 50.0 and records.sonar[0].node_m == 50.0
    with pytest.raises(ValueError, match="whole multiple"):
        replace(scenario, map=MapSpec(node_m=12.0))


def test_an_injected_jump_moves_the_dead_reckoning_once():
    from lost.host.scenario import FaultSpec

    plain = simulate(_quiet())[1]
    faulty = simulate(_quiet(fault=FaultSpec(position_jump_m=(300.0, 400.0), at_s=100.0)))[1]
    jump = np.array([faulty.vel_x_mps - plain.vel_x_mps, faulty.vel_y_mps - plain.vel_y_mps])
    assert np.flatnonzero(np.abs(jump).sum(axis=0) > 1e-9).tolist() == [100]
    assert jump[:, 100] == pytest.approx((300.0, 400.0))


def test_von_karman_terrain_has_its_corner_and_a_repeated_tile_repeats():
    from lost.host.terrain import synthetic_terrain

    floor = synthetic_terrain((256, 256), seed=2, relief_m=0.0, roughness_m=1.0, corner_nodes=32.0, hurst=0.8)
    power = np.abs(np.fft.rfft2(floor - floor.mean())) ** 2
    k = np.hypot(np.fft.fftfreq(256)[:, None], np.fft.rfftfreq(256)[None, :])
    flat = power[(k > 0) & (k < 1 / 128)].mean() / power[(k > 1 / 64) & (k < 1 / 48)].mean()
    steep = power[(k > 1 / 8) & (k < 1 / 6)].mean() / power[(k > 1 / 4) & (k < 1 / 3)].mean()
    assert flat < 3.0 < steep  # flat beyond the corner, a power law well inside it
    tiled = synthetic_terrain((100, 100), seed=2, repeat_nodes=(40, 40))
    np.testing.assert_array_equal(tiled[:40, :40], tiled[40:80, 40:80])


def test_a_grid_files_sign_and_nodata_can_be_named_in_the_scenario(tmp_path, monkeypatch):
    import lost.host.io as io

    seen = {}
    monkeypatch.setattr(io, "read_grid", lambda path, **kwargs: seen.update(kwargs) or io.Grid(np.full((50, 60), 700.0), 0.0, 0.0, 10.0))
    path = tmp_path / "file.toml"
    path.write_text('[terrain]\nfile = "elevation.tif"\npositive = "up"\nnodata = -32768\n')
    from lost.host.scenario import scenario_floor

    scenario_floor(load_scenario(path))
    assert seen == {"positive": "up", "nodata": -32768.0}
    path.write_text('[terrain]\nfile = "elevation.tif"\npositive = "sideways"\n')
    with pytest.raises(ValueError, match="terrain.positive"):
        load_scenario(path)


def test_lost_run_lists_the_shipped_scenarios_with_their_descriptions(capsys):
    from lost.host.cli import main

    assert main(["run", "--list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in lines] == builtin_scenarios()
    assert any(line.startswith("short_exact_map") and "map = floor" in line for line in lines)
