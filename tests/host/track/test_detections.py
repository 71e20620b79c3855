"""The detection log: the documented CSV layout in, pings and an honest report out, named errors for bad input."""

import numpy as np
import pytest

from lost.host.track import Ping, Sonar, polar_to_world, read_detections, world_to_polar, write_detections

HEADER = "ping,t_s,platform_x_m,platform_y_m,heading_deg,range_m,bearing_deg,strength_db"
ROWS = [
    "0,0.0,100.0,200.0,90.0,450.0,-10.0,12.5",
    "0,0.0,100.0,200.0,90.0,300.0,20.0,",
    "1,1.3,100.5,200.0,90.0,,,",
    "2,2.6,101.0,200.0,91.0,449.0,-9.5,13.0",
]


def write(tmp_path, lines, name="det.csv"):
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path


def test_documented_layout_reads_every_value(tmp_path):
    pings, report = read_detections(write(tmp_path, [HEADER, *ROWS]))
    assert [p.index for p in pings] == [0, 1, 2] and [p.detections for p in pings] == [2, 0, 1]
    np.testing.assert_array_equal(pings[0].range_m, [450.0, 300.0])
    np.testing.assert_array_equal(pings[0].bearing_deg, [-10.0, 20.0])
    np.testing.assert_array_equal(pings[0].strength_db, [12.5, np.nan])
    np.testing.assert_array_equal(pings[2].platform_xy, [101.0, 200.0])
    assert pings[1].t_s == 1.3 and pings[2].heading_deg == 91.0
    assert (report.rows, report.pings, report.detections, report.dropped) == (4, 3, 3, 0)


