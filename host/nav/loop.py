"""The record loop: every record through each estimator of a bank, with the lay-back and dead-reckoning baselines.

One record at a time over a :class:`~lost.host.records.NavRecords`: the loop turns the record into a
:class:`~lost.host.nav.estimator.Motion` (the measured velocity, the last one held when a reading is
missing, counted) and an :class:`~lost.host.nav.estimator.Observation` (patch, ocean depth, slant range,
ship fix), and hands both to each estimator of the bank in turn (:mod:`lost.host.nav.bank`). All start
from the lay-back model's position (plus ``initial_offset_m``) at the first record that has one. Two
baselines run on the same records: the lay-back model and dead reckoning from the same start.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from typing import TYPE_CHECKING

import numpy as np

from ..records import NavRecords
from .estimator import Estimator, Motion, Observation
from .guard import DeadReckoningGuard
from .motion import compensated, record_bias
from .parameters import NavParameters
from .results import FilterTrack, NavResult
from .stages import TrackFrame, layback_position, state_update

if TYPE_CHECKING:
    from ..usbl.sound import SoundSpeedProfile

__all__ = ["RecordLoop", "StreamLoop", "layback_distance", "PATENT_OUTPUTS"]

#: The patent pipeline's per-record stage outputs, as ``Estimate.stages`` carries them into ``NavResult``.
PATENT_OUTPUTS = ("predicted", "mle", "cat", "distinctness", "cross_velocity_mps", "slant_corrected", "off_map")


def layback_distance(cable_out_m: float, vehicle_depth_m: float, params: NavParameters) -> float:
    """Horizontal ship-to-vehicle distance of the lay-back model (NaN when its input is missing)."""
    if params.layback_model == "depth_ratio":
        return params.layback_depth_ratio * vehicle_depth_m
    return math.sqrt(max(cable_out_m**2 - vehicle_depth_m**2, 0.0))


def _frame(records: NavRecords, n: int) -> TrackFrame | None:
    x, y, h = records.ship_x_m[n], records.ship_y_m[n], records.ship_heading_deg[n]
    if not (np.isfinite(x) and np.isfinite(y) and np.isfinite(h)):
        return None
    return TrackFrame(float(x), float(y), float(h))



class RecordLoop:
    """The shared per-record work: velocity held, depth held, lay-back, start, baselines, estimators."""

    def __init__(self, records: NavRecords, params: NavParameters, estimators: list[Estimator], counts: Counter,
                 profile: SoundSpeedProfile | None = None) -> None:
        n = len(records)
        self._records, self._p, self._estimators, self.counts = records, params, estimators, counts
        self._profile = profile
        self._sonar = records.sonar if records.sonar else (None,) * n
        self._velocity = np.zeros(2)
        self._last_depth = float("nan")
        self._dead: np.ndarray | None = None
        self._bias = np.zeros(2)  # the velocity bias the record's soundings are placed by (the record before's)
        self._answers: list = []
        self.layback, self.dead_reckoning = np.full((n, 2), np.nan), np.full((n, 2), np.nan)
        self.tracks = {e.name: FilterTrack.empty(n) for e in estimators}
        self._guards = {e.name: DeadReckoningGuard(params) for e in estimators}
        self.patent = {"predicted": np.full((n, 2), np.nan), "mle": np.full((n, 2), np.nan), "cat": np.full((n, 2), np.nan),
                       "distinctness": np.full(n, np.nan), "cross_velocity_mps": np.full(n, np.nan),
                       "slant_corrected": np.zeros(n, bool), "off_map": np.zeros(n, bool), "mle_source": np.full(n, "", dtype="<U5")}

    def step(self, n: int) -> None:
        records = self._records
        frame = _frame(records, n)
        measured = np.array([records.vel_x_mps[n], records.vel_y_mps[n]])
        held = not np.all(np.isfinite(measured))
        if not held:
            self._velocity = measured
        elif self._dead is not None:
            self.counts["velocity_held"] += 1
        depth = float(records.vehicle_depth_m[n])
        if np.isfinite(depth):
            self._last_depth = depth
        distance = layback_distance(float(records.cable_out_m[n]), self._last_depth, self._p)
        if frame is not None and np.isfinite(distance):
            self.layback[n] = layback_position(frame, distance)
        fix = records.usbl_fix(n)
        observation = Observation(t_s=float(records.t_s[n]), frame=frame, patch=self._placed_patch(n),
                                  ocean_depth_m=depth + float(records.altitude_m[n]), vehicle_depth_m=self._last_depth,
                                  slant_range_m=self._slant_range(n), fix_position_m=None if fix is None else fix[0],
                                  fix_covariance_m2=None if fix is None else fix[1],
                                  layback_m=self.layback[n].copy() if np.all(np.isfinite(self.layback[n])) else None)
        if self._dead is None:
            # Initialization: the lay-back model (cross-track zero), plus the requested offset.
            if not np.all(np.isfinite(self.layback[n])):
                self.counts["before_initialization"] += 1
                return
            self._dead = start = self.layback[n] + np.array(self._p.initial_offset_m)
            self.dead_reckoning[n] = start
            self._answers = []
            for estimator in self._estimators:
                estimator.start(observation.t_s, start, observation)
                self._guards[estimator.name].start(start)
                self._record(n, estimator, 0.0)
            self._bias = record_bias(self._answers)
            return
        motion = Motion(dt_s=observation.t_s - float(records.t_s[n - 1]), velocity_mps=self._velocity, held=held)
        self.dead_reckoning[n] = self._dead = state_update(self._dead, self._velocity, motion.dt_s)
        self._answers = []
        for estimator in self._estimators:
            begin = time.perf_counter()
            estimator.predict(motion)
            estimator.update(observation)
            self._guards[estimator.name].predict(self._velocity, motion.dt_s)
            self._record(n, estimator, (time.perf_counter() - begin) * 1e3)
        self._bias = record_bias(self._answers)

    def _placed_patch(self, n: int):
        """The record's plausible patch, its soundings placed by the velocity bias of the record before (``compensate_patch_motion``)."""
        patch = self._plausible_patch(n)
        if patch is None or not self._p.compensate_patch_motion:
            return patch
        placed = compensated(patch, self._bias)
        if placed is not patch:
            self.counts["patches_placed_by_age"] += 1
        return placed

    def _plausible_patch(self, n: int):
        """The record's sonar patch, unless its age is not a plausible one (see ``NavParameters.max_patch_age_s``)."""
        patch = self._sonar[n]
        if patch is None:
            return None
        age = float(patch.age_s)
        if not (math.isfinite(age) and 0.0 <= age <= self._p.max_patch_age_s):
            self.counts["patch_age_implausible"] += 1
            return None
        return patch

    def _slant_range(self, n: int) -> float:
        """The record's slant range: ray-traced from its USBL travel time when there is a profile, else the straight one."""
        straight, travel = float(self._records.slant_range_m[n]), float(self._records.usbl_travel_time_s[n])
        if not math.isfinite(travel):
            return straight
        if self._profile is None:
            self.counts["usbl_travel_time_without_profile"] += 1
            return straight
        from ..usbl.rays import slant_range_from_travel_time  # lazily: gsw and pandas load only for a USBL run

        try:
            slant, _ = slant_range_from_travel_time(self._profile, travel, self._p.reference_depth_m, self._last_depth)
        except ValueError:  # too short for the depth, below the profile, a depth not yet measured: not this ray
            self.counts["usbl_ray_failed"] += 1
            return straight
        self.counts["slant_range_ray_traced"] += 1
        if math.isfinite(straight):
            self.counts["slant_range_ray_over_straight"] += 1
        return slant

    def _record(self, n: int, estimator: Estimator, ms: float) -> None:
        guard = self._guards[estimator.name]
        answer = guard.shown(estimator.estimate())
        self._answers.append(answer)
        track = self.tracks[estimator.name]
        track.held[n], track.reinitialized[n] = guard.held, answer.reinitialized
        if guard.held:
            estimator.counts["held_to_dead_reckoning"] += 1
        track.position[n], track.covariance[n], track.usable[n] = answer.position, answer.covariance, answer.usable
        track.stage[n], track.nis[n], track.rejected[n], track.ms[n] = answer.stage, answer.nis, answer.rejected, ms
        track.depth_bias_m[n] = answer.depth_bias_m
        track.velocity_bias_mps[n], track.velocity_bias_sigma_mps[n] = answer.velocity_bias_mps, answer.velocity_bias_sigma_mps
        if answer.stages:
            self._record_stages(n, answer.stages)

    def _record_stages(self, n: int, stages: dict) -> None:
        """An estimator's stage outputs (the patent pipeline's) into the run's per-record arrays."""
        patent = self.patent
        patent["predicted"][n] = stages["predicted"]
        if "mle" not in stages:
            return
        if stages["mle"] is not None:
            patent["mle"][n] = stages["mle"]
            patent["mle_source"][n] = self._p.matching
        if stages["cat"] is not None:
            patent["cat"][n] = stages["cat"]
        for name in ("distinctness", "cross_velocity_mps", "slant_corrected", "off_map"):
            patent[name][n] = stages[name]

    def result(self) -> NavResult:
        records, patent = self._records, self.patent
        truth = np.column_stack([records.truth_x_m, records.truth_y_m]) if records.has_truth else None
        self.counts["records"] = len(records)
        self.counts["mle_updates"] = int(np.count_nonzero(patent["mle_source"] != ""))
        self.counts["slant_range_corrections"] = int(patent["slant_corrected"].sum())
        lost = self.tracks.get("lost")
        tracks = {name: FilterTrack(**{**track.__dict__, "counts": dict(self._counts_of(name))}) for name, track in self.tracks.items()}
        return NavResult(
            t_s=np.asarray(records.t_s, float),
            estimate=lost.position if lost is not None else np.full((len(records), 2), np.nan),
            predicted=patent["predicted"], mle=patent["mle"], mle_source=patent["mle_source"], distinctness=patent["distinctness"],
            cat=patent["cat"], cross_velocity_mps=patent["cross_velocity_mps"], slant_corrected=patent["slant_corrected"],
            off_map=patent["off_map"], layback=self.layback, dead_reckoning=self.dead_reckoning, truth=truth,
            counts=dict(self.counts), tracks=tracks,
        )

    def _counts_of(self, name: str) -> Counter:
        for estimator in self._estimators:
            if estimator.name == name:
                return estimator.counts
        return Counter()


