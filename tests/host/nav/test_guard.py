"""The estimate a user sees of a filter that is not usable: held within dead reckoning's 3 sigma; re-initializations named."""

import numpy as np
import pytest

from lost.host.nav import NavParameters
from lost.host.nav.estimator import Estimate
from lost.host.nav.guard import DeadReckoningGuard
from lost.host.nav.trust import RESTART_CAUSES, Trust

PARAMS = NavParameters(initial_sigma_m=10.0, velocity_noise_mps=0.1, velocity_bias_sigma_mps=0.0, gyro_bias_rps=0.0, accel_bias_mps2=0.0)


def _estimate(position, usable, sigma=2.0):
    return Estimate(position=np.asarray(position, float), covariance=np.eye(2) * sigma**2, usable=usable, stage="acquisition")


def test_a_usable_estimate_is_shown_as_it_is_and_becomes_the_anchor():
    guard = DeadReckoningGuard(PARAMS)
    guard.start(np.zeros(2))
    shown = guard.shown(_estimate([500.0, 0.0], usable=True))
    assert np.array_equal(shown.position, [500.0, 0.0]) and not guard.held
    guard.predict(np.array([1.0, 0.0]), 10.0)
    # Dead reckoning from the anchor: 510 m east, sigma sqrt(2**2 + (0.1 * 10)**2) per axis.
    far = guard.shown(_estimate([900.0, 0.0], usable=False))
    sigma = np.sqrt(4.0 + 1.0)
    assert guard.held
    assert np.allclose(far.position, [510.0 + 3.0 * sigma, 0.0])
    assert np.allclose(far.covariance, np.eye(2) * sigma**2)


def test_an_unusable_estimate_within_three_sigma_is_its_own():
    guard = DeadReckoningGuard(PARAMS)
    guard.start(np.array([100.0, 100.0]))
    near = guard.shown(_estimate([120.0, 90.0], usable=False))  # within 3 x 10 m of the start
    assert np.array_equal(near.position, [120.0, 90.0]) and not guard.held


@pytest.mark.parametrize("reason, cause", [(None, "updates_refused"), ("reinitialized_elsewhere", "fits_better_elsewhere"),
                                           ("reinitialized_by_ranges", "ranges_refused"),
                                           ("reinitialized_by_fixes", "fixes_refused")])
def test_a_reinitialization_carries_its_cause(reason, cause):
    trust = Trust(NavParameters(reinit_after=2), node_m=10.0)
    assert RESTART_CAUSES[reason] == cause
    if reason is None:
        trust.rejected("misfit")
        assert trust.rejected("misfit")
    elif reason == "reinitialized_by_ranges":
        assert any(trust.range_outcome(refused=True) for _ in range(4))
    else:
        trust._restart(reason)
    assert trust.restart_cause == cause


def test_a_lost_filter_shows_dead_reckoning_not_a_far_peak():
    """A filter started 400 m off on flat ground never converges: what it shows stays within dead reckoning's ellipse."""
    from lost.host.grid import Grid
    from lost.host.nav import navigate
    from lost.host.records import NavRecords, SonarPatch

    n, node = 60, 10.0
    depth = np.full((80, 80), 500.0)
    depth[:, 60:] += np.linspace(0, 50, 20)[None, :] ** 1.5  # a feature far east the flat patches half fit
    grid = Grid(depth, 0.0, 0.0, node)
    t = np.arange(n, dtype=float)
    truth = np.column_stack([np.full(n, 300.0), 200.0 + 2.0 * t])
    patches = tuple(SonarPatch(np.full((7, 7), 500.0) + np.random.default_rng(k).normal(0, 0.3, (7, 7)), node) for k in range(n))
    records = NavRecords(t_s=t, ship_x_m=truth[:, 0], ship_y_m=truth[:, 1] + 300.0, ship_heading_deg=np.zeros(n),
                         vehicle_depth_m=np.zeros(n), altitude_m=np.full(n, np.nan), vel_x_mps=np.zeros(n), vel_y_mps=np.full(n, 2.0),
                         slant_range_m=np.full(n, np.nan), cable_out_m=np.full(n, 300.0), sonar=patches,
                         truth_x_m=truth[:, 0], truth_y_m=truth[:, 1])
    params = NavParameters(initial_sigma_m=50.0, search_half_width_m=100.0)
    result = navigate(records, grid, params, estimators=("pmf", "pf"))
    for track in result.tracks.values():
        off = np.hypot(*(track.position - result.dead_reckoning).T)
        sigma = np.sqrt(np.linalg.eigvalsh(np.nan_to_num(track.covariance))[:, -1])
        unusable = ~track.usable
        assert np.all(off[unusable] <= 3.0 * sigma[unusable] + 1e-6)
