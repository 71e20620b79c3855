"""Hostile tracking input: scenario files with wrong types, unknown keys and impossible sizes; detections in wrong units."""

from __future__ import annotations

import csv
import dataclasses
import math
import time

import pytest

from lost.host.config import ConfigError
from lost.host.track.detections import read_detections, write_detections
from lost.host.track.simulate import MAX_SCENARIO_BYTES, builtin_scenario_path, check_size, load_scenario, simulate

SMALL = """
name = "small"
seed = 4
duration_s = 60.0
[sonar]
clutter_per_ping = 5.0
[[target]]
start_range_m = 300.0
"""


def _scenario(tmp_path, text: str):
    path = tmp_path / "s.toml"
    path.write_text(text)
    return path


# (TOML text, error fragment): each a value a hostile or hurried user writes.
BAD_SCENARIOS = {
    "unknown_top_level": ("duration = 30\n" + SMALL, "unknown top-level field(s) ['duration']"),
    "seed_as_string": (SMALL.replace("seed = 4", 'seed = "4"'), "seed: Input should be a valid integer, got '4' (str)"),
    "seed_fractional": (SMALL.replace("seed = 4", "seed = 4.5"), "seed: Input should be a valid integer, got 4.5"),
    "duration_as_string": (SMALL.replace("duration_s = 60.0", 'duration_s = "60"'), "duration_s (seconds): Input should be a valid number"),
    "duration_zero": (SMALL.replace("duration_s = 60.0", "duration_s = 0"), "duration_s (seconds): Input should be greater than 0, got 0"),
    "duration_nan": (SMALL.replace("duration_s = 60.0", "duration_s = nan"), "duration_s (seconds): Input should be a finite number"),
    "clutter_as_string": (SMALL.replace("clutter_per_ping = 5.0", 'clutter_per_ping = "5"'), "sonar.clutter_per_ping: Input should be a valid number"),
    "zero_ping_interval": (SMALL.replace("[sonar]", "[sonar]\nping_interval_s = 0"), "ping_interval_s (seconds): Input should be greater than 0, got 0"),
    "fov_above_180": (SMALL.replace("[sonar]", "[sonar]\nhalf_fov_deg = 200"), "sonar.half_fov_deg (degrees): Input should be less than or equal to 180"),
    "target_as_table": (SMALL.replace("[[target]]", "[target]"), "target must be an array of tables ([[target]])"),
    "target_range_as_string": (SMALL.replace("start_range_m = 300.0", 'start_range_m = "300"'),
                               "target.0.start_range_m (metres): Input should be a valid number"),
    "target_unknown_field": (SMALL + "range_m = 3\n", "[target.0] has unknown field(s) ['range_m']"),
    "tracker_unknown_field": (SMALL + "[tracker]\nconfirm = 3\n", "[tracker] has unknown field(s) ['confirm']"),
    "tracker_particles_float": (SMALL + "[tracker]\nparticles = 1e4\n", "tracker.particles: Input should be a valid integer, got 10000.0"),
    "platform_start_strings": (SMALL + '[platform]\nstart_m = ["0", "0"]\n', "platform.start_m.0 (metres): Input should be a valid number"),
}


@pytest.mark.parametrize("case", sorted(BAD_SCENARIOS))
def test_bad_scenario_is_named(tmp_path, case):
    text, fragment = BAD_SCENARIOS[case]
    with pytest.raises(ConfigError) as caught:
        load_scenario(_scenario(tmp_path, text))
    assert fragment in str(caught.value)
    assert str(caught.value).startswith("s.toml")


def test_a_scenario_too_long_is_refused_by_name_before_allocating(tmp_path):
    start = time.perf_counter()
    with pytest.raises(ConfigError, match=r"duration_s = 1e\+08 s .* lower duration_s") as caught:
        load_scenario(_scenario(tmp_path, SMALL.replace("duration_s = 60.0", "duration_s = 1e8")))
    assert time.perf_counter() - start < 1.0  # refused up front, not after filling memory
    assert "GB of memory" in str(caught.value)