def test_written_log_reads_back_value_for_value(tmp_path):
    pings, _ = read_detections(write(tmp_path, [HEADER, *ROWS]))
    again, _ = read_detections(write_detections(tmp_path / "again.csv", pings))
    assert len(again) == len(pings) == 3
    for a, b in zip(pings, again):
        assert (a.index, a.t_s, a.heading_deg) == (b.index, b.t_s, b.heading_deg)
        for name in ("platform_xy", "range_m", "bearing_deg", "strength_db"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_detections_outside_the_sector_are_dropped_and_counted_by_reason(tmp_path):
    rows = [*ROWS, "3,3.9,101.5,200.0,91.0,520.0,0.0,", "3,3.9,101.5,200.0,91.0,200.0,46.0,",
            "3,3.9,101.5,200.0,91.0,200.0,-60.0,", "3,3.9,101.5,200.0,91.0,-1.0,0.0,", "3,3.9,101.5,200.0,91.0,10.0,45.0,"]
    pings, report = read_detections(write(tmp_path, [HEADER, *rows]))
    assert (report.beyond_range, report.outside_field_of_view, report.negative_range) == (1, 2, 1)
    assert pings[3].detections == 1 and report.detections == 4
    assert "dropped 2 detection(s) outside the field of view" in report.summary()
    _, narrow = read_detections(write(tmp_path, [HEADER, *rows], "n.csv"), sonar=Sonar(half_fov_deg=15.0, max_range_m=600.0))
    assert (narrow.beyond_range, narrow.outside_field_of_view, narrow.negative_range) == (0, 4, 1)


def test_header_is_case_and_space_blind_and_unknown_columns_are_reported(tmp_path):
    header = " PING , T_s,platform_x_m,platform_y_m,heading_deg,range_m,bearing_deg,snr"
    _, report = read_detections(write(tmp_path, ["# a comment", header, "0,0,0,0,0,10,0,3"]))
    assert report.unknown_columns == ("snr",) and report.detections == 1


@pytest.mark.parametrize(
    "lines, message",
    [
        (["ping,t_s,platform_x_m,heading_deg,range_m,bearing_deg", "0,0,0,0,1,0"],
         r"lacks the required column.*platform_x_m/platform_y_m \(or platform_lat/platform_lon\)"),
        ([HEADER, "0,0.0,100.0,200.0,90.0,abc,0.0,"], r"line 2: range_m is not a number: 'abc'"),
        ([HEADER, "0,0.0,100.0,,90.0,10.0,0.0,"], r"line 2: platform_y_m is not a number: ''"),
        ([HEADER, "0,0.0,100.0,200.0,90.0,10.0,,"], r"line 2: bearing_deg is not a number"),
        ([HEADER, "0,0.0,100.0,200.0,90.0,inf,0.0,"], r"range_m must be a finite number"),
        ([HEADER, ROWS[0], "1,0.0,100.0,200.0,90.0,10.0,0.0,"], r"line 3: t_s 0.0 of ping 1 does not increase"),
        ([HEADER, ROWS[0], "1,-1.0,100.0,200.0,90.0,10.0,0.0,"], r"line 3: t_s -1.0 of ping 1 does not increase"),
        ([HEADER, ROWS[3], ROWS[0]], r"line 3: ping 0 comes after ping 2"),
        ([HEADER, ROWS[0], ROWS[2], ROWS[1]], r"line 4: ping 0 appears again"),
        ([HEADER, ROWS[0], "0,0.0,100.0,201.0,90.0,10.0,0.0,"], r"line 3: platform_y_m 201.0 differs from 200.0"),
        ([HEADER, "0.5,0.0,100.0,200.0,90.0,10.0,0.0,"], r"ping must be an integer"),
        ([HEADER, "0,0.0,100.0,200.0,90.0,10.0,0.0,1,2"], r"line 2: 9 cells but the header names 8 columns"),
        ([HEADER], r"holds a header but no ping"),
        (["# only a comment"], r"no header row"),
    ],
)
def test_bad_input_raises_an_error_naming_the_problem(tmp_path, lines, message):
    with pytest.raises(ValueError, match=message):
        read_detections(write(tmp_path, lines))


def test_missing_file_raises():
    with pytest.raises(FileNotFoundError):
        read_detections("/nonexistent/detections.csv")


def test_polar_and_world_frames_are_inverse_and_oriented():
    platform = np.array([100.0, -50.0])
    # Heading east, 10 degrees to starboard: an azimuth of 100 degrees, a little south of east.
    xy = polar_to_world(platform, 90.0, np.array([200.0]), np.array([10.0]))
    np.testing.assert_allclose(xy[0], platform + 200.0 * np.array([np.sin(np.radians(100.0)), np.cos(np.radians(100.0))]))
    assert xy[0, 1] < platform[1]
    rng = np.random.default_rng(1)
    r, b = rng.uniform(1, 500, 50), rng.uniform(-45, 45, 50)
    back_r, back_b = world_to_polar(platform, 350.0, polar_to_world(platform, 350.0, r, b))
    np.testing.assert_allclose(back_r, r)
    np.testing.assert_allclose(back_b, b, atol=1e-9)


def test_ping_rejects_mismatched_detections():
    with pytest.raises(ValueError, match="2 ranges but 1 bearings"):
        Ping(0, 0.0, (0, 0), 0.0, [1.0, 2.0], [0.0])


def test_latitude_longitude_are_projected_and_headings_turned_to_grid_north(tmp_path):
    from pyproj import Proj, Transformer

    header = "ping,t_s,platform_lat,platform_lon,heading_deg,range_m,bearing_deg"
    rows = ["0,0.0,60.0,5.0,90.0,300.0,0.0", "1,1.3,60.0001,5.0,90.0,299.0,0.0"]
    pings, report = read_detections(write(tmp_path, [header, *rows]))
    assert report.crs == "EPSG:32631" and "projected to EPSG:32631" in report.summary()
    x, y = Transformer.from_crs("EPSG:4326", "EPSG:32631", always_xy=True).transform(5.0, 60.0)
    np.testing.assert_allclose(pings[0].platform_xy, [x, y])
    convergence = Proj("EPSG:32631").get_factors(5.0, 60.0).meridian_convergence
    assert pings[0].heading_deg == pytest.approx(90.0 - convergence) and abs(convergence) > 1.0
    _, utm32 = read_detections(write(tmp_path, [header, *rows], "b.csv"), crs="EPSG:32632")
    assert utm32.crs == "EPSG:32632"


@pytest.mark.parametrize(
    "rows, message",
    [
        (["0,0.0,95.0,5.0,90.0,300.0,0.0"], "line 2: platform_lat/platform_lon 95.0, 5.0 are not a latitude and longitude"),
        (["0,0.0,,5.0,90.0,300.0,0.0"], "line 2: platform_lat is not a number"),
        (["0,0.0,60.0,5.0,90.0,300.0,0.0", "0,0.0,60.0,5.1,90.0,300.0,0.0"], "line 3: platform_lon 5.1 differs from 5.0"),
    ],
)
def test_bad_latitude_longitude_are_named(tmp_path, rows, message):
    header = "ping,t_s,platform_lat,platform_lon,heading_deg,range_m,bearing_deg"
    with pytest.raises(ValueError, match=message):
        read_detections(write(tmp_path, [header, *rows]))


def test_a_geographic_crs_is_refused(tmp_path):
    header = "ping,t_s,platform_lat,platform_lon,heading_deg,range_m,bearing_deg"
    with pytest.raises(ValueError, match="is not a projected"):
        read_detections(write(tmp_path, [header, "0,0.0,60.0,5.0,90.0,300.0,0.0"]), crs="EPSG:4326")


def test_truth_is_interpolated_to_the_pings_and_checked(tmp_path):
    from lost.host.track.truth import read_truth

    pings = [Ping(i, 1.0 * i, (0.0, 0.0), 0.0, [], []) for i in range(5)]
    truth_path = tmp_path / "truth.csv"
    truth_path.write_text("target,t_s,x_m,y_m\nA,0.5,0.0,300.0\nA,2.5,0.0,298.0\nB,0.0,600.0,0.0\nB,4.0,600.0,8.0\n")
    truth = read_truth(truth_path, pings)
    np.testing.assert_allclose(truth.xy[1:3, 0, 1], [299.5, 298.5])
    assert np.isnan(truth.xy[0, 0, 0]) and np.isnan(truth.xy[3, 0, 0])  # before the first and after the last fix
    np.testing.assert_allclose(truth.velocity[1, 0], [0.0, -1.0])
    assert truth.in_sector[1, 0] and not truth.in_sector[:, 1].any()  # B abeam at 600 m: never in the sector
    assert truth.kinds == ("diver", "diver")
    truth_path.write_text("target,t_s,x_m,y_m\nA,1.0,0.0,300.0\nA,1.0,0.0,299.0\n")
    with pytest.raises(ValueError, match="data row 2: t_s 1.0 of target 'A' does not increase"):
        read_truth(truth_path, pings)
    truth_path.write_text("target,t_s,x_m\nA,1.0,0.0\n")
    with pytest.raises(ValueError, match="lacks the truth column"):
        read_truth(truth_path, pings)
