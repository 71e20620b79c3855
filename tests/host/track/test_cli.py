"""`lost track`: a scenario and a detections CSV through the command, every output checked; bad input exits 2."""

import csv
import json

import pytest

from lost.host.cli import main
from lost.host.track.output import TRACK_COLUMNS

SCENARIO = """
name = "short_diver"
seed = 4
duration_s = 40.0
[sonar]
clutter_per_ping = 5.0
[[target]]
start_range_m = 300.0
start_bearing_deg = 10.0
speed_mps = 0.8
"""


@pytest.fixture(scope="module")
def scenario_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("track")
    path = folder / "short.toml"
    path.write_text(SCENARIO)
    out = folder / "out"
    assert main(["track", str(path), "--out", str(out), "--particles", "2000", "--write-detections", "--baseline"]) == 0
    return out


def test_a_scenario_run_writes_every_output(scenario_run, capsys):
    for name in ("tracks.csv", "sector.png", "tracks.gif", "summary.json", "detections.csv", "truth.csv"):
        assert (scenario_run / name).stat().st_size > 0
    assert not list(scenario_run.glob("*.partial"))
    summary = json.loads((scenario_run / "summary.json").read_text())
    assert summary["truth_known"] and summary["pings"] == 31
    assert summary["pings_to_lock"][0] is not None and summary["pings_to_lock"][0] <= 8
    assert summary["confirmed_tracks"] == 1 and summary["false_tracks"] == 0
    assert 0 <= summary["gospa_mean"] < 25 and summary["ms_per_ping"] > 0
    assert summary["tracks"][0]["class"] == "diver"
    baselines = summary["baselines"]
    assert baselines["gm_phd"]["tracker"].startswith("Stone Soup GM-PHD") and "gospa_mean" in baselines["gm_phd"]
    assert baselines["jpda"]["tracker"].startswith("Stone Soup JPDA") and "gospa_mean" in baselines["jpda"]
    assert {"Completeness", "Spuriousness"} <= set(summary["siap"])


def test_tracks_csv_has_the_documented_columns_and_confirmed_rows(scenario_run):
    with (scenario_run / "tracks.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert tuple(rows[0]) == TRACK_COLUMNS
    confirmed = [r for r in rows if r["status"] == "confirmed"]
    assert confirmed and all(float(r["speed_mps"]) >= 0 for r in confirmed)
    assert {r["class"] for r in confirmed} <= {"unknown", "drifting", "diver", "fast animal"}
    assert all(r["ping"].isdigit() and r["track_id"].isdigit() for r in rows)


def test_the_written_detections_run_as_a_recorded_log(scenario_run, tmp_path, capsys):
    out = tmp_path / "csv_run"
    assert main(["track", str(scenario_run / "detections.csv"), "--out", str(out), "--particles", "2000", "--no-animation"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert not summary["truth_known"] and summary["gospa_mean"] is None and summary["pings_to_lock"] is None
    assert summary["confirmed_tracks"] == 1 and summary["pings"] == 31
    assert not (out / "tracks.gif").exists()
    assert "detections kept" in capsys.readouterr().out


def test_bad_detections_exit_1_naming_the_line(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("ping,t_s,platform_x_m,platform_y_m,heading_deg,range_m,bearing_deg\n0,0,0,0,0,ten,0\n")
    assert main(["track", str(bad), "--out", str(tmp_path / "o")]) == 1
    assert "line 2: range_m is not a number: 'ten'" in capsys.readouterr().err
    assert not (tmp_path / "o" / "summary.json").exists()


def test_unknown_scenario_name_exits_1(tmp_path, capsys):
    assert main(["track", "no_such_scenario", "--out", str(tmp_path / "o")]) == 1
    assert "no built-in tracking scenario 'no_such_scenario'" in capsys.readouterr().err


def test_set_reaches_the_tracker_and_unknown_names_are_refused(scenario_run, tmp_path, capsys):
    out = tmp_path / "strict"
    detections = str(scenario_run / "detections.csv")
    assert main(["track", detections, "--out", str(out), "--particles", "2000", "--no-animation", "--set", "confirm_existence=0.999",
                 "--set", "em_points=500", "--max-range", "600"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert (summary["tracker"]["confirm_existence"], summary["tracker"]["em_points"]) == (0.999, 500)
    assert main(["track", detections, "--out", str(out), "--set", "confirm=3"]) == 2
    assert "--set names no tracker parameter: confirm" in capsys.readouterr().err
    # Types are the strict schema's, as for lost run's --set: no string, None or fraction where a number or count goes.
    for value, message in (("pd=abc", "--set pd: Input should be a valid number, got 'abc' (str)"),
                           ("pd=none", "--set pd: Input should be a valid number, got None (NoneType)"),
                           ("em_points=4.5", "--set em_points: Input should be a valid integer, got 4.5")):  # a count: no unit
        assert main(["track", detections, "--out", str(out), "--set", value]) == 2
        assert message in capsys.readouterr().err


def test_a_recorded_log_with_its_truth_scores_as_the_simulation_did(scenario_run, tmp_path):
    out = tmp_path / "scored"
    args = ["track", str(scenario_run / "detections.csv"), "--truth", str(scenario_run / "truth.csv"), "--out", str(out), "--particles", "2000"]
    assert main([*args, "--no-animation"]) == 0
    recorded = json.loads((out / "summary.json").read_text())
    simulated = json.loads((scenario_run / "summary.json").read_text())
    assert recorded["truth_known"] and recorded["pings_to_lock"] == simulated["pings_to_lock"]
    assert recorded["gospa_mean"] == pytest.approx(simulated["gospa_mean"], abs=0.5)  # velocities from the fixes differ a little
