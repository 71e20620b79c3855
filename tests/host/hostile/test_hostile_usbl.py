"""Hostile INS+USBL input: processing settings and scenarios of the wrong type or range, casts in the wrong unit,
encoding or with doubled columns, logs whose travel times or directions are in the wrong unit or meaning."""

from __future__ import annotations

from pathlib import Path

import gsw
import numpy as np
import pytest

from lost.host.config import ConfigError
from lost.host.usbl.checks import UsblLogError
from lost.host.usbl.pipeline import UsblConfig, process, read_imu, read_log
from lost.host.usbl.scenario import ReplyFaultSpec, TowSpec, UsblScenario, load_processing_config, load_usbl_scenario
from lost.host.usbl.simulate import LOG_COLUMNS, simulate_tow
from lost.host.usbl.sound import CastError, read_cast

HEADER = "# latitude = 18.0\n# longitude = 115.5\n"


@pytest.mark.parametrize(("body", "message"), [
    ('earth_rotation = "false"', r"c.toml: earth_rotation: Input should be a valid boolean, got 'false' \(str\)"),
    ('gate_probability = "0.999"', r"c.toml: gate_probability: Input should be a valid number, got '0.999' \(str\)"),
    ('gate_probability = "high"', r"c.toml: gate_probability: Input should be a valid number, got 'high' \(str\)"),
    ("gate_probability = 1.0", r"c.toml: gate_probability: Input should be less than 1, got 1.0"),
    ("align_window_s = 0", r"c.toml: align_window_s \(seconds\): Input should be greater than 0, got 0"),
    ('align_window_s = "40"', r"c.toml: align_window_s \(seconds\): Input should be a valid number, got '40' \(str\)"),
    ("gate = 0.99", r"unknown key\(s\) \['gate'\]"),
])
def test_processing_settings_are_checked_by_name(tmp_path, body, message):
    path = tmp_path / "c.toml"
    path.write_text(body + "\n")
    with pytest.raises(ConfigError, match=message):
        load_processing_config(path)


def test_good_processing_settings_pass(tmp_path):
    settings = load_processing_config(_write(tmp_path / "c.toml", "gate_probability = 0.99\nearth_rotation = false\n"))
    assert settings == {"gate_probability": 0.99, "earth_rotation": False}


@pytest.mark.parametrize(("body", "message"), [
    ("[tow]\nspeed_m_s = 0", r"s.toml: tow.speed_m_s \(m/s\): Input should be greater than 0, got 0"),
    ("[faults]\ndropout_rate = 1.5", r"s.toml: faults.dropout_rate: Input should be less than or equal to 1, got 1.5"),
    ('gate_probability = "high"', r"s.toml: gate_probability: Input should be a valid number, got 'high'"),
    ("duration_s = 1e7", r"s.toml: scenario x: duration_s 1e\+07 s at imu_rate_hz 10 .* is 100,004,667 IMU samples; the simulator holds "
                         r"at most 1,000,000"),
    ("duration_s = 1e5\n[tow]\nspeed_m_s = 0.01", r"s.toml: scenario x: .* IMU samples"),
])
def test_scenarios_out_of_range_or_too_long_are_refused_up_front(tmp_path, body, message):
    path = tmp_path / "s.toml"
    path.write_text('name = "x"\n' + body + "\n")
    with pytest.raises(ConfigError, match=message):
        load_usbl_scenario(path)


def test_a_tow_speed_of_zero_is_refused_from_python_too():
    with pytest.raises(ValueError, match="tow speed_m_s must be positive"):
        TowSpec(speed_m_s=0.0)


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def _cast_rows(unit_scale: float) -> str:
    depth = np.array([2.0, 50.0, 400.0, 1000.0])
    temperature = np.array([28.0, 25.0, 9.0, 4.5])
    conductivity = gsw.C_from_SP([33.8, 34.3, 34.4, 34.55], temperature, gsw.p_from_z(-depth, 18.0))
    return "".join(f"{a},{b},{float(c) * unit_scale!r}\n" for a, b, c in zip(depth, temperature, conductivity))


def test_conductivity_in_siemens_per_metre_is_converted_under_its_own_name(tmp_path):
    in_s_m = read_cast(_write(tmp_path / "a.csv", HEADER + "depth_m,temperature_c,conductivity_s_m\n" + _cast_rows(0.1)))
    in_ms_cm = read_cast(_write(tmp_path / "b.csv", HEADER + "depth_m,temperature_c,conductivity_ms_cm\n" + _cast_rows(1.0)))
    np.testing.assert_allclose(in_s_m.sound_speed_m_s, in_ms_cm.sound_speed_m_s, atol=1e-9)
    np.testing.assert_allclose(in_s_m.salinity_psu, [33.8, 34.3, 34.4, 34.55], atol=1e-9)


