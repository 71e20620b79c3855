"""A filter's recovery: refused patches, ranges and USBL fixes re-initialize it, and where its new search lies."""

from dataclasses import replace

import numpy as np
import pytest

from lost.host.grid import Grid
from lost.host.nav.estimator import Motion
from lost.host.nav.likelihood import TerrainLikelihood
from lost.host.nav.mapprep import PreparedMap
from lost.host.nav.pf import ParticleFilter
from lost.host.nav.pmf import PointMassFilter
from lost.host.terrain import synthetic_terrain

from .test_filters import NODE, _map, _observation, _patch_at, _quiet, _track


def test_an_injected_outlier_patch_is_gated_and_counted():
    grid = _map(shape=(120, 80))
    pmf = PointMassFilter(TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0), _quiet(), grid=grid)
    pmf.start(0.0, np.array([400.0, 300.0]), _observation())
    position = _track(pmf, grid, (400.0, 300.0), 8)
    before = pmf.estimate()
    assert before.usable and np.hypot(*(before.position - position)) < 3.0
    # A patch of another place (300 m away) does not fit anywhere the filter may be.
    _track(pmf, grid, position, 1, seen=lambda p: p + (-300.0, 100.0))
    after = pmf.estimate()
    assert after.stage == "rejected" and "misfit" in after.rejected and not after.usable
    assert pmf.counts["rejected_misfit"] == 1
    assert np.hypot(*(after.position - before.position - (0.0, 10.0))) < 1.0



@pytest.mark.parametrize("kind", ["pmf", "pf"])
def test_refusals_reinitialize_wide_and_the_filter_recovers(kind):
    grid = _map(shape=(140, 100))
    params = _quiet(reinit_after=3, initial_sigma_m=100.0, velocity_bias_sigma_mps=0.0, velocity_bias_walk_mps=0.0)
    likelihood = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0)
    pmf = PointMassFilter(likelihood, params, grid=grid) if kind == "pmf" else ParticleFilter(likelihood, params, grid=grid, seed=5)
    pmf.start(0.0, np.array([500.0, 300.0]), _observation())
    position = _track(pmf, grid, (500.0, 300.0), 4)
    # From now on the vehicle is really 150 m east of where its motion says (a jump the motion did not see).
    stages = []
    for _ in range(10):
        position = _track(pmf, grid, position, 1, seen=lambda p: p + (150.0, 0.0))
        stages.append(pmf.estimate().stage)
    assert "reinitialized" in stages and pmf.counts["reinitializations"] == 1
    assert np.hypot(*(pmf.estimate().position - position - (150.0, 0.0))) < 3.0
    if kind == "pf":
        assert pmf.counts["redrawn_from_likelihood"] == 1  # the flat cloud was drawn where the next patch fits



def test_ranges_that_contradict_a_terrain_lock_twenty_times_in_a_row_reinitialize_it():
    """The terrain holds the density 150 m east of the truth (a wrong lock); every range says otherwise."""
    from lost.host.nav.stages import TrackFrame

    grid = _map(shape=(120, 100))
    lik = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0)
    params = _quiet(use_slant_range=True, initial_sigma_m=20.0, velocity_bias_sigma_mps=0.0, velocity_bias_walk_mps=0.0)
    pmf = PointMassFilter(lik, params, grid=grid)
    truth = np.array([300.0, 200.0])
    pmf.start(0.0, truth + (150.0, 0.0), _observation())
    for k in range(2 * params.reinit_after):
        truth = truth + (0.0, 10.0)
        pmf.predict(Motion(dt_s=1.0, velocity_mps=np.array([0.0, 10.0])))
        ship = TrackFrame(truth[0] - 1000.0, truth[1], 90.0)
        assert pmf.counts["reinitializations"] == 0, k
        pmf.update(_observation(_patch_at(grid, *(truth + (150.0, 0.0))), slant=1000.0, frame=ship))
    assert pmf.counts["range_rejected_innovation"] == 2 * params.reinit_after
    assert pmf.counts["reinitialized_by_ranges"] == 1 and pmf.estimate().stage == "reinitialized"



def test_usbl_fixes_refused_twenty_times_in_a_row_reinitialize_a_wrong_terrain_lock():
    """The terrain holds the density 150 m east of the truth; every USBL fix, at the truth, is gated out until the
    filter re-initializes; then the fixes bring it back."""
    from dataclasses import replace as with_fix

    grid = _map(shape=(120, 100))
    lik = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0)
    params = _quiet(use_usbl_fix=True, initial_sigma_m=300.0, velocity_bias_sigma_mps=0.0, velocity_bias_walk_mps=0.0)
    pmf = PointMassFilter(lik, params, grid=grid)
    truth = np.array([300.0, 200.0])
    pmf.start(0.0, truth + (150.0, 0.0), _observation())
    cov = np.diag([9.0, 9.0])
    for k in range(2 * params.reinit_after + 5):
        truth = truth + (0.0, 10.0)
        pmf.predict(Motion(dt_s=1.0, velocity_mps=np.array([0.0, 10.0])))
        if k < 2 * params.reinit_after:
            assert pmf.counts["reinitializations"] == 0, k
        patch = _patch_at(grid, *(truth + (150.0, 0.0))) if k < 2 * params.reinit_after else None
        pmf.update(with_fix(_observation(patch), fix_position_m=truth.copy(), fix_covariance_m2=cov))
    assert pmf.counts["fix_rejected_gate"] == 2 * params.reinit_after
    assert pmf.counts["reinitialized_by_fixes"] == 1 and pmf.counts["fix_updates"] >= 4
    assert np.hypot(*(pmf.estimate().position - truth)) < 10.0



