"""A real survey (the GA-4430 EM122 .all) into the navigation's records: truth, dead reckoning, patches, streaming, the run."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from lost.host.cli import main
from lost.host.io import read_grid
from lost.host.io.survey import open_survey
from lost.host.io.survey_grid import grid_survey, write_survey_grid
from lost.host.io.survey_records import SurveyRecorder, survey_records

REAL = Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "real_survey"
EM122 = REAL / "ga4430_em122_all" / "0243_P007_MBES_EM122_20150207_044356_Supporter_GA4430.all"
needs_real = pytest.mark.skipif(not EM122.is_file(), reason=f"the real survey files are not at {REAL} (shared/data/real_survey beside the repository)")

OFFSET, BIAS = np.array([30.0, -20.0]), np.array([0.1, 0.05])


@pytest.fixture(scope="module")
def em122_map(tmp_path_factory):
    return write_survey_grid(grid_survey([EM122], node_m=20.0), tmp_path_factory.mktemp("map") / "em122_20m.nc")


def _recorder(node_m: float, **kw) -> SurveyRecorder:
    settings = {"patch_shape": (15, 15), "interval_s": 3.0, "window_s": 40.0, "dr_bias_mps": BIAS, "start_offset_m": OFFSET,
                "patch_centre": "soundings", **kw}
    return SurveyRecorder(node_m=node_m, **settings)


@needs_real
def test_records_carry_the_files_track_as_truth_and_a_dead_reckoning_off_by_the_injected_errors(em122_map):
    grid = read_grid(em122_map)
    pings = list(open_survey(EM122, crs=grid.crs))
    records = survey_records(open_survey(EM122, crs=grid.crs), _recorder(grid.node_m))
    assert len(records) == 6  # 38.3 s of pings in 3 s intervals, the empty ones giving no record
    # Each record is its interval's last ping: its time (from the first ping) and its position, the truth.
    by_time = {round(p.time_s - pings[0].time_s, 6): p for p in pings}
    for n, t in enumerate(records.t_s):
        ping = by_time[round(float(t), 6)]
        assert (records.truth_x_m[n], records.truth_y_m[n]) == (ping.east_m, ping.north_m)
        assert records.ship_heading_deg[n] == pytest.approx((ping.heading_deg + ping.convergence_deg) % 360)
    # The navigation's track (ship_x/y, what it is given) is the truth moved by the offset and the bias times the time.
    truth = np.column_stack([records.truth_x_m, records.truth_y_m])
    reckoned = np.column_stack([records.ship_x_m, records.ship_y_m])
    np.testing.assert_allclose(reckoned - truth, OFFSET + BIAS * (records.t_s - records.t_s[0])[:, None], atol=1e-6)
    assert np.all(records.cable_out_m == 0) and np.all(np.isnan(records.slant_range_m))


@needs_real
def test_each_patch_placed_at_the_truth_matches_the_map_of_the_same_soundings(em122_map):
    grid = read_grid(em122_map)
    # Without a bias the patch is the soundings' true geometry around the vehicle: at the true position it lies on the map.
    records = survey_records(open_survey(EM122, crs=grid.crs), _recorder(grid.node_m, dr_bias_mps=(0.0, 0.0)))
    medians = []
    for n, patch in enumerate(records.sonar):
        h, w = patch.depth_m.shape
        x = records.truth_x_m[n] + patch.centre_offset_m[0] + (np.arange(w) - (w - 1) / 2) * grid.node_m
        y = records.truth_y_m[n] + patch.centre_offset_m[1] + (np.arange(h) - (h - 1) / 2) * grid.node_m
        row, col = (np.rint(v).astype(int) for v in grid.row_col(*np.meshgrid(x, y)))
        inside = (row >= 0) & (row < grid.shape[0]) & (col >= 0) & (col < grid.shape[1])
        on_map = np.full((h, w), np.nan)
        on_map[inside] = grid.depth_m[row[inside], col[inside]]
        both = np.isfinite(patch.depth_m) & np.isfinite(on_map)
        assert both.sum() >= 20
        medians.append(np.median(np.abs(patch.depth_m - on_map)[both]))
        assert 0 <= patch.age_s <= 40.0
    # 3.5 km of water: a node's mean over all pings against this window's pings (0.26 to 0.63 m measured).
    assert max(medians) < 1.5


@needs_real
def test_the_recorder_streams_a_ping_at_a_time_to_the_same_records(em122_map):
    grid = read_grid(em122_map)
    recorder = _recorder(grid.node_m)
    streamed = []
    for ping in open_survey(EM122, crs=grid.crs):
        streamed += recorder.add(ping)
        assert all(r.t_s <= ping.time_s - recorder.epoch_s for r in streamed)  # a record is out once its interval is over
    streamed += recorder.finish()
    records = survey_records(open_survey(EM122, crs=grid.crs), _recorder(grid.node_m))
    np.testing.assert_array_equal([r.truth_x_m for r in streamed], records.truth_x_m)
    np.testing.assert_array_equal([r.ship_y_m for r in streamed], records.ship_y_m)
    for a, b in zip(streamed, records.sonar):
        np.testing.assert_array_equal(a.sonar.depth_m, b.depth_m)


@needs_real
def test_lost_run_survey_takes_the_maps_depth_std_and_says_so(em122_map, tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["run", "--survey", str(EM122), "--bathy", str(em122_map), "--start-offset", "30,-20", "--dr-bias", "0.1,0.05",
                 "--record-s", "3", "--window-s", "40", "--patch-shape", "4x4", "--patch-centre", "soundings", "--out", str(out)])
    assert code == 0
    printed = capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    grid = read_grid(em122_map)
    with_depth = np.isfinite(grid.depth_m)
    layer = summary["map_uncertainty"]
    assert layer["source"] == "the grid file's uncertainty layer" and layer["used"]
    assert layer["nodes_from_layer"] == int((with_depth & np.isfinite(grid.sigma_m)).sum()) > 0
    assert layer["nodes_from_survey_sigma_m"] == int((with_depth & np.isnan(grid.sigma_m)).sum()) > 0  # nodes of one sounding
    assert layer["layer_median_m"] == pytest.approx(np.median(grid.sigma_m[with_depth & np.isfinite(grid.sigma_m)]), abs=1e-4)
    assert "map uncertainty: the grid file's uncertainty layer" in printed
    assert summary["survey"]["dr_bias_mps"] == [0.1, 0.05] and summary["survey"]["start_offset_m"] == [30.0, -20.0]
    assert summary["records"] == 6 and summary["truth_known"]


def _assert_same_records(a, b) -> None:
    """Every series value for value (NaN where NaN), every patch node for node with its centre, age and node."""
    for name in ("t_s", "ship_x_m", "ship_y_m", "ship_heading_deg", "vehicle_depth_m", "altitude_m", "vel_x_mps", "vel_y_mps",
                 "slant_range_m", "cable_out_m", "truth_x_m", "truth_y_m"):
        np.testing.assert_array_equal(getattr(b, name), getattr(a, name), err_msg=name)
    assert len(a.sonar) == len(b.sonar)
    for p, q in zip(a.sonar, b.sonar, strict=True):
        assert (p is None) == (q is None)
        if p is not None:
            np.testing.assert_array_equal(q.depth_m, p.depth_m)
            assert (q.node_m, q.centre_offset_m, q.age_s) == (p.node_m, p.centre_offset_m, p.age_s)


@needs_real
def test_survey_records_written_as_a_navigation_log_read_back_value_for_value(em122_map, tmp_path):
    from lost.host.io.navlog import read_navlog, write_navlog

    grid = read_grid(em122_map)
    recorder = _recorder(grid.node_m)
    records = survey_records(open_survey(EM122, crs=grid.crs), recorder)
    assert sum(p is not None for p in records.sonar) == len(records) and np.all(records.cable_out_m == 0)
    write_navlog(records, tmp_path / "log.csv", sonar=tmp_path / "sonar.csv", epoch_utc_s=recorder.epoch_s)
    back, report = read_navlog(tmp_path / "log.csv", sonar=tmp_path / "sonar.csv", patch_shape=(15, 15), node_m=grid.node_m)
    _assert_same_records(records, back)
    assert any("the sonar is on the ship" in note for note in report.notes) and not report.warnings
    first = (tmp_path / "log.csv").read_text().splitlines()[1].split(",")[1]
    assert first.startswith("2015-02-07T04:43:") and first.endswith("Z")  # the file's clock beside t_s


@needs_real
def test_a_survey_run_saves_its_records_and_lost_run_log_on_them_navigates_alike(em122_map, tmp_path):
    survey_out, log_out = tmp_path / "survey", tmp_path / "log"
    common = ["--bathy", str(em122_map), "--patch-shape", "4x4", "--estimator", "pmf"]
    assert main(["run", "--survey", str(EM122), "--start-offset", "30,-20", "--dr-bias", "0.1,0.05", "--record-s", "3",
                 "--window-s", "40", "--patch-centre", "soundings", "--out", str(survey_out), *common]) == 0
    summary = json.loads((survey_out / "summary.json").read_text())
    assert summary["survey"]["log"] == {"log": "records.csv", "sonar": "records_sonar.csv"}
    assert main(["run", "--log", str(survey_out / "records.csv"), "--sonar", str(survey_out / "records_sonar.csv"),
                 "--out", str(log_out), *common]) == 0
    import pandas as pd

    a, b = pd.read_csv(survey_out / "track.csv"), pd.read_csv(log_out / "track.csv")
    assert list(a.columns) == list(b.columns) and len(a) == len(b) == summary["records"]
    pd.testing.assert_frame_equal(a, b)
