"""GSF read through gsfu and written through gsfu, checked against libgsf (bluemvmt-gsf), the format's reference C library.

libgsf's JSON hand-over gives the depth, across-track offsets, position, heading and attitude of each ping (and the
beam flags of files with a sensor-specific subrecord), not the along-track offsets: it is the independent decoder of
those, and the along-track offsets are decoded here with ``struct`` from the format's layout. Real pings (an EM122
.all, the EX1604 GSF, an EM2040 .kmall) written as GSF read back to the format's precision; a simulated tow written
as GSF gives the records and the navigation the .all export gives.
"""

from __future__ import annotations

import json
import math
from collections import Counter
from dataclasses import replace
from itertools import islice
from pathlib import Path

import numpy as np
import pytest

from lost.host.io.gsf import read_gsf_pings
from lost.host.io.gsf_write import write_gsf_pings
from lost.host.io.kongsberg_all import write_all_pings
from lost.host.io.simulated import simulated_pings
from lost.host.io.survey import open_survey
from lost.host.io.survey_records import SurveyRecorder, survey_records
from lost.host.scenario import builtin_scenario_path, load_scenario

from .records_compare import assert_records_agree
from .survey_run import survey_run_summary

REAL = Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "real_survey"
EX1604 = REAL / "noaa_okeanos_ex1604_gsf" / "0029_20160323_185603_EX1604_MB.gsf"
REAL_FILES = [REAL / "ga4430_em122_all" / "0243_P007_MBES_EM122_20150207_044356_Supporter_GA4430.all", EX1604,
              REAL / "kongsberg_snippets_tmtgp" / "kmall_OS02_-2962169266352575506.kmall"]
needs_real = pytest.mark.skipif(not all(p.is_file() for p in REAL_FILES), reason=f"the real survey files are not under {REAL}")


def libgsf_pings(path: Path) -> list[dict]:
    """Each swath bathymetry ping record as libgsf hands it over (JSON)."""
    from bluemvmt_gsf.libgsf import GsfFile

    out = []
    with GsfFile(path) as gsf:
        for raw in gsf.next_json_record():
            record = json.loads(raw)
            if record.get("record_type") == 2:
                out.append(record["json_record"])
    return out


def assert_libgsf_agrees(pings, records: list[dict]) -> None:
    assert len(pings) == len(records) > 0
    for p, r in zip(pings, records, strict=True):
        assert p.time_s == pytest.approx(r["ping_time"], abs=1e-6)  # gsfu hands the time over to the microsecond
        assert (p.lat_deg, p.lon_deg, p.heading_deg) == (r["latitude"], r["longitude"], r["heading"])
        for name, key in (("roll_deg", "roll"), ("pitch_deg", "pitch"), ("heave_m", "heave")):
            assert getattr(p, name) == r[key] or (math.isnan(getattr(p, name)) and r[key] == 99), name
        np.testing.assert_array_equal(p.depth_m, r["depth"])
        np.testing.assert_array_equal(p.across_m, r["across_track"])
        if "beam_flags" in r:
            np.testing.assert_array_equal(p.valid, np.array(r["beam_flags"]) == 0)


def along_track_by_struct(path: Path) -> list[np.ndarray]:
    """Each ping's along-track offsets decoded here from GSF's layout (libgsf's gsf_dec.c): the record framing, the
    ping's 56-byte fixed part (GSF 3), then subrecords (identifier in the top byte of a word, size in the rest): the
    scale factors (100: per array a word, a multiplier, an offset) and the along-track array (3: value = raw / multiplier - offset)."""
    import struct

    data, at, out = path.read_bytes(), 0, []
    scale: dict[int, tuple[int, int]] = {}
    while at + 8 <= len(data):
        size, word = struct.unpack_from(">II", data, at)
        start = at + 8 + (4 if word & 0x80000000 else 0)
        if word & 0x3FFFFF == 2:
            beams = struct.unpack_from(">H", data, start + 16)[0]
            p, along = start + 56, None
            while p + 4 <= start + size:
                head = struct.unpack_from(">I", data, p)[0]
                kind, length = head >> 24, head & 0xFFFFFF
                if kind == 100:
                    for k in range(struct.unpack_from(">I", data, p + 4)[0]):
                        sub, multiplier, offset = struct.unpack_from(">IIi", data, p + 8 + 12 * k)
                        scale[sub >> 24] = (multiplier, offset)
                elif kind == 3:
                    raw = np.frombuffer(data, f">i{length // beams}", beams, p + 4)
                    along = raw / scale[3][0] - scale[3][1]
                p += 4 + length
            out.append(along)
        at = start + size
    return out


@needs_real
def test_the_ex1604_pings_are_libgsfs_values_and_carry_their_along_track_offsets():
    skipped, notes = Counter(), Counter()
    pings = list(read_gsf_pings(EX1604, skipped, notes))
    assert not skipped and not notes
    records = libgsf_pings(EX1604)
    assert all("beam_flags" in r and "along_track" not in r for r in records)  # what libgsf's JSON leaves out
    assert_libgsf_agrees(pings, records)
    assert sum(int(p.valid.sum()) for p in pings) == 2369  # the independent parser's count
    for p, along in zip(pings, along_track_by_struct(EX1604), strict=True):
        np.testing.assert_array_equal(p.along_m, along)
    along = np.concatenate([p.along_m for p in pings])
    assert along.min() < -600.0  # the outer beams hundreds of metres aft: taken as 0, they would be misplaced by that