def test_conductivity_in_siemens_per_metre_under_the_millisiemens_name_is_refused(tmp_path):
    path = _write(tmp_path / "cast.csv", HEADER + "depth_m,temperature_c,conductivity_ms_cm\n" + _cast_rows(0.1))
    with pytest.raises(CastError, match=r"cast.csv: conductivity_ms_cm runs 3\.\d+ to 5\.\d+: as mS/cm that is a practical salinity of 2\.\d+ "
                                        r"to 2\.\d+, as S/m 33\.80 to 34\.55; the values are S/m: name the column conductivity_s_m"):
        read_cast(path)


def test_a_latin1_cast_names_the_file_and_the_line(tmp_path):
    path = tmp_path / "latin.csv"
    path.write_bytes((HEADER + "# temperature in \xb0C\ndepth_m,temperature_c,salinity_psu\n0,20,35\n10,19,35\n").encode("latin-1"))
    with pytest.raises(CastError, match=r"latin.csv: line 3 is not UTF-8 \(byte 0xb0"):
        read_cast(path)


@pytest.mark.parametrize("header", ["depth_m,DEPTH_M,temperature_c,salinity_psu", "depth_m,temperature_c,salinity_psu,depth_m"])
def test_a_doubled_column_is_refused_by_name(tmp_path, header):
    rows = "0,0,20,35\n10,10,19,35\n" if header.count(",") == 3 and header.startswith("depth_m,DEPTH") else "0,20,35,0\n10,19,35,10\n"
    with pytest.raises(CastError, match=r"dup.csv: column\(s\) \['depth_m'\] appear more than once"):
        read_cast(_write(tmp_path / "dup.csv", HEADER + header + "\n" + rows))


# ------------------------------------------------------------------ logs: units and meanings of whole columns


@pytest.fixture(scope="module")
def tow():
    """Two minutes of straight tow at 300 m, every reply good: the log, the IMU samples and the cast."""
    scenario = UsblScenario(name="hostile", seed=5, duration_s=120.0, tow=TowSpec(depth_m=300.0, layback_m=200.0, course=((120.0, 0.0),)),
                            faults=ReplyFaultSpec(dropout_rate=0.0, dropout_rate_turning=0.0, bad_fix_rate=0.0, bad_fix_rate_turning=0.0))
    return scenario, simulate_tow(scenario)


@pytest.fixture
def files(tmp_path, tow):
    _, sim = tow
    sim.log[LOG_COLUMNS].to_csv(tmp_path / "log.csv", index=False, float_format="%.10g")
    sim.imu.to_csv(tmp_path / "imu.csv", index=False, float_format="%.10g")
    (tmp_path / "cast.csv").write_text(Path(sim.cast.source).read_text())
    return tmp_path


def _process(files: Path, log_name: str, scenario, **read) -> None:
    log = read_log(files / log_name, **read)
    process(log, read_imu(files / "imu.csv"), read_cast(files / "cast.csv"), UsblConfig(array=scenario.usbl, imu=scenario.imu))


def _rewrite(files: Path, change) -> str:
    table = read_log(files / "log.csv")
    change(table)
    table.to_csv(files / "changed.csv", index=False, float_format="%.10g")
    return "changed.csv"


def test_the_clean_log_passes(files, tow):
    _process(files, "log.csv", tow[0])


@pytest.mark.parametrize(("change", "message"), [
    (lambda t: t.__setitem__("travel_time_s", t.travel_time_s * 1000.0), r"changed.csv: travel_time_s looks like milliseconds: .* is (9\d\d|1\d\d\d) times"),
    (lambda t: t.__setitem__("travel_time_s", t.travel_time_s * 2.0), r"changed.csv: travel_time_s looks like two-way travel times: .* is [12]\.\d+ "
                                                                      r"times .* name the column two_way_travel_time_s"),
    (lambda t: t.__setitem__("phase_x_rad", np.degrees(t.phase_x_rad)) or t.__setitem__("phase_y_rad", np.degrees(t.phase_y_rad)),
     r"changed.csv: phase_x_rad, phase_y_rad give no downward direction for \d+ of 60 replies .* the values look like degrees"),
    (lambda t: t.__setitem__("fish_depth_m", t.fish_depth_m * 3.0), r"changed.csv: travel times and directions disagree with the towfish's depth"),
])
def test_a_column_in_the_wrong_unit_is_refused_by_name(files, tow, change, message):
    with pytest.raises(UsblLogError, match=message):
        _process(files, _rewrite(files, change), tow[0])


