"""NMEA sentences as sent and read back; the replay's pacing at a speed factor."""

from __future__ import annotations

import math
import socket
import time
from collections import Counter

import pynmea2
import pytest

from lost.host.live.nmea import HeadingFix, NmeaDecoder, PositionFix, fix_sentences
from lost.host.live.stream import LiveDatagram, send_datagrams

MIDNIGHT = 1_767_225_600.0  # 2026-01-01T00:00:00Z


@pytest.mark.parametrize("time_s, lat, lon", [(MIDNIGHT - 0.0004, -33.123456789, -151.5), (MIDNIGHT + 45_296.789, 59.99999999, 179.99999999),
                                              (MIDNIGHT + 1.5, 0.0, 0.0)])
def test_a_fix_reads_back_to_the_sentences_precision(time_s, lat, lon):
    sentences = fix_sentences(time_s, lat, lon, heading_deg=359.996, course_deg=-0.001, speed_mps=2.0)
    assert [s[3:6] for s in sentences] == ["ZDA", "GGA", "VTG", "HDT"]
    for sentence in sentences:  # pynmea2 itself agrees with every checksum
        pynmea2.parse(sentence, check=True)
    counts = Counter()
    decoder = NmeaDecoder(counts)
    out = [value for s in sentences for value in decoder.feed(s)] + decoder.flush()
    (fix,) = [v for v in out if isinstance(v, PositionFix)]
    (heading,) = [v for v in out if isinstance(v, HeadingFix)]
    assert fix.time_s == pytest.approx(round(time_s, 3), abs=1e-6)  # the millisecond, across midnight too
    assert fix.lat_deg == pytest.approx(lat, abs=2e-9) and fix.lon_deg == pytest.approx(lon, abs=2e-9)  # 1e-7 minute
    assert fix.course_deg == 0.0 and fix.speed_mps == pytest.approx(2.0, abs=1e-3) and fix.quality == 1
    assert heading.heading_deg == 0.0 and heading.time_s == fix.time_s  # 359.996 is 0.00, never 360.00
    assert not [r for r in counts if "wrong" in r or "parse" in r or "skipped" in r]


def test_without_a_course_there_is_no_vtg_and_the_fix_comes_at_the_next_gga():
    first = fix_sentences(MIDNIGHT + 1, 10.0, 20.0)
    second = fix_sentences(MIDNIGHT + 2, 10.0001, 20.0)
    assert len(first) == 2  # ZDA, GGA: no heading, no course
    decoder = NmeaDecoder(Counter())
    out = [v for s in first + second for v in decoder.feed(s)] + decoder.flush()
    assert [f.time_s for f in out] == [MIDNIGHT + 1, MIDNIGHT + 2] and all(math.isnan(f.speed_mps) for f in out)


def test_the_replay_keeps_the_datagrams_times_divided_by_the_speed():
    receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    receiver.bind(("127.0.0.1", 0))
    try:
        datagrams = [LiveDatagram(MIDNIGHT + k, "nmea", b"$x") for k in range(5)]  # 4 s of datagrams
        started = time.monotonic()
        sent = send_datagrams(datagrams, receiver.getsockname(), speed=20.0)
        assert 0.2 - 0.01 <= time.monotonic() - started < 1.5  # 4 s at 20x: 0.2 s, not less
        assert sent["nmea datagrams sent"] == 5 and sent["bytes sent"] == 10
    finally:
        receiver.close()
    with pytest.raises(ValueError, match="speed must be 0"):
        send_datagrams(datagrams, ("127.0.0.1", 9), speed=-1.0)


@pytest.mark.parametrize(("time_s", "decimals", "clock", "day"), [
    (1767225600.0 + 17 * 3600 + 4.53, 2, "170004.53", 1),
    (1767225600.0 + 17 * 3600 + 4.5304, 3, "170004.530", 1),
    (1767225600.0 + 86_399.9996, 3, "000000.000", 2),  # rounds up past midnight: the next day's date with it
    (1767225600.0 + 86_399.994, 2, "235959.99", 1),
    (1767225600.0 + 59.6, 0, "000100", 1),
])
def test_the_time_of_day_is_written_rounded_with_the_date_of_the_rounded_moment(time_s, decimals, clock, day):
    from lost.host.live.clock import nmea_clock

    moment, text = nmea_clock(time_s, decimals)
    assert text == clock and (moment.year, moment.month, moment.day) == (2026, 1, day)
