"""A USBL's own sentences (Sonardyne `$PSONLLD`, Kongsberg `$PSIMSSB`) and `$--THS` headings: real lines printed by public
sources, used verbatim, and lines built from the documented layouts decode to the fix they carry, its covariance from the
sentence's error fields (or the configured default), checksums checked."""

from __future__ import annotations

import datetime as dt
import math

import numpy as np
import pytest

from lost.host.live.inputs import UsblFix
from lost.host.live.nmea import HeadingFix, fix_sentences
from lost.host.live.receiver import LiveDecoder
from lost.host.live.usbl_nmea import ellipse_covariance, psimssb_sentence, psonlld_sentence

# Printed in WHOI's ds_sensors (sonardyne_usbl.cpp) as an Alvin fix from a Ranger 2; and in MARUM's NMEA documentation.
WHOI_PSONLLD = "$PSONLLD,170004.53,ALVIN 914,A,28.8114807,-87.80925696,1951.156,13.96,13.96,0.00,2.62,,,,*6F"
MARUM_PSONLLD = "$PSONLLD,153005.253,24,A,50.02495,8.873323,425.3,,,,,,,,*3e"
# Printed in Navis' NavDP 4000 manual as its SSB example; its checksum does not match its characters (0C, not 20).
NAVIS_PSIMSSB = "$PSIMSSB,085405.61,B42,A,,C,H,M,134.5,114.5,120.0,,,,*20"
DAY = dt.datetime(2026, 1, 1, tzinfo=dt.UTC).timestamp()


def _dated(default_sigma_m: float | None = None, at_s: float = DAY + 12 * 3600.0) -> LiveDecoder:
    decoder = LiveDecoder(usbl_default_sigma_m=default_sigma_m)
    for sentence in fix_sentences(at_s, 0.0, 0.0):
        decoder.feed(sentence.encode())
    return decoder


def _feed(decoder: LiveDecoder, line: str) -> list:
    return decoder.feed((line + "\r\n").encode())


def test_the_printed_psonlld_lines_decode_to_their_fix_with_the_ellipse_or_the_default():
    decoder = _dated()
    (fix,) = _feed(decoder, WHOI_PSONLLD)
    assert fix == UsblFix(DAY + 17 * 3600 + 4.53, 28.8114807, -87.80925696, 1951.156, 13.96 ** 2, 13.96 ** 2, 0.0)
    assert _feed(decoder, MARUM_PSONLLD) == []  # no error fields, no default: refused
    assert decoder.counts["USBL $PSONLLD without error fields and no [serve] usbl_default_sigma_m (skipped)"] == 1
    decoder = _dated(default_sigma_m=5.0)
    (fix,) = _feed(decoder, MARUM_PSONLLD)
    assert fix == UsblFix(DAY + 15 * 3600 + 30 * 60 + 5.253, 50.02495, 8.873323, 425.3, 25.0, 25.0, 0.0)
    assert decoder.counts["USBL $PSONLLD fixes given the default sigma"] == 1 and decoder.counts["USBL $PSONLLD sentences"] == 1


def test_the_printed_psimssb_line_is_refused_for_its_checksum_and_relative_coordinates_are_counted():
    decoder = _dated()
    assert _feed(decoder, NAVIS_PSIMSSB) == []
    assert decoder.counts["NMEA sentence with a wrong or missing checksum"] == 1
    assert _feed(decoder, NAVIS_PSIMSSB[:-2] + "0C") == []  # its checksum mended: cartesian, relative to the vessel
    assert decoder.counts["USBL $PSIMSSB in coordinate system C (not geographic; skipped)"] == 1


