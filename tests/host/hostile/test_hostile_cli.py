"""Hostile command lines: every error a user can cause is one line naming the file or field, with the documented exit code."""

from __future__ import annotations

import json

import numpy as np
import pytest

from lost.host.cli import EXIT_ERROR, EXIT_USAGE, main

from .test_hostile_config import BAD_SETTINGS, _with
from .test_hostile_grids import _cut, _depths, _geotiff, _gmt_native, _land_and_sea, _netcdf


def _argparse_exit(argv, capsys):
    with pytest.raises(SystemExit) as caught:
        main(argv)
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return caught.value.code, err


@pytest.mark.parametrize("argv, message", [
    (["run", "x.toml", "--node-m", "-5"], "expected a positive number of metres, got '-5'"),
    (["run", "x.toml", "--node-m", "nan"], "expected a positive number of metres, got 'nan'"),
    (["run", "x.toml", "--positive", "sideways"], "invalid choice: 'sideways'"),
    (["run", "x.toml", "--patch-shape", "10.5x10"], "expected ROWSxCOLS with two positive integers"),
    (["run", "x.toml", "--set", "novalue"], "expected NAME=VALUE, got 'novalue'"),
    (["frobnicate"], "invalid choice: 'frobnicate'"),
    (["correlate", "m.npz", "p.npy", "--exclusion-radius", "-3"], "argument --exclusion-radius: expected a whole number of nodes, 0 or more, got '-3'"),
    (["correlate", "m.npz", "p.npy", "--exclusion-radius", "2.5"], "argument --exclusion-radius: expected a whole number of nodes"),
    (["correlate", "m.npz", "p.npy", "--lsb-m", "0"], "argument --lsb-m: expected a positive number of metres, got '0'"),
], ids=["negative_node", "nan_node", "bad_positive", "fractional_shape", "set_without_value", "unknown_command", "negative_exclusion",
        "fractional_exclusion", "zero_lsb"])
def test_bad_options_exit_2_through_argparse(argv, message, capsys):
    code, err = _argparse_exit(argv, capsys)
    assert code == EXIT_USAGE and message in err


def test_every_option_of_correlate_and_run_says_what_it_is(capsys):
    """`--help` names each option's meaning, the backends among them, not only its choices."""
    helps = {}
    for command in ("correlate", "run", "demo"):
        with pytest.raises(SystemExit):
            main([command, "--help"])
        helps[command] = " ".join(capsys.readouterr().out.split())
        assert "rtl (the device co-simulated on Verilator)" in helps[command]
    assert "--exclusion-radius NODES" in helps["correlate"] and "--lsb-m METRES" in helps["correlate"]
    assert "(default runs/demo, replaced at each run)" in helps["demo"] and "(default runs/NAME)" in helps["run"]


@pytest.mark.parametrize("extra, message", [
    (["--set", "k=true"], "--set k: Input should be a valid number, got True"),
    (["--set", "use_slant_range=yes"], "--set use_slant_range: Input should be a valid boolean, got 'yes' (str)"),
    (["--set", "u=-1"], "--set: The adaptive constant u must lie in (0, 1)"),
    (["--set", "kay=3"], "--set names no navigation parameter: kay"),
    (["--node-m", "20"], "--node-m apply to a recorded tow"),
    (["--bathy", "map.nc"], "give either a scenario or --log and --bathy, not both"),
], ids=["set_bool_for_float", "set_word_for_bool", "set_out_of_range", "set_unknown", "grid_option_with_scenario", "scenario_and_bathy"])
def test_usage_errors_of_a_scenario_run_exit_2_in_one_line(tiny, tmp_path, run_cli, extra, message):
    code, _, err = run_cli("run", tiny, "--out", tmp_path / "o", *extra)
    assert code == EXIT_USAGE and message in err
    assert not (tmp_path / "o").exists()


def test_a_missing_scenario_file_exits_1_naming_it(tmp_path, run_cli):
    code, _, err = run_cli("run", tmp_path / "absent.toml", "--out", tmp_path / "o")
    assert code == EXIT_ERROR and "no scenario file at" in err and "absent.toml" in err


def test_an_unknown_builtin_scenario_exits_1(run_cli):
    code, _, err = run_cli("run", "atlantis")
    assert code == EXIT_ERROR and "no built-in scenario 'atlantis'" in err


