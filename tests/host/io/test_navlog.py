"""Navigation logs and sonar side files: CSV text in, NavRecords and an honest LoadReport out."""

import numpy as np
import pytest
from pyproj import Transformer

from lost.host.io.navlog import read_navlog

HEADER = "t_s,x_m,y_m,ship_heading_deg,vehicle_depth_m,altitude_m,vel_x_mps,vel_y_mps,slant_range_m,cable_out_m"
ROWS = [
    "0.0,1000.0,2000.0,90.0,300.0,20.0,1.5,0.0,450.0,500.0",
    "1.0,1001.5,2000.0,90.0,301.0,19.5,1.5,0.0,451.0,500.0",
    "2.0,1003.0,2000.0,91.0,302.0,,1.5,0.1,,500.0",
]


def write(tmp_path, text, name="nav.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_documented_layout_reads_every_value(tmp_path):
    records, report = read_navlog(write(tmp_path, "\n".join([HEADER, *ROWS]) + "\n"))
    assert len(records) == 3 and not records.has_truth and records.sonar == ()
    np.testing.assert_array_equal(records.t_s, [0.0, 1.0, 2.0])
    np.testing.assert_array_equal(records.ship_x_m, [1000.0, 1001.5, 1003.0])
    np.testing.assert_array_equal(records.ship_heading_deg, [90.0, 90.0, 91.0])
    np.testing.assert_array_equal(records.vel_y_mps, [0.0, 0.0, 0.1])
    np.testing.assert_array_equal(records.altitude_m, [20.0, 19.5, np.nan])
    np.testing.assert_array_equal(records.slant_range_m, [450.0, 451.0, np.nan])
    assert (report.rows, report.records) == (3, 3)
    assert report.nan_counts["altitude_m"] == 1 and report.nan_counts["slant_range_m"] == 1
    assert report.nan_counts["x_m"] == 0 and report.skipped_rows == () and report.unknown_columns == ()
    assert "altitude_m 1, slant_range_m 1" in report.summary()


def test_nan_text_and_empty_cells_are_both_missing_readings(tmp_path):
    text = "\n".join([HEADER, *ROWS[:2]]) + "\n2.0,NaN,2000.0,91.0,302.0,19.0,1.5,0.1,452.0, \n"
    records, report = read_navlog(write(tmp_path, text))
    assert np.isnan(records.ship_x_m[2]) and np.isnan(records.cable_out_m[2])
    assert report.nan_counts["x_m"] == 1 and report.nan_counts["cable_out_m"] == 1


def test_missing_required_columns_are_named(tmp_path):
    text = "t_s,x_m,y_m,ship_heading_deg,vel_x_mps,vel_y_mps\n0,0,0,0,0,0\n"
    with pytest.raises(ValueError, match="lacks the required column.*vehicle_depth_m, altitude_m, cable_out_m"):
        read_navlog(write(tmp_path, text))


@pytest.mark.parametrize(
    "header, message",
    [
        (HEADER.replace("x_m,y_m,", ""), "ship position is missing.*x_m/y_m or lat/lon"),
        (HEADER.replace("vel_x_mps,vel_y_mps,", ""), "velocity is missing.*speed_mps/course_deg"),
        (HEADER.replace("y_m,", ""), "x_m needs y_m too"),
    ],
)
def test_missing_pairs_are_named(tmp_path, header, message):
    n = header.count(",") + 1
    with pytest.raises(ValueError, match=message):
        read_navlog(write(tmp_path, header + "\n" + ",".join(["1"] * n) + "\n"))


def test_time_going_backwards_names_the_row_and_line(tmp_path):
    text = "# survey 12\n" + "\n".join([HEADER, ROWS[0], ROWS[2], ROWS[1]]) + "\n"
    with pytest.raises(ValueError, match=r"time goes backwards at data row 2 \(line 5\): t_s=1.0 after 2.0"):
        read_navlog(write(tmp_path, text))


def test_repeated_time_is_refused(tmp_path):
    with pytest.raises(ValueError, match="time repeats at data row 1"):
        read_navlog(write(tmp_path, "\n".join([HEADER, ROWS[0], ROWS[0]]) + "\n"))


def test_row_without_time_is_skipped_and_reported(tmp_path):
    text = "\n".join([HEADER, ROWS[0], "," + ROWS[1].split(",", 1)[1], ROWS[2]]) + "\n"
    records, report = read_navlog(write(tmp_path, text))
    assert len(records) == 2 and (report.rows, report.records) == (3, 2)
    assert report.skipped_rows == ((1, "no time (t_s empty or NaN)"),)
    assert "skipped 1 row(s), no time" in report.summary()


def test_non_numeric_cell_is_named(tmp_path):
    text = "\n".join([HEADER, ROWS[0], ROWS[1].replace("19.5", "n/a?")]) + "\n"
    with pytest.raises(ValueError, match=r"altitude_m is not a number at data row 1 \(line 3\): 'n/a\?'"):
        read_navlog(write(tmp_path, text))


def test_unknown_columns_and_absent_slant_range_are_reported(tmp_path):
    header = HEADER.replace(",slant_range_m", "") + ",Water_Temp_C"
    rows = [",".join(r.split(",")[:8] + r.split(",")[9:]) + ",11.5" for r in ROWS]
    records, report = read_navlog(write(tmp_path, "\n".join([header, *rows]) + "\n"))
    assert report.unknown_columns == ("Water_Temp_C",)
    assert np.all(np.isnan(records.slant_range_m))
    assert any("no slant_range_m column" in n for n in report.notes)
    assert "unknown columns, not read: Water_Temp_C" in report.summary()


def test_speed_and_course_become_velocity(tmp_path):
    header = HEADER.replace("vel_x_mps,vel_y_mps", "speed_mps,course_deg")
    rows = ["0,0,0,0,100,10,2.0,90,,300", "1,2,0,0,100,10,2.0,30,,300"]
    records, _ = read_navlog(write(tmp_path, "\n".join([header, *rows]) + "\n"))
    np.testing.assert_allclose(records.vel_x_mps, [2.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(records.vel_y_mps, [0.0, np.sqrt(3.0)], atol=1e-12)


def test_truth_columns_are_read(tmp_path):
    header = HEADER + ",truth_x_m,truth_y_m"
    rows = [r + f",{900 + i},{1900 + i}" for i, r in enumerate(ROWS)]
    records, report = read_navlog(write(tmp_path, "\n".join([header, *rows]) + "\n"))
    assert records.has_truth
    np.testing.assert_array_equal(records.truth_y_m, [1900.0, 1901.0, 1902.0])
    assert not any("truth" in n for n in report.notes)


LAT_LON_HEADER = "t_s,lat,lon,ship_heading_deg,vehicle_depth_m,altitude_m,vel_x_mps,vel_y_mps,cable_out_m,truth_lat,truth_lon"


def test_lat_lon_are_projected_and_turned_to_grid_north(tmp_path):
    # At 5.5 E, 52 N, east of zone 31's central meridian (3 E), true north lies about 2 degrees west of
    # grid north: meridians converge toward the pole.
    rows = ["0,52.0,5.5,0.0,100,10,0.0,1.0,300,51.999,5.5", "1,52.0001,5.5,90.0,100,10,1.0,0.0,300,51.999,5.5001"]
    records, report = read_navlog(write(tmp_path, "\n".join([LAT_LON_HEADER, *rows]) + "\n"), crs="EPSG:32631")
    to_utm = Transformer.from_crs("EPSG:4326", "EPSG:32631", always_xy=True)
    x, y = to_utm.transform([5.5, 5.5], [52.0, 52.0001])
    np.testing.assert_allclose(records.ship_x_m, x, atol=1e-6)
    np.testing.assert_allclose(records.ship_y_m, y, atol=1e-6)
    # True north, as the grid sees it: the bearing from the first fix to the second (due north of it).
    grid_bearing_of_north = np.degrees(np.arctan2(x[1] - x[0], y[1] - y[0]))
    assert -2.5 < grid_bearing_of_north < -1.5
    np.testing.assert_allclose(records.ship_heading_deg, np.mod([grid_bearing_of_north, 90.0 + grid_bearing_of_north], 360), atol=1e-3)
    # A velocity due north (true) has the same grid bearing as true north.
    np.testing.assert_allclose(np.degrees(np.arctan2(records.vel_x_mps[0], records.vel_y_mps[0])), grid_bearing_of_north, atol=1e-3)
    np.testing.assert_allclose(np.hypot(records.vel_x_mps, records.vel_y_mps), [1.0, 1.0])
    tx, ty = to_utm.transform([5.5, 5.5001], [51.999, 51.999])
    np.testing.assert_allclose(records.truth_x_m, tx, atol=1e-6)
    assert any("meridian convergence" in n for n in report.notes)


def test_lat_lon_without_crs_is_refused(tmp_path):
    rows = ["0,52.0,5.5,0.0,100,10,0.0,1.0,300,51.999,5.5"]
    with pytest.raises(ValueError, match="pass crs="):
        read_navlog(write(tmp_path, "\n".join([LAT_LON_HEADER, *rows]) + "\n"))


def test_latitude_out_of_range_is_named(tmp_path):
    rows = ["0,52.0,5.5,0.0,100,10,0.0,1.0,300,51.999,5.5", "1,520.0,5.5,0.0,100,10,0.0,1.0,300,51.999,5.5"]
    with pytest.raises(ValueError, match=r"lat/lon \(520.0, 5.5\) is not a latitude/longitude .* data row 1"):
        read_navlog(write(tmp_path, "\n".join([LAT_LON_HEADER, *rows]) + "\n"), crs="EPSG:32631")


# ------------------------------------------------------------------ sonar side file


def nav_with_times(tmp_path, times):
    rows = [f"{t},{1000 + i},2000,90,300,20,1,0,450,500" for i, t in enumerate(times)]
    return write(tmp_path, "\n".join([HEADER, *rows]) + "\n")


def test_sonar_by_time_is_gridded_per_record_and_every_sounding_accounted(tmp_path):
    nav = nav_with_times(tmp_path, [0.0, 1.0, 2.0, 3.0])
    sonar = write(
        tmp_path,
        "t_s,east_m,north_m,depth_m\n"
        "0.0,0.0,0.0,320\n"      # record 0, centre node (2, 2) of a 5 x 5 patch at 2 m
        "0.0,0.2,-0.3,322\n"     # same node: mean 321
        "0.0004,-4.0,4.0,330\n"  # record 0 within 1 ms: node (4, 0)
        "2.0,0.0,0.0,340\n"      # record 2
        "2.0,50.0,0.0,999\n"     # record 2, beyond the patch
        "1.5,0.0,0.0,999\n"      # no record at 1.5 s
        "3.0,,0.0,999\n"         # no east offset
        "7.0,0.0,0.0,999\n",     # after the last record
        "sonar.csv",
    )
    records, report = read_navlog(nav, sonar=sonar, patch_shape=(5, 5), node_m=2.0)
    assert len(records.sonar) == 4
    patch0 = records.sonar[0].depth_m
    assert patch0[2, 2] == 321.0 and patch0[4, 0] == 330.0 and np.isfinite(patch0).sum() == 2
    assert records.sonar[1] is None and records.sonar[3] is None
    assert records.sonar[2].depth_m[2, 2] == 340.0 and records.sonar[2].node_m == 2.0
    # Each patch carries its soundings (the filters grid them again between nodes), beyond-the-patch ones included.
    east, north, depth, age = records.sonar[2].soundings.arrays()
    assert sorted(depth) == [340.0, 999.0] and np.all(age == 0.0)
    assert (report.soundings, report.soundings_used, report.records_with_sonar) == (8, 4, 2)
    assert (report.soundings_unmatched, report.soundings_without_value, report.soundings_outside_patch) == (2, 1, 1)
    summary = report.summary()
    assert "2 matching no record" in summary and "1 beyond the patch" in summary and "1 without a value" in summary


def test_sonar_by_record_index_counts_soundings_of_skipped_rows(tmp_path):
    nav = write(tmp_path, "\n".join([HEADER, ROWS[0], "," + ROWS[1].split(",", 1)[1], ROWS[2]]) + "\n")
    sonar = write(tmp_path, "record,east_m,north_m,depth_m\n0,0,0,310\n1,0,0,311\n2,1,1,312\n5,0,0,313\n", "s.csv")
    records, report = read_navlog(nav, sonar=sonar, patch_shape=(3, 3), node_m=1.0)
    assert len(records) == 2
    assert records.sonar[0].depth_m[1, 1] == 310.0
    assert records.sonar[1].depth_m[2, 2] == 312.0  # data row 2 is the second kept record
    assert (report.soundings_of_skipped_records, report.soundings_unmatched, report.soundings_used) == (1, 1, 2)


def test_sonar_needs_node_m_and_its_columns(tmp_path):
    nav = nav_with_times(tmp_path, [0.0, 1.0])
    sonar = write(tmp_path, "t_s,east_m,depth_m\n0,0,300\n", "s.csv")
    with pytest.raises(ValueError, match="needs node_m"):
        read_navlog(nav, sonar=sonar)
    with pytest.raises(ValueError, match="lacks the sonar column.*north_m"):
        read_navlog(nav, sonar=sonar, node_m=1.0)
    fractional = write(tmp_path, "record,east_m,north_m,depth_m\n0.5,0,0,300\n", "f.csv")
    with pytest.raises(ValueError, match="whole data-row index"):
        read_navlog(nav, sonar=fractional, node_m=1.0)


def test_missing_or_empty_files_are_named(tmp_path):
    with pytest.raises(FileNotFoundError):
        read_navlog(tmp_path / "absent.csv")
    with pytest.raises(ValueError, match="is empty"):
        read_navlog(write(tmp_path, ""))


def test_short_row_is_missing_readings_and_long_row_an_error(tmp_path):
    records, report = read_navlog(write(tmp_path, "\n".join([HEADER, ROWS[0], "1,1,2,3,4,5,6,7"]) + "\n"))
    assert np.isnan(records.slant_range_m[1]) and np.isnan(records.cable_out_m[1])
    assert report.nan_counts["cable_out_m"] == 1
    with pytest.raises(ValueError, match="not a well-formed CSV"):
        read_navlog(write(tmp_path, "\n".join([HEADER, ROWS[0], ROWS[1] + ",99"]) + "\n"))


def test_written_records_read_back_value_for_value(tmp_path):
    from lost.host.io.navlog import write_navlog
    from lost.host.records import NavRecords, SonarPatch

    rng = np.random.default_rng(3)
    n = 40
    columns = {name: rng.normal(100.0, 30.0, n) for name in (
        "ship_x_m", "ship_y_m", "ship_heading_deg", "vehicle_depth_m", "altitude_m", "vel_x_mps", "vel_y_mps",
        "slant_range_m", "cable_out_m", "truth_x_m", "truth_y_m")}
    columns["altitude_m"][[3, 17]] = np.nan
    columns["slant_range_m"][::4] = np.nan
    patches = []
    for i in range(n):
        depth = rng.normal(500.0, 5.0, (6, 8))
        depth[rng.random((6, 8)) < 0.3] = np.nan
        # Every third patch lies behind the vehicle, as one gathered in real time does.
        centre = (rng.normal(0.0, 30.0), rng.normal(-60.0, 10.0)) if i % 3 == 0 else (0.0, 0.0)
        age = float(rng.uniform(20.0, 50.0)) if i % 3 == 0 else 0.0
        patches.append(None if i % 5 == 0 else SonarPatch(depth_m=depth, node_m=7.5, centre_offset_m=centre, age_s=age))
    records = NavRecords(t_s=np.cumsum(rng.uniform(0.1, 2.0, n)), sonar=tuple(patches), **columns)
    write_navlog(records, tmp_path / "nav.csv", sonar=tmp_path / "sonar.csv")
    back, report = read_navlog(tmp_path / "nav.csv", sonar=tmp_path / "sonar.csv", patch_shape=(6, 8), node_m=7.5)
    for name in ("t_s", *columns):
        np.testing.assert_array_equal(getattr(back, name), getattr(records, name), err_msg=name)
    for mine, theirs in zip(back.sonar, records.sonar):
        assert (mine is None) == (theirs is None)
        if mine is not None:
            np.testing.assert_array_equal(mine.depth_m, theirs.depth_m)
            assert mine.centre_offset_m == theirs.centre_offset_m and mine.age_s == theirs.age_s
    assert report.nan_counts["altitude_m"] == 2 and report.nan_counts["slant_range_m"] == 10
    assert "patch_east_m" not in report.nan_counts and "patch_age_s" not in report.nan_counts  # empty: no missing reading
    assert report.soundings == report.soundings_used and report.records_with_sonar == 32
    with pytest.raises(ValueError, match="pass sonar="):
        write_navlog(records, tmp_path / "again.csv")


UTC_HEADER = HEADER.replace("t_s,", "time_utc,")


def test_iso_times_count_seconds_from_the_first_and_key_the_sonar(tmp_path):
    rows = [
        "2024-05-01T10:00:00Z,1000,2000,90,300,20,1,0,450,500",
        "2024-05-01T12:00:00.5+02:00,1001,2000,90,300,20,1,0,450,500",  # 10:00:00.5 UTC
        ",1002,2000,90,300,20,1,0,450,500",
        "2024-05-01 10:00:02,1003,2000,90,300,20,1,0,450,500",  # no zone: UTC
    ]
    nav = write(tmp_path, "\n".join([UTC_HEADER, *rows]) + "\n")
    sonar = write(tmp_path, "time_utc,east_m,north_m,depth_m\n2024-05-01T10:00:00.5Z,0,0,321\n2024-05-01T10:00:09Z,0,0,1\n", "s.csv")
    records, report = read_navlog(nav, sonar=sonar, patch_shape=(3, 3), node_m=1.0)
    np.testing.assert_array_equal(records.t_s, [0.0, 0.5, 2.0])
    assert report.skipped_rows == ((2, "no time (time_utc empty or NaN)"),)
    assert any("2024-05-01T10:00:00+00:00" in n for n in report.notes)
    assert records.sonar[1].depth_m[1, 1] == 321.0 and report.soundings_unmatched == 1
    by_seconds = write(tmp_path, "t_s,east_m,north_m,depth_m\n0.5,0,0,321\n", "t.csv")
    with pytest.raises(ValueError, match="time_utc or record .t_s cannot be matched"):
        read_navlog(nav, sonar=by_seconds, node_m=1.0)


def test_bad_iso_time_is_named(tmp_path):
    rows = ["2024-05-01T10:00:00Z,1000,2000,90,300,20,1,0,450,500", "yesterday,1001,2000,90,300,20,1,0,450,500"]
    with pytest.raises(ValueError, match=r"time_utc is not an ISO 8601 time at data row 1 \(line 3\): 'yesterday'"):
        read_navlog(write(tmp_path, "\n".join([UTC_HEADER, *rows]) + "\n"))


def test_log_without_any_time_column_is_refused(tmp_path):
    header = HEADER.replace("t_s,", "")
    with pytest.raises(ValueError, match=r"lacks the required column\(s\) t_s \(or time_utc\)"):
        read_navlog(write(tmp_path, header + "\n" + ",".join(["1"] * 9) + "\n"))


def test_sonar_offsets_of_a_lat_lon_log_turn_to_grid_axes(tmp_path):
    rows = ["0,52.0,5.5,0.0,100,10,0.0,1.0,300,51.999,5.5"]
    nav = write(tmp_path, "\n".join([LAT_LON_HEADER, *rows]) + "\n")
    # 100 m true north of the vehicle; grid north is 1.97 degrees east of true north here.
    sonar = write(tmp_path, "record,east_m,north_m,depth_m\n0,0,100,321\n", "s.csv")
    records, _ = read_navlog(nav, sonar=sonar, crs="EPSG:32631", patch_shape=(201, 201), node_m=1.0)
    k, l = np.argwhere(np.isfinite(records.sonar[0].depth_m))[0]
    assert (k - 100, l - 100) == (100, -3)  # 100 m * sin(-1.97 deg) = -3.4 m east


def test_log_with_no_timed_record_is_refused(tmp_path):
    with pytest.raises(ValueError, match="no record with a time .0 data row"):
        read_navlog(write(tmp_path, HEADER + "\n"))
    with pytest.raises(ValueError, match="no record with a time .1 data row"):
        read_navlog(write(tmp_path, HEADER + "\n," + ROWS[0].split(",", 1)[1] + "\n"))


@pytest.mark.parametrize("cell", ["", " ", "NaN", "nan", "Nan", "NULL", "n/a", "NA"])
def test_every_spelling_of_missing_is_a_missing_reading(tmp_path, cell):
    text = "\n".join([HEADER, ROWS[0], ROWS[1].replace("19.5", cell)]) + "\n"
    records, report = read_navlog(write(tmp_path, text))
    assert np.isnan(records.altitude_m[1]) and report.nan_counts["altitude_m"] == 1
    assert records.altitude_m[0] == 20.0


def test_true_false_column_is_not_numbers(tmp_path):
    text = "\n".join([HEADER, ROWS[0].replace("20.0", "True"), ROWS[1].replace("19.5", "False")]) + "\n"
    with pytest.raises(ValueError, match="altitude_m holds true/false"):
        read_navlog(write(tmp_path, text))


def test_patch_centre_from_the_log_or_the_soundings(tmp_path):
    header = HEADER + ",patch_east_m,patch_north_m"
    rows = [ROWS[0] + ",0,-40", ROWS[1] + ",,", ROWS[2] + ",,"]
    nav = write(tmp_path, "\n".join([header, *rows]) + "\n")
    # Record 0's soundings around its logged centre 40 m south; record 1's in a strip 30-50 m south.
    sonar = write(tmp_path, "record,east_m,north_m,depth_m\n0,0,-40,321\n0,10,-50,322\n1,0,-30,5\n1,0,-50,6\n", "s.csv")
    by_vehicle, report = read_navlog(nav, sonar=sonar, patch_shape=(3, 3), node_m=10.0)
    assert by_vehicle.sonar[0].centre_offset_m == (0.0, -40.0)
    assert by_vehicle.sonar[0].depth_m[1, 1] == 321.0 and by_vehicle.sonar[0].depth_m[0, 2] == 322.0
    # Around the vehicle the 3 x 3 patch reaches 15 m south: record 1's soundings all fall beyond it.
    assert by_vehicle.sonar[1] is None and report.soundings_outside_patch == 2
    by_soundings, report = read_navlog(nav, sonar=sonar, patch_shape=(3, 3), node_m=10.0, patch_centre="soundings")
    assert by_soundings.sonar[1].centre_offset_m == (0.0, -40.0) and report.soundings_outside_patch == 0
    np.testing.assert_array_equal(by_soundings.sonar[1].depth_m[:, 1], [6.0, np.nan, 5.0])
    with pytest.raises(ValueError, match="patch_centre must be one of"):
        read_navlog(nav, sonar=sonar, node_m=10.0, patch_centre="ship")
    half = write(tmp_path, "\n".join([HEADER + ",patch_east_m", *(r + ",0" for r in ROWS)]) + "\n", "half.csv")
    with pytest.raises(ValueError, match="patch_east_m needs patch_north_m"):
        read_navlog(half)
