"""The .kmall writer, read back by pykmall (lost.host.io.kmall): real pings re-encoded, a simulated tow, and its records."""

from __future__ import annotations

import math
from dataclasses import replace
from itertools import islice
from pathlib import Path

import numpy as np
import pytest

from lost.host.io.kmall_write import HeadIndex, encode_mrz, split_datagram, write_kmall_pings
from lost.host.io.kongsberg_all import write_all_pings
from lost.host.io.simulated import simulated_pings
from lost.host.io.survey import open_survey
from lost.host.io.survey_records import SurveyRecorder, survey_records
from lost.host.scenario import builtin_scenario_path, load_scenario

from .records_compare import assert_records_agree

REAL = Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "real_survey"
REAL_FILES = [REAL / "kongsberg_snippets_tmtgp" / "all_a_c_519880139284219668.all",
              REAL / "ga4430_em122_all" / "0243_P007_MBES_EM122_20150207_044356_Supporter_GA4430.all",
              REAL / "noaa_okeanos_ex1604_gsf" / "0029_20160323_185603_EX1604_MB.gsf",
              REAL / "kongsberg_snippets_tmtgp" / "kmall_OS02_-2962169266352575506.kmall"]
_FLOAT32_REL = 2.0 ** -23


def assert_same_pings(written, read, heads: HeadIndex) -> None:
    """Value for value, within the format's float32 (doubles for time and position)."""
    assert len(read) == len(written) > 0
    for a, b in zip(written, read, strict=True):
        assert b.time_s == pytest.approx(a.time_s, abs=1e-6)
        assert (b.lat_deg, b.lon_deg) == (a.lat_deg, a.lon_deg)
        assert b.heading_deg == pytest.approx(a.heading_deg % 360.0, rel=_FLOAT32_REL, abs=1e-5)
        for name in ("roll_deg", "pitch_deg", "heave_m", "sound_speed_mps"):
            x, y = getattr(a, name), getattr(b, name)
            assert (math.isnan(x) and math.isnan(y)) or y == pytest.approx(x, rel=_FLOAT32_REL, abs=1e-6), name
        origin = a.origin_depth_m if math.isfinite(a.origin_depth_m) else 0.0
        assert b.origin_depth_m == pytest.approx(origin, rel=_FLOAT32_REL, abs=1e-6)
        assert b.head == heads[a.head]
        np.testing.assert_array_equal(b.valid, a.valid)
        for name in ("along_m", "across_m"):
            np.testing.assert_allclose(getattr(b, name), getattr(a, name), rtol=_FLOAT32_REL, atol=1e-6)
        # The depth is stored re the reference point: float32 of (depth - origin), plus the float32 origin back.
        np.testing.assert_allclose(b.depth_m, a.depth_m, rtol=0, atol=4 * _FLOAT32_REL * (np.nanmax(np.abs(a.depth_m)) + abs(origin)) + 1e-6)


@pytest.mark.parametrize("source", REAL_FILES, ids=lambda p: p.suffix + ":" + p.name[:12])
def test_real_pings_reencoded_as_kmall_read_back_value_for_value(source, tmp_path):
    if not source.exists():
        pytest.skip(f"real survey file not at {source}")
    written = list(islice(open_survey(source), 12))
    path = write_kmall_pings(written, tmp_path / "out.kmall")
    survey = open_survey(path)
    read = list(survey)
    assert survey.format == "kmall" and not survey.skipped and not survey.notes.get(f"{path.name}: no SKM attitude datagram")
    heads = HeadIndex()
    for ping in written:
        heads(ping.head)
    assert_same_pings(written, read, heads)
    assert not (tmp_path / "out.kmall.partial").exists()


def _short_pings(count: int):
    scenario = load_scenario(builtin_scenario_path("short_exact_map"))
    grid, crs, pings = simulated_pings(scenario)
    return grid, crs, list(islice(pings, count))


def test_a_simulated_tow_as_kmall_reads_back_and_gives_the_all_routes_records(tmp_path):
    grid, crs, pings = _short_pings(200)
    kmall = write_kmall_pings(pings, tmp_path / "tow.kmall")
    allfile = write_all_pings(pings, tmp_path / "tow.all")
    read = list(open_survey(kmall, crs=crs))
    heads = HeadIndex()
    heads(pings[0].head)
    assert_same_pings(pings, read, heads)  # no attitude, no sound speed: NaN back

    def records(path):
        recorder = SurveyRecorder(node_m=grid.node_m, patch_shape=(10, 10), interval_s=2.0, window_s=20.0, patch_centre="soundings")
        return survey_records(open_survey(path, crs=crs), recorder)

    a, b = records(allfile), records(kmall)
    assert_records_agree(a, b, 100)  # 200 pings at 1 Hz, a record each 2 s
    np.testing.assert_allclose(b.vehicle_depth_m, a.vehicle_depth_m, atol=0.01)


def test_a_large_mrz_splits_into_parts_that_join_back(tmp_path):
    _, _, pings = _short_pings(1)
    datagram = encode_mrz(pings[0])
    parts = split_datagram(datagram, 1000)
    assert len(parts) == math.ceil((len(datagram) - 28) / (1000 - 28)) and all(len(p) <= 1000 for p in parts)
    for number, part in enumerate(parts, start=1):
        assert int.from_bytes(part[:4], "little") == len(part) == int.from_bytes(part[-4:], "little")
        assert part[4:8] == b"#MRZ"
        assert (int.from_bytes(part[20:22], "little"), int.from_bytes(part[22:24], "little")) == (len(parts), number)
    assert b"".join(p[24:-4] for p in parts) == datagram[24:-4]
    assert split_datagram(datagram, len(datagram)) == [datagram]
    with pytest.raises(ValueError, match="no room"):
        split_datagram(datagram, 20)


def test_a_ping_without_position_is_refused_by_name():
    _, _, pings = _short_pings(1)
    with pytest.raises(ValueError, match="no position or heading"):
        encode_mrz(replace(pings[0], lat_deg=math.nan))


def test_a_ping_without_position_mid_file_leaves_no_file(tmp_path):
    _, _, pings = _short_pings(3)
    pings[1] = replace(pings[1], lon_deg=math.nan)
    with pytest.raises(ValueError, match="no position or heading"):
        write_kmall_pings(pings, tmp_path / "tow.kmall")
    assert list(tmp_path.iterdir()) == []
