"""Hostile navigation logs: duplicate columns, other separators, implausible motion, units and zones, wrong maps."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from lost.host.grid import Grid
from lost.host.io.navlog import check_against_map, read_navlog
from lost.host.records import SonarPatch

COLUMNS = ["t_s", "x_m", "y_m", "ship_heading_deg", "vehicle_depth_m", "altitude_m", "vel_x_mps", "vel_y_mps", "cable_out_m"]


def _log(n=60, *, dt=1.0, speed=1.5, x0=500_000.0, y0=5_700_000.0):
    t = np.arange(n) * dt
    return pd.DataFrame({"t_s": t, "x_m": x0 + speed * t, "y_m": np.full(n, y0), "ship_heading_deg": 90.0, "vehicle_depth_m": 300.0,
                         "altitude_m": 50.0, "vel_x_mps": speed, "vel_y_mps": 0.0, "cable_out_m": 600.0})


def _write(tmp_path, table, *, sep=",", name="nav.csv"):
    path = tmp_path / name
    table.to_csv(path, sep=sep, index=False)
    return path


# ------------------------------------------------------------------ columns and separators


@pytest.mark.parametrize("second", ["x_m", "X_M", " x_m ", "X_m"])
def test_a_duplicate_column_name_is_refused_whatever_its_case(tmp_path, second):
    path = tmp_path / "nav.csv"
    text = _log().to_csv(index=False)
    header, body = text.split("\n", 1)
    path.write_text(header + f",{second}\n" + "\n".join(line + ",1" for line in body.splitlines()) + "\n")
    with pytest.raises(ValueError, match=rf"nav.csv: the column name '{second.strip()}' appears twice \(columns 2 and 10"):
        read_navlog(path)


def test_a_duplicate_column_in_the_sonar_file_is_refused(tmp_path):
    nav = _write(tmp_path, _log(5))
    (tmp_path / "s.csv").write_text("t_s,east_m,north_m,depth_m,Depth_M\n0,0,0,300,301\n")
    with pytest.raises(ValueError, match="s.csv: the column name 'Depth_M' appears twice"):
        read_navlog(nav, sonar=tmp_path / "s.csv", node_m=10.0)


@pytest.mark.parametrize("sep", [";", "\t", ","])
def test_semicolon_tab_and_comma_logs_read_the_same(tmp_path, sep):
    records, report = read_navlog(_write(tmp_path, _log(), sep=sep))
    assert len(records) == 60 and report.unknown_columns == ()
    np.testing.assert_allclose(records.ship_x_m, 500_000.0 + 1.5 * np.arange(60))


def test_a_semicolon_sonar_file_reads(tmp_path):
    nav = _write(tmp_path, _log(5))
    (tmp_path / "s.csv").write_text("t_s;east_m;north_m;depth_m\n0;0;0;300\n1;10;0;301\n")
    records, report = read_navlog(nav, sonar=tmp_path / "s.csv", node_m=10.0, patch_shape=(3, 3))
    assert report.soundings_used == 2 and records.sonar[0].depth_m[1, 1] == 300.0


def test_a_binary_file_given_as_a_log_is_named(tmp_path):
    (tmp_path / "nav.csv").write_bytes(b"\x89PNG\r\n\x1a\n\xff\xfe" + bytes(100))
    with pytest.raises(ValueError, match="nav.csv is not UTF-8 text"):
        read_navlog(tmp_path / "nav.csv")


def test_a_log_of_only_comments_is_empty(tmp_path):
    (tmp_path / "nav.csv").write_text("# nothing here\n\n# still nothing\n")
    with pytest.raises(ValueError, match="nav.csv is empty; a header row"):
        read_navlog(tmp_path / "nav.csv")


# ------------------------------------------------------------------ plausibility


def test_positions_jumping_faster_than_any_ship_are_reported(tmp_path):
    table = _log()
    table.loc[30, "x_m"] += 900.0  # a bad fix
    _, report = read_navlog(_write(tmp_path, table))
    assert len(report.warnings) == 1 and "2 ship position step(s) faster than any ship (> 25 m/s), the first at data row 30" in report.warnings[0]
    assert "warning: 2 ship position step(s)" in report.summary()


def test_a_clean_log_has_no_warning(tmp_path):
    assert read_navlog(_write(tmp_path, _log()))[1].warnings == ()


def test_times_in_milliseconds_are_refused(tmp_path):
    table = _log()
    table["t_s"] *= 1000.0
    with pytest.raises(ValueError, match=r"moves 0.001 times as fast .*records are 1000 s apart: t_s looks like milliseconds"):
        read_navlog(_write(tmp_path, table))


def test_positions_in_kilometres_are_refused(tmp_path):
    table = _log()
    table[["x_m", "y_m"]] /= 1000.0
    with pytest.raises(ValueError, match="x_m/y_m look like kilometres"):
        read_navlog(_write(tmp_path, table))


def test_a_velocity_a_thousand_times_too_small_is_refused(tmp_path):
    table = _log()
    table["vel_x_mps"] /= 1000.0  # km/s, say: far off, not a calibration error
    with pytest.raises(ValueError, match="is the velocity in another unit than m/s"):
        read_navlog(_write(tmp_path, table))


def test_a_ship_at_rest_is_not_judged_by_its_speed(tmp_path):
    table = _log(speed=0.0)
    assert len(read_navlog(_write(tmp_path, table))[0]) == 60


def test_mixed_zoned_and_bare_times_are_reported(tmp_path):
    table = _log(5).drop(columns="t_s")
    table.insert(0, "time_utc", ["2024-05-01T10:00:00+01:00", "2024-05-01T09:00:01Z", "2024-05-01 09:00:02", "2024-05-01T09:00:03Z",
                                 "2024-05-01T09:00:04Z"])
    records, report = read_navlog(_write(tmp_path, table))
    assert any("time_utc mixes times with a zone and without one (the first change at data row 2" in w for w in report.warnings)
    assert any("several time zones (+01:00, Z)" in n for n in report.notes)
    np.testing.assert_allclose(records.t_s, [0, 1, 2, 3, 4])


def test_zoned_times_of_one_zone_raise_no_warning(tmp_path):
    table = _log(3).drop(columns="t_s")
    table.insert(0, "time_utc", ["2024-05-01T10:00:00-03:00", "2024-05-01T10:00:01-03:00", "2024-05-01T10:00:02-03:00"])
    _, report = read_navlog(_write(tmp_path, table))
    assert report.warnings == () and not any("several time zones" in n for n in report.notes)


# ------------------------------------------------------------------ records against the map


def _grid(x0=500_000.0, y0=5_699_000.0, node=10.0, shape=(200, 300)):
    return Grid(np.full(shape, 800.0), x0, y0, node, "EPSG:32631")


def test_a_patch_with_another_node_size_than_the_map_is_an_error(tmp_path):
    records, _ = read_navlog(_write(tmp_path, _log(5)))
    from dataclasses import replace

    patches = (SonarPatch(np.full((10, 10), 800.0), node_m=5.0),) + (None,) * 4
    with pytest.raises(ValueError, match="the sonar patches have 5 m nodes but the map has 10 m nodes"):
        check_against_map(replace(records, sonar=patches), _grid())


def test_positions_in_kilometres_are_diagnosed_against_the_map(tmp_path):
    records, _ = read_navlog(_write(tmp_path, _log(5, speed=0.0, x0=501.0, y0=5700.0)))
    with pytest.raises(ValueError, match="no ship position lies within 2000 m of the map.*look like kilometres"):
        check_against_map(records, _grid())


def test_swapped_x_and_y_are_diagnosed(tmp_path):
    records, _ = read_navlog(_write(tmp_path, _log(5, speed=0.0, x0=5_700_500.0, y0=501_000.0)))
    with pytest.raises(ValueError, match="with x and y swapped they would be on it"):
        check_against_map(records, Grid(np.full((200, 300), 800.0), 500_000.0, 5_699_000.0, 10.0, None))


def test_swapped_latitude_and_longitude_are_diagnosed(tmp_path):
    from pyproj import Transformer

    x, y = 501_000.0, 5_700_000.0
    lon, lat = Transformer.from_crs("EPSG:32631", "EPSG:4326", always_xy=True).transform(x, y)
    table = _log(5, speed=0.0).drop(columns=["x_m", "y_m"])
    table.insert(1, "lat", lon)  # swapped columns
    table.insert(2, "lon", lat)
    records, _ = read_navlog(_write(tmp_path, table), crs="EPSG:32631")
    with pytest.raises(ValueError, match="with latitude and longitude swapped they would be on it"):
        check_against_map(records, _grid())


def test_a_log_far_from_its_map_is_an_error_naming_both_extents(tmp_path):
    records, _ = read_navlog(_write(tmp_path, _log(5, x0=100_000.0)))
    with pytest.raises(ValueError, match=r"map x 500000 to 502990.*first position is \(100000.0, 5700000.0\).*right map"):
        check_against_map(records, _grid())


def test_a_log_partly_off_its_map_is_a_warning(tmp_path):
    records, _ = read_navlog(_write(tmp_path, _log(60, speed=20.0, x0=497_000.0)))
    warnings = check_against_map(records, _grid())
    assert warnings and "of the ship positions lie within 2000 m of the map" in warnings[0]


def test_a_recorded_run_with_kilometre_positions_exits_1_naming_it(recorded, tmp_path, run_cli):
    table = pd.read_csv(recorded["nav"])
    table[["x_m", "y_m"]] /= 1000.0
    table.to_csv(recorded["nav"], index=False)
    code, _, err = run_cli("run", "--log", recorded["nav"], "--bathy", recorded["npz"], "--out", tmp_path / "o")
    assert code == 1 and "look like kilometres" in err and not (tmp_path / "o").exists()


def test_a_recorded_run_reports_log_warnings_in_its_summary(recorded, tmp_path, run_cli):
    import json

    table = pd.read_csv(recorded["nav"])
    table.loc[20, "x_m"] += 500.0
    table.to_csv(recorded["nav"], index=False)
    code, _, _ = run_cli("run", "--log", recorded["nav"], "--bathy", recorded["npz"], "--sonar", recorded["sonar"], "--out", tmp_path / "o")
    assert code == 0
    assert any("faster than any ship" in w for w in json.loads((tmp_path / "o" / "summary.json").read_text())["warnings"])


# ------------------------------------------------------------------ physically impossible readings


@pytest.mark.parametrize("column, value, why", [
    ("altitude_m", -3.0, "a negative height above the floor"),
    ("vehicle_depth_m", -20.0, "the vehicle more than 1 m above the surface"),
    ("cable_out_m", -600.0, "a negative cable length"),
])
def test_an_impossible_reading_is_set_to_missing_and_counted(tmp_path, column, value, why):
    table = _log()
    table.loc[[10, 11, 40], column] = value
    records, report = read_navlog(_write(tmp_path, table))
    attribute = {"altitude_m": "altitude_m", "vehicle_depth_m": "vehicle_depth_m", "cable_out_m": "cable_out_m"}[column]
    assert np.isnan(getattr(records, attribute)[[10, 11, 40]]).all() and np.isfinite(getattr(records, attribute)[12])
    assert any(w.startswith(f"3 {column} reading(s) set to missing, {why} (the first at data row 10") for w in report.warnings)


def test_a_negative_slant_range_is_set_to_missing(tmp_path):
    table = _log()
    table["slant_range_m"] = 700.0
    table.loc[5, "slant_range_m"] = -700.0
    records, report = read_navlog(_write(tmp_path, table))
    assert np.isnan(records.slant_range_m[5]) and any("1 slant_range_m reading(s)" in w for w in report.warnings)


def test_a_cable_shorter_than_the_depth_in_every_record_is_refused(tmp_path):
    table = _log()
    table["cable_out_m"] = 0.6  # kilometres
    with pytest.raises(ValueError, match=r"cable_out_m is shorter than vehicle_depth_m in every record \(e.g. 0.6 m of cable at 300 m"):
        read_navlog(_write(tmp_path, table))


def test_a_cable_shorter_than_the_depth_in_some_records_is_reported(tmp_path):
    table = _log()
    table.loc[3:4, "cable_out_m"] = 200.0
    _, report = read_navlog(_write(tmp_path, table))
    assert any("2 record(s) with less cable out than the vehicle's depth, the first at data row 3" in w for w in report.warnings)


def test_a_cable_of_zero_in_every_record_is_a_sonar_on_the_ship_noted_and_some_zeros_still_reported(tmp_path):
    table = _log()
    table["cable_out_m"] = 0.0  # a hull-mounted survey: no cable, no lay-back
    records, report = read_navlog(_write(tmp_path, table))
    assert np.all(records.cable_out_m == 0) and not any("cable" in w for w in report.warnings)
    assert any("cable_out_m is 0 in every record: the sonar is on the ship" in n for n in report.notes)
    table = _log()
    table.loc[3:4, "cable_out_m"] = 0.0  # a towed log with two zeros: readings to doubt, not a hull-mounted sonar
    _, report = read_navlog(_write(tmp_path, table))
    assert any("2 record(s) with less cable out than the vehicle's depth, the first at data row 3" in w for w in report.warnings)
    assert not any("on the ship" in n for n in report.notes)


def test_a_vehicle_deeper_than_any_sea_is_set_to_missing(tmp_path):
    table = _log()
    table.loc[7, "vehicle_depth_m"] = 30000.0  # feet? centimetres? not metres
    records, report = read_navlog(_write(tmp_path, table))
    assert np.isnan(records.vehicle_depth_m[7]) and any("1 vehicle_depth_m reading(s) set to missing, deeper than any sea" in w for w in report.warnings)


def test_a_long_gap_in_time_is_reported(tmp_path):
    table = _log()
    table.loc[30:, "t_s"] += 7200.0  # two hours without a record
    _, report = read_navlog(_write(tmp_path, table))
    assert any("1 gap(s) in time longer than 60 s, the first 7201 s before data row 30" in w for w in report.warnings)


def test_headings_in_radians_are_reported(tmp_path):
    table = _log()
    table["ship_heading_deg"] = np.pi / 2  # east, in radians
    _, report = read_navlog(_write(tmp_path, table))
    assert any("are the headings in radians?" in w for w in report.warnings)


def test_a_ship_heading_north_in_degrees_is_not_taken_for_radians(tmp_path):
    table = _log()
    table[["vel_x_mps", "vel_y_mps", "ship_heading_deg"]] = [0.0, 1.5, 2.0]
    table["x_m"], table["y_m"] = 500_000.0, 5_700_000.0 + 1.5 * table["t_s"]
    assert read_navlog(_write(tmp_path, table))[1].warnings == ()


def test_soundings_no_sea_floor_has_are_counted_not_gridded(tmp_path):
    nav = _write(tmp_path, _log(5))
    (tmp_path / "s.csv").write_text("t_s,east_m,north_m,depth_m\n0,0,0,300\n0,10,0,-500\n0,0,10,32768\n1,0,0,301\n")
    records, report = read_navlog(nav, sonar=tmp_path / "s.csv", node_m=10.0, patch_shape=(3, 3))
    assert report.soundings_implausible == 2 and report.soundings_used == 2 and report.soundings_without_value == 0
    assert np.isnan(records.sonar[0].depth_m[1, 2]) and "not used: 2 with a depth no sea floor has" in report.summary()


def test_a_log_whose_second_half_is_in_kilometres_is_refused_at_the_change(tmp_path):
    table = _log()
    table.loc[30:, ["x_m", "y_m"]] /= 1000.0
    table.loc[30:, "x_m"] += table.loc[29, "x_m"]  # kilometres onward from where the metres stopped
    with pytest.raises(ValueError, match=r"nav.csv: positions move 0.001 times as fast .* from about data row 3\d"):
        read_navlog(_write(tmp_path, table))


def test_a_log_whose_second_half_is_in_feet_is_refused(tmp_path):
    table = _log()
    table.loc[30:, "x_m"] = table.loc[30, "x_m"] + (table.loc[30:, "x_m"] - table.loc[30, "x_m"]) / 0.3048
    with pytest.raises(ValueError, match=r"positions move 3.28 times as fast .* a change of unit part-way"):
        read_navlog(_write(tmp_path, table))


def test_a_bare_clock_jumping_by_two_hours_is_refused_as_a_zone_change(tmp_path):
    table = _log().drop(columns="t_s")
    stamps = pd.Timestamp("2024-05-01T10:00:00") + pd.to_timedelta(np.arange(60), unit="s")
    stamps = stamps.where(np.arange(60) < 30, stamps + pd.Timedelta(hours=2))
    table.insert(0, "time_utc", stamps.strftime("%Y-%m-%dT%H:%M:%S"))
    with pytest.raises(ValueError, match=r"nav.csv: time jumps by 7201 s \(2 h and \+1 s\) before data row 30.*a change of time zone"):
        read_navlog(_write(tmp_path, table))
