"""Hostile settings: scenario files and navigation parameters with the wrong types, ranges, names and physics."""

from __future__ import annotations

import pytest

from lost.host.config import ConfigError, read_navigation_table
from lost.host.nav import navigation_parameters
from lost.host.scenario import load_scenario

from .conftest import TINY_SCENARIO


def _scenario(tmp_path, extra: str):
    path = tmp_path / "s.toml"
    path.write_text(TINY_SCENARIO + "\n" + extra + "\n")
    return path


def _with(tmp_path, table: str, line: str):
    """The tiny scenario with ``line`` put into ``[table]`` (created if absent)."""
    key = line.split("=")[0].strip()
    text = "\n".join(kept for kept in TINY_SCENARIO.splitlines() if not kept.startswith(f"{key} ="))  # the tiny one's own value goes
    if f"[{table}]\n" in text:
        text = text.replace(f"[{table}]\n", f"[{table}]\n{line}\n", 1)
    else:
        text += f"\n[{table}]\n{line}\n"
    path = tmp_path / "s.toml"
    path.write_text(text)
    return path


# (table, line, error fragment): each a value a hostile or hurried user writes.
BAD_SETTINGS = {
    "boolean_as_string": ("vehicle", 'has_velocity_sensor = "false"', "vehicle.has_velocity_sensor: Input should be a valid boolean, got 'false' (str)"),
    "boolean_as_int": ("sensors.sonar", "enabled = 0", "sensors.sonar.enabled: Input should be a valid boolean, got 0"),
    "fractional_patch_shape": ("sensors.sonar", "shape = [10.5, 10]", "sensors.sonar.shape.0: Input should be a valid integer, got 10.5"),
    "patch_shape_of_three": ("sensors.sonar", "shape = [10, 10, 10]", "sensors.sonar.shape: Tuple should have at most 2 items"),
    "zero_patch_side": ("sensors.sonar", "shape = [0, 10]", "sensors.sonar.shape.0: Input should be greater than 0, got 0"),
    "patch_shape_as_string": ("sensors.sonar", 'shape = "10x10"', "sensors.sonar.shape: Input should be a valid tuple, got '10x10' (str)"),
    "negative_noise": ("sensors.sonar", "noise = -1.0", "sensors.sonar.noise: Input should be greater than or equal to 0, got -1.0"),
    "nan_noise": ("sensors.gps", "noise = nan", "sensors.gps.noise: Input should be a finite number"),
    "infinite_speed": ("ship", "speed_kn = inf", "ship.speed_kn (knots): Input should be a finite number"),
    "negative_altitude": ("vehicle", "altitude_m = -5.0", "vehicle.altitude_m (metres): Input should be greater than 0, got -5.0"),
    "zero_time_constant": ("vehicle", "depth_time_constant_s = 0", "vehicle.depth_time_constant_s (seconds): Input should be greater than 0, got 0"),
    "zero_cable": ("cable", "out_m = 0", "cable.out_m (metres): Input should be greater than 0, got 0"),
    "catenary_above_one": ("cable", "catenary_factor = 1.2", "cable.catenary_factor: Input should be less than or equal to 1, got 1.2"),
    "negative_current": ("current", "speed_kn = -0.5", "current.speed_kn (knots): Input should be greater than or equal to 0"),
    "dropout_above_one": ("sensors.altimeter", "dropout_rate = 1.5", "sensors.altimeter.dropout_rate: Input should be less than or equal to 1"),
    "unknown_sonar_mode": ("sensors.sonar", 'mode = "sidescan"', "sensors.sonar.mode: Input should be 'gridded' or 'swath', got 'sidescan'"),
    "one_beam": ("sensors.sonar", "beams = 1", "sensors.sonar.beams: Input should be greater than or equal to 2, got 1"),
    "zero_interval": ("sensors.sonar", "interval_s = 0", "sensors.sonar.interval_s (seconds): Input should be greater than 0"),
    "speed_as_string": ("ship", 'turn_rate_dps = "0.5"', "ship.turn_rate_dps (degrees/s): Input should be a valid number, got '0.5' (str)"),
    "waypoint_as_strings": ("ship", 'waypoints_m = [["0", "0"], [100, 0]]', "ship.waypoints_m.0.0 (metres): Input should be a valid number, got '0' (str)"),
    "terrain_shape_float": ("terrain", "shape = [120.0, 160]", "terrain.shape.0: Input should be a valid integer, got 120.0"),
    "negative_seed": ("terrain", "seed = -1", "terrain.seed: Input should be greater than or equal to 0, got -1"),
    "hurst_above_one": ("terrain", "hurst = 1.5", "terrain.hurst: Input should be less than or equal to 1, got 1.5"),
    "map_noise_negative": ("map", "noise_m = -0.1", "map.noise_m (metres): Input should be greater than or equal to 0"),
    "unknown_field": ("ship", "speed_knots = 3", "[ship] has unknown field(s) ['speed_knots']"),
    "navigation_boolean_as_string": ("navigation", 'use_slant_range = "False"',
                                     "navigation.use_slant_range: Input should be a valid boolean, got 'False' (str)"),
    "navigation_negative_k": ("navigation", "k = -100", "[navigation]: k must be a positive finite number, got -100"),
    "navigation_u_above_one": ("navigation", "u = 2.0", "[navigation]: The adaptive constant u must lie in (0, 1)"),
    "navigation_fraction": ("navigation", "min_valid_fraction = 1.5", "[navigation]: min_valid_fraction must lie in (0, 1], got 1.5"),
    "navigation_offset_of_three": ("navigation", "initial_offset_m = [1, 2, 3]", "navigation.initial_offset_m (metres): Tuple should have at most 2 items"),
    "navigation_unknown": ("navigation", "kay = 3", "[navigation] has unknown field(s) ['kay']"),
    "navigation_int_as_float": ("navigation", "pf_particles = 1000.5", "navigation.pf_particles: Input should be a valid integer, got 1000.5"),
    "navigation_elsewhere_negative": ("navigation", "elsewhere_margin = -0.5",
                                      "[navigation]: elsewhere_margin must be a positive finite number, got -0.5"),
    "navigation_bias_learning_zero": ("navigation", "bias_learning_updates = 0",
                                      "[navigation]: bias_learning_updates must be a whole number of at least 1, got 0"),
}


