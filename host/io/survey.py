"""A multibeam survey as one value type: pings streamed from Kongsberg ``.all``/``.kmall`` and GSF files.

:func:`open_survey` recognises each file by its content and returns a :class:`Survey`; iterating it yields
:class:`Ping` values one at a time (each format's reader holds one datagram, or one record, plus the
navigation and attitude samples it interpolates at the ping times), so a file of any size is read in
memory bounded by its duration, not its size. What could not be read is counted in :attr:`Survey.skipped`
(reason -> count), never dropped silently.

A ping carries its time (POSIX seconds, UTC), the reference point's position (WGS 84 latitude/longitude
and, projected, easting/northing in :attr:`Survey.crs`), heading, roll, pitch, heave, the sound speed at
the transducer, and per beam the along-track and across-track offsets from the reference point (metres,
forward and starboard, in the heading frame), the depth below the water line (metres, positive down; the
file's depth re the transducer or reference point plus that point's depth below the water line; no tide)
and whether the beam is valid (not flagged by the sonar or by processing).
"""

from __future__ import annotations

import math
import os
from collections import Counter
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import SurveyFileError

__all__ = ["Ping", "Survey", "open_survey", "project_ping", "survey_format", "SURVEY_FORMATS"]

SURVEY_FORMATS = ("kongsberg-all", "kmall", "gsf")
# Kongsberg .all datagram types (EM Series datagram formats), enough to recognise a file by its first.
_ALL_TYPES = frozenset(b"0123ABCDEFGHIJKLNOPRSTUWXYZfhijklnopqrstuvwxyz")
#: A head's pings may come out of order by less than this; a ping earlier by more than any of the same head read
#: before it is skipped and counted (a clock jump, files given out of order).
BACKWARDS_TOLERANCE_S = 1.0


@dataclass(frozen=True)
class Ping:
    """One multibeam ping; per-beam arrays share one length.

    ``head`` tells the heads of a dual-head sonar apart (the serial number in a Kongsberg file, 0 in GSF).
    ``origin_depth_m`` is the depth below the water line of the point the file measures beam depths from
    (the transmit transducer in ``.all``, the reference point in ``.kmall``; NaN in GSF, whose depths are
    below the surface already): ``depth_m - origin_depth_m`` is the file's own relative depth.
    ``east_m``/``north_m`` are the reference point's projected position (NaN when the file has no position
    for the ping's time; such pings are not yielded by :class:`Survey`), ``convergence_deg`` the grid
    bearing of true north there (the projection's meridian convergence, a few degrees in a UTM zone: 44 m
    at the edge of a 5 km swath per degree). ``beam_east_m``/``beam_north_m`` place each beam: the offsets
    turned by the heading plus the convergence.
    """

    time_s: float
    lat_deg: float
    lon_deg: float
    heading_deg: float
    roll_deg: float
    pitch_deg: float
    heave_m: float
    sound_speed_mps: float
    along_m: np.ndarray
    across_m: np.ndarray
    depth_m: np.ndarray
    valid: np.ndarray
    head: int = 0
    origin_depth_m: float = math.nan
    east_m: float = math.nan
    north_m: float = math.nan
    convergence_deg: float = 0.0

    @property
    def beams(self) -> int:
        return int(self.depth_m.size)

    @property
    def beam_east_m(self) -> np.ndarray:
        h = math.radians(self.heading_deg + self.convergence_deg)
        return self.east_m + self.along_m * math.sin(h) + self.across_m * math.cos(h)

    @property
    def beam_north_m(self) -> np.ndarray:
        h = math.radians(self.heading_deg + self.convergence_deg)
        return self.north_m + self.along_m * math.cos(h) - self.across_m * math.sin(h)


def survey_format(path: Path) -> str:
    """``"kongsberg-all"``, ``"kmall"`` or ``"gsf"`` from the file's first bytes; a named error otherwise."""
    if not path.is_file():
        raise FileNotFoundError(f"no survey file at {path}")
    with path.open("rb") as f:
        head = f.read(16)
    if len(head) < 16:
        raise SurveyFileError(f"{path.name} is {len(head)} bytes long: too short for any multibeam format")
    if head[4:5] == b"#" and head[5:8].isalpha() and head[5:8].isupper():
        return "kmall"
    if head[4] == 0x02 and head[5] in _ALL_TYPES:
        return "kongsberg-all"
    if head[8:16] == b"GSF-v03." or head[8:11] == b"GSF":
        return "gsf"
    raise SurveyFileError(
        f"{path.name} is not a Kongsberg .all, .kmall or GSF file (first bytes {head[:12]!r}); a bathymetry grid is read by read_grid"
    )


