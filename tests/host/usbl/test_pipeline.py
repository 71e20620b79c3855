"""Recorded-tow processing: the log and IMU readers' named errors, the config and scenario loaders, and the
`lost usbl LOG.csv --svp CAST.csv` path on files."""

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from lost.host.cli import main
from lost.host.usbl.pipeline import UsblConfig, read_imu, read_log
from lost.host.usbl.scenario import load_processing_config, load_usbl_scenario, processing_config_toml
from lost.host.usbl.simulate import LOG_COLUMNS


@pytest.fixture
def recording(tmp_path, short_tow):
    """The short simulated tow written as a recording: log (without truth), IMU, cast, config."""
    folder = tmp_path / "tow"
    folder.mkdir()
    short_tow.log[LOG_COLUMNS].to_csv(folder / "log.csv", index=False, float_format="%.10g")
    short_tow.log.to_csv(folder / "log_with_truth.csv", index=False, float_format="%.10g")
    short_tow.imu.to_csv(folder / "imu.csv", index=False, float_format="%.10g")
    (folder / "cast.csv").write_text(Path(short_tow.cast.source).read_text())
    (folder / "usbl.toml").write_text("gate_probability = 0.999\n[usbl]\nphase_noise_rad = 0.01\n[imu]\naccel_bias_mg = 0.1\n")
    return folder


