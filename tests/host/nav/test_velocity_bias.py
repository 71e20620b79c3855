"""The point-mass filter's velocity-bias Kalman filter: its estimate and its variance against the truth."""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

from lost.host.nav.velocity_bias import VelocityBiasFilter


def _learn(bias_mps: np.ndarray, steps: int, *, sigma_m: float, seed: int, walk: float = 0.0) -> VelocityBiasFilter:
    """A density that dead-reckons with the filter's estimate and is fixed by the terrain to ``sigma_m`` each second."""
    rng = np.random.default_rng(seed)
    f = VelocityBiasFilter(0.05, walk)
    truth = np.zeros(2)
    estimate = truth + rng.normal(0.0, sigma_m, 2)
    for _ in range(steps):
        truth = truth + (1.5, 0.3) - bias_mps  # the velocity reading runs ahead by the bias
        f.walk(1.0)
        estimate = estimate + np.array([1.5, 0.3]) - f.mean_mps
        fixed = truth + rng.normal(0.0, sigma_m, 2)
        f.update(fixed - estimate, 1.0, np.full(2, sigma_m**2), weight=1.0)
        estimate = fixed
    return f


def test_the_bias_is_learned_from_the_drift_of_the_corrections_and_its_variance_is_honest():
    bias = np.array([0.06, -0.03])
    runs = [_learn(bias, 200, sigma_m=1.0, seed=seed) for seed in range(200)]
    errors = np.array([f.mean_mps - bias for f in runs])
    variances = np.array([f.variance_mps2 for f in runs])
    # 200 s of 1 m fixes pin a slope to about 1 m * sqrt(12 / 200) / 200 s = 1.2 mm/s.
    assert np.all(np.sqrt(variances) < 0.002)
    assert np.sqrt(np.mean(errors**2)) < 0.002
    nees = np.sum(errors**2 / variances)  # 400 squared normalized errors (two axes, 200 runs)
    assert chi2.ppf(0.005, 400) < nees < chi2.ppf(0.995, 400)


def test_the_bias_variance_shrinks_as_it_is_learned_and_the_walk_keeps_it_open():
    short, long = _learn(np.zeros(2), 30, sigma_m=1.0, seed=1), _learn(np.zeros(2), 300, sigma_m=1.0, seed=1)
    assert np.all(long.variance_mps2 < short.variance_mps2 / 10.0)
    walking = _learn(np.zeros(2), 300, sigma_m=1.0, seed=1, walk=0.0005)
    assert np.all(walking.variance_mps2 > 2.0 * long.variance_mps2)


def test_a_restart_keeps_what_was_learned_and_anchors_a_new_sum():
    f = _learn(np.array([0.05, 0.0]), 100, sigma_m=1.0, seed=2)
    mean, variance = f.mean_mps, f.variance_mps2
    f.restart()
    assert not f.following
    f.update(np.array([480.0, -200.0]), 1.0, np.full(2, 1e4), weight=1.0)  # the jump a re-initialization makes
    np.testing.assert_array_equal(f.mean_mps, mean)
    np.testing.assert_array_equal(f.variance_mps2, variance)
    assert f.following


def test_a_patch_may_lie_off_by_the_bias_uncertainty_times_its_age():
    f = VelocityBiasFilter(0.05, 0.001)
    assert f.misplacement_var(60.0) == 0.05**2 * 60.0**2
    f.walk(100.0)
    assert np.isclose(f.misplacement_var(10.0), (0.05**2 + 0.001**2 * 100.0) * 100.0)


def test_a_density_of_one_point_does_not_make_the_gain_zero_over_zero():
    f = VelocityBiasFilter(0.05, 0.0)
    f.update(np.zeros(2), 1.0, np.zeros(2), weight=0.0)  # anchors
    f.update(np.array([-1.0, 1.0]), 1.0, np.zeros(2), weight=0.0)
    assert np.all(np.isfinite(f.mean_mps)) and np.all(np.isfinite(f.variance_mps2))
    assert f.mean_mps[0] > 0.0 > f.mean_mps[1]
