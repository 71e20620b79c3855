"""The point-mass filter's velocity bias as a Kalman filter on the drift of its corrections.

A velocity reading that runs ahead of the truth by b moves the dead-reckoned position b metres per
second too far, and the terrain pulls it back: the sum of the density's corrections, less what the
bias estimate already took out, falls along a line of slope -b. Per axis, the state is that sum's
noiseless value s and the bias b::

    s(k+1) = s(k) - b * dt        b(k+1) = b(k) + walk        (walk: velocity_bias_walk_mps per sqrt s)
    z(k)   = s(k) + e(k)          e: the density's own position error after the update

The measurement's noise is the position variance, divided by the update's tempering weight: successive
patches share most of their soundings, so their position errors are as correlated as their
likelihoods (one independent measurement per patch length). The sum does not grow with time, so the
slope is learned as fast as the terrain allows, and the bias's variance says how well: that variance
times a patch's age is how far the patch may lie from where it was reckoned (``misplacement_var``).
"""

from __future__ import annotations

import numpy as np

__all__ = ["VelocityBiasFilter"]


class VelocityBiasFilter:
    """Velocity bias (east, north), m/s, with its variance, learned from a density's corrections.

    Parameters
    ----------
    sigma_mps : float
        The bias's prior 1-sigma each axis (``velocity_bias_sigma_mps``).
    walk_mps : float
        Its random walk, m/s per square-root second (``velocity_bias_walk_mps``).
    """

    def __init__(self, sigma_mps: float, walk_mps: float) -> None:
        self._walk = float(walk_mps)
        self._state = np.zeros((2, 2))  # per axis: (s, b)
        self._cov = np.zeros((2, 2, 2))
        self._cov[:, 1, 1] = float(sigma_mps) ** 2
        self._drift = np.zeros(2)
        self._following = False

    @property
    def mean_mps(self) -> np.ndarray:
        """The bias estimate (east, north), m/s."""
        return self._state[:, 1].copy()

    @property
    def variance_mps2(self) -> np.ndarray:
        """Its variance each axis, (m/s)^2."""
        return self._cov[:, 1, 1].copy()

    @property
    def following(self) -> bool:
        """Whether a sum of corrections is being followed (since the first update after a start or restart)."""
        return self._following

    def misplacement_var(self, age_s: float) -> float:
        """The variance (m^2, the larger axis) of where a patch reckoned ``age_s`` back truly lies."""
        return float(self.variance_mps2.max()) * age_s**2

    def walk(self, dt_s: float) -> None:
        """The bias may have changed over ``dt_s`` (a towfish's lag follows the ship's turns)."""
        self._cov[:, 1, 1] += self._walk**2 * dt_s

    def restart(self) -> None:
        """The density jumped (a re-initialization): its corrections start a new sum; the bias learned stays."""
        self._following = False

    def update(self, correction_m: np.ndarray, dt_s: float, position_var_m2: np.ndarray, weight: float) -> None:
        """One terrain update: ``correction_m`` the density's corrections over the ``dt_s`` since the last.

        ``position_var_m2`` the density's variance each axis after it, ``weight`` the update's tempering.
        The first update after a start or restart only anchors the sum at the density's position.
        """
        # A millimetre at least: a density of one point would otherwise make the gain 0 / 0.
        noise = np.maximum(np.asarray(position_var_m2, float), 1e-6) / max(weight, 1e-3)
        if not self._following:
            self._following = True
            self._drift = np.zeros(2)
            self._state[:, 0] = 0.0
            self._cov[:, 0, :] = 0.0
            self._cov[:, :, 0] = 0.0
            self._cov[:, 0, 0] = noise
            return
        # What the corrections would have summed to without the estimate the prediction applied.
        self._drift = self._drift + np.asarray(correction_m, float) - self.mean_mps * dt_s
        step = np.array([[1.0, -dt_s], [0.0, 1.0]])
        for axis in range(2):
            mean = step @ self._state[axis]
            cov = step @ self._cov[axis] @ step.T
            innovation_var = cov[0, 0] + noise[axis]
            gain = cov[:, 0] / innovation_var
            self._state[axis] = mean + gain * (self._drift[axis] - mean[0])
            self._cov[axis] = cov - np.outer(gain, cov[0])
