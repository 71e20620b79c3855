"""USBL fixes as the ships' USBLs send them: Sonardyne ``$PSONLLD`` and Kongsberg HiPAP/HPR ``$PSIMSSB``; and the
``$--THS`` heading sentence, which pynmea2 does not know.

``$PSONLLD`` (Sonardyne Ranger 2 / Fusion USBL, the beacon's geographic position)::

    $PSONLLD,hhmmss.sss,ID,S,LAT,LON,DEPTH,MAJOR,MINOR,DIRECTION,DEPTH_SD,,,,*hh
    time of the fix (UTC time of day), beacon name or number, status (A valid, V not),
    latitude and longitude in decimal degrees (signed), depth (m),
    the position's error ellipse: semi-major and semi-minor axes (1 sigma, m) and the direction of the major axis
    (degrees clockwise from true north), the depth's 1 sigma (m); the fields after these left empty.

``$PSIMSSB`` (Kongsberg HiPAP/HPR/APOS "SSB", a transponder's position)::

    $PSIMSSB,hhmmss.ss,TP,S,ERR,CS,OR,FILTER,X,Y,DEPTH,ACCURACY,ADD,ADD1,ADD2*hh
    time of day, transponder code (B01 ...), status (A valid, V not), error code, coordinate system
    (C cartesian, P polar, U UTM, R geographic in radians), orientation (H vessel, N north, E east),
    software filter (M measured, F filtered, P predicted), X and Y (for R: latitude and longitude, radians),
    depth (m), expected accuracy (m), additional information and its values.

Only ``R`` places a fix without the ship's position and heading (``C``, ``P``: relative to the vessel) or a UTM
zone the sentence does not carry (``U``): those are counted and skipped. The expected accuracy is taken as an
isotropic 1 sigma (m). A sentence without error fields (empty, or 0) takes ``default_sigma_m`` when one is set,
and is refused and counted when not.

The time of day is dated by the latest ZDA (the day before or after it when that is nearer the latest GGA's time,
across midnight). Without a ZDA (no GNSS on any port, or none yet), by the sonar's own clock: the day of the latest
``.kmall`` datagram's time (its header's epoch seconds), the day before or after when that is nearer it. Each fix
is counted by what dated it; a fix before any ZDA and any ``.kmall`` datagram is counted and skipped.
"""

from __future__ import annotations

import datetime as dt
import math
from collections import Counter

import pynmea2
from pynmea2 import nmea_utils

from .clock import nmea_clock
from .inputs import UsblFix

__all__ = ["THS", "usbl_fix", "psonlld_sentence", "psimssb_sentence", "ellipse_covariance", "HEADING_MODES_USED"]

HEADING_MODES_USED = frozenset({"A", "E"})  # THS mode: autonomous, estimated; not M manual, S simulator, V not valid
_DAY_S = 86_400.0


class THS(pynmea2.TalkerSentence):
    """True heading and status (NMEA 0183 4.x): heading in degrees, mode indicator. pynmea2 registers it by its name."""

    fields = (("Heading", "heading", float), ("Mode indicator", "mode"))


def ellipse_covariance(major_m: float, minor_m: float, direction_deg: float) -> tuple[float, float, float]:
    """The (east variance, north variance, covariance) of a 1-sigma error ellipse whose major axis points ``direction_deg`` from north."""
    theta = math.radians(direction_deg)
    ue, un = math.sin(theta), math.cos(theta)  # the major axis, east and north
    a2, b2 = major_m * major_m, minor_m * minor_m
    return a2 * ue * ue + b2 * un * un, a2 * un * un + b2 * ue * ue, (a2 - b2) * ue * un