@pytest.mark.parametrize("table, line, message", BAD_SETTINGS.values(), ids=BAD_SETTINGS.keys())
def test_a_bad_setting_is_refused_naming_its_path(tmp_path, table, line, message):
    path = _with(tmp_path, table, line)
    with pytest.raises(ValueError) as caught:
        load_scenario(path)
    assert str(caught.value).startswith("s.toml: ") and message in str(caught.value), str(caught.value)
    assert "\n" not in str(caught.value)


def test_top_level_types_are_strict(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('duration_s = "600"\n')
    with pytest.raises(ConfigError, match=r"s.toml: duration_s \(seconds\): Input should be a valid number, got '600' \(str\)"):
        load_scenario(path)


def test_an_int_is_a_float_but_a_bool_is_not(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text("duration_s = 60\nrate_hz = 1\n")
    assert load_scenario(path).duration_s == 60.0
    path.write_text("duration_s = true\n")
    with pytest.raises(ConfigError, match="duration_s .seconds.: Input should be a valid number, got True"):
        load_scenario(path)


def test_a_cable_shorter_than_the_depth_is_refused_not_clamped(tmp_path):
    path = _with(tmp_path, "cable", "out_m = 500.0")
    text = path.read_text().replace("out_m = 1200.0\n", "")
    path.write_text(text)
    with pytest.raises(ValueError, match=r"cable.out_m \(500 m\) is shorter than the vehicle's depth \(about 920 m"):
        load_scenario(path)


def test_a_cable_shorter_than_a_deep_trench_is_refused_while_simulating(tmp_path):
    from dataclasses import replace

    from lost.host.scenario import simulate

    scenario = load_scenario(_scenario(tmp_path, ""))
    # Deep enough on average for the 1200 m cable, but relief takes the floor below it.
    scenario = replace(scenario, terrain=replace(scenario.terrain, mean_depth_m=1240.0, relief_m=300.0))
    with pytest.raises(ValueError, match=r"cable.out_m \(1200 m\) is shorter than the vehicle's depth"):
        simulate(scenario)


@pytest.mark.parametrize("line, what", [("rate_hz = 1e6\nduration_s = 36000", "36,000,000,000 records"),
                                        ("[terrain]\nshape = [100000, 100000]", "a 100000 x 100000 floor")])
def test_a_scenario_that_would_need_terabytes_is_refused(tmp_path, line, what):
    path = tmp_path / "big.toml"
    path.write_text(line + "\n")
    with pytest.raises(ValueError, match=rf"would need about [\d,]+ GB of memory .*{what}"):
        load_scenario(path)


def test_sensors_must_be_tables(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text("sensors = 3\n")
    with pytest.raises(ValueError, match="s.toml: \\[sensors\\] must be a table"):
        load_scenario(path)


def test_a_scenario_that_is_not_utf8_is_named(tmp_path):
    path = tmp_path / "s.toml"
    path.write_bytes(b"name = \"\xff\xfe\"\n")
    with pytest.raises(ValueError, match="s.toml is not valid TOML"):
        load_scenario(path)


def test_navigation_parameters_pick_up_every_field_of_the_dataclass():
    from dataclasses import fields

    from lost.host.nav import NavParameters

    for f in fields(NavParameters):
        # A value of the wrong type for every field: each is in the schema, none passes silently.
        with pytest.raises(ConfigError, match=f"navigation.{f.name}"):
            navigation_parameters({f.name: object()})


def test_none_for_an_optional_parameter_is_accepted_and_for_a_required_one_refused():
    assert navigation_parameters({"cross_damping_per_s": None}).cross_damping_per_s is None
    with pytest.raises(ConfigError, match="navigation.k: Input should be a valid number, got None"):
        navigation_parameters({"k": None})


def test_the_navigation_table_of_a_file_without_one_is_named(tmp_path):
    (tmp_path / "c.toml").write_text("[ship]\nspeed_kn = 3\n")
    with pytest.raises(ConfigError, match="c.toml has no \\[navigation\\] table \\(it has: ship\\)"):
        read_navigation_table(tmp_path / "c.toml")


def test_a_missing_config_file_is_named(tmp_path):
    with pytest.raises(ConfigError, match="no configuration file at"):
        read_navigation_table(tmp_path / "absent.toml")