@needs_real
@pytest.mark.parametrize("source", REAL_FILES, ids=lambda p: p.suffix + ":" + p.name[:12])
def test_real_pings_written_as_gsf_read_back_to_the_formats_precision(source, tmp_path):
    written = list(open_survey(source))
    path = write_gsf_pings(written, tmp_path / "out.gsf")
    skipped, notes = Counter(), Counter()
    read = list(read_gsf_pings(path, skipped, notes))
    assert not skipped and not notes and len(read) == len(written)
    for a, b in zip(written, read, strict=True):
        assert b.time_s == pytest.approx(a.time_s, abs=1e-6)
        assert b.lat_deg == pytest.approx(a.lat_deg, abs=0.5e-7) and b.lon_deg == pytest.approx(a.lon_deg, abs=0.5e-7)
        assert b.heading_deg == pytest.approx(a.heading_deg % 360.0, abs=0.005)
        for name in ("roll_deg", "pitch_deg", "heave_m"):
            x, y = getattr(a, name), getattr(b, name)
            assert (math.isnan(x) and math.isnan(y)) or y == pytest.approx(x, abs=0.005 + 1e-9), name
        assert math.isnan(b.sound_speed_mps)  # not written: GSF keeps it in vendor subrecords
        finite = np.isfinite(a.depth_m) & np.isfinite(a.across_m) & np.isfinite(a.along_m)
        np.testing.assert_array_equal(b.valid, a.valid & finite)
        np.testing.assert_allclose(b.depth_m[finite], a.depth_m[finite], atol=0.001 + 1e-9)  # a step of 1 mm (gsfu rounds within one)
        np.testing.assert_allclose(b.across_m[finite], a.across_m[finite], atol=0.001 + 1e-9)  # a step of 1 mm (gsfu rounds within one)
        np.testing.assert_allclose(b.along_m[finite], a.along_m[finite], atol=0.001 + 1e-9)  # a step of 1 mm (gsfu rounds within one)
    assert_libgsf_agrees(read, libgsf_pings(path))  # the reference library reads what gsfu wrote, as gsfu reads it
    for p, along in zip(read, along_track_by_struct(path), strict=True):
        np.testing.assert_array_equal(p.along_m, along)


@needs_real
def test_a_ping_without_attitude_reads_back_without_it_not_as_gsfs_placeholder(tmp_path):
    ping = next(iter(open_survey(EX1604)))
    path = write_gsf_pings([replace(ping, roll_deg=math.nan, pitch_deg=math.nan, heave_m=math.nan)], tmp_path / "no_attitude.gsf")
    back = next(read_gsf_pings(path, Counter(), Counter()))
    assert math.isnan(back.roll_deg) and math.isnan(back.pitch_deg) and math.isnan(back.heave_m)
    assert libgsf_pings(path)[0]["roll"] == 99  # GSF's "not available", which would read as 99 degrees


@needs_real
def test_a_ping_without_position_or_above_the_water_line_is_refused_and_leaves_no_file(tmp_path):
    ping = next(iter(open_survey(EX1604)))
    with pytest.raises(ValueError, match="ping 1 at t=.* has no position or heading; a GSF ping needs both"):
        write_gsf_pings([ping, replace(ping, lat_deg=math.nan)], tmp_path / "a.gsf")
    depth = ping.depth_m.copy()
    depth[5] = -2.0
    with pytest.raises(ValueError, match="beam 5 is 2.00 m above the water line"):
        write_gsf_pings([replace(ping, depth_m=depth)], tmp_path / "b.gsf")
    assert list(tmp_path.iterdir()) == []


def test_a_simulated_tow_as_gsf_gives_the_all_routes_records(tmp_path):
    scenario = load_scenario(builtin_scenario_path("short_exact_map"))
    grid, crs, pings = simulated_pings(scenario)
    pings = list(islice(pings, 200))
    gsf, allfile = write_gsf_pings(pings, tmp_path / "tow.gsf"), write_all_pings(pings, tmp_path / "tow.all")

    def records(path):
        recorder = SurveyRecorder(node_m=grid.node_m, patch_shape=(10, 10), interval_s=2.0, window_s=20.0, patch_centre="soundings")
        return survey_records(open_survey(path, crs=crs), recorder)

    assert_records_agree(records(allfile), records(gsf), 100)


def test_lost_run_survey_on_a_gsf_export_converges_like_the_all_export(tmp_path, capsys):
    from lost.host.io import write_npz

    scenario = load_scenario(builtin_scenario_path("short_exact_map"))
    grid, _, pings = simulated_pings(scenario)
    path, map_path = write_gsf_pings(pings, tmp_path / "short.gsf"), write_npz(grid, tmp_path / "short_map.npz")
    out = tmp_path / "run"
    summary = survey_run_summary(path, map_path, out)
    capsys.readouterr()
    pmf, dead = summary["methods"]["pmf"], summary["methods"]["dead_reckoning"]
    # The thresholds of the .all export's run (tests/host/io/test_simulated_export.py): its records are the .all route's (above).
    assert summary["convergence"]["converged"]
    assert pmf["rms_m"] < 4.0 and pmf["p95_m"] < 7.0 and dead["rms_m"] > 40.0
    assert 0.7 <= pmf["nees_in_band"] <= 1.0