def _number(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(text)
    return value


def _sigma(text: str) -> float | None:
    """A 1-sigma field: None when empty or 0 (the sentence gives none); a negative one is no sigma."""
    value = _number(text) if text.strip() else 0.0
    if value < 0.0:
        raise ValueError(text)
    return value or None


def usbl_fix(sentence: pynmea2.ProprietarySentence, date: dt.date | None, near_s: float, default_sigma_m: float | None,
             counts: Counter, *, sonar_time_s: float = math.nan) -> list[UsblFix]:
    """The fix of one ``$PSONLLD`` or ``$PSIMSSB`` (pynmea2's proprietary sentence, checksum checked); [] and a count otherwise.

    ``date`` is the latest ZDA's and ``near_s`` the latest GGA's time (NaN: none); ``sonar_time_s`` the latest ``.kmall``
    datagram's time (NaN: none), which dates the fix when no ZDA has come.
    """
    name = f"$P{sentence.manufacturer}{sentence.data[0]}"
    data = [*sentence.data[1:], *[""] * 14]
    counts[f"USBL {name} sentences"] += 1
    try:
        if name == "$PSONLLD":
            clock, status, lat, lon, depth = data[0], data[2], _number(data[3]), _number(data[4]), _number(data[5])
            major, minor = _sigma(data[6]), _sigma(data[7])
            direction = _number(data[8]) if data[8].strip() else 0.0
            covariance = ellipse_covariance(major, minor or major, direction) if major else None
        else:
            clock, status, system = data[0], data[2], data[4]
            if system != "R":
                counts[f"USBL $PSIMSSB in coordinate system {system[:1] or 'none'} (not geographic; skipped)"] += 1
                return []
            lat, lon, depth = math.degrees(_number(data[7])), math.degrees(_number(data[8])), _number(data[9])
            sigma = _sigma(data[10])
            covariance = (sigma * sigma, sigma * sigma, 0.0) if sigma else None
        seconds = _clock_s(clock)
    except (ValueError, IndexError):
        counts[f"USBL {name} with a field that is no number (skipped)"] += 1
        return []
    if status != "A":
        counts[f"USBL {name} marked not valid (status not A; skipped)"] += 1
        return []
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
        counts[f"USBL {name} with a position off the globe (skipped)"] += 1
        return []
    if covariance is None:
        if default_sigma_m is None:
            counts[f"USBL {name} without error fields and no [serve] usbl_default_sigma_m (skipped)"] += 1
            return []
        covariance = (default_sigma_m ** 2, default_sigma_m ** 2, 0.0)
        counts[f"USBL {name} fixes given the default sigma"] += 1
    if date is not None:
        dated_by = "the ZDA"
        near_s = near_s if math.isfinite(near_s) else sonar_time_s
    elif math.isfinite(sonar_time_s):
        dated_by, near_s = "the sonar's datagram time (no ZDA)", sonar_time_s
        date = dt.datetime.fromtimestamp(sonar_time_s, dt.UTC).date()
    else:
        counts[f"USBL {name} before any ZDA or .kmall datagram (no date; skipped)"] += 1
        return []
    time_s = dt.datetime.combine(date, dt.time(), dt.UTC).timestamp() + seconds
    if math.isfinite(near_s):
        time_s += round((near_s - time_s) / _DAY_S) * _DAY_S  # the day nearest the clock's time (a fix just before midnight)
    counts[f"USBL {name} fixes dated by {dated_by}"] += 1
    return [UsblFix(time_s, lat, lon, depth, *covariance)]


def _clock_s(text: str) -> float:
    """Seconds of the day of an ``hhmmss.s...`` field, read by pynmea2 (to the microsecond); ValueError if it is no time of day."""
    if len(text) < 6 or not text[:6].isdigit():
        raise ValueError(text)
    clock = nmea_utils.timestamp(text)  # datetime.time: an hour 24 or more, a minute or second 60 or more raise ValueError
    return clock.hour * 3600.0 + clock.minute * 60.0 + clock.second + clock.microsecond * 1e-6


def _clock(time_s: float, decimals: int) -> str:
    return nmea_clock(time_s, decimals)[1]


def psonlld_sentence(fix: UsblFix, beacon: str = "1", *, major_m: float | None = None, minor_m: float | None = None,
                     direction_deg: float = 0.0, depth_sd_m: float | None = None) -> str:
    """A ``$PSONLLD`` of ``fix`` in the layout above (error fields empty when ``major_m`` is None), with checksum, no line end."""
    errors = ("", "", "", "") if major_m is None else (f"{major_m:.2f}", f"{minor_m:.2f}", f"{direction_deg:.2f}",
                                                        "" if depth_sd_m is None else f"{depth_sd_m:.2f}")
    fields = ("LLD", _clock(fix.time_s, 3), beacon, "A", f"{fix.lat_deg:.8f}", f"{fix.lon_deg:.8f}", f"{fix.depth_m:.3f}", *errors, "", "", "", "")
    return str(pynmea2.ProprietarySentence("SON", fields))


def psimssb_sentence(fix: UsblFix, transponder: str = "B01", *, accuracy_m: float | None = None, system: str = "R") -> str:
    """A ``$PSIMSSB`` of ``fix`` in geographic radians (``system`` R), with checksum, no line end."""
    accuracy = "" if accuracy_m is None else f"{accuracy_m:.2f}"
    fields = ("SSB", _clock(fix.time_s, 2), transponder, "A", "", system, "N", "M", f"{math.radians(fix.lat_deg):.10f}",
              f"{math.radians(fix.lon_deg):.10f}", f"{fix.depth_m:.2f}", accuracy, "N", "", "")
    return str(pynmea2.ProprietarySentence("SIM", fields))
