"""The drift test of the usable flag: terrain corrections that keep pulling one way say the density trails the truth."""

import numpy as np
from scipy.stats import chi2

from lost.host.nav import NavParameters
from lost.host.nav.trust import Trust

PRIOR = np.diag([25.0, 25.0])
POST = np.diag([16.0, 16.0])  # each update's shift then has covariance P_prior - P_post = 9 m**2 per axis


def _trust(**changes):
    return Trust(NavParameters(**changes), node_m=30.0)


def test_consistent_shifts_sum_to_a_chi_square_with_two_degrees_of_freedom():
    rng = np.random.default_rng(2)
    values = []
    for _ in range(300):
        trust = _trust()
        for _ in range(30):
            value = trust.note_correction(rng.normal(0.0, 3.0, 2), PRIOR, POST)
        values.append(value)
    # Mean 2 and the 0.999 quantile as chi-square(2) has them, within the sampling error of 300 draws.
    assert abs(np.mean(values) - 2.0) < 0.35
    assert np.mean(np.array(values) > chi2.ppf(0.999, 2)) < 0.01


def test_modest_shifts_all_one_way_are_a_drift_and_keep_the_flag_down():
    trust = _trust(usable_updates=30)
    for _ in range(40):
        # Each shift alone is 0.8 of its sigma (NIS 0.64 a update, far inside the 13.8 gate); 30 in a row sum to 19.2.
        trust.note_correction(np.array([2.4, 0.0]), PRIOR, POST)
        trust.accepted(POST)
        assert not trust.usable
    assert trust.drift == np.float64(19.2) or abs(trust.drift - 19.2) < 1e-3
    assert trust.counts["corrections_drifting"] == 40 - 29


def test_without_the_gate_the_same_shifts_make_the_filter_usable():
    trust = _trust(usable_updates=30, drift_gate=None)
    for _ in range(40):
        trust.note_correction(np.array([2.4, 0.0]), PRIOR, POST)
        trust.accepted(POST)
    assert trust.usable and trust.counts["corrections_drifting"] == 0


def test_the_test_waits_for_a_full_window_and_a_restart_empties_it():
    trust = _trust(usable_updates=5)
    for _ in range(4):
        assert np.isnan(trust.note_correction(np.array([3.0, 0.0]), PRIOR, POST))
    assert abs(trust.note_correction(np.array([3.0, 0.0]), PRIOR, POST) - 15.0**2 / 45.0) < 1e-3
    trust._restart(None)
    assert np.isnan(trust.note_correction(np.array([3.0, 0.0]), PRIOR, POST))
