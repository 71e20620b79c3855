"""NMEA 0183 sentences of a GNSS and a gyro: GGA, VTG, ZDA and HDT (and THS) formatted and parsed through pynmea2.

Sent per fix, in this order: ZDA (the date, which GGA lacks), GGA (position, fix quality), VTG (course and speed
over ground), HDT (true heading). Times to the millisecond, latitude and longitude to 1e-7 minute (0.2 mm),
course and heading to 0.01 degree, speed to 0.001 knot. Parsing checks each sentence's checksum (a sentence
without one is refused too) and joins a GGA's time of day with the date of the latest ZDA;
a GGA of the same time as the one before (a duplicate) is counted and skipped. A USBL's ``$PSONLLD`` and
``$PSIMSSB`` are decoded by :mod:`lost.host.live.usbl_nmea`, a ``$--THS`` heading like HDT.
"""

from __future__ import annotations

import datetime as dt
import math
from dataclasses import dataclass

import pynmea2

from .clock import nmea_clock
from .inputs import UsblFix
from .usbl_nmea import HEADING_MODES_USED, usbl_fix

__all__ = ["PositionFix", "HeadingFix", "fix_sentences", "NmeaDecoder", "KNOT_MPS"]

KNOT_MPS = 1852.0 / 3600.0
_TALKER = "GP"


@dataclass(frozen=True)
class PositionFix:
    """A GNSS fix: POSIX time (UTC), WGS 84 latitude/longitude, GGA fix quality; course and speed over ground (NaN when not yet known)."""

    time_s: float
    lat_deg: float
    lon_deg: float
    quality: int
    course_deg: float = math.nan
    speed_mps: float = math.nan


@dataclass(frozen=True)
class HeadingFix:
    """A true heading (HDT), degrees clockwise from north, at the time of the latest fix."""

    time_s: float
    heading_deg: float


def _angle(value: float, degree_digits: int, hemispheres: str) -> tuple[str, str]:
    degrees_part = int(abs(value))
    minutes = round((abs(value) - degrees_part) * 60.0, 7)
    if minutes >= 60.0:
        degrees_part, minutes = degrees_part + 1, 0.0
    return f"{degrees_part:0{degree_digits}d}{minutes:010.7f}", hemispheres[0] if value >= 0 else hemispheres[1]


def _bearing(degrees: float) -> str:
    """0.00 to 359.99: 359.996 is 0.00, not 360.00."""
    return f"{round(degrees % 360.0, 2) % 360.0:.2f}"


def fix_sentences(time_s: float, lat_deg: float, lon_deg: float, *, heading_deg: float = math.nan, course_deg: float = math.nan,
                  speed_mps: float = math.nan) -> list[str]:
    """The sentences of one fix (see the module), each with its ``$`` and checksum, without line ending; HDT only with a heading, VTG only with a course."""
    moment, clock = nmea_clock(time_s, 3)
    lat, ns = _angle(lat_deg, 2, "NS")
    lon, ew = _angle(lon_deg, 3, "EW")
    out = [pynmea2.ZDA(_TALKER, "ZDA", (clock, f"{moment.day:02d}", f"{moment.month:02d}", f"{moment.year:04d}", "00", "00")),
           pynmea2.GGA(_TALKER, "GGA", (clock, lat, ns, lon, ew, "1", "12", "0.8", "0.0", "M", "0.0", "M", "", ""))]
    if math.isfinite(course_deg) and math.isfinite(speed_mps):
        knots = speed_mps / KNOT_MPS
        out.append(pynmea2.VTG(_TALKER, "VTG", (_bearing(course_deg), "T", "", "M", f"{knots:.3f}", "N", f"{speed_mps * 3.6:.3f}", "K", "A")))
    if math.isfinite(heading_deg):
        out.append(pynmea2.HDT("HE", "HDT", (_bearing(heading_deg), "T")))
    return [str(sentence) for sentence in out]


