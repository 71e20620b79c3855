"""USBL fixes in the records: each received fix fed to the navigation at the record whose interval holds it.

A record's USBL fix (:class:`~lost.host.records.NavRecords`' ``usbl_x_m`` ... ``usbl_sxy``, the series the batch
path fills for a scenario with a USBL, read by :meth:`~lost.host.records.NavRecords.usbl_fix`) is a position of the
vehicle at the record's time. A live fix comes at its own time, between records; :class:`UsblPlacer` gives each
record the fixes of its interval (after the record before, up to the record):

- each fix carried to the record's time on the record's velocity (the one its dead reckoning moves on: the DVL's,
  or the differenced positions'): ``position + velocity * (t_record - t_fix)``, its covariance kept;
- several fixes in one interval combined as independent measurements, weighted by their information:
  ``P = (sum P_k^-1)^-1``, ``x = P sum P_k^-1 x_k``.

The estimators then weigh the record's fix as they weigh a batch record's (``use_usbl_fix``; gated, counted).

Not used, counted: a fix at or before the first record (the navigation starts there from its own start), and a fix
whose record was already stepped when it came (late). Bounded: at most :data:`MAX_FIXES` fixes wait for their record
(the oldest dropped, counted).

The batch survey path (``lost run --survey --usbl-fixes FILE``) reads a file of fixes in the layouts `lost serve`
receives (:func:`read_usbl_fixes`) and places them in the survey's records by the same placer, fed in time order as
a stream on time would feed it (:func:`place_usbl_fixes`): the served and the batch records carry the same fixes.
"""

from __future__ import annotations

import math
import os
from collections import Counter, deque
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .inputs import UsblFix

__all__ = ["UsblPlacer", "PlacedFix", "combine_fixes", "MAX_FIXES", "placed_fix", "read_usbl_fixes", "place_usbl_fixes"]

MAX_FIXES = 4096


@dataclass(frozen=True)
class PlacedFix:
    """A USBL fix in the map's frame: POSIX time, position (east, north; m), covariance (2 x 2; m²)."""

    time_s: float
    position_m: np.ndarray
    covariance_m2: np.ndarray