def test_too_few_fixes_say_why(files, tow):
    def eight_replies_four_wrapped(table):
        silent = np.arange(len(table)) >= 8
        for column in ("travel_time_s", "phase_x_rad", "phase_y_rad"):
            table.loc[silent, column] = np.nan
        table.loc[[1, 3, 5, 7], ["phase_x_rad", "phase_y_rad"]] = 3.0
    with pytest.raises(ValueError, match=r"changed.csv: the alignment needs at least five USBL fixes; 8 of 60 pings have a reply and 4 of "
                                         r"them a fix; 4 replies gave no fix, the first \(row 2\): direction cosines .* no downward component"):
        _process(files, _rewrite(files, eight_replies_four_wrapped), tow[0])


# ------------------------------------------------------------------ a cast that stops above the towfish


def _truncated_cast(files: Path, bottom_m: float) -> Path:
    lines = (files / "cast.csv").read_text().splitlines()
    kept = [line for line in lines if line.startswith("#") or line.startswith("depth_m") or float(line.split(",")[0]) <= bottom_m]
    return _write(files / "short_cast.csv", "\n".join(kept) + "\n")


def _run(files: Path, cast: Path, scenario, **settings):
    config = UsblConfig(array=scenario.usbl, imu=scenario.imu, **settings)
    return process(read_log(files / "log.csv"), read_imu(files / "imu.csv"), read_cast(cast), config)


def test_a_cast_that_stops_above_the_towfish_is_extended_and_counted(files, tow):
    scenario, sim = tow
    full = _run(files, files / "cast.csv", scenario)
    extended = _run(files, _truncated_cast(files, 250.0), scenario)
    assert full.cast["replies_below_cast"] == 0 and full.cast["extended_to_m"] is None
    assert extended.cast["bottom_m"] == 250.0 and extended.cast["replies_below_cast"] == 60 and extended.cast["policy"] == "extend"
    assert extended.cast["extended_to_m"] > 300.0 and extended.cast["source"].endswith("short_cast.csv")
    # The deep-ocean gradient stands in for the missing 50 m: the fixes move by centimetres, not metres.
    moved = np.hypot(*(extended.usbl_position - full.usbl_position)[:, :2].T)
    assert np.nanmax(moved) < 0.5 and np.all(np.isfinite(extended.usbl_position[:, 0]))


@pytest.mark.parametrize(("settings", "message"), [
    ({"cast_below_vehicle": "refuse"}, r"cast .*short_cast.csv stops at 250.0 m, above the towfish: 60 of 60 replies come from below it "
                                       r"\(the deepest at 30\d\.\d m\); take a deeper cast, or set cast_below_vehicle = \"extend\""),
    ({"cast_extension_limit_m": 20.0}, r"cast .*short_cast.csv stops at 250.0 m, 5\d\.\d m above the deepest reply's transponder .* "
                                       r"cast_extension_limit_m = 20 m: take a deeper cast"),
])
def test_a_cast_too_shallow_for_the_policy_is_refused_by_name(files, tow, settings, message):
    with pytest.raises(CastError, match=message):
        _run(files, _truncated_cast(files, 250.0), tow[0], **settings)


def test_the_cast_policy_is_a_checked_setting(tmp_path):
    with pytest.raises(ConfigError, match=r"cast_below_vehicle: Input should be 'extend' or 'refuse', got 'ignore'"):
        load_processing_config(_write(tmp_path / "c.toml", 'cast_below_vehicle = "ignore"\n'))


@pytest.mark.parametrize("problem", ["latin1_cast", "log_in_milliseconds", "cast_refused"])
def test_the_command_reports_bad_input_in_one_line_and_writes_no_summary(files, run_cli, problem):
    cast, log, extra = files / "cast.csv", files / "log.csv", []
    if problem == "latin1_cast":
        cast = files / "latin.csv"
        cast.write_bytes(("# temperature in \xb0C\n" + (files / "cast.csv").read_text()).encode("latin-1"))
    elif problem == "log_in_milliseconds":
        log = files / _rewrite(files, lambda t: t.__setitem__("travel_time_s", t.travel_time_s * 1000.0))
    else:
        cast = _truncated_cast(files, 250.0)
        (files / "refuse.toml").write_text('cast_below_vehicle = "refuse"\n')
        extra = ["--config", files / "refuse.toml"]
    code, _, err = run_cli("usbl", log, "--svp", cast, "--imu", files / "imu.csv", "--out", files / "out", *extra)
    named = log if problem == "log_in_milliseconds" else cast
    assert code == 1 and named.name in err
    assert not (files / "out" / "summary.json").exists()
