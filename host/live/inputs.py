"""The vehicle's own sensors on the network: its DVL as Teledyne RDI PD6 or as JSON lines, its depth, the USBL's fixes.

PD6 (Teledyne RDI's ASCII output of a Workhorse Navigator or Pathfinder DVL, one ensemble as several lines, each
starting with ``:`` and ending CR LF; no checksum)::

    :SA,±PP.PP,±RR.RR,HHH.HH                          pitch, roll, heading (degrees)
    :TS,YYMMDDHHmmsshh,SS.S,+TT.T,DDDD.D,CCCC.C,BBB   time (to 1/100 s), salinity, temperature, transducer depth (m), sound speed, BIT
    :WI / :BI,±X,±Y,±Z,±E,S                           water-mass / bottom-track velocity, instrument axes (mm/s), status A or V
    :WS / :BS,±T,±L,±N,S                              ... ship axes (transverse, longitudinal, normal)
    :WE / :BE,±E,±N,±U,S                              ... earth axes (east, north, up)
    :WD / :BD,±E,±N,±U,RRRR.RR,TTT.TT                 distance travelled (m) east, north, up; range to bottom (m); seconds since the last good velocity

Used: ``:TS`` (the ensemble's time and the transducer's depth: a :class:`DepthReading`) and ``:BE`` (velocity over
the ground in earth axes, mm/s: a :class:`DvlVelocity` at the time of the ``:TS`` before it), when its status is
``A`` and no component is the bad-value marker -32768. Water-track lines (velocity through the water, not over the
ground) and the others are counted, not used; a ``:BE`` with status ``V`` is counted as bad.

JSON lines (one object a line, UTF-8), kind by the ``kind`` key, every field required, none other allowed::

    {"kind": "dvl", "time_utc_s": 1767225623.0, "east_mps": 0.12, "north_mps": 1.48}
    {"kind": "depth", "time_utc_s": 1767225623.0, "depth_m": 712.3}
    {"kind": "usbl", "time_utc_s": 1767225623.0, "lat_deg": 0.0123, "lon_deg": 0.0071, "depth_m": 712.3,
     "sxx_m2": 64.0, "syy_m2": 49.0, "sxy_m2": 3.5}

A USBL fix carries its covariance (east variance, north variance, their covariance, m²: the USBL's own error
ellipse), which the navigation weighs it by; variances not positive or ``sxy_m2² >= sxx_m2 * syy_m2`` make no
covariance, and the line is refused.

Nothing raises on bad input: a line that cannot be used is counted by kind (:attr:`counts`) and skipped.
"""

from __future__ import annotations

import datetime as dt
import json
import math
from collections import Counter
from dataclasses import dataclass

__all__ = ["DvlVelocity", "DepthReading", "UsblFix", "Pd6Decoder", "JsonInputDecoder", "pd6_sentences", "json_input_line"]

_BAD_VELOCITY = -32768  # PD6's marker of a velocity component it could not measure


@dataclass(frozen=True)
class DvlVelocity:
    """The DVL's velocity over the ground, earth axes: POSIX time, east and north m/s."""

    time_s: float
    east_mps: float
    north_mps: float


@dataclass(frozen=True)
class DepthReading:
    """The vehicle's depth (its pressure sensor, or the DVL transducer's), metres below the surface, at a POSIX time."""

    time_s: float
    depth_m: float


@dataclass(frozen=True)
class UsblFix:
    """A USBL position of the vehicle: POSIX time, WGS 84 latitude and longitude, depth (m), and its covariance
    (east variance, north variance, their covariance; m²)."""

    time_s: float
    lat_deg: float
    lon_deg: float
    depth_m: float
    sxx_m2: float
    syy_m2: float
    sxy_m2: float