class Survey:
    """Pings of one or more files of one format, projected to one CRS.

    Parameters
    ----------
    paths : path-like or iterable of them
        The files, read in the order given.
    crs : str, optional
        The projected CRS of the pings' eastings/northings; default the WGS 84 UTM zone of the first
        ping with a position.

    Attributes
    ----------
    skipped : Counter
        Reason -> count of what could not be used (datagrams, records, pings); filled while iterating.
    notes : Counter
        Reason -> count of what was used with a caveat (a position dead-reckoned from the nearest fix).
    """

    def __init__(self, paths: str | os.PathLike | Iterable[str | os.PathLike], *, crs: str | None = None) -> None:
        if isinstance(paths, str | os.PathLike):
            paths = [paths]
        self.paths = [Path(p) for p in paths]
        if not self.paths:
            raise ValueError("a survey needs at least one file")
        formats = {survey_format(p) for p in self.paths}
        if len(formats) > 1:
            raise SurveyFileError(f"the files are of different formats ({', '.join(sorted(formats))}); read each format on its own")
        self.format = formats.pop()
        self.crs = crs
        self.skipped: Counter[str] = Counter()
        self.notes: Counter[str] = Counter()
        self._transformer = None

    def __iter__(self) -> Iterator[Ping]:
        self.skipped.clear()
        self.notes.clear()
        earlier_files = -math.inf  # the latest ping of the files before
        first_heads: set[int] | None = None
        for path in self.paths:
            latest: dict[int, float] = {}
            for ping in self._raw_pings(path):
                if not (math.isfinite(ping.lat_deg) and math.isfinite(ping.lon_deg)):
                    self.skipped[f"{path.name}: ping without a position at its time"] += 1
                    continue
                if ping.time_s < max(latest.get(ping.head, -math.inf), earlier_files) - BACKWARDS_TOLERANCE_S:
                    self.skipped[f"{path.name}: ping time going backwards (more than {BACKWARDS_TOLERANCE_S:g} s before a ping read earlier)"] += 1
                    continue
                latest[ping.head] = max(latest.get(ping.head, -math.inf), ping.time_s)
                yield self._projected(ping)
            if latest:
                earlier_files = max(earlier_files, *latest.values())
                if first_heads is None:
                    first_heads = set(latest)
                elif not set(latest) <= first_heads:
                    heads = ", ".join(map(str, sorted(set(latest) - first_heads)))
                    self.notes[f"{path.name}: pings of another sonar head or ship (serial {heads}) than the first file's"] += 1

    def _raw_pings(self, path: Path) -> Iterator[Ping]:
        if self.format == "kongsberg-all":
            from .kongsberg_all import read_all_pings

            return read_all_pings(path, self.skipped, self.notes)
        if self.format == "kmall":
            from .kmall import read_kmall_pings

            return read_kmall_pings(path, self.skipped, self.notes)
        from .gsf import read_gsf_pings

        return read_gsf_pings(path, self.skipped, self.notes)

    def _projected(self, ping: Ping) -> Ping:
        if self._transformer is None:
            from .crs import as_crs, transformer, utm_crs

            if self.crs is None:
                self.crs = utm_crs(ping.lon_deg, ping.lat_deg)
            elif not as_crs(self.crs).is_projected:
                raise ValueError(f"crs must be a projected (metric) CRS, got {self.crs!r}")
            self._transformer = transformer("EPSG:4326", self.crs)
        return project_ping(ping, self._transformer)


def project_ping(ping: Ping, transformer) -> Ping:
    """``ping`` with its projected position and meridian convergence, by a pyproj ``transformer`` from EPSG:4326."""
    # True north's grid bearing: where a small step north lands on the map.
    east, north = transformer.transform([ping.lon_deg, ping.lon_deg], [ping.lat_deg, min(ping.lat_deg + 1e-5, 90.0)])
    convergence = math.degrees(math.atan2(east[1] - east[0], north[1] - north[0]))
    return Ping(**{**ping.__dict__, "east_m": float(east[0]), "north_m": float(north[0]), "convergence_deg": convergence})


def open_survey(paths: str | os.PathLike | Iterable[str | os.PathLike], *, crs: str | None = None) -> Survey:
    """A :class:`Survey` of the files (see the class); the format is recognised by content."""
    return Survey(paths, crs=crs)


def interpolate_at(times: np.ndarray, t: np.ndarray, values: np.ndarray, *, max_gap_s: float, angle: bool = False) -> np.ndarray:
    """Values of a time series at ``times``; NaN outside it or where its samples are more than ``max_gap_s`` apart."""
    out = np.full(np.shape(times), np.nan)
    if t.size == 0:
        return out
    k = np.searchsorted(t, times)
    inside = (k > 0) & (k < t.size)
    exact = (k < t.size) & (t[np.minimum(k, t.size - 1)] == times)
    out[exact] = values[k[exact]]
    lo, hi = np.maximum(k - 1, 0), np.minimum(k, t.size - 1)
    gap = t[hi] - t[lo]
    use = inside & ~exact & (gap <= max_gap_s)
    w = np.where(gap > 0, (times - t[lo]) / np.where(gap > 0, gap, 1), 0.0)
    if angle:
        diff = (values[hi] - values[lo] + 180.0) % 360.0 - 180.0
        out[use] = (values[lo] + w * diff)[use] % 360.0
    else:
        out[use] = (values[lo] + w * (values[hi] - values[lo]))[use]
    return out
