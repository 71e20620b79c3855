"""The interface every position estimator of the record loop follows, and the values that cross it.

The record loop (:mod:`lost.host.nav.loop`) turns each record into a :class:`Motion` (what the
vehicle did since the previous record) and an :class:`Observation` (what it measured now), and hands
both to each estimator in turn: ``predict(motion)`` then ``update(observation)``, then reads an
:class:`Estimate`. The shape follows MB-System's TRN (``motionUpdate``, ``measUpdate``,
``computeMMSE``): one interface, several filters behind it.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from ..records import SonarPatch
from .stages import TrackFrame

__all__ = ["Motion", "Observation", "Estimate", "Estimator", "STAGES"]

#: What produced an estimate at a record (``Estimate.stage``).
STAGES = (
    "uninitialized",   # before the first ship fix
    "initialization",  # the start: the lay-back model
    "dead_reckoning",  # no measurement used at this record
    "off_map",         # the measurement fell off the map (or on holes): no information
    "rejected",        # a measurement was refused by its gate (``Estimate.rejected`` says which)
    "acquisition",     # a terrain update while the estimate is not yet usable (wide, perhaps multimodal)
    "tracking",        # a terrain update while usable
    "patch",           # the patent pipeline: its MLE came from a sonar patch
    "point",           # the patent pipeline: its MLE came from a single depth
    "reinitialized",   # the filter widened its search after divergence
    "usbl_fix",        # the patent pipeline: a USBL fix re-centred its dead reckoning (no MLE for cat_restart_s)
)


@dataclass(frozen=True)
class Motion:
    """The vehicle's motion over one record step.

    Attributes
    ----------
    dt_s : float
        Time since the previous record, seconds.
    velocity_mps : (2,) array
        Measured velocity over ground (east, north), or the last measured one when ``held``.
    held : bool
        No velocity was measured at this record; the last one is reused.
    """

    dt_s: float
    velocity_mps: np.ndarray
    held: bool = False

    def __post_init__(self) -> None:
        velocity = np.asarray(self.velocity_mps, dtype=float)
        if velocity.shape != (2,) or not np.isfinite(velocity).all():
            raise ValueError(f"a motion needs a finite (east, north) velocity; hold the last one when a reading is missing, got {self.velocity_mps!r}")
        if not (np.isfinite(self.dt_s) and self.dt_s >= 0):
            raise ValueError(f"a motion's time step must be a non-negative number of seconds, got {self.dt_s!r}")
        object.__setattr__(self, "velocity_mps", velocity)


@dataclass(frozen=True)
class Observation:
    """What was measured at one record; NaN where a sensor gave nothing.

    Attributes
    ----------
    t_s : float
        Time of the record.
    frame : TrackFrame or None
        The ship's position and heading (None when its fix is missing).
    patch : SonarPatch or None
        The sonar patch of this record.
    ocean_depth_m : float
        Vehicle depth plus altitude: the single-depth (point) measurement of the sea floor.
    vehicle_depth_m : float
        The last measured vehicle depth (for the slant range's vertical leg).
    slant_range_m : float
        Ship to vehicle: ray-traced from the USBL's travel time when the loop has a sound-speed profile,
        else the record's straight-line ``slant_range_m`` (see :mod:`lost.host.nav.loop`).
    fix_position_m : (2,) array or None
        The USBL fix of the vehicle (east, north), metres; None without one.
    fix_covariance_m2 : (2, 2) array or None
        Its covariance, m**2.
    layback_m : (2,) array or None
        The cable model's position of the vehicle (behind the ship; cross-track unknown): where a
        re-initialized search is centred, as the first one is. None without a ship fix or cable length.
    """

    t_s: float
    frame: TrackFrame | None
    patch: SonarPatch | None
    ocean_depth_m: float
    vehicle_depth_m: float
    slant_range_m: float
    fix_position_m: np.ndarray | None = None
    fix_covariance_m2: np.ndarray | None = None
    layback_m: np.ndarray | None = None


@dataclass(frozen=True)
class Estimate:
    """An estimator's answer at one record.

    Attributes
    ----------
    position : (2,) array
        East, north, metres (the MMSE estimate for the Bayesian filters).
    covariance : (2, 2) array
        Its covariance, m**2; NaN for an estimator that carries none (the patent pipeline).
    usable : bool
        Whether the estimator vouches for the estimate (see each estimator's rule).
    stage : str
        One of :data:`STAGES`.
    nis : float
        Normalized innovation squared of the terrain update at this record (NaN without one).
    rejected : str
        Why a measurement of this record was refused ("" when none was).
    depth_bias_m : float
        The single-depth form's depth-bias estimate, measured minus map (NaN for the patch form).
    velocity_bias_mps, velocity_bias_sigma_mps : (east, north)
        The velocity-bias estimate (the measured velocity less the true, m/s) and its 1-sigma; NaN for an
        estimator that does not estimate one.
    stages : mapping
        The estimator's own intermediate outputs at this record, by name (the patent pipeline's
        ``predicted``, ``mle``, ``cat``, ...; see :data:`lost.host.nav.loop.PATENT_OUTPUTS`); empty for the filters.
    reinitialized : str
        At a re-initialization (stage ``reinitialized``), its cause (:data:`lost.host.nav.trust.RESTART_CAUSES`); else "".
    """

    position: np.ndarray
    covariance: np.ndarray
    usable: bool
    stage: str
    nis: float = float("nan")
    rejected: str = ""
    depth_bias_m: float = float("nan")
    velocity_bias_mps: tuple[float, float] = (float("nan"), float("nan"))
    velocity_bias_sigma_mps: tuple[float, float] = (float("nan"), float("nan"))
    stages: Mapping[str, Any] = field(default_factory=dict)
    reinitialized: str = ""


class Estimator(Protocol):
    """A position estimator driven by the record loop."""

    name: str
    counts: Counter

    def start(self, t_s: float, position: np.ndarray, observation: Observation) -> None:
        """Begin at ``position`` (the lay-back start) at the first record the loop can place."""

    def predict(self, motion: Motion) -> None:
        """Move the estimate by the motion, with its uncertainty (Nygren eq. 3.3)."""

    def update(self, observation: Observation) -> None:
        """Use what the record measured (Nygren eq. 3.5), gated."""

    def estimate(self) -> Estimate:
        """The estimate after this record's update."""