def test_log_path_writes_a_complete_run(recording, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["usbl", str(recording / "log_with_truth.csv"), "--svp", str(recording / "cast.csv"), "--imu", str(recording / "imu.csv"),
                 "--config", str(recording / "usbl.toml"), "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["truth_known"] and summary["epochs_without_fused_position"] == 0
    assert summary["methods"]["fused"]["rms_m"] < 0.5 * summary["methods"]["usbl_good_fixes"]["rms_m"]
    for name in ("track.csv", "track.png", "error.png", "profile.png"):
        assert (out / name).stat().st_size > 0
    assert "fused" in capsys.readouterr().out


def test_log_without_truth_reports_no_errors(recording, tmp_path):
    out = tmp_path / "out"
    assert main(["usbl", str(recording / "log.csv"), "--svp", str(recording / "cast.csv"), "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert not summary["truth_known"] and summary["methods"]["fused"]["rms_m"] is None
    assert summary["gating"]["accepted"] > 100
    assert not (out / "error.png").exists()


def test_a_log_needs_its_cast(recording, capsys):
    assert main(["usbl", str(recording / "log.csv")]) == 2
    assert "--svp" in capsys.readouterr().err


def _edit(source: Path, target: Path, change) -> Path:
    lines = source.read_text().splitlines()
    target.write_text("\n".join(change(lines)) + "\n")
    return target


@pytest.mark.parametrize(("change", "message"), [
    (lambda lines: [lines[0].replace("fish_depth_m,", "")] + [",".join(l.split(",")[:9] + l.split(",")[10:]) for l in lines[1:]],
     r"missing column\(s\) \['fish_depth_m'\]"),
    (lambda lines: lines[:3] + [lines[3].replace(lines[3].split(",")[1], "north", 1)] + lines[4:], "column 'ship_lat_deg' row 3: 'north'"),
    (lambda lines: lines[:2] + [lines[1]] + lines[3:], "time_s must increase; row 2"),
    (lambda lines: lines[:4] + [",".join(p if k != 7 else "" for k, p in enumerate(lines[4].split(",")))] + lines[5:],
     "row 4 has some of phase_x_rad, phase_y_rad, travel_time_s but not all"),
])
def test_bad_logs_name_the_problem(recording, tmp_path, change, message):
    bad = _edit(recording / "log.csv", tmp_path / "bad.csv", change)
    with pytest.raises(ValueError, match=message):
        read_log(bad)


def test_bad_imu_files_name_the_problem(recording, tmp_path):
    slow = _edit(recording / "imu.csv", tmp_path / "slow.csv", lambda lines: lines[:1] + lines[1::5])
    with pytest.raises(ValueError, match="slower than 10 Hz"):
        read_imu(slow)
    with pytest.raises(FileNotFoundError, match="IMU file"):
        read_imu(tmp_path / "none.csv")


def test_loaders_refuse_unknown_keys(tmp_path):
    config = tmp_path / "c.toml"
    config.write_text("[usbl]\nphase_noise = 0.01\n")
    with pytest.raises(ValueError, match=r"unknown key\(s\) \['phase_noise'\]"):
        load_processing_config(config)
    scenario = tmp_path / "s.toml"
    scenario.write_text('name = "x"\n[tow]\nspeed = 2.0\n')
    with pytest.raises(ValueError, match=r"\[tow\]: unknown key\(s\) \['speed'\]"):
        load_usbl_scenario(scenario)
    with pytest.raises(ValueError, match="the shipped ones are \\['usbl_stale_cast', 'usbl_turns'\\]"):
        load_usbl_scenario("no_such_scenario")


def test_a_turn_makes_more_dropouts_and_bad_fixes(short_scenario):
    from lost.host.usbl.scenario import ReplyFaultSpec, TowSpec
    from lost.host.usbl.simulate import simulate_tow

    faults = ReplyFaultSpec(dropout_rate=0.0, dropout_rate_turning=0.5, bad_fix_rate=0.0, bad_fix_rate_turning=0.5)
    turning = TowSpec(depth_m=300.0, layback_m=150.0, course=((100.0, 0.0), (200.0, 0.3)))
    log = simulate_tow(short_scenario(tow=turning, faults=faults)).log
    ship_turning = log.time_s.to_numpy() + 100.0 > 100.0  # the ship is 100 s ahead on the track
    assert np.all(log.travel_time_s[~ship_turning].notna())
    assert log.travel_time_s[ship_turning].isna().mean() > 0.3
    assert (log.injected[ship_turning] != "").mean() > 0.15


def test_a_log_gives_the_direction_as_phases_or_cosines_not_both(recording, tmp_path):
    as_cosines = _edit(recording / "log.csv", tmp_path / "cosines.csv", lambda lines: [lines[0].replace("phase_x_rad,phase_y_rad", "dir_x,dir_y")] + lines[1:])
    assert read_log(as_cosines).attrs["direction_columns"] == ("dir_x", "dir_y")
    both = _edit(recording / "log.csv", tmp_path / "both.csv", lambda lines: [lines[0] + ",dir_x,dir_y"] + [l + ",0.1,0.1" for l in lines[1:]])
    with pytest.raises(ValueError, match="exactly one pair"):
        read_log(both)


def test_an_imu_that_stops_early_is_refused(recording, tmp_path, capsys):
    short = _edit(recording / "imu.csv", tmp_path / "imu.csv", lambda lines: lines[: len(lines) // 2])
    assert main(["usbl", str(recording / "log.csv"), "--svp", str(recording / "cast.csv"), "--imu", str(short), "--out", str(tmp_path / "o")]) == 1
    assert "must cover the pings" in capsys.readouterr().err
    assert not (tmp_path / "o" / "summary.json").exists()


def test_fixes_that_cannot_be_computed_are_counted_and_named(recording, tmp_path):
    def wrap_phases(lines):
        parts = lines[6].split(",")
        parts[7], parts[8] = "3.0", "3.0"  # no downward direction
        return lines[:6] + [",".join(parts)] + lines[7:]

    log = _edit(recording / "log.csv", tmp_path / "log.csv", wrap_phases)
    out = tmp_path / "out"
    assert main(["usbl", str(log), "--svp", str(recording / "cast.csv"), "--imu", str(recording / "imu.csv"), "--out", str(out)]) == 0
    gating = json.loads((out / "summary.json").read_text())["gating"]
    assert gating["failed"] == 1
    assert gating["failed_examples"][0]["row"] == 6 and "no downward component" in gating["failed_examples"][0]["reason"]


def test_a_two_way_travel_time_is_halved_after_the_turnaround(recording, tmp_path):
    def two_way(lines):
        header = lines[0].split(",")
        column = header.index("travel_time_s")
        header[column] = "two_way_travel_time_s"
        rows = []
        for line in lines[1:]:
            parts = line.split(",")
            parts[column] = "" if parts[column] == "" else repr(2 * float(parts[column]) + 0.05)
            rows.append(",".join(parts))
        return [",".join(header)] + rows

    converted = read_log(_edit(recording / "log.csv", tmp_path / "two_way.csv", two_way), turnaround_s=0.05)
    original = read_log(recording / "log.csv")
    np.testing.assert_allclose(converted["travel_time_s"], original["travel_time_s"], rtol=1e-12)
    with pytest.raises(ValueError, match="not longer than the turnaround"):
        read_log(tmp_path / "two_way.csv", turnaround_s=5.0)


def test_a_step_in_the_cast_with_a_long_layback_loses_no_reply_and_writes_every_file(tmp_path, short_scenario, imu_samples):
    """+40 m/s over a metre at 200 m, the towfish 2 km behind at 1000 m: rays near the step's grazing angle."""
    from lost.host.usbl.pipeline import process
    from lost.host.usbl.report import summarize, write_outputs
    from lost.host.usbl.scenario import ReplyFaultSpec, TowSpec
    from lost.host.usbl.simulate import simulate_tow

    depth = np.concatenate(([0.0, 200.0, 201.0], np.arange(250.0, 1501.0, 50.0)))
    speed = np.where(depth <= 200.0, 1500.0, 1540.0 + 0.0165 * (depth - 201.0))
    cast = tmp_path / "step.csv"
    cast.write_text("# latitude = 18\n# longitude = 115.5\ndepth_m,sound_speed_m_s\n" + "".join(f"{a},{b}\n" for a, b in zip(depth, speed)))
    scenario = short_scenario(duration_s=120.0, cast=str(cast), tow=TowSpec(depth_m=1000.0, layback_m=2000.0, course=((120.0, 0.0),)),
                              faults=ReplyFaultSpec(dropout_rate=0.0, dropout_rate_turning=0.0, bad_fix_rate=0.0, bad_fix_rate_turning=0.0))
    sim = simulate_tow(scenario)
    run = process(sim.log, imu_samples(sim.imu), sim.cast, scenario.processing_config())
    summary = summarize(run, name="step", run_time_s=0.0)
    assert summary["gating"]["failed"] == 0 and summary["gating"]["accepted"] >= 55
    out, warnings = tmp_path / "out", []
    out.mkdir()
    write_outputs(out, run, summary, warnings)
    assert warnings == [] and {path.name for path in out.iterdir()} == {"track.csv", "track.png", "error.png", "profile.png", "summary.json"}


SHORT_SCENARIO = """name = "short_turn"
seed = 5
duration_s = 120.0
[tow]
depth_m = 600.0
layback_m = 400.0
course = [[60.0, 0.0], [60.0, 0.3]]
[usbl]
phase_noise_rad = 0.008
noise_growth_per_km = 0.5
transponder_lever_arm_m = [1.0, 0.0, -1.5]
[processing]
cast_age_h = 2.0
sound_speed_sigma_m_s = 0.4
"""


def test_a_scenario_run_can_be_repeated_from_its_inputs(tmp_path, capsys, monkeypatch):
    """The recording a scenario run writes, with its inputs/usbl.toml, is processed to the same track; without that
    file the defaults (no transponder lever arm, another phase noise) give another one, and a warning says so."""
    monkeypatch.setattr("lost.host.usbl.report.run_plots", lambda run: {})  # the tracks are compared; the plots cost seconds
    scenario = tmp_path / "short_turn.toml"
    scenario.write_text(SHORT_SCENARIO)
    first = tmp_path / "first"
    assert main(["usbl", str(scenario), "--out", str(first)]) == 0
    inputs = first / "inputs"
    again, defaults = tmp_path / "again", tmp_path / "defaults"
    recording = [str(inputs / "log.csv"), "--svp", str(inputs / "cast.csv"), "--imu", str(inputs / "imu.csv")]
    assert main(["usbl", *recording, "--config", str(inputs / "usbl.toml"), "--out", str(again)]) == 0
    assert main(["usbl", *recording, "--out", str(defaults)]) == 0
    columns = ["north_m", "east_m", "depth_m", "var_north_m2", "var_east_m2", "nis"]
    expected = pd.read_csv(first / "track.csv")[columns]
    pd.testing.assert_frame_equal(pd.read_csv(again / "track.csv")[columns], expected)
    assert not np.allclose(pd.read_csv(defaults / "track.csv")[columns].to_numpy(), expected.to_numpy(), equal_nan=True)
    warned = json.loads((defaults / "summary.json").read_text())["warnings"]
    assert any("no --config" in warning for warning in warned)
    assert not json.loads((again / "summary.json").read_text())["warnings"]
    assert "warning: no --config" in capsys.readouterr().out


@pytest.mark.parametrize("name", ["usbl_turns", "usbl_stale_cast"])
def test_the_processing_settings_round_trip_through_their_toml(tmp_path, name):
    config = load_usbl_scenario(name).processing_config()
    path = tmp_path / "usbl.toml"
    path.write_text(processing_config_toml(config))
    assert UsblConfig(**load_processing_config(path)) == config


def test_lost_usbl_lists_its_shipped_scenarios_and_asks_for_a_source(capsys):
    assert main(["usbl", "--list"]) == 0
    listed = dict(line.split(maxsplit=1) for line in capsys.readouterr().out.splitlines())
    assert set(listed) == {"usbl_turns", "usbl_stale_cast"} and "4 h old cast" in listed["usbl_stale_cast"]
    assert main(["usbl"]) == 2
    assert "give a log (LOG.csv --svp CAST.csv) or a scenario" in capsys.readouterr().err
