"""Expectation-maximization of a Gaussian mixture over the particle cloud: the paper's proposed clustering.

Section 6 of the paper: "first perform distribution-based clustering of the particles to determine how many
in-water target clusters there are ... Expectation-Maximization would be a strong candidate". The particles
of a resampled cloud weigh the same, so this is plain EM on points in the plane, started from given seeds
(the tracker passes the ping's detections, where the cloud gathers), components whose share falls below
``min_share`` dropped as it goes. A regularizing ``floor_m**2`` on the covariances keeps a component on a
handful of coincident particles from collapsing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Mixture", "fit_mixture"]


@dataclass(frozen=True)
class Mixture:
    """Shares (k,), means (k, 2) and covariances (k, 2, 2) of the clusters found."""

    shares: np.ndarray
    means: np.ndarray
    covariances: np.ndarray

    def __len__(self) -> int:
        return int(self.shares.size)


def _log_densities(points: np.ndarray, means: np.ndarray, covariances: np.ndarray) -> np.ndarray:
    """log N(point; mean_k, cov_k), shape (n, k), with the 2x2 inverse written out."""
    a, b, d = covariances[:, 0, 0], covariances[:, 0, 1], covariances[:, 1, 1]
    det = a * d - b * b
    dx = points[:, None, 0] - means[None, :, 0]
    dy = points[:, None, 1] - means[None, :, 1]
    m2 = (d * dx * dx - 2 * b * dx * dy + a * dy * dy) / det
    return -0.5 * m2 - np.log(2 * np.pi * np.sqrt(det))


def fit_mixture(points: np.ndarray, seeds: np.ndarray, *, iterations: int = 6, seed_sigma_m: float = 20.0,
                min_share: float = 0.01, floor_m: float = 1.0) -> Mixture:
    """Fit a Gaussian mixture to ``points`` (n, 2) by EM from components at ``seeds`` (k, 2).

    Parameters
    ----------
    points : ndarray (n, 2)
        The particles, world metres.
    seeds : ndarray (k, 2)
        Where the components start; each starts round with ``seed_sigma_m``.
    iterations : int
        EM rounds.
    min_share : float
        Components with less of the cloud are dropped after each round.
    floor_m : float
        Added to each covariance's diagonal (squared) so a component cannot collapse.
    """
    if seeds.shape[0] == 0 or points.shape[0] == 0:
        return Mixture(np.empty(0), np.empty((0, 2)), np.empty((0, 2, 2)))
    means = np.asarray(seeds, float).copy()
    covariances = np.repeat((seed_sigma_m**2 * np.eye(2))[None], means.shape[0], axis=0)
    shares = np.full(means.shape[0], 1.0 / means.shape[0])
    x, y = points[:, 0], points[:, 1]
    for _ in range(iterations):
        log_r = np.log(shares)[None, :] + _log_densities(points, means, covariances)
        log_r -= log_r.max(axis=1, keepdims=True)
        resp = np.exp(log_r)
        resp /= resp.sum(axis=1, keepdims=True)
        mass = resp.sum(axis=0)
        keep = mass / points.shape[0] >= min_share
        if not keep.any():
            keep = mass == mass.max()
        resp, mass = resp[:, keep], mass[keep]
        shares = mass / mass.sum()
        means = (resp.T @ points) / mass[:, None]
        # Second moments by three products with the responsibilities (no (n, k, 2, 2) intermediate).
        sxx, sxy, syy = (resp.T @ products / mass for products in (x * x, x * y, y * y))
        covariances = np.empty((means.shape[0], 2, 2))
        covariances[:, 0, 0] = sxx - means[:, 0] ** 2 + floor_m**2
        covariances[:, 1, 1] = syy - means[:, 1] ** 2 + floor_m**2
        covariances[:, 0, 1] = covariances[:, 1, 0] = sxy - means[:, 0] * means[:, 1]
    return Mixture(shares, means, covariances)
