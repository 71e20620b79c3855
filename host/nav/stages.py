"""The four stages of the LOST patent (US 09/599,868), each one small function of plain numbers.

Frames: positions are (easting x, northing y) in metres, in the :class:`~lost.host.grid.Grid`'s
frame. The patent's internal frame is along-track / cross-track relative to the towing ship: with
the ship's heading h (degrees clockwise from grid north) the along-track unit vector is
``(sin h, cos h)`` and the cross-track unit vector, positive to starboard, is ``(cos h, -sin h)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "TrackFrame",
    "state_update",
    "point_likelihood",
    "patch_likelihood",
    "CrossTrackTracker",
    "slant_range_correct",
    "layback_position",
    "refine_minimum",
]


@dataclass(frozen=True)
class TrackFrame:
    """The ship-relative along/cross-track frame of one instant (the patent's f_ct and its inverse).

    Attributes
    ----------
    ship_x_m, ship_y_m : float
        The towing ship's position, the frame's origin.
    heading_deg : float
        The ship's heading (its track direction), degrees clockwise from grid north.
    """

    ship_x_m: float
    ship_y_m: float
    heading_deg: float

    @property
    def along_unit(self) -> np.ndarray:
        h = np.radians(self.heading_deg)
        return np.array([np.sin(h), np.cos(h)])

    @property
    def cross_unit(self) -> np.ndarray:
        h = np.radians(self.heading_deg)
        return np.array([np.cos(h), -np.sin(h)])

    def along(self, position: np.ndarray) -> float:
        """Along-track coordinate of a position (negative behind the ship)."""
        return float(np.dot(np.asarray(position, float) - (self.ship_x_m, self.ship_y_m), self.along_unit))

    def cross(self, position: np.ndarray) -> float:
        """The patent's f_ct: cross-track coordinate of a position, positive to starboard."""
        return float(np.dot(np.asarray(position, float) - (self.ship_x_m, self.ship_y_m), self.cross_unit))

    def position(self, along_m: float, cross_m: float) -> np.ndarray:
        """The grid position of along/cross-track coordinates."""
        return np.array([self.ship_x_m, self.ship_y_m]) + along_m * self.along_unit + cross_m * self.cross_unit


def state_update(previous_estimate: np.ndarray, velocity_mps: np.ndarray, dt_s: float) -> np.ndarray:
    """State updater, patent eq. 1: ``P_p(t) = P_e(t-1) + v dt`` (dead reckoning over one step).

    Parameters
    ----------
    previous_estimate : (2,) array
        ``P_e(t-1)``, metres.
    velocity_mps : (2,) array
        The vehicle's velocity over ground (or the ship's when the vehicle has none), m/s.
    dt_s : float
        Time since the previous estimate, seconds, not negative.
    """
    if not dt_s >= 0:
        raise ValueError(f"the time step must be a non-negative number of seconds, got {dt_s!r}")
    return np.asarray(previous_estimate, float) + np.asarray(velocity_mps, float) * dt_s


def point_likelihood(
    dx_m: np.ndarray, dy_m: np.ndarray, measured_depth_m: float, map_depth_m: np.ndarray, *, k: float
) -> np.ndarray:
    """The patent's likelihood of one ocean-depth measurement at bathymetry nodes, eqs. 2-3.

    ``lambda = dx**2 + dy**2 + k**2 * dz**2``, with ``dx, dy`` the predicted position minus the node's
    and ``dz`` the measured ocean depth (vehicle depth + altitude) minus the node's depth; the smallest
    value is the most likely node. This is eq. 2 multiplied by ``2 sigma_x**2`` with the patent's
    definition ``k = sigma_x / sigma_z`` (nominal 100-1000): the weight of ``dz**2`` is therefore
    ``k**2``; eq. 3 as printed writes ``k``, which contradicts that definition and would make a 1 m
    depth error worth only 10-30 m of position. Nodes with a NaN depth (map holes) get +inf.
    """
    dz = measured_depth_m - np.asarray(map_depth_m, float)
    value = np.asarray(dx_m, float) ** 2 + np.asarray(dy_m, float) ** 2 + k**2 * dz**2
    return np.where(np.isnan(value), np.inf, value)


def patch_likelihood(
    dx_m: np.ndarray, dy_m: np.ndarray, surface: np.ndarray, *, valid_nodes: int, lsb_m: float, k: float
) -> np.ndarray:
    """Eqs. 2-3 with the correlator's surface V as the depth term: the patent's MLE for a sonar patch.

    For n beams the depth term becomes the sum over the beams of ``k**2 dz**2`` (see
    :func:`point_likelihood` for why ``k**2``). The exact
    correlator gives V = n * sum |dz_i - mean dz| in depth words (ARCHITECTURE.md), a sum of absolute
    rather than squared residuals; with the mean absolute residual ``r = V lsb / n**2`` metres the
    sum of squares is approximated by ``n r**2``, so::

        lambda = dx**2 + dy**2 + k**2 * (V * lsb)**2 / n**3

    A placement excluded by the caller (V = -1, or any negative value) gets +inf. Mean compensation
    makes the term blind to a constant depth bias of the sonar, as Nygren's eq. 8.1 intends.
    """
    if valid_nodes < 1:
        raise ValueError(f"a patch needs at least one valid node, got {valid_nodes}")
    v = np.asarray(surface)
    residual = v.astype(np.float64) * lsb_m
    value = np.asarray(dx_m, float) ** 2 + np.asarray(dy_m, float) ** 2 + k**2 * residual**2 / float(valid_nodes) ** 3
    return np.where(v < 0, np.inf, value)


def refine_minimum(values: np.ndarray, i: int, j: int) -> tuple[float, float]:
    """Sub-node position of a minimum by a parabola through it and its two neighbours on each axis.

    Returns the fractional (row, col); an axis whose neighbours are missing (edge or +inf) or whose
    parabola is not convex stays at the node.
    """

    def offset(a: float, b: float, c: float) -> float:
        if not (np.isfinite(a) and np.isfinite(c)):
            return 0.0
        curvature = a - 2.0 * b + c
        if curvature <= 0:
            return 0.0
        return float(np.clip(0.5 * (a - c) / curvature, -0.5, 0.5))

    rows, cols = values.shape
    di = offset(values[i - 1, j], values[i, j], values[i + 1, j]) if 0 < i < rows - 1 else 0.0
    dj = offset(values[i, j - 1], values[i, j], values[i, j + 1]) if 0 < j < cols - 1 else 0.0
    return i + di, j + dj


class CrossTrackTracker:
    """Constrained adaptive tracker (CAT), patent eqs. 4-7.

    Each update::

        e     = f_ct(MLE(t)) - f_ct(P(t))                    (4)
        d(t)  = f_a(2 u e)                                   (5)
        w(t)  = f_v((1 - u) w(t-1) + d dt)                   (6)
        cross = f_ct(P(t) + w(t) dt)                         (7)

    with f_a, f_v clipping to +-``max_accel_mps2`` and +-``max_speed_mps``.

    Eqs. 5-6 are a spring of stiffness ``2u`` whose only damping is the ``(1 - u)`` decay of w: per
    second, ``s**2 + (u / dt) s + 2u = 0``, a damping ratio of about 0.035 at u = 0.01 and one update
    a second. The loop rings (44 s period) and amplifies MLE noise near that period about 14 times.
    ``damping_per_s`` replaces the decay by ``exp(-damping_per_s * dt)`` (a documented departure from
    the patent; None keeps the patent's ``1 - u``): 0.05 /s gives a damping ratio of 0.18 at u = 0.01
    whatever the update rate. The patent writes P(t) as
    P_e(t-1), the previous estimate, and notes that the state updater leaves its cross-track part
    unchanged when the ship's velocity is used; this implementation takes the state updater's
    prediction P_p(t), which is the same thing then, and also keeps a vehicle's own measured
    cross-track motion (INS/DVL) instead of undoing it. Along track the CAT keeps the MLE's estimate.

    Parameters
    ----------
    u : float
        Adaptive constant in (0, 1); the patent's nominal range is 0.001-0.01.
    max_accel_mps2 : float
        Threshold of f_a, m/s**2; set from the vehicle's dynamics (the patent gives no number).
    max_speed_mps : float
        Threshold of f_v, m/s.
    damping_per_s : float or None
        Decay rate of w, 1/s, in place of the patent's ``1 - u`` per update (see above); None: the patent.
    """

    def __init__(self, *, u: float = 0.01, max_accel_mps2: float = 0.05, max_speed_mps: float = 1.0,
                 damping_per_s: float | None = None) -> None:
        if not 0.0 < u < 1.0:
            raise ValueError(f"The adaptive constant u must lie in (0, 1); the patent's nominal range is 0.001-0.01, got {u!r}.")
        if not max_accel_mps2 > 0:
            raise ValueError(f"The cross-track acceleration threshold must be positive, got {max_accel_mps2!r}.")
        if not max_speed_mps > 0:
            raise ValueError(f"The cross-track velocity threshold must be positive, got {max_speed_mps!r}.")
        if damping_per_s is not None and not (isinstance(damping_per_s, (int, float)) and math.isfinite(damping_per_s) and damping_per_s >= 0):
            raise ValueError(f"The cross-track damping must be a finite rate of at least 0 per second, or None (the patent's 1 - u), got {damping_per_s!r}.")
        self._u = float(u)
        self._damping = None if damping_per_s is None else float(damping_per_s)
        self._max_accel = float(max_accel_mps2)
        self._max_speed = float(max_speed_mps)
        self.velocity_mps = 0.0  # w(t-1)

    def restart(self) -> None:
        """Forget w: after a gap in the MLEs its cross-track velocity is stale."""
        self.velocity_mps = 0.0

    def decay(self, dt_s: float) -> float:
        """The factor on w(t-1) in eq. 6: the patent's ``1 - u``, or ``exp(-damping_per_s * dt)``."""
        return 1.0 - self._u if self._damping is None else math.exp(-self._damping * dt_s)

    def update(self, *, predicted_cross_m: float, mle_cross_m: float, dt_s: float) -> float:
        """One step of eqs. 4-7; returns the new cross-track position cross(t) and keeps w(t)."""
        e = mle_cross_m - predicted_cross_m
        d = float(np.clip(2.0 * self._u * e, -self._max_accel, self._max_accel))
        self.velocity_mps = float(np.clip(self.decay(dt_s) * self.velocity_mps + d * dt_s, -self._max_speed, self._max_speed))
        return predicted_cross_m + self.velocity_mps * dt_s


def slant_range_correct(position: np.ndarray, reference: np.ndarray, measured_range_m: float) -> np.ndarray:
    """Slant-range corrector, patent eq. 8: ``P_e = P_ref + (CAT - P_ref) R_m / R_a``.

    Works on vectors of any dimension; the pipeline applies it to the horizontal projection with the
    horizontal range that the measured slant range leaves after the known depth difference.

    Raises
    ------
    ValueError
        A negative or non-finite measured range, or an estimate on the reference point (no direction).
    """
    if not (np.isfinite(measured_range_m) and measured_range_m >= 0):
        raise ValueError(f"the measured range must be a non-negative finite number of metres, got {measured_range_m!r}")
    position = np.asarray(position, float)
    reference = np.asarray(reference, float)
    estimated_range = float(np.linalg.norm(position - reference))
    if estimated_range == 0.0:
        raise ValueError("the estimate lies on the reference point, so the range gives no direction to correct along")
    return reference + (position - reference) * (measured_range_m / estimated_range)


def layback_position(frame: TrackFrame, layback_m: float) -> np.ndarray:
    """The lay-back model: the vehicle ``layback_m`` straight behind the ship, on its track (cross-track 0)."""
    return frame.position(-layback_m, 0.0)
