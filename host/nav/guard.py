"""What a user sees of a Bayesian filter while it is not usable: an estimate held near dead reckoning.

A filter that has not converged, or has lost its fix, may hold a flat or many-peaked density whose mean
(or whichever peak it favours) lies far from anything the motion supports: on a smooth shelf both filters
moved the estimate 190 m off while dead reckoning was 30 m off, and held it there for minutes. The filter
itself keeps its whole density (it may yet find the right peak); the estimate it shows is guarded:

- the anchor: the last usable estimate and its covariance (at the start, the start and ``initial_sigma_m``),
  moved by the measured velocity: dead reckoning from it, its covariance grown by the velocity noise, the
  velocity bias's prior (``velocity_bias_sigma_mps`` times the time since the anchor) and the INS error model;
- while the filter is usable, the estimate is its own and becomes the anchor;
- while it is not, an estimate beyond the anchor's 3-sigma ellipse is brought back onto it along the line
  to the dead-reckoned position, and its covariance is the dead reckoning's (counted
  ``held_to_dead_reckoning``; ``FilterTrack.held`` marks the records).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .estimator import Estimate
from .trust import ins_position_sigma

__all__ = ["DeadReckoningGuard", "GUARD_SIGMAS"]

#: The ellipse an unusable estimate is held within, in dead reckoning's standard deviations.
GUARD_SIGMAS = 3.0


class DeadReckoningGuard:
    """The guarded estimate of one filter (see the module docstring)."""

    def __init__(self, params) -> None:
        self._p = params
        self._position: np.ndarray | None = None
        self._anchor_cov = np.zeros((2, 2))
        self._since_s = 0.0
        self._noise_var = 0.0
        self.held = False

    def start(self, position: np.ndarray) -> None:
        self._position = np.asarray(position, float).copy()
        self._anchor_cov = np.eye(2) * self._p.initial_sigma_m**2
        self._since_s, self._noise_var = 0.0, 0.0

    def predict(self, velocity_mps: np.ndarray, dt_s: float) -> None:
        if self._position is None:
            return
        self._position = self._position + np.asarray(velocity_mps, float) * dt_s
        self._since_s += dt_s
        self._noise_var += (self._p.velocity_noise_mps * dt_s) ** 2

    @property
    def covariance(self) -> np.ndarray:
        """Dead reckoning's covariance from the anchor, m**2."""
        p, t = self._p, self._since_s
        ins = float(ins_position_sigma(t, gyro_bias_rps=p.gyro_bias_rps, accel_bias_mps2=p.accel_bias_mps2)) ** 2
        return self._anchor_cov + np.eye(2) * (self._noise_var + (p.velocity_bias_sigma_mps * t) ** 2 + ins)

    def shown(self, estimate: Estimate) -> Estimate:
        """The estimate to report: the filter's own while usable (and the anchor moves to it), else held within 3 sigma."""
        self.held = False
        if self._position is None or not np.all(np.isfinite(estimate.covariance)):
            return estimate
        if estimate.usable:
            self._position = np.asarray(estimate.position, float).copy()
            self._anchor_cov = np.asarray(estimate.covariance, float).copy()
            self._since_s, self._noise_var = 0.0, 0.0
            return estimate
        cov = self.covariance
        d = np.asarray(estimate.position, float) - self._position
        distance_sq = float(d @ np.linalg.solve(cov, d))
        if distance_sq <= GUARD_SIGMAS**2:
            return estimate
        self.held = True
        held = self._position + d * (GUARD_SIGMAS / np.sqrt(distance_sq))
        return replace(estimate, position=held, covariance=cov)
