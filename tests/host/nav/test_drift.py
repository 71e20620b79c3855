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


# The trail test (``Trust._one_way``): a gain of 1 - 16/25 = 0.36 an update, so a mean shift d says a lag of d / 0.36,
# against the posterior's 4 m sigma per axis.

def _noted(trust, shifts):
    for shift in shifts:
        trust.note_correction(np.asarray(shift, float), PRIOR, POST)
        trust.accepted(POST)
    return trust


def test_shifts_one_way_whose_lag_exceeds_two_sigmas_trail_and_keep_the_flag_down():
    """A towfish lagging the ship it is reckoned by: each shift small and noisy, all one way. The chi-square's bar is set out
    of reach (a particle cloud's noisy P_prior - P_post kept it at 3-5 on such a tow): the trail test alone lowers the flag."""
    rng = np.random.default_rng(4)
    shifts = np.column_stack([3.6 + rng.normal(0.0, 1.0, 40), rng.normal(0.0, 1.0, 40)])  # lag 10 m = 2.5 sigma
    trust = _noted(_trust(usable_updates=30, drift_gate=1e9), shifts)
    assert trust.trailing and not trust.usable
    assert trust.counts["corrections_one_way"] == trust.counts["corrections_drifting"] == 40 - 29
    # A lag under two sigmas (7 m), as one way, keeps the flag.
    trust = _noted(_trust(usable_updates=30, drift_gate=1e9), shifts * (7.0 / 10.0))
    assert not trust.trailing and trust.usable


def test_a_crawl_one_way_within_the_density_or_shifts_either_way_do_not_trail():
    rng = np.random.default_rng(5)
    crawl = np.column_stack([np.full(40, 0.5), rng.normal(0.0, 0.5, 40)])  # all one way, but a lag of 1.4 m = 0.35 sigma
    trust = _noted(_trust(usable_updates=30), crawl)
    assert not trust.trailing and trust.usable
    # As large a mean, but the signs mixed (a consistent filter's shifts, one large pull among them): no sign test passes.
    mixed = np.column_stack([np.tile([3.0, -2.0], 20), np.zeros(40)])
    mixed[-1, 0] = 60.0
    trust = _noted(_trust(usable_updates=30), mixed)
    assert not trust.trailing


def test_the_trail_test_needs_a_window_of_twenty_and_a_restart_clears_it():
    shifts = np.tile([4.0, 0.0], (12, 1))
    trust = _noted(_trust(usable_updates=12, drift_gate=1e9), shifts)
    assert not trust.trailing and trust.usable  # 12 of 12 one way is no evidence the test is built to weigh
    trust = _noted(_trust(usable_updates=20, drift_gate=1e9), np.tile([4.0, 0.0], (20, 1)))
    assert trust.trailing and not trust.usable  # drift_gate only raises the chi-square's bar; the trail test stands
    trust._restart(None)
    assert not trust.trailing


def test_the_range_gate_learns_how_far_the_stated_innovation_variance_overstates_the_real_one():
    from lost.host.nav.gate import CHI2_1_MEDIAN
    from lost.host.nav.gate import GATE_MEMORY as RANGE_MEMORY
    from lost.host.nav.gate import GATE_SCALE_MIN as RANGE_SCALE_MIN

    rng = np.random.default_rng(6)
    trust = _trust()
    honest = rng.chisquare(1, RANGE_MEMORY)
    for value in honest[:-1]:
        assert trust.note_range_innovation(value) == 1.0  # unlearned until the window is full
    assert trust.note_range_innovation(honest[-1]) == 1.0 or abs(trust.range_scale - np.median(honest) / CHI2_1_MEDIAN) < 1e-9
    # Ranges four times as good as stated, with 1 % far outliers among them: the scale is about a quarter.
    trust = _trust()
    for value in np.where(rng.random(200) < 0.01, 1e4, 0.25 * rng.chisquare(1, 200)):
        trust.note_range_innovation(value)
    assert 0.2 <= trust.range_scale < 0.35
    # Never looser than stated, never tighter than the least scale; a NaN is not counted.
    trust = _trust()
    for _ in range(RANGE_MEMORY):
        trust.note_range_innovation(5.0)
    assert trust.range_scale == 1.0
    for _ in range(RANGE_MEMORY):
        trust.note_range_innovation(1e-6)
    trust.note_range_innovation(float("nan"))
    assert trust.range_scale == RANGE_SCALE_MIN


def test_the_shift_share_is_one_for_a_consistent_filter_and_small_for_a_density_wider_than_its_error():
    rng = np.random.default_rng(5)
    consistent, too_wide = _trust(usable_updates=30), _trust(usable_updates=30)
    shares = []
    for _ in range(200):
        consistent.note_correction(rng.normal(0.0, 3.0, 2), PRIOR, POST)  # as P_prior - P_post says: 9 m**2 an axis
        too_wide.note_correction(rng.normal(0.0, 1.0, 2), PRIOR, POST)  # a ninth of it
        shares.append(consistent.shift_share())
    assert abs(np.nanmean(shares) - 1.0) < 0.1
    assert too_wide.shift_share() < 0.25


def test_the_shift_share_waits_for_a_full_window():
    trust = _trust(usable_updates=5)
    for _ in range(4):
        trust.note_correction(np.array([3.0, 0.0]), PRIOR, POST)
        assert np.isnan(trust.shift_share())
    trust.note_correction(np.array([3.0, 0.0]), PRIOR, POST)
    assert abs(trust.shift_share() - 45.0 / 90.0) < 1e-4  # |d|^2 of 9 against a trace of 18, five times
