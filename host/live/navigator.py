"""Received pings in, estimates out: the batch survey path (``lost run --survey``) one ping at a time.

:class:`LiveNavigator` projects each raw ping as :class:`~lost.host.io.survey.Survey` does (the grid's CRS; a ping
without a position is counted and skipped), passes it to a :class:`~lost.host.io.survey_records.SurveyRecorder`,
and steps each record the recorder closes through a :class:`~lost.host.nav.loop.StreamLoop` over the same
:class:`~lost.host.nav.bank.EstimatorBank` the batch run builds. Its answers are therefore the batch run's,
record for record, when the same pings arrive.

The vehicle's DVL velocities and depth readings (:meth:`LiveNavigator.add_sensor`) amend each record before it is
stepped (:mod:`lost.host.live.sensors`): without them the records are the batch run's, unchanged. USBL fixes (projected
into the map's CRS as the pings are) become the fix of the record whose interval holds them (:mod:`lost.host.live.usbl`),
which the estimators weigh as they weigh a batch record's.

Counted (:attr:`LiveNavigator.counts`): records, records stepped without a patch (dead reckoning through them),
record intervals that passed without a ping (the sonar silent), pings without a position.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, replace

import numpy as np

from ..grid import Grid
from ..io.survey import Ping, project_ping
from ..io.survey_records import SurveyRecord, SurveyRecorder, nav_records
from ..nav.bank import EstimatorBank
from ..nav.loop import StreamLoop
from ..nav.mapprep import PreparedMap
from ..nav.parameters import NavParameters
from .inputs import DepthReading, DvlVelocity, UsblFix
from .sensors import VehicleSensors
from .usbl import UsblPlacer, placed_fix

__all__ = ["LiveNavigator", "LiveEstimate"]


@dataclass(frozen=True)
class LiveEstimate:
    """One estimator's answer at one record: what goes out on UDP and into the run's log."""

    record: int
    time_utc_s: float
    t_s: float
    estimator: str
    east_m: float
    north_m: float
    covariance_m2: tuple[float, float, float]  # east variance, north variance, their covariance
    usable: bool
    stage: str
    held: bool
    truth_east_m: float
    truth_north_m: float
    velocity_source: str = "positions"  # what the record's dead reckoning moved on: "dvl" or the pings' differenced "positions"
    velocity_mps: tuple[float, float] = (math.nan, math.nan)  # that velocity, east and north (NaN at the first record)
    vehicle_depth_m: float = math.nan
    usbl_fixes: int = 0  # the USBL fixes the record's fix was made of (0: none)

    def as_dict(self) -> dict:
        def finite(value: float) -> float | None:
            return value if math.isfinite(value) else None

        sxx, syy, sxy = self.covariance_m2
        return {"record": self.record, "time_utc_s": self.time_utc_s, "t_s": self.t_s, "estimator": self.estimator,
                "east_m": finite(self.east_m), "north_m": finite(self.north_m),
                "sxx_m2": finite(sxx), "syy_m2": finite(syy), "sxy_m2": finite(sxy), "usable": self.usable, "stage": self.stage,
                "held": self.held, "truth_east_m": finite(self.truth_east_m), "truth_north_m": finite(self.truth_north_m),
                "velocity_source": self.velocity_source, "vel_east_mps": finite(self.velocity_mps[0]),
                "vel_north_mps": finite(self.velocity_mps[1]), "vehicle_depth_m": finite(self.vehicle_depth_m),
                "usbl_fixes": self.usbl_fixes}


class LiveNavigator:
    """Pings in (raw, as :class:`~lost.host.live.receiver.LiveDecoder` yields them), estimates out (see the module)."""

    def __init__(self, grid: Grid, params: NavParameters, estimators: tuple[str, ...], recorder: SurveyRecorder) -> None:
        from ..io.crs import as_crs, transformer

        if grid.crs is None or not as_crs(grid.crs).is_projected:
            raise ValueError(f"the map's CRS must be a projected (metric) one to place received pings on it, got {grid.crs!r}")
        self.grid, self.recorder = grid, recorder
        self.counts: Counter[str] = Counter()
        self._transformer = transformer("EPSG:4326", grid.crs)
        self.prepared = PreparedMap.for_navigation(grid, params)
        self._bank = EstimatorBank(estimators, self.prepared, params, self.counts).estimators
        self._loop = StreamLoop(params, self._bank, self.counts)
        self._names = estimators
        self.sensors = VehicleSensors(self.counts)
        self.usbl = UsblPlacer(self.counts)
        self._before: SurveyRecord | None = None
        self._records = 0

    def add_sensor(self, value: DvlVelocity | DepthReading | UsblFix) -> None:
        """Take a DVL velocity, a depth reading or a USBL fix: used by the record of its time (:mod:`lost.host.live.sensors`, ``usbl``)."""
        if isinstance(value, UsblFix):
            self.usbl.add(placed_fix(value, self._transformer))
        else:
            self.sensors.add(value)

    def add(self, ping: Ping) -> list[LiveEstimate]:
        """Take one received ping; the estimates of the records it closed (often none)."""
        if not (math.isfinite(ping.lat_deg) and math.isfinite(ping.lon_deg)):
            self.counts["pings without a position (skipped)"] += 1
            return []
        interval = self.recorder._interval
        closed = self.recorder.add(self._projected(ping))
        if closed and interval is not None and self.recorder.epoch_s is not None:
            passed = math.floor((ping.time_s - self.recorder.epoch_s) / self.recorder.interval_s) - interval - 1
            if passed > 0:
                self.counts["record intervals without a ping (the sonar silent)"] += passed
        return [estimate for record in closed for estimate in self._step(record)]

    def finish(self) -> list[LiveEstimate]:
        """The end of the stream: the last record closed and stepped."""
        return [estimate for record in self.recorder.finish() for estimate in self._step(record)]

    def _projected(self, ping: Ping) -> Ping:
        return project_ping(ping, self._transformer)  # as a Survey does: a received ping lands where the file's does

    def _step(self, record: SurveyRecord) -> list[LiveEstimate]:
        record, velocity_source = self.sensors.amend(record, self.recorder.epoch_s or 0.0)
        if record.sonar is None:
            self.counts["records without a patch (dead reckoning)"] += 1
        epoch = self.recorder.epoch_s or 0.0
        fix = self.usbl.place(epoch + record.t_s, (record.vel_x_mps, record.vel_y_mps))
        rows = [record] if self._before is None else [self._before, record]
        records = nav_records(rows)
        if fix is not None:
            records = replace(records, **_fix_series(len(rows), *fix[:2]))
        row = self._loop.push(records)
        self._before = record
        number, self._records = self._records, self._records + 1
        self.counts["records stepped"] += 1
        out = []
        for name in self._names:
            track = self._loop.tracks[name]
            c = track.covariance[row]
            out.append(LiveEstimate(record=number, time_utc_s=epoch + record.t_s, t_s=record.t_s, estimator=name,
                                    east_m=float(track.position[row, 0]), north_m=float(track.position[row, 1]),
                                    covariance_m2=(float(c[0, 0]), float(c[1, 1]), float(c[0, 1])), usable=bool(track.usable[row]),
                                    stage=str(track.stage[row]), held=bool(track.held[row]),
                                    truth_east_m=record.truth_x_m, truth_north_m=record.truth_y_m, velocity_source=velocity_source,
                                    velocity_mps=(record.vel_x_mps, record.vel_y_mps), vehicle_depth_m=record.vehicle_depth_m,
                                    usbl_fixes=0 if fix is None else fix[2]))
        return out

    def estimator_counts(self) -> dict[str, dict]:
        """Each estimator's own counts (skips, rejections, re-initializations)."""
        return {e.name: dict(e.counts) for e in self._bank}


def _fix_series(rows: int, position: np.ndarray, covariance: np.ndarray) -> dict[str, np.ndarray]:
    """NavRecords' USBL fix series for a window whose last row has the fix (the rows before have none)."""
    values = {"usbl_x_m": position[0], "usbl_y_m": position[1], "usbl_sxx": covariance[0, 0], "usbl_syy": covariance[1, 1],
              "usbl_sxy": covariance[0, 1]}
    series = {}
    for name, value in values.items():
        column = np.full(rows, np.nan)
        column[-1] = value
        series[name] = column
    return series


def usable_fraction(estimates: list[LiveEstimate]) -> float:
    """The fraction of ``estimates`` their estimator vouched for (NaN for none)."""
    return float(np.mean([e.usable for e in estimates])) if estimates else math.nan
