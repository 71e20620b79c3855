"""The vehicle's DVL and depth in the records: what :class:`~lost.host.io.survey_records.SurveyRecorder` makes of the pings, amended.

Without a DVL the navigation dead-reckons, as ``lost run --survey`` does, from the pings' positions differenced
record to record (plus ``dr_bias_mps``). With one, :meth:`VehicleSensors.amend` replaces that velocity by the mean
of the DVL's velocities over the record's interval (after the record before, up to the record), and the record's
dead-reckoned position (``ship_x_m``/``ship_y_m``) by the one reckoned on them from the record before; a record
whose interval holds no DVL velocity (the DVL silent, its bottom lock lost) keeps the differenced positions'
velocity for that interval, counted. The depth sensor's latest reading in the interval becomes the record's
``vehicle_depth_m`` (and its altitude the nadir beam's depth less it); without one the record keeps the ping's.

What is not changed: the placement of a window's pings in its patch (the recorder's: the pings' true
displacement plus ``dr_bias_mps`` over their age), and the first record (the navigation's start).

Bounded: the samples not yet used by a record, at most :data:`MAX_SAMPLES` of each kind (the oldest dropped, counted).
"""

from __future__ import annotations

import math
from collections import Counter, deque
from dataclasses import replace

import numpy as np

from ..io.survey_records import SurveyRecord
from .inputs import DepthReading, DvlVelocity

__all__ = ["VehicleSensors", "MAX_SAMPLES"]

MAX_SAMPLES = 4096


class VehicleSensors:
    """DVL velocities and depth readings held until the record of their time (see the module)."""

    def __init__(self, counts: Counter) -> None:
        self.counts = counts
        self._dvl: deque[DvlVelocity] = deque()
        self._depth: deque[DepthReading] = deque()
        self._last: tuple[float, np.ndarray] | None = None  # the record before: its time (s from the epoch) and dead-reckoned position
        self._dvl_used = False

    def add(self, value: DvlVelocity | DepthReading) -> None:
        store = self._dvl if isinstance(value, DvlVelocity) else self._depth
        store.append(value)
        if len(store) > MAX_SAMPLES:
            store.popleft()
            self.counts[f"{'DVL velocities' if store is self._dvl else 'depth readings'} no record came for (oldest dropped)"] += 1

    def amend(self, record: SurveyRecord, epoch_s: float) -> tuple[SurveyRecord, str]:
        """The record with the DVL's velocity and the depth sensor's depth where they have any; and the velocity's source."""
        t_end = epoch_s + record.t_s
        t_start = -math.inf if self._last is None else epoch_s + self._last[0]
        velocities = [v for v in self._dvl if t_start < v.time_s <= t_end]
        depths = [d for d in self._depth if t_start < d.time_s <= t_end]
        self._dvl = deque(v for v in self._dvl if v.time_s > t_end)
        self._depth = deque(d for d in self._depth if d.time_s > t_end)
        source = "positions"
        changes: dict = {}
        if self._last is not None:
            if velocities:
                velocity = np.array([np.mean([v.east_mps for v in velocities]), np.mean([v.north_mps for v in velocities])])
                source, self._dvl_used = "dvl", True
                self.counts["records on the DVL's velocity"] += 1
            else:
                velocity = np.array([record.vel_x_mps, record.vel_y_mps])
                if self._dvl_used:
                    self.counts["records without a DVL velocity in their interval (differenced positions)"] += 1
            if self._dvl_used:  # once the DVL has moved the reckoning, it goes on from its own position
                t0, reckoned0 = self._last
                reckoned = reckoned0 + velocity * (record.t_s - t0)
                changes.update(vel_x_mps=float(velocity[0]), vel_y_mps=float(velocity[1]), ship_x_m=float(reckoned[0]), ship_y_m=float(reckoned[1]))
        if depths:
            depth = max(depths, key=lambda d: d.time_s).depth_m
            changes.update(vehicle_depth_m=depth, altitude_m=record.altitude_m + record.vehicle_depth_m - depth)
            self.counts["records at the depth sensor's depth"] += 1
        amended = replace(record, **changes) if changes else record
        self._last = (record.t_s, np.array([amended.ship_x_m, amended.ship_y_m]))
        return amended, source
