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
"""

from __future__ import annotations

from collections import Counter, deque
from dataclasses import dataclass

import numpy as np

__all__ = ["UsblPlacer", "PlacedFix", "combine_fixes", "MAX_FIXES"]

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
