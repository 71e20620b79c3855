"""Pings written as Kongsberg .all and read back: real pings of three sonars, to the format's precision."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lost.host.io.kongsberg_all import write_all_pings
from lost.host.io.survey import Ping, open_survey

REAL = Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "real_survey"
needs_real = pytest.mark.skipif(not REAL.is_dir(), reason=f"the real survey files are not at {REAL} (shared/data/real_survey beside the repository)")
SOURCES = ["ga4430_em122_all/*.all", "noaa_okeanos_ex1604_gsf/*.gsf", "kongsberg_snippets_tmtgp/kmall_OS02_-29*.kmall"]


@needs_real
@pytest.mark.parametrize("pattern", SOURCES)
def test_real_pings_written_as_all_read_back_to_the_formats_precision(tmp_path, pattern):
    source = sorted(REAL.glob(pattern))
    pings = list(open_survey(source))
    path = write_all_pings(pings, tmp_path / "export.all")
    survey = open_survey(path)
    back = list(survey)
    assert len(back) == len(pings) and not survey.skipped and not list(tmp_path.glob("*.partial"))
    for a, b in zip(pings, back):
        assert b.time_s == pytest.approx(a.time_s, abs=0.0005)
        assert b.lat_deg == pytest.approx(a.lat_deg, abs=0.5 / 2e7) and b.lon_deg == pytest.approx(a.lon_deg, abs=0.5 / 1e7)
        assert b.heading_deg == pytest.approx(a.heading_deg % 360, abs=0.005)
        for name, step in (("roll_deg", 0.005), ("pitch_deg", 0.005), ("heave_m", 0.005), ("sound_speed_mps", 0.05)):
            if np.isfinite(getattr(a, name)):
                assert getattr(b, name) == pytest.approx(getattr(a, name), abs=step), name
        np.testing.assert_array_equal(b.valid, a.valid)
        for name in ("depth_m", "across_m", "along_m"):
            np.testing.assert_allclose(getattr(b, name), getattr(a, name), rtol=2**-23, atol=1e-6, err_msg=name)


def test_a_ping_without_a_position_is_refused_and_nothing_is_left(tmp_path):
    beams = np.zeros(3)
    ping = Ping(time_s=1.6e9, lat_deg=float("nan"), lon_deg=2.0, heading_deg=0.0, roll_deg=0.0, pitch_deg=0.0, heave_m=0.0,
                sound_speed_mps=1500.0, along_m=beams, across_m=beams, depth_m=beams + 10, valid=beams == 0)
    with pytest.raises(ValueError, match="ping 0 at t=1600000000.0 has no position or heading"):
        write_all_pings([ping], tmp_path / "bad.all")
    assert not list(tmp_path.iterdir())
