"""The USBL in the tow simulator and the records: [sensors.usbl], the optional navlog columns, their errors."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
from scipy.stats import chi2

from lost.host.io.navlog import read_navlog, write_navlog
from lost.host.records import NavRecords
from lost.host.scenario import builtin_scenario_path, load_scenario, simulate, usbl_profile
from lost.host.usbl.rays import slant_range_from_travel_time

# Four minutes at 1 Hz over a small deep floor: a reply every 2 s.
SMALL = """
name = "small_usbl"
seed = 7
duration_s = 240
[terrain]
shape = [150, 300]
mean_depth_m = 1200.0
[ship]
waypoints_m = [[1700.0, 700.0], [2900.0, 700.0]]
[cable]
out_m = 1800.0
[sensors.gps]
noise = 1.0
[sensors.heading]
noise = 0.1
[sensors.depth]
noise = 0.1
[sensors.sonar]
enabled = false
[sensors.usbl]
enabled = true
{usbl}
"""


def small(tmp_path, usbl: str = "dropout_rate = 0.0") -> tuple:
    path = tmp_path / "small.toml"
    path.write_text(SMALL.format(usbl=usbl))
    scenario = load_scenario(path)
    return scenario, *simulate(scenario)


@pytest.fixture(scope="module", name="clean")
def clean_run(tmp_path_factory):
    return small(tmp_path_factory.mktemp("usbl"))


def test_a_reply_every_interval_and_its_travel_time_is_the_ray_to_the_true_vehicle(clean):
    scenario, _, records = clean
    pinged = np.flatnonzero(np.isfinite(records.usbl_travel_time_s))
    np.testing.assert_array_equal(pinged, np.arange(0, len(records), 2))
    profile = usbl_profile(scenario)
    truth_depth = records.vehicle_depth_m  # recorded with 0.1 m noise: the range error it makes is tiny
    for k in pinged[::20]:
        slant, horizontal = slant_range_from_travel_time(profile, records.usbl_travel_time_s[k], 5.0, truth_depth[k])
        true_horizontal = math.hypot(records.truth_x_m[k] - records.ship_x_m[k], records.truth_y_m[k] - records.ship_y_m[k])
        # GPS noise 1 m moves the recorded ship; travel-time noise is 3 cm; depth noise 0.1 m.
        assert abs(horizontal - true_horizontal) < 5.0
        assert slant > horizontal


def test_the_fixes_scatter_as_their_covariance_says(clean):
    _, _, records = clean
    fixes = [records.usbl_fix(k) for k in range(len(records))]
    used = [k for k, fix in enumerate(fixes) if fix is not None]
    assert len(used) == 120
    nees = np.array([d @ np.linalg.solve(fixes[k][1], d) for k in used
                     for d in [fixes[k][0] - (records.truth_x_m[k], records.truth_y_m[k])]])
    # 2 degrees of freedom: the mean is 2 (standard error 0.18 over 120 draws); outside [1.2, 2.8] the covariance is wrong.
    assert 1.2 < nees.mean() < 2.8
    assert np.mean(nees < chi2.ppf(0.95, 2)) > 0.88


def test_dropouts_grow_with_range_and_outliers_are_late(tmp_path):
    _, _, records = small(tmp_path, "dropout_rate = 0.1\ndropout_rate_per_km = 0.2\noutlier_rate = 0.5\noutlier_delay_s = 0.05")
    replies = np.isfinite(records.usbl_travel_time_s[::2]).mean()
    # About 0.1 + 0.2 * 1.7 km = 44 % lost.
    assert 0.4 < replies < 0.7


def test_without_a_usbl_nothing_else_changes(tmp_path):
    path = builtin_scenario_path("short")
    scenario = load_scenario(path)
    _, plain = simulate(scenario)
    assert not plain.has_usbl
    sensors = {**scenario.sensors, "usbl": replace(scenario.sensors["usbl"], enabled=True, cast="scs_june", transducer_depth_m=5.0)}
    _, with_usbl = simulate(replace(scenario, sensors=sensors))
    assert with_usbl.has_usbl
    for name in ("ship_x_m", "vehicle_depth_m", "altitude_m", "vel_x_mps", "slant_range_m", "truth_x_m"):
        np.testing.assert_array_equal(getattr(plain, name), getattr(with_usbl, name))


@pytest.mark.parametrize(("text", "message"), [
    ("dropout_rate = 1.5", r"sensors.usbl.dropout_rate: Input should be less than or equal to 1"),
    ("interval_s = 0", r"sensors.usbl.interval_s \(seconds\): Input should be greater than 0"),
    ("ping_s = 2", r"\[sensors.usbl\] has unknown field\(s\) \['ping_s'\]"),
    ("transducer_depth_m = \"5\"", r"sensors.usbl.transducer_depth_m \(metres\): Input should be a valid number"),
])
def test_the_usbl_table_is_strict(tmp_path, text, message):
    path = tmp_path / "bad.toml"
    path.write_text(SMALL.format(usbl=text))
    with pytest.raises(ValueError, match=message):
        load_scenario(path)


def test_a_cast_that_stops_above_the_vehicle_is_refused(tmp_path):
    (tmp_path / "shallow.csv").write_text("# latitude = 18\n# longitude = 115\ndepth_m,sound_speed_m_s\n0,1540\n500,1500\n")
    with pytest.raises(ValueError, match=r"sensors.usbl.cast 'shallow.csv' spans 0-500 m but the vehicle goes from"):
        small(tmp_path, 'cast = "shallow.csv"')


def test_the_navlog_keeps_the_usbl_columns_value_for_value(clean, tmp_path):
    _, _, records = clean
    write_navlog(records, tmp_path / "nav.csv")
    back, report = read_navlog(tmp_path / "nav.csv")
    for name in ("usbl_travel_time_s", "usbl_x_m", "usbl_y_m", "usbl_sxx", "usbl_syy", "usbl_sxy"):
        np.testing.assert_array_equal(getattr(back, name), getattr(records, name))
    assert report.unknown_columns == () and "120 USBL fix(es) read" in report.notes


# ------------------------------------------------------------------ hostile logs


def _log(n=6, **extra):
    t = np.arange(n, dtype=float)
    table = pd.DataFrame({"t_s": t, "x_m": 1000.0 + 1.5 * t, "y_m": 2000.0, "ship_heading_deg": 90.0, "vehicle_depth_m": 1000.0,
                          "altitude_m": 50.0, "vel_x_mps": 1.5, "vel_y_mps": 0.0, "cable_out_m": 1800.0})
    fix = {"usbl_x_m": -200.0, "usbl_y_m": 2000.0, "usbl_sxx": 25.0, "usbl_syy": 100.0, "usbl_sxy": 10.0}
    return table.assign(**{**fix, **extra})


def _write(tmp_path, table):
    path = tmp_path / "nav.csv"
    table.to_csv(path, index=False)
    return path


def test_a_fix_without_all_its_columns_is_refused(tmp_path):
    with pytest.raises(ValueError, match=r"nav.csv has the USBL fix column\(s\) usbl_x_m, usbl_y_m, usbl_sxx, usbl_syy but lacks usbl_sxy"):
        read_navlog(_write(tmp_path, _log().drop(columns="usbl_sxy")))


def test_a_row_with_part_of_a_fix_is_refused_by_row_and_line(tmp_path):
    table = _log()
    table.loc[3, "usbl_syy"] = np.nan
    with pytest.raises(ValueError, match=r"the USBL fix at data row 3 \(line 5\) lacks usbl_syy \(1 such row\(s\)\)"):
        read_navlog(_write(tmp_path, table))


@pytest.mark.parametrize(("column", "value"), [("usbl_sxx", -4.0), ("usbl_syy", 0.0), ("usbl_sxy", 60.0)])
def test_a_covariance_that_is_none_is_refused(tmp_path, column, value):
    table = _log()
    table.loc[2, column] = value
    with pytest.raises(ValueError, match=r"the USBL fix at data row 2 \(line 4\) has no covariance"):
        read_navlog(_write(tmp_path, table))


def test_impossible_travel_times_are_set_missing_and_counted(tmp_path):
    table = _log(usbl_travel_time_s=[1.0, -1.0, 0.0, 1.2, 30.0, 1.1])
    records, report = read_navlog(_write(tmp_path, table))
    np.testing.assert_array_equal(np.isnan(records.usbl_travel_time_s), [False, True, True, False, True, False])
    assert any("2 usbl_travel_time_s reading(s) set to missing, a travel time not after the ping" in w for w in report.warnings)
    assert any("1 usbl_travel_time_s reading(s) set to missing, longer than 10 s" in w for w in report.warnings)


def test_a_fix_in_a_lat_lon_log_is_refused(tmp_path):
    table = _log().drop(columns=["x_m", "y_m"]).assign(lat=50.0, lon=1.0)
    with pytest.raises(ValueError, match="gives ship positions as lat/lon but the USBL fix as usbl_x_m/usbl_y_m"):
        read_navlog(_write(tmp_path, table), crs="EPSG:32631")


def test_records_refuse_a_partial_fix_and_a_bad_covariance():
    n = 3
    z = np.zeros(n)
    base = dict(t_s=np.arange(n, dtype=float), ship_x_m=z, ship_y_m=z, ship_heading_deg=z, vehicle_depth_m=z, altitude_m=z, vel_x_mps=z,
                vel_y_mps=z, slant_range_m=z, cable_out_m=z)
    ones = np.ones(n)
    with pytest.raises(ValueError, match="the USBL fix of record 0 lacks usbl_sxy"):
        NavRecords(**base, usbl_x_m=ones, usbl_y_m=ones, usbl_sxx=ones, usbl_syy=ones)
    with pytest.raises(ValueError, match="the USBL fix of record 0 has no covariance"):
        NavRecords(**base, usbl_x_m=ones, usbl_y_m=ones, usbl_sxx=ones, usbl_syy=ones, usbl_sxy=2 * ones)
    with pytest.raises(ValueError, match="usbl_travel_time_s must be positive seconds, got -1.0 at record 0"):
        NavRecords(**base, usbl_travel_time_s=-ones)


# ------------------------------------------------------------------ the INS+USBL scenario loader, strict


@pytest.mark.parametrize(("body", "message"), [
    ('[tow]\nspeed_m_s = "2"\n', r"s.toml: tow.speed_m_s \(m/s\): Input should be a valid number, got '2' \(str\)"),
    ("seed = 2.5\n", r"s.toml: seed: Input should be a valid integer, got 2.5"),
    ("[usbl]\nlever_arm_m = [0, 0]\n", r"s.toml: usbl.lever_arm_m.2 \(metres\): Field required"),
    ("duration_s = nan\n", r"s.toml: duration_s \(seconds\): Input should be a finite number"),
    ("[faults]\ndropout_rate = true\n", r"s.toml: faults.dropout_rate: Input should be a valid number, got True \(bool\)"),
    ("folder = \"/tmp\"\n", r"s.toml: unknown key\(s\) \['folder'\]"),
    ("[imu]\ngyro_bias = 0.1\n", r"s.toml \[imu\]: unknown key\(s\) \['gyro_bias'\]"),
])
def test_the_usbl_scenario_loader_is_strict(tmp_path, body, message):
    from lost.host.usbl.scenario import load_usbl_scenario

    path = tmp_path / "s.toml"
    path.write_text('name = "x"\n' + body)
    with pytest.raises(ValueError, match=message):
        load_usbl_scenario(path)


def test_the_usbl_scenario_loader_reads_the_shipped_one_as_before():
    from lost.host.usbl.scenario import load_usbl_scenario

    scenario = load_usbl_scenario("usbl_turns")
    assert scenario.tow.course[1] == (600.0, 0.3) and scenario.usbl.lever_arm_m == (0.0, 0.0, 20.0)
    assert scenario.faults.bad_delay_s == (0.015, 0.1) and scenario.folder is not None and scenario.folder.name == "scenarios"