def test_the_ellipse_is_the_rotated_diagonal():
    for major, minor, direction in [(3.0, 1.0, 0.0), (3.0, 1.0, 90.0), (5.0, 2.0, 30.0), (4.0, 4.0, 123.0), (2.5, 0.5, 315.0)]:
        theta = math.radians(direction)
        axes = np.array([[math.sin(theta), math.cos(theta)], [math.cos(theta), -math.sin(theta)]]).T  # columns: major, minor (east, north)
        expected = axes @ np.diag([major ** 2, minor ** 2]) @ axes.T
        sxx, syy, sxy = ellipse_covariance(major, minor, direction)
        np.testing.assert_allclose([[sxx, sxy], [sxy, syy]], expected, atol=1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_built_sentences_decode_to_their_fix_at_their_precision(seed):
    rng = np.random.default_rng(seed)
    decoder = _dated(at_s=DAY + 6 * 3600.0)
    for _ in range(40):
        time_s = DAY + round(float(rng.uniform(0, 64_000)), 2)  # within 12 h of the GGA at 06:00
        lat, lon, depth = float(rng.uniform(-89, 89)), float(rng.uniform(-179, 179)), float(rng.uniform(0, 6000))
        major, minor, direction = round(float(rng.uniform(1, 30)), 2), 0.0, round(float(rng.uniform(0, 360)), 2)
        minor = round(major * float(rng.uniform(0.2, 1.0)), 2)
        fix = UsblFix(time_s, lat, lon, depth, 0.0, 0.0, 0.0)
        (son,) = _feed(decoder, psonlld_sentence(fix, major_m=major, minor_m=minor, direction_deg=direction, depth_sd_m=1.0))
        assert son.time_s == pytest.approx(time_s, abs=1e-6) and son.depth_m == pytest.approx(depth, abs=5e-4)
        assert (son.lat_deg, son.lon_deg) == pytest.approx((lat, lon), abs=5e-9)
        assert (son.sxx_m2, son.syy_m2, son.sxy_m2) == pytest.approx(ellipse_covariance(major, minor, direction), rel=1e-12)
        accuracy = round(float(rng.uniform(0.5, 20)), 2)
        (sim,) = _feed(decoder, psimssb_sentence(fix, accuracy_m=accuracy))
        assert sim.time_s == pytest.approx(time_s, abs=1e-6) and sim.depth_m == pytest.approx(depth, abs=5e-3)
        assert (sim.lat_deg, sim.lon_deg) == pytest.approx((lat, lon), abs=1e-8)  # 1e-10 rad: under a millimetre
        assert (sim.sxx_m2, sim.syy_m2, sim.sxy_m2) == (accuracy ** 2, accuracy ** 2, 0.0)
    assert decoder.counts["USBL $PSONLLD sentences"] == decoder.counts["USBL $PSIMSSB sentences"] == 40


def test_a_fix_just_before_midnight_is_dated_the_day_before_the_latest_zda():
    decoder = _dated(at_s=DAY + 86_400.0 + 0.5)  # ZDA and GGA of the next day, 00:00:00.5
    fix = UsblFix(DAY + 86_399.9, 1.0, 2.0, 100.0, 0.0, 0.0, 0.0)
    (late,) = _feed(decoder, psonlld_sentence(fix, major_m=2.0, minor_m=2.0))
    assert late.time_s == pytest.approx(DAY + 86_399.9, abs=1e-6)


def test_ths_headings_are_decoded_like_hdt_and_a_not_valid_one_counted():
    decoder = _dated()
    (heading,) = _feed(decoder, "$HETHS,123.45,A*1C")
    assert heading == HeadingFix(DAY + 12 * 3600.0, 123.45)
    assert _feed(decoder, "$HETHS,123.45,V*0B") == [] and _feed(decoder, "$HETHS,123.45,A*1D") == []
    assert decoder.counts["NMEA THS sentences"] == 2 and decoder.counts["NMEA THS heading marked not valid (mode not A or E; skipped)"] == 1
    assert decoder.counts["NMEA sentence with a wrong or missing checksum"] == 1


def test_without_a_zda_a_fix_is_dated_by_the_sonars_datagram_time_and_counted_by_what_dated_it():
    from lost.host.io.kmall_write import encode_spo

    decoder = LiveDecoder()  # no GNSS: only the sonar's datagrams
    assert decoder.feed(encode_spo(DAY + 12 * 3600.0 + 0.25, 0.0, 0.0)) == []
    (fix,) = _feed(decoder, WHOI_PSONLLD)
    assert fix.time_s == pytest.approx(DAY + 17 * 3600 + 4.53, abs=1e-6)
    # Across midnight: the sonar's clock at 00:00:00.5 of the next day, a fix at 23:59:59.9 is the day before's.
    decoder.feed(encode_spo(DAY + 86_400.0 + 0.5, 0.0, 0.0))
    late = UsblFix(DAY + 86_399.9, 1.0, 2.0, 100.0, 0.0, 0.0, 0.0)
    (fix,) = _feed(decoder, psimssb_sentence(late, accuracy_m=2.0))
    assert fix.time_s == pytest.approx(DAY + 86_399.9, abs=1e-6)
    assert decoder.counts["USBL $PSONLLD fixes dated by the sonar's datagram time (no ZDA)"] == 1
    assert decoder.counts["USBL $PSIMSSB fixes dated by the sonar's datagram time (no ZDA)"] == 1
    # Once a ZDA has come, it dates the fixes, whatever the sonar's clock says.
    for sentence in fix_sentences(DAY + 2 * 86_400.0 + 12 * 3600.0, 0.0, 0.0):
        decoder.feed(sentence.encode())
    (fix,) = _feed(decoder, WHOI_PSONLLD)
    assert fix.time_s == pytest.approx(DAY + 2 * 86_400.0 + 17 * 3600 + 4.53, abs=1e-6)
    assert decoder.counts["USBL $PSONLLD fixes dated by the ZDA"] == 1