def test_a_scenario_with_a_bad_value_exits_1_naming_file_and_path(tmp_path, run_cli):
    (tmp_path / "bad.toml").write_text('[vehicle]\nhas_velocity_sensor = "false"\n')
    code, _, err = run_cli("run", tmp_path / "bad.toml", "--out", tmp_path / "o")
    assert code == EXIT_ERROR and "bad.toml: vehicle.has_velocity_sensor: Input should be a valid boolean" in err


def test_a_missing_log_exits_1_naming_it(recorded, tmp_path, run_cli):
    code, _, err = run_cli("run", "--log", tmp_path / "gone.csv", "--bathy", recorded["npz"], "--out", tmp_path / "o")
    assert code == EXIT_ERROR and "gone.csv" in err


def test_a_missing_grid_exits_1_naming_it(recorded, tmp_path, run_cli):
    code, _, err = run_cli("run", "--log", recorded["nav"], "--bathy", tmp_path / "gone.nc", "--out", tmp_path / "o")
    assert code == EXIT_ERROR and "no bathymetry file at" in err and "gone.nc" in err


def test_a_truncated_grid_exits_1_and_writes_nothing(recorded, tmp_path, run_cli):
    data = recorded["nc"].read_bytes()
    recorded["nc"].write_bytes(data[: len(data) // 2])
    code, _, err = run_cli("run", "--log", recorded["nav"], "--bathy", recorded["nc"], "--out", tmp_path / "o")
    assert code == EXIT_ERROR and "map.nc" in err and ("truncated" in err) and not (tmp_path / "o").exists()


def test_config_gives_a_recorded_tow_the_scenarios_navigation(recorded, tiny, tmp_path, run_cli):
    (tmp_path / "nav.toml").write_text("[navigation]\nk = 250.0\nsearch_half_width_m = 120.0\n")
    args = ["run", "--log", recorded["nav"], "--bathy", recorded["npz"], "--sonar", recorded["sonar"]]
    assert run_cli(*args, "--config", tmp_path / "nav.toml", "--set", "k=300", "--out", tmp_path / "a")[0] == 0
    parameters = json.loads((tmp_path / "a" / "summary.json").read_text())["parameters"]
    assert parameters["k"] == 300.0 and parameters["search_half_width_m"] == 120.0  # --set over --config
    assert run_cli(*args, "--config", tiny, "--out", tmp_path / "b")[0] == 0  # a whole scenario file: its [navigation]
    assert json.loads((tmp_path / "b" / "summary.json").read_text())["parameters"]["search_half_width_m"] == 100.0


def test_a_config_with_a_bad_value_exits_1_naming_file_and_field(recorded, tmp_path, run_cli):
    (tmp_path / "nav.toml").write_text('[navigation]\nuse_slant_range = "false"\n')
    code, _, err = run_cli("run", "--log", recorded["nav"], "--bathy", recorded["npz"], "--config", tmp_path / "nav.toml", "--out", tmp_path / "o")
    assert code == EXIT_ERROR and "nav.toml [navigation].use_slant_range: Input should be a valid boolean, got 'false' (str)" in err


def test_a_config_without_a_navigation_table_exits_1(recorded, tmp_path, run_cli):
    (tmp_path / "nav.toml").write_text("k = 3\n")
    code, _, err = run_cli("run", "--log", recorded["nav"], "--bathy", recorded["npz"], "--config", tmp_path / "nav.toml", "--out", tmp_path / "o")
    assert code == EXIT_ERROR and "has no [navigation] table" in err


def test_node_m_regrids_map_and_sonar_alike(recorded, tmp_path, run_cli):
    args = ["run", "--log", recorded["nav"], "--bathy", recorded["npz"], "--sonar", recorded["sonar"], "--node-m", "20", "--out", tmp_path / "o"]
    code, printed, _ = run_cli(*args)
    assert code == 0 and json.loads((tmp_path / "o" / "summary.json").read_text())["records"] == 60


def test_a_bad_patch_file_for_correlate_exits_1(recorded, tmp_path, run_cli):
    (tmp_path / "patch.npy").write_bytes(b"not numpy")
    code, _, err = run_cli("correlate", recorded["npz"], tmp_path / "patch.npy")
    assert code == EXIT_ERROR and err.startswith("lost correlate: ")


# Every bad setting of the settings suite, through the command line: exit 1, one line naming file and path.
@pytest.mark.parametrize("table, line, message", BAD_SETTINGS.values(), ids=BAD_SETTINGS.keys())
def test_every_bad_setting_is_one_line_from_the_command_line(tmp_path, run_cli, table, line, message):
    code, _, err = run_cli("run", _with(tmp_path, table, line), "--out", tmp_path / "o")
    assert code == EXIT_ERROR and err.startswith("lost run: s.toml: ") and message in err
    assert not (tmp_path / "o").exists()


def _bad_grids(tmp_path):
    band = -_depths()
    band[3, 3] = -32768
    return {
        "truncated_classic": (_cut(_netcdf(tmp_path / "a.grd", _depths()), 0.5), "a.grd is truncated"),
        "truncated_netcdf4": (_cut(_netcdf(tmp_path / "b.nc", _depths(), fmt="NETCDF4"), 0.5), "b.nc is truncated"),
        "truncated_geotiff": (_cut(_geotiff(tmp_path / "c.tif", _depths(), dtype="float32"), 0.5), "c.tif is truncated"),
        "untagged_nodata": (_geotiff(tmp_path / "d.tif", band, dtype="int16"), "pass nodata=-32768 (lost run --nodata)"),
        "mostly_land": (_netcdf(tmp_path / "e.nc", _land_and_sea()), "--positive on the command line"),
        "gmt_native_int16": (_gmt_native(tmp_path / "f.grd", np.round(_depths()), code="bs"), "gmt grdconvert"),
        "surfer": (_write(tmp_path / "g.grd", b"DSBB" + bytes(900)), "Surfer 6 binary grid"),
        "not_a_grid": (_write(tmp_path / "h.nc", b"hello"), "h.nc has a .nc name but its content is not nc"),
        "unknown_suffix": (_write(tmp_path / "i.dem", b"hello"), "unknown grid format '.dem'"),
        "empty_xyz": (_write(tmp_path / "j.xyz", b"# nothing\n"), "j.xyz holds no data lines"),
    }


def _write(path, data):
    path.write_bytes(data)
    return path


GRID_CASES = ["truncated_classic", "truncated_netcdf4", "truncated_geotiff", "untagged_nodata", "mostly_land", "gmt_native_int16", "surfer",
              "not_a_grid", "unknown_suffix", "empty_xyz"]


@pytest.mark.parametrize("case", GRID_CASES)
def test_every_bad_grid_is_one_line_from_the_command_line(recorded, tmp_path, run_cli, case):
    path, message = _bad_grids(tmp_path)[case]
    code, _, err = run_cli("run", "--log", recorded["nav"], "--bathy", path, "--out", tmp_path / "o")
    assert code == EXIT_ERROR and message in err and "nothing was written to" in err


def test_a_folder_named_as_a_shipped_scenario_does_not_hide_it(tmp_path, monkeypatch, run_cli):
    """`lost run short --out short` leaves a folder `short`; the next `lost run short` there still means the shipped one
    (the scenario is read, then the unknown --set is refused: exit 2, not 'Is a directory')."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "short").mkdir()
    code, _, err = run_cli("run", "short", "--set", "kay=3", "--out", tmp_path / "o")
    assert code == EXIT_USAGE and "--set names no navigation parameter: kay" in err
    (tmp_path / "usbl_turns").mkdir()
    from lost.host.usbl.scenario import load_usbl_scenario

    assert load_usbl_scenario("usbl_turns").name == "usbl_turns"


def test_the_patent_pipelines_counts_are_printed_only_when_it_ran(tiny, tmp_path, run_cli):
    code, out, _ = run_cli("run", tiny, "--estimator", "pmf", "--out", tmp_path / "pmf")
    assert code == 0 and "records without an MLE" not in out
    code, out, _ = run_cli("run", tiny, "--out", tmp_path / "all")
    assert code == 0 and "LOST: off-map records " in out and ", records without an MLE " in out


def test_track_and_replay_take_the_shipped_scenario_beside_a_folder_of_its_name(tmp_path, monkeypatch, run_cli):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "one_diver").mkdir()
    code, _, err = run_cli("track", "one_diver", "--set", "kay=3", "--out", tmp_path / "o")
    assert code == EXIT_USAGE and "names no tracker parameter: kay" in err
    code, _, err = run_cli("track", "one_diver", "--set", "confirm_existence=abc", "--out", tmp_path / "o")
    assert code == EXIT_USAGE and "confirm_existence: Input should be a valid number" in err and "tracker." not in err
    (tmp_path / "short_exact_map").mkdir()
    code, out, _ = run_cli("replay", "short_exact_map", "--to", "127.0.0.1:9", "--speed", "0")
    assert code == 0 and "sent 600 pings" in out