@pytest.mark.parametrize("kind", ["pmf", "pf"])
def test_a_reinitialized_search_is_the_starts_gaussian_around_the_layback_or_flat_around_the_estimate(kind):
    grid = _map(shape=(140, 140))
    likelihood = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0)
    params = _quiet(initial_sigma_m=60.0)
    f = PointMassFilter(likelihood, params, grid=grid) if kind == "pmf" else ParticleFilter(likelihood, params, grid=grid, seed=3)
    estimate, layback = np.array([700.0, 700.0]), np.array([500.0, 650.0])
    f.start(0.0, estimate, _observation())
    f.update(_observation())  # no lay-back known yet
    f._reinitialize()
    mean, cov = f._moments()
    assert np.hypot(*(mean - estimate)) < 5.0
    assert np.all(np.sqrt(np.diag(cov)) > 2.0 * params.initial_sigma_m)  # flat over pmf_sigmas initial sigmas
    f.update(replace(_observation(), layback_m=layback))
    f._reinitialize()
    mean, cov = f._moments()
    assert np.hypot(*(mean - layback)) < 5.0
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), params.initial_sigma_m, rtol=0.05)



def test_patches_that_fit_better_elsewhere_re_initialize_a_wrong_lock():
    """150 m east of the truth lies a noisy copy of its terrain: a lock there is accepted, but every patch fits the truth better."""
    rng = np.random.default_rng(3)
    depth = synthetic_terrain((140, 100), seed=4, roughness_m=10.0, hurst=0.5)
    depth[:, 39:52] = depth[:, 24:37] + rng.normal(0.0, 1.0, (140, 13))
    grid = Grid(depth, 0.0, 0.0, NODE)
    params = _quiet(initial_sigma_m=15.0, velocity_bias_sigma_mps=0.0, velocity_bias_walk_mps=0.0)
    pmf = PointMassFilter(TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0), params, grid=grid)
    truth = np.array([300.0, 300.0])
    pmf.start(0.0, truth + (150.0, 0.0), _observation())
    for k in range(params.reinit_after - 1):
        truth = _track(pmf, grid, truth, 1)
        assert pmf.counts["reinitializations"] == 0, k
    assert np.hypot(*(pmf.estimate().position - truth - (150.0, 0.0))) < 5.0  # locked on the copy
    assert pmf.counts["fits_better_elsewhere"] == params.reinit_after - 1 and pmf.counts["rejected_misfit"] == 0
    truth = _track(pmf, grid, truth, 1)
    after = pmf.estimate()
    assert pmf.counts["reinitialized_elsewhere"] == 1 and after.stage == "reinitialized"
    assert np.sqrt(np.linalg.eigvalsh(after.covariance)).min() > 0.9 * params.initial_sigma_m  # searching again



def test_the_wrong_place_check_counts_a_window_of_patches_not_a_run():
    from lost.host.nav.trust import Trust

    class Margins:
        def __init__(self, values):
            self.values = iter(values)

        def margin(self, *args, **kwargs):
            return next(self.values)

    params = _quiet()
    trust = Trust(params, node_m=NODE)
    n = params.reinit_after
    # Alternating: n better-elsewhere patches take 2n - 1 checks; the n-th re-initializes.
    margins = Margins([-1.0, 0.8] * n)
    outcomes = [trust.look_alike(margins, np.zeros(2), np.eye(2), None) for _ in range(2 * n - 1)]
    assert outcomes == [False] * (2 * n - 2) + [True] and trust.counts["reinitialized_elsewhere"] == 1
    # A look-alike (about as good elsewhere) lowers the flag but is no evidence of a wrong place.
    ties = Margins([0.0] * (3 * n))
    assert not any(trust.look_alike(ties, np.zeros(2), np.eye(2), None) for _ in range(3 * n))
    assert trust.counts["lookalike"] == n + 3 * n and trust.counts["reinitializations"] == 1
    # A wide density is not checked at all.
    assert not trust.look_alike(Margins([-5.0]), np.zeros(2), 1e6 * np.eye(2), None)


@pytest.mark.parametrize("kind", ["pmf", "pf"])
def test_a_search_for_a_better_fit_elsewhere_stays_around_the_estimate_when_the_layback_lies_beyond_the_search(kind):
    grid = _map(shape=(140, 140))
    likelihood = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0)
    params = _quiet(initial_sigma_m=60.0, pmf_sigmas=4.0)
    estimate = np.array([700.0, 700.0])
    for layback, centre in ((np.array([700.0, 200.0]), estimate), (np.array([500.0, 650.0]), np.array([500.0, 650.0]))):
        f = PointMassFilter(likelihood, params, grid=grid) if kind == "pmf" else ParticleFilter(likelihood, params, grid=grid, seed=3)
        f.start(0.0, estimate, _observation())
        f.update(replace(_observation(), layback_m=layback))
        f._trust.restart_cause = "fits_better_elsewhere"
        f._reinitialize()
        mean, cov = f._moments()
        assert np.hypot(*(mean - centre)) < 5.0, layback
        np.testing.assert_allclose(np.sqrt(np.diag(cov)), params.initial_sigma_m, rtol=0.05)
        f._trust.restart_cause = "ranges_refused"  # any other cause: the lay-back, however far
        f._reinitialize()
        assert np.hypot(*(f._moments()[0] - layback)) < 5.0
