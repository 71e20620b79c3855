"""Every real multibeam file of ../shared/data/real_survey read against the figures its README and SOURCE.txt give."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import numpy as np
import pytest

from lost.host.io.survey import open_survey, survey_format
from lost.host.io.survey_summary import format_summary, summarize_survey

REAL = Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "real_survey"
needs_real = pytest.mark.skipif(not REAL.is_dir(), reason=f"the real survey files are not at {REAL} (shared/data/real_survey beside the repository)")


def _utc(text: str) -> float:
    return dt.datetime.fromisoformat(text).replace(tzinfo=dt.UTC).timestamp()


def _real(pattern: str) -> list[Path]:
    return sorted(REAL.glob(pattern))


@needs_real
def test_the_gsf_file_holds_the_independent_parsers_figures():
    s = summarize_survey(_real("noaa_okeanos_ex1604_gsf/*.gsf"))
    assert s["format"] == "gsf" and s["pings"] == 8 and s["beams_per_ping"] == [432]
    assert s["valid_soundings"] == 2369
    assert _utc("2016-03-23 18:55:53") <= _utc(s["time_start_utc"][:-1]) < _utc("2016-03-23 18:55:54")
    assert _utc("2016-03-23 18:56:58") <= _utc(s["time_end_utc"][:-1]) < _utc("2016-03-23 18:56:59")
    assert round(s["depth_m"]["min"]) == 3862 and round(s["depth_m"]["max"]) == 4145
    e = s["extent"]
    assert 8.6 < e["south"] < e["north"] < 8.8 and 167.4 < e["west"] < e["east"] < 167.6
    assert not s["skipped"]


@needs_real
def test_the_ga4430_em122_file_holds_its_figures():
    s = summarize_survey(_real("ga4430_em122_all/*.all"))
    assert s["format"] == "kongsberg-all" and s["pings"] == 11 and s["beams_per_ping"] == [432]
    assert s["time_start_utc"].startswith("2015-02-07T04:43:49") and s["time_end_utc"].startswith("2015-02-07T04:44:27")
    assert round(s["depth_m"]["min"]) == 3480 and round(s["depth_m"]["max"]) == 3661
    e = s["extent"]  # beams span 38.962-38.920 S, 86.691-86.711 E
    assert e["south"] == pytest.approx(-38.962, abs=0.002) and e["north"] == pytest.approx(-38.920, abs=0.002)
    assert e["west"] == pytest.approx(86.691, abs=0.002) and e["east"] == pytest.approx(86.711, abs=0.002)
    assert not s["skipped"]


@needs_real
def test_the_investigator_em710_file_holds_its_figures():
    s = summarize_survey(_real("ausseabed_investigator_em710_all/*.all"))
    assert s["pings"] == 158 and s["beams_per_ping"] == [400] and s["valid_soundings"] == 62936
    assert s["time_start_utc"].startswith("2020-01-07T03:55:0") and s["duration_s"] == pytest.approx(7, abs=0.5)
    assert s["depth_m"]["min"] == pytest.approx(10.9, abs=0.05) and s["depth_m"]["max"] == pytest.approx(15.5, abs=0.05)
    assert s["extent"]["south"] == pytest.approx(-32.1537, abs=0.002) and s["extent"]["west"] == pytest.approx(115.7651, abs=0.002)


@needs_real
@pytest.mark.parametrize("name", [p.name for p in _real("kongsberg_snippets_tmtgp/*.all")] or ["none"])
def test_each_kongsberg_all_snippet_reads_whole(name):
    path = REAL / "kongsberg_snippets_tmtgp" / name
    if not path.is_file():
        pytest.skip("no snippet files")
    s = summarize_survey(path)
    assert 8 <= s["pings"] <= 35 and not s["skipped"]
    assert 10.5 <= s["depth_m"]["min"] <= s["depth_m"]["max"] <= 212  # the folder's 11-211 m
    assert s["beams_per_ping"][0] in (128, 256, 400) and s["valid_soundings"] > 0.5 * s["soundings"]


@needs_real
@pytest.mark.parametrize("name", [p.name for p in _real("kongsberg_snippets_tmtgp/*.kmall")] or ["none"])
def test_each_kmall_snippet_is_where_and_how_deep_its_source_says(name):
    path = REAL / "kongsberg_snippets_tmtgp" / name
    if not path.is_file():
        pytest.skip("no snippet files")
    s = summarize_survey(path)
    e = s["extent"]
    assert not s["skipped"]
    if "_OS0" in name:  # near Ostend, 5-6 pings, moored
        assert 5 <= s["pings"] <= 6
        assert 51.2 < e["south"] <= e["north"] < 51.27 and 2.89 < e["west"] <= e["east"] < 2.96
        assert 2 < s["depth_m"]["min"] <= s["depth_m"]["max"] < 12
    else:  # 'eg': 25 pings at 27.58 N 82.75 W, 1.7-5 m
        assert s["pings"] == 25
        assert e["south"] == pytest.approx(27.58, abs=0.01) and e["west"] == pytest.approx(-82.75, abs=0.01)
        assert 1.7 <= s["depth_m"]["min"] <= s["depth_m"]["max"] <= 5


@needs_real
def test_pings_are_projected_and_their_beams_placed_by_heading():
    survey = open_survey(_real("ga4430_em122_all/*.all"))
    ping = next(iter(survey))
    assert survey.crs == "EPSG:32745"  # UTM 45 S (84-90 E)
    assert np.isfinite(ping.east_m) and np.isfinite(ping.north_m)
    across = ping.beam_east_m - ping.east_m, ping.beam_north_m - ping.north_m
    from pyproj import Proj

    # The grid bearing of true north, checked against pyproj's own meridian convergence (sign: its angle is grid north's true bearing).
    factors = Proj(survey.crs).get_factors(ping.lon_deg, ping.lat_deg)
    assert ping.convergence_deg == pytest.approx(-factors.meridian_convergence, abs=1e-3)
    assert 0.05 < abs(ping.convergence_deg) < 0.5  # 86.70 E is 0.3 degrees west of zone 45's central meridian, at 38.9 S
    h = np.radians(ping.heading_deg + ping.convergence_deg)  # starboard of a grid heading h points to (cos h, -sin h)
    starboard = ping.across_m > 1000
    assert np.allclose(across[0][starboard] / ping.across_m[starboard], np.cos(h), atol=0.01)
    assert np.allclose(across[1][starboard] / ping.across_m[starboard], -np.sin(h), atol=0.01)
    assert 1400 < ping.sound_speed_mps < 1600 and 0 <= ping.heading_deg < 360


@needs_real
def test_the_text_summary_names_format_counts_and_depths():
    text = format_summary(summarize_survey(_real("noaa_okeanos_ex1604_gsf/*.gsf")))
    assert "gsf" in text and "pings 8" in text and "valid soundings 2369 of 3456" in text and "3862.43" in text


def test_a_file_of_no_survey_format_is_named(tmp_path):
    path = tmp_path / "notes.all"
    path.write_text("this is a text file, not a sonar's\n")
    with pytest.raises(ValueError, match="notes.all is not a Kongsberg .all, .kmall or GSF file"):
        survey_format(path)
