"""Hostile scenarios: tows too short to be one, patches larger than their maps, features off the floor, maps that do not fit
their floors: each refused by name before anything is simulated."""

from __future__ import annotations

import time

import numpy as np
import pytest

from lost.host.config import ConfigError
from lost.host.grid import Grid
from lost.host.scenario import MapSpec, Scenario, SonarSpec, TerrainSpec, load_scenario, simulate
from lost.host.terrain import Feature

from .conftest import TINY_SCENARIO


def _file(tmp_path, text: str):
    path = tmp_path / "s.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("duration, rate, records", [(0.4, 1.0, 0), (1.0, 1.0, 1), (0.3, 5.0, 2)])
def test_a_tow_of_fewer_than_two_records_is_refused_by_name(tmp_path, duration, rate, records):
    text = TINY_SCENARIO.replace("duration_s = 60", f"duration_s = {duration}\nrate_hz = {rate}")
    if records < 2:
        with pytest.raises(ConfigError, match=rf"makes {records} record\(s\); a tow needs at least 2"):
            load_scenario(_file(tmp_path, text))
        return
    grid, nav = simulate(load_scenario(_file(tmp_path, text)))  # two records: the shortest tow there is
    assert nav.t_s.size == 2 and np.isfinite(nav.vel_x_mps).all()


def test_a_patch_larger_than_its_map_is_refused_before_any_floor_is_made(tmp_path):
    # A 4 km x 4 km floor at 5 m would take seconds to make; the refusal takes none.
    text = TINY_SCENARIO.replace("shape = [120, 160]\nnode_m = 10.0", "shape = [800, 800]\nnode_m = 5.0")
    text += "\n[map]\nnode_m = 500.0\n[sensors.sonar]\nshape = [10, 10]\n"
    start = time.perf_counter()
    with pytest.raises(ConfigError, match=r"sensors.sonar.shape \(10 x 10 map nodes\) is larger than the map \(8 x 8 nodes of 500 m\)"):
        load_scenario(_file(tmp_path, text))
    assert time.perf_counter() - start < 1.0
    scenario = Scenario(terrain=TerrainSpec(shape=(40, 400), node_m=10.0), sensors={"sonar": SonarSpec(shape=(50, 10))})
    with pytest.raises(ConfigError, match=r"larger than the map \(40 x 400 nodes\)"):
        simulate(scenario)


def test_a_patch_larger_than_a_map_cut_short_is_refused(tmp_path):
    text = TINY_SCENARIO + "\n[map]\nextent_m = [0.0, 0.0, 50.0, 1190.0]\n"
    with pytest.raises(ConfigError, match=r"larger than the map \(120 x 6 nodes\)"):
        load_scenario(_file(tmp_path, text))


def test_a_patch_larger_than_the_map_of_a_grid_file_is_refused_once_the_file_is_read(tmp_path):
    from lost.host.io import write_npz

    write_npz(Grid(np.full((60, 300), 700.0), 0.0, 0.0, 25.0), tmp_path / "floor.npz")
    text = ('duration_s = 10\n[terrain]\nfile = "floor.npz"\n[map]\nnode_m = 250.0\n'
            "[ship]\nwaypoints_m = [[3000.0, 700.0], [4400.0, 700.0]]\n[cable]\nout_m = 800.0\n")
    scenario = load_scenario(_file(tmp_path, text))  # the file's node is not known until it is read
    with pytest.raises(ConfigError, match=r"larger than the map \(6 x 30 nodes of 250 m\)"):
        simulate(scenario)


def test_a_map_node_not_a_multiple_of_the_floors_or_larger_than_it_is_named():
    with pytest.raises(ValueError, match=r"whole multiple of the floor's node, 10 m \(terrain.node_m\), got 25.0"):
        Scenario(terrain=TerrainSpec(shape=(100, 100)), map=MapSpec(node_m=25.0))
    with pytest.raises(ValueError, match=r"map.node_m \(2000 m\) is larger than the floor"):
        simulate(Scenario(terrain=TerrainSpec(shape=(100, 100)), map=MapSpec(node_m=2000.0), sensors={"sonar": SonarSpec(enabled=False)}))


