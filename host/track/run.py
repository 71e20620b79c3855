"""A whole run of the tracker over pings: reports, the confirmed contacts per ping, cloud snapshots, timing."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from .amplitude import check_strength_scale
from .detections import Ping
from .estimates import Estimate
from .geometry import Sonar
from .tracker import MultiTargetTracker, TrackerParameters, TrackReport

__all__ = ["TrackerRun", "run_tracker", "confirmed_estimates"]


@dataclass(frozen=True)
class TrackerRun:
    """What :func:`run_tracker` returns.

    Attributes
    ----------
    reports : list of list of TrackReport
        Every live track (tentative ones included) after each ping.
    clouds : list of ndarray
        A sample of the search cloud after each ping (for the plots), ``(n, 2)``.
    step_ms : ndarray
        Wall time of each ping's step, milliseconds.
    tracks_born : int
        Tentative tracks started over the run.
    step_cpu_ms : ndarray
        CPU time of each ping's step (this thread's), milliseconds: the step's cost when the machine is shared.
    """

    reports: list[list[TrackReport]]
    clouds: list[np.ndarray]
    step_ms: np.ndarray
    tracks_born: int
    step_cpu_ms: np.ndarray = field(default_factory=lambda: np.empty(0))

    @property
    def estimates(self) -> list[list[Estimate]]:
        return confirmed_estimates(self.reports)


def confirmed_estimates(reports: Sequence[Sequence[TrackReport]]) -> list[list[Estimate]]:
    """The confirmed tracks of each ping as :class:`Estimate` (what is scored and shown as a contact)."""
    return [[Estimate(r.track_id, r.x_m, r.y_m, r.vx_mps, r.vy_mps) for r in ping if r.status == "confirmed"] for ping in reports]


def run_tracker(pings: Sequence[Ping], *, sonar: Sonar, parameters: TrackerParameters, seed: int = 0,
                cloud_points: int = 600, progress: Callable[[Iterable], Iterable] | None = None) -> TrackerRun:
    """Run the multi-target tracker over ``pings`` (seeded); keep ``cloud_points`` particles a ping for plots.

    Raises
    ------
    StrengthScaleError
        The detections' strengths cannot be on the scale of ``parameters``' amplitude model (:func:`.amplitude.check_strength_scale`).
    """
    check_strength_scale(pings, parameters)
    tracker = MultiTargetTracker(sonar=sonar, parameters=parameters, rng=np.random.default_rng(seed))
    reports, clouds = [], []
    for ping in (progress or iter)(pings):
        reports.append(tracker.step(ping))
        clouds.append(tracker.cloud_sample(cloud_points).astype(np.float32) if cloud_points else np.empty((0, 2), np.float32))
    return TrackerRun(reports, clouds, np.array(tracker.step_ms), tracker.tracks_born, np.array(tracker.step_cpu_ms))