def test_the_size_check_guards_simulate_too():
    base = load_scenario(builtin_scenario_path("one_diver"))
    check_size(dataclasses.replace(base, duration_s=86_400.0))  # a day of pings is fine
    with pytest.raises(ConfigError, match="limit is"):
        simulate(dataclasses.replace(base, duration_s=MAX_SCENARIO_BYTES))


def test_shipped_scenarios_still_load():
    for name in ("one_diver", "two_divers", "clutter_hour"):
        assert load_scenario(builtin_scenario_path(name)).name == name


@pytest.fixture
def detections_csv(tmp_path):
    """A minute of one diver in clutter, written as a detection log."""
    sim = simulate(load_scenario(_scenario(tmp_path, SMALL)))
    return write_detections(tmp_path / "detections.csv", sim.pings)


def _rewrite(source, target, column: str, convert) -> None:
    with source.open(newline="") as handle:
        rows = list(csv.reader(handle))
    index = rows[0].index(column)
    for row in rows[1:]:
        if row[index]:
            row[index] = repr(convert(float(row[index])))
    with target.open("w", newline="") as handle:
        csv.writer(handle).writerows(rows)


def test_the_log_in_proper_units_reads(detections_csv):
    pings, report = read_detections(detections_csv)
    assert report.detections > 100 and report.dropped == 0


def test_bearings_in_radians_are_refused_by_name(tmp_path, detections_csv):
    bad = tmp_path / "radians.csv"
    _rewrite(detections_csv, bad, "bearing_deg", math.radians)
    with pytest.raises(ValueError, match=r"bearing_deg: all \d+ bearings lie within \+/-0.785.*in radians.*give degrees"):
        read_detections(bad)


def test_ranges_in_kilometres_are_refused_by_name(tmp_path, detections_csv):
    bad = tmp_path / "km.csv"
    _rewrite(detections_csv, bad, "range_m", lambda r: r / 1000.0)
    with pytest.raises(ValueError, match=r"range_m: all \d+ ranges lie within 0.5, .* in kilometres.*give metres"):
        read_detections(bad)


def test_the_unit_checks_do_not_judge_a_handful_of_detections(tmp_path):
    path = tmp_path / "few.csv"
    path.write_text("ping,t_s,platform_x_m,platform_y_m,heading_deg,range_m,bearing_deg\n"
                    + "".join(f"{i},{1.3 * i},0,0,0,300,0.1\n" for i in range(5)))
    pings, report = read_detections(path)
    assert report.detections == 5


def test_lost_track_exits_with_one_line_on_radians(tmp_path, detections_csv, run_cli):
    bad = tmp_path / "radians.csv"
    _rewrite(detections_csv, bad, "bearing_deg", math.radians)
    code, out, err = run_cli("track", bad, "--out", tmp_path / "out", "--no-animation")
    assert code != 0
    assert "in radians" in err
    assert not (tmp_path / "out" / "summary.json").exists()


def test_strengths_on_another_scale_are_refused_by_name(tmp_path, detections_csv, run_cli):
    """Strengths in dB re 1 uPa (about 150) are not dB above the threshold: every ratio would be the clip's."""
    from lost.host.track.amplitude import StrengthScaleError, check_strength_scale
    from lost.host.track.tracker import TrackerParameters

    bad = tmp_path / "upa.csv"
    _rewrite(detections_csv, bad, "strength_db", lambda s: s + 150.0)
    pings, _ = read_detections(bad)
    with pytest.raises(StrengthScaleError, match=r"strength_db: the median detection strength is 15\d dB, outside .*--set amplitude=false"):
        check_strength_scale(pings, TrackerParameters())
    check_strength_scale(pings, TrackerParameters(amplitude=False))  # tracking without the strengths is allowed
    code, out, err = run_cli("track", bad, "--out", tmp_path / "out", "--no-animation")
    assert code != 0 and "strength_db" in err and "amplitude=false" in err
    assert not (tmp_path / "out" / "summary.json").exists()
    code, out, err = run_cli("track", bad, "--out", tmp_path / "off", "--no-animation", "--set", "amplitude=false")
    assert code == 0, err