class NmeaDecoder:
    """Sentences in, fixes out; what cannot be used is counted in ``counts`` (reason -> count), never raised."""

    def __init__(self, counts, usbl_default_sigma_m: float | None = None) -> None:
        self.counts = counts
        self.usbl_default_sigma_m = usbl_default_sigma_m  # the 1 sigma (m) of a vendor USBL fix without error fields; None: refused
        self._date: dt.date | None = None
        self._last_time_s = math.nan
        self._pending: PositionFix | None = None
        self.sonar_time_s = math.nan  # the latest .kmall datagram's time, set by the receiver: dates a vendor USBL fix when no ZDA has come

    def feed(self, line: str) -> list[PositionFix | HeadingFix | UsblFix]:
        """The fixes one sentence completes (a GGA is held until its VTG, or the next GGA, comes; a USBL's at once)."""
        try:
            sentence = pynmea2.parse(line.strip(), check=True)
        except pynmea2.ChecksumError:
            self.counts["NMEA sentence with a wrong or missing checksum"] += 1
            return []
        except (pynmea2.ParseError, ValueError, AttributeError, TypeError):
            self.counts["NMEA sentence that does not parse"] += 1
            return []
        if isinstance(sentence, pynmea2.ProprietarySentence):
            return self._proprietary(sentence)
        kind = sentence.sentence_type
        self.counts[f"NMEA {kind} sentences"] += 1
        try:
            if kind == "ZDA":
                self._date = dt.date(int(sentence.year), int(sentence.month), int(sentence.day))
                return []
            if kind == "GGA":
                return self._gga(sentence)
            if kind == "VTG":
                return self._vtg(sentence)
            if kind == "HDT":
                return [HeadingFix(self._last_time_s, float(sentence.heading))]
            if kind == "THS":
                if sentence.mode not in HEADING_MODES_USED:
                    self.counts["NMEA THS heading marked not valid (mode not A or E; skipped)"] += 1
                    return []
                return [HeadingFix(self._last_time_s, float(sentence.heading))]
        except (ValueError, TypeError):
            self.counts[f"NMEA {kind} sentence with a field that is no number"] += 1
            return []
        self.counts[f"NMEA {kind} sentence (not used)"] += 1
        return []

    def _proprietary(self, sentence: pynmea2.ProprietarySentence) -> list[UsblFix]:
        kind = f"P{sentence.manufacturer}{sentence.data[0] if sentence.data else ''}"
        if kind in ("PSONLLD", "PSIMSSB"):
            return usbl_fix(sentence, self._date, self._last_time_s, self.usbl_default_sigma_m, self.counts, sonar_time_s=self.sonar_time_s)
        self.counts["NMEA proprietary sentence (not used)"] += 1  # one counter: a vendor's names are not a bounded set
        return []

    def flush(self) -> list[PositionFix]:
        """The fix held for its VTG, if any."""
        held, self._pending = self._pending, None
        return [held] if held is not None else []

    def _gga(self, sentence) -> list[PositionFix]:
        out = self.flush()
        if self._date is None:
            self.counts["NMEA GGA before any ZDA (no date)"] += 1
            return out
        clock = sentence.timestamp
        if clock is None or not sentence.lat or not sentence.lon:
            self.counts["NMEA GGA without time or position"] += 1
            return out
        moment = dt.datetime.combine(self._date, clock.replace(tzinfo=None), dt.UTC)
        if moment.timestamp() == self._last_time_s:
            self.counts["NMEA GGA repeating the time of the one before (skipped)"] += 1
            return out
        self._last_time_s = moment.timestamp()
        self._pending = PositionFix(self._last_time_s, float(sentence.latitude), float(sentence.longitude), int(sentence.gps_qual or 0))
        return out

    def _vtg(self, sentence) -> list[PositionFix]:
        if self._pending is None:
            self.counts["NMEA VTG without a GGA before it"] += 1
            return []
        held, self._pending = self._pending, None
        speed = float(sentence.spd_over_grnd_kmph) / 3.6 if sentence.spd_over_grnd_kmph is not None else math.nan  # 0 is a speed
        course = float(sentence.true_track) if sentence.true_track is not None else math.nan
        return [PositionFix(held.time_s, held.lat_deg, held.lon_deg, held.quality, course, speed)]