class Pd6Decoder:
    """PD6 lines in, :class:`DvlVelocity` and :class:`DepthReading` out (see the module)."""

    def __init__(self, counts: Counter) -> None:
        self.counts = counts
        self._time_s: float | None = None  # the latest :TS of a good ensemble

    def feed(self, line: str) -> list[DvlVelocity | DepthReading]:
        kind, _, rest = line.strip().partition(",")
        fields = rest.split(",")
        try:
            if kind == ":TS":
                return self._ts(fields)
            if kind == ":BE":
                return self._be(fields)
        except (ValueError, IndexError):
            self.counts[f"PD6 {kind} line that does not parse (skipped)"] += 1
            return []
        if kind in (":SA", ":WI", ":BI", ":WS", ":BS", ":WE", ":WD", ":BD"):
            self.counts[f"PD6 {kind} lines (not used)"] += 1
        else:
            self.counts["PD6 line of no PD6 kind (skipped)"] += 1
        return []

    def _ts(self, fields: list[str]) -> list[DepthReading]:
        stamp = fields[0].strip()
        if len(stamp) != 14 or not stamp.isdigit():
            raise ValueError(stamp)
        moment = dt.datetime(2000 + int(stamp[0:2]), int(stamp[2:4]), int(stamp[4:6]), int(stamp[6:8]), int(stamp[8:10]), int(stamp[10:12]),
                             int(stamp[12:14]) * 10_000, tzinfo=dt.UTC)
        depth = float(fields[3])
        self._time_s = moment.timestamp()
        self.counts["PD6 :TS lines"] += 1
        return [DepthReading(self._time_s, depth)] if math.isfinite(depth) else []

    def _be(self, fields: list[str]) -> list[DvlVelocity]:
        east, north, up = (int(f) for f in fields[:3])
        if self._time_s is None:
            self.counts["PD6 :BE before any :TS (no time; skipped)"] += 1
            return []
        if fields[3].strip() != "A" or _BAD_VELOCITY in (east, north, up):
            self.counts["PD6 :BE marked bad (status V or -32768; skipped)"] += 1
            return []
        self.counts["PD6 :BE lines"] += 1
        return [DvlVelocity(self._time_s, east / 1000.0, north / 1000.0)]


_JSON_KINDS = {"dvl": (DvlVelocity, ("east_mps", "north_mps")), "depth": (DepthReading, ("depth_m",)),
               "usbl": (UsblFix, ("lat_deg", "lon_deg", "depth_m", "sxx_m2", "syy_m2", "sxy_m2"))}


class JsonInputDecoder:
    """JSON lines in, :class:`DvlVelocity`, :class:`DepthReading` and :class:`UsblFix` out (see the module)."""

    def __init__(self, counts: Counter) -> None:
        self.counts = counts

    def feed(self, line: str) -> list[DvlVelocity | DepthReading | UsblFix]:
        try:
            value = json.loads(line)
        except ValueError:
            self.counts["JSON line that does not parse (skipped)"] += 1
            return []
        kind = value.get("kind") if isinstance(value, dict) else None
        if kind not in _JSON_KINDS:
            self.counts["JSON line of no known kind (skipped)"] += 1
            return []
        cls, names = _JSON_KINDS[kind]
        wanted = {"kind", "time_utc_s", *names}
        numbers = [value.get(name) for name in ("time_utc_s", *names)]
        if set(value) != wanted or not all(type(v) in (int, float) and math.isfinite(v) for v in numbers):
            self.counts[f"JSON {kind} line with a missing, unknown or bad field (skipped)"] += 1
            return []
        if kind == "usbl" and not _is_covariance(value["sxx_m2"], value["syy_m2"], value["sxy_m2"]):
            self.counts["JSON usbl line whose covariance is no covariance (skipped)"] += 1
            return []
        self.counts[f"JSON {kind} lines"] += 1
        return [cls(*(float(v) for v in numbers))]


def _is_covariance(sxx: float, syy: float, sxy: float) -> bool:
    return sxx > 0 and syy > 0 and sxy * sxy < sxx * syy


def pd6_sentences(time_s: float, east_mps: float, north_mps: float, depth_m: float) -> list[str]:
    """A PD6 ensemble's ``:TS`` and ``:BE`` lines (without line endings); a NaN velocity is sent as -32768, status V."""
    moment = dt.datetime.fromtimestamp(round(time_s, 2), dt.UTC)
    stamp = moment.strftime("%y%m%d%H%M%S") + f"{moment.microsecond // 10_000:02d}"
    depth = f"{depth_m:6.1f}" if math.isfinite(depth_m) else "   0.0"
    good = math.isfinite(east_mps) and math.isfinite(north_mps)
    east, north = (round(v * 1000.0) if good else _BAD_VELOCITY for v in (east_mps, north_mps))
    return [f":TS,{stamp},35.0,+10.0,{depth},1500.0,  0", f":BE,{east:+06d},{north:+06d},{0:+06d},{'A' if good else 'V'}"]


def json_input_line(value: DvlVelocity | DepthReading | UsblFix) -> str:
    """The JSON line of an input value (see the module), without its line feed."""
    kind = next(name for name, (cls, _) in _JSON_KINDS.items() if isinstance(value, cls))
    return json.dumps({"kind": kind, "time_utc_s": value.time_s, **{k: v for k, v in value.__dict__.items() if k != "time_s"}},
                      separators=(",", ":"), allow_nan=False)