@pytest.mark.parametrize("feature, where", [
    (Feature(kind="seamount", height_m=100.0, width_m=200.0, at_m=(90000.0, 500.0)), r"a seamount \(at_m = \(90000.0, 500.0\)\)"),
    (Feature(kind="canyon", height_m=50.0, width_m=50.0, path_m=((-9000.0, 0.0), (-8000.0, 500.0))), r"a canyon \(path_m = .*\)"),
])
def test_a_feature_wholly_off_the_floor_is_named_not_silently_dropped(feature, where):
    scenario = Scenario(terrain=TerrainSpec(shape=(100, 200), features=(feature,)), sensors={"sonar": SonarSpec(enabled=False)})
    with pytest.raises(ValueError, match=rf"terrain.features\[0\], {where}, lies wholly off the floor \(east 0 to 1990 m"):
        simulate(scenario)


@pytest.mark.parametrize("table, message", [
    ('[terrain]\n[[terrain.features]]\nkind = "canyon"\nheight_m = "deep"\nwidth_m = 5.0\npath_m = [[0.0, 0.0], [1.0, 1.0]]\n',
     r"terrain.features\[0\].height_m \(metres\)"),
    ('[terrain]\n[[terrain.features]]\nkind = "canyon"\nheight_m = 5.0\nwidth_m = 5.0\npath_m = [[0.0, 0.0], [1.0, 1.0]]\ndepth_m = 3.0\n',
     r"\[terrain.features\[0\]\] has unknown field\(s\) \['depth_m'\]"),
    ('[terrain]\nfeatures = {kind = "canyon"}\n', "terrain.features must be an array of tables"),
    ("[map]\nhole_fraction = 1.0\n", "map.hole_fraction"),
    ('[map]\ngridding = "mode"\n', "map.gridding"),
    ("[map]\nline_spacing_m = 0.0\n", "map.line_spacing_m"),
    ("[terrain]\nrefine_node_m = 5.0\n", "refine a grid file"),
])
def test_bad_floor_and_survey_settings_are_named(tmp_path, table, message):
    with pytest.raises(ConfigError, match=message):
        load_scenario(_file(tmp_path, "[cable]\nout_m = 2000.0\n" + table))


def test_a_grid_file_refined_beyond_memory_is_refused_by_name_before_refining(tmp_path, monkeypatch):
    import lost.host.scenario.floor as floor_module
    from lost.host.io import write_npz
    from lost.host.scenario import scenario_floor

    write_npz(Grid(np.full((200, 300), 700.0), 0.0, 0.0, 100.0), tmp_path / "dem.npz")
    monkeypatch.setattr(floor_module, "refine", lambda *args, **kwargs: pytest.fail("refined before the size was checked"))
    text = '[terrain]\nfile = "dem.npz"\nrefine_node_m = 0.5\n[map]\nnode_m = 100.0\n[cable]\nout_m = 900.0\n'
    with pytest.raises(ConfigError, match=r"refined to terrain.refine_node_m = 0.5 m would be 39,801 x 59,801 nodes, about 114 GB"):
        scenario_floor(load_scenario(_file(tmp_path, text)))


def test_a_survey_that_leaves_no_sounding_is_named_not_a_map_of_holes():
    from lost.host.scenario import survey_map

    floor = Grid(np.full((40, 60), 500.0), 5.0, 0.0, 10.0)  # every node 5 m off the north-running lines at x = 0, 100, ...
    with pytest.raises(ConfigError, match=r"the survey leaves no sounding on the map \(map.swath_width_m = 4.0 m between lines 100.0 m apart"):
        survey_map(floor, MapSpec(node_m=50.0, line_spacing_m=100.0, swath_width_m=4.0), seed=1)