def combine_fixes(fixes: list[PlacedFix], time_s: float, velocity_mps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The fixes carried to ``time_s`` on ``velocity_mps`` and combined by their information (see the module)."""
    information = np.zeros((2, 2))
    weighted = np.zeros(2)
    for fix in fixes:
        carried = fix.position_m + velocity_mps * (time_s - fix.time_s)
        inverse = np.linalg.inv(fix.covariance_m2)
        information += inverse
        weighted += inverse @ carried
    covariance = np.linalg.inv(information)
    return covariance @ weighted, covariance


class UsblPlacer:
    """Fixes in (:meth:`add`), each record's fix out (:meth:`place`); see the module."""

    def __init__(self, counts: Counter) -> None:
        self.counts = counts
        self._waiting: deque[PlacedFix] = deque()
        self._stepped_to: float | None = None  # POSIX time of the last record placed

    def add(self, fix: PlacedFix) -> None:
        if self._stepped_to is not None and fix.time_s <= self._stepped_to:
            self.counts["USBL fixes after their record was stepped (late; not used)"] += 1
            return
        self._waiting.append(fix)
        if len(self._waiting) > MAX_FIXES:
            self._waiting.popleft()
            self.counts["USBL fixes no record came for (oldest dropped)"] += 1

    def place(self, time_s: float, velocity_mps: tuple[float, float]) -> tuple[np.ndarray, np.ndarray, int] | None:
        """The fix of the record at POSIX ``time_s`` moving at ``velocity_mps``: position, covariance, fixes combined; or None."""
        first = self._stepped_to is None
        mine = [f for f in self._waiting if f.time_s <= time_s]
        self._waiting = deque(f for f in self._waiting if f.time_s > time_s)
        self._stepped_to = time_s
        if not mine:
            return None
        if first:
            self.counts["USBL fixes up to the first record (not used: the navigation starts there)"] += len(mine)
            return None
        position, covariance = combine_fixes(mine, time_s, np.asarray(velocity_mps, dtype=np.float64))
        self.counts["USBL fixes used"] += len(mine)
        self.counts["records with a USBL fix"] += 1
        return position, covariance, len(mine)


def placed_fix(fix: UsblFix, to_map) -> PlacedFix:
    """A received fix in the map's frame: latitude and longitude through ``to_map`` (a pyproj Transformer from EPSG:4326,
    always_xy), as the pings are projected; its covariance taken in the map's axes."""
    east, north = to_map.transform(fix.lon_deg, fix.lat_deg)
    covariance = np.array([[fix.sxx_m2, fix.sxy_m2], [fix.sxy_m2, fix.syy_m2]])
    return PlacedFix(fix.time_s, np.array([east, north], dtype=np.float64), covariance)


def read_usbl_fixes(path: str | os.PathLike, *, sonar_time_s: float = math.nan,
                    default_sigma_m: float | None = None) -> tuple[list[UsblFix], Counter]:
    """The USBL fixes of a text file of lines as `lost serve` receives them, and the decoder's counts.

    A line each: LOST's JSON ``usbl`` lines, ``$PSONLLD`` or ``$PSIMSSB`` sentences (dated by a ``ZDA`` among the lines,
    or else by ``sonar_time_s``, the survey's first ping, as the live decoder dates them by the sonar's datagrams), any
    other line the receiver takes (counted, not used). Decoded by :class:`~lost.host.live.receiver.LiveDecoder`: the same
    checks, the same values and the same counters as served.

    Raises
    ------
    FileNotFoundError
        No file at ``path``.
    ValueError
        The file holds no usable fix (the decoder's counts say why).
    """
    from .receiver import LiveDecoder

    path = Path(path)
    decoder = LiveDecoder(usbl_default_sigma_m=default_sigma_m)
    decoder.sonar_clock(sonar_time_s)
    fixes: list[UsblFix] = []
    with path.open("rb") as lines:
        for line in lines:
            if line.strip():
                fixes += [value for value in decoder.feed(line.strip()) if isinstance(value, UsblFix)]
    fixes += [value for value in decoder.finish() if isinstance(value, UsblFix)]
    if not fixes:
        counted = ", ".join(f"{reason}: {n}" for reason, n in sorted(decoder.counts.items())) or "no line"
        raise ValueError(f"{path}: no USBL fix in it (JSON usbl lines, $PSONLLD or $PSIMSSB sentences); read: {counted}")
    return fixes, decoder.counts


def place_usbl_fixes(records, epoch_s: float, fixes: list[PlacedFix], counts: Counter):
    """``records`` (:class:`~lost.host.records.NavRecords` of a survey, times ``epoch_s`` + ``t_s``) with each record's
    USBL fix series filled by a :class:`UsblPlacer` as the live navigator fills them (fixes given in time order, each
    before the record whose interval holds it); and the fixes each record's fix was made of (an int array)."""
    placer = UsblPlacer(counts)
    waiting = deque(sorted(fixes, key=lambda fix: fix.time_s))
    series = {name: np.full(len(records), np.nan) for name in ("usbl_x_m", "usbl_y_m", "usbl_sxx", "usbl_syy", "usbl_sxy")}
    used = np.zeros(len(records), dtype=np.int64)
    for k in range(len(records)):
        time_s = epoch_s + records.t_s[k]
        while waiting and waiting[0].time_s <= time_s:
            placer.add(waiting.popleft())
        fix = placer.place(time_s, (records.vel_x_mps[k], records.vel_y_mps[k]))
        if fix is not None:
            (series["usbl_x_m"][k], series["usbl_y_m"][k]), covariance, used[k] = fix
            series["usbl_sxx"][k], series["usbl_syy"][k], series["usbl_sxy"][k] = covariance[0, 0], covariance[1, 1], covariance[0, 1]
    if waiting:
        counts["USBL fixes after the last record (not used)"] += len(waiting)
    return replace(records, **series), used