class StreamLoop(RecordLoop):
    """The record loop on a stream whose length is not known: :meth:`push` steps each record as it comes.

    Each record is stepped by :meth:`RecordLoop.step` on a window of two rows (the record before it, for the
    time step, and itself), so every estimator sees exactly what it sees in a whole-tow run; the per-record
    arrays are those of the window only, so memory stays flat however long the stream.
    """

    def __init__(self, params: NavParameters, estimators: list[Estimator], counts: Counter, profile: SoundSpeedProfile | None = None) -> None:
        self._stream_args = (params, estimators, counts, profile)
        self._carried: tuple | None = None  # the loop's state between records: velocity and depth held, dead reckoning, guards

    def push(self, window: NavRecords) -> int:
        """Step the last row of ``window`` (one row: the stream's first record; two: the record before, then it).

        Returns the row stepped; read its answers from ``tracks``, ``layback`` and ``dead_reckoning`` at that row.
        """
        if len(window) not in (1, 2) or (len(window) == 1 and self._carried is not None):
            raise ValueError(f"a stream's window is the first record alone or the record before and the new one, got {len(window)} rows")
        super().__init__(window, *self._stream_args)
        if self._carried is not None:
            self._velocity, self._last_depth, self._dead, self._guards, self._bias = self._carried
        row = len(window) - 1
        self.step(row)
        self._carried = (self._velocity, self._last_depth, self._dead, self._guards, self._bias)
        return row
