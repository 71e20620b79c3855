"""Nygren's variance of the maximum-likelihood position (eq. 5.2), and a Monte Carlo check of it.

For a bottom profile made by an AR(1) process of pole ``a`` and variance sigma_x**2, measured by a linear
array of N beams with independent errors of variance sigma_e**2, eq. 5.2 gives the variance of the ML
estimate of the array's position along the profile, in beam spacings squared::

    Var(x) ~ 1/2 (1 + a) / N  sigma_e**2 / sigma_x**2

The Monte Carlo below draws a profile, a true sub-beam offset and noisy beams, finds the ML offset by a
fine search with the profile interpolated linearly between its samples, and returns the variance of the
error over many trials. (Linearizing the ML estimate gives ``1/2 / ((1 - a) N) sigma_e**2 / sigma_x**2``,
which eq. 5.2 matches to first order in a.)
"""

from __future__ import annotations

import numpy as np

__all__ = ["nygren_ml_variance", "ar1_profile", "ml_offset_variance"]


def nygren_ml_variance(a: float, n_beams: int, noise_to_terrain: float) -> float:
    """Eq. 5.2: the ML position variance, beam spacings squared; ``noise_to_terrain`` = sigma_e / sigma_x."""
    return 0.5 * (1.0 + a) / n_beams * noise_to_terrain**2


def ar1_profile(length: int, a: float, rng: np.random.Generator) -> np.ndarray:
    """A stationary AR(1) profile of unit variance: h[k] = a h[k-1] + w[k]."""
    w = rng.normal(0.0, np.sqrt(1.0 - a * a), length)
    h = np.empty(length)
    h[0] = rng.normal()
    for k in range(1, length):
        h[k] = a * h[k - 1] + w[k]
    return h


def ml_offset_variance(a: float, n_beams: int, noise_to_terrain: float, *, trials: int = 2000, seed: int = 0,
                       step: float = 0.005) -> float:
    """Monte Carlo variance of the ML offset (beam spacings squared) of an N-beam array on AR(1) terrain."""
    rng = np.random.default_rng(seed)
    candidates = np.arange(-1.0, 1.0 + step / 2, step)
    errors = np.empty(trials)
    for trial in range(trials):
        profile = ar1_profile(n_beams + 8, a, rng)
        truth = rng.uniform(-0.5, 0.5)
        beams = np.arange(n_beams) + 4.0
        measured = np.interp(beams + truth, np.arange(profile.size), profile) + rng.normal(0.0, noise_to_terrain, n_beams)
        at = beams[None, :] + candidates[:, None]
        model = np.interp(at.ravel(), np.arange(profile.size), profile).reshape(at.shape)
        cost = np.sum((measured[None, :] - model) ** 2, axis=1)
        errors[trial] = candidates[int(np.argmin(cost))] - truth
    return float(np.mean(errors**2))
