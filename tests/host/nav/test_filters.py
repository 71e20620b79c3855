"""The Bayesian filters: motion and measurement updates by hand, gating, recovery, PF against PMF, eq. 5.2."""

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import chi2

from lost.host.grid import Grid
from lost.host.nav import NavParameters, navigate
from lost.host.nav.estimator import Motion, Observation
from lost.host.nav.likelihood import TerrainLikelihood
from lost.host.nav.mapprep import PreparedMap
from lost.host.nav.pf import ParticleFilter, systematic_resample
from lost.host.nav.pmf import PointMassFilter
from lost.host.nav.theory import ml_offset_variance, nygren_ml_variance
from lost.host.nav.trust import SCHULER_PERIOD_S, ins_position_sigma, nis
from lost.host.records import SonarPatch
from lost.host.terrain import synthetic_terrain

NODE = 10.0


def _map(seed=4, shape=(80, 80)):
    return Grid(synthetic_terrain(shape, seed=seed, roughness_m=10.0, hurst=0.5), 0.0, 0.0, NODE)


def _patch_at(grid, x, y, side=9, bias=2.0):
    """A patch cut exactly from the map around node (x, y), with a constant bias."""
    row, col = (int(round(v)) for v in grid.row_col(x, y))
    half = side // 2
    return SonarPatch(grid.depth_m[row - half : row + half + 1, col - half : col + half + 1] + bias, NODE)


def _observation(patch=None, slant=np.nan, frame=None):
    return Observation(t_s=0.0, frame=frame, patch=patch, ocean_depth_m=np.nan, vehicle_depth_m=0.0, slant_range_m=slant)


def _quiet(**changes):
    """No error growth besides what a test asks for; every update usable at once."""
    base = NavParameters(velocity_noise_mps=0.0, gyro_bias_rps=0.0, accel_bias_mps2=0.0, use_slant_range=False,
                         usable_updates=1, estimate_velocity_bias=False)
    return replace(base, **changes)


def test_the_motion_update_is_a_shift_and_a_gaussian_convolution_by_hand():
    grid = _map()
    params = _quiet(velocity_noise_mps=2.0, position_floor_nodes=0.01, pmf_min_cell_m=1.0, initial_sigma_m=5.0)
    pmf = PointMassFilter(TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0), params, grid=grid)
    pmf.start(0.0, np.array([400.0, 400.0]), _observation())
    # A delta: all the mass in one cell.
    x, y, p = pmf.density
    k = np.unravel_index(np.argmin(np.hypot(x - 400.0, y - 400.0)), p.shape)
    at = np.array([x[k], y[k]])
    pmf._p_grid[:] = 0.0
    pmf._p_grid[k] = 1.0
    cell = pmf._cell
    pmf.predict(Motion(dt_s=1.0, velocity_mps=np.array([3.0, -1.0])))
    x, y, p = pmf.density
    # The mass moved by the velocity exactly, and spread as N(0, 2**2) per axis: the convolution by hand.
    assert pmf._cell == cell == pytest.approx(1.0)  # a shift and a blur, no new grid
    assert ((p * x).sum(), (p * y).sum()) == pytest.approx((at[0] + 3.0, at[1] - 1.0), abs=1e-9)
    by_hand = np.exp(-0.5 * ((x - at[0] - 3.0) ** 2 + (y - at[1] + 1.0) ** 2) / 4.0)
    by_hand /= by_hand.sum()
    assert np.abs(p - by_hand).max() < 0.01 * by_hand.max()


def test_the_measurement_update_is_eq_3_5_on_a_tiny_grid():
    grid = _map()
    lik = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=30.0)
    pmf = PointMassFilter(lik, _quiet(pmf_cells=8, initial_sigma_m=10.0, position_floor_nodes=0.001), grid=grid)
    pmf._follow = lambda: None  # keep the grid, to compare cell for cell
    pmf.start(0.0, np.array([400.0, 400.0]), _observation())
    x, y, prior = (a.copy() for a in pmf.density)
    assert prior.shape == (8, 8) and pmf._cell == NODE
    patch = _patch_at(grid, 405.0, 395.0)
    expected = lik.patch(x, y, patch, weight=1.0).log_likelihood
    pmf.update(_observation(patch))
    assert pmf.estimate().stage == "acquisition"
    # Eq. 3.5: the posterior is the likelihood times the prior, normalized.
    by_hand = prior * np.exp(expected - expected.max())
    by_hand /= by_hand.sum()
    np.testing.assert_allclose(pmf.density[2], by_hand, rtol=1e-9, atol=1e-15)


def test_the_laplace_likelihood_is_the_correlators_sum_of_absolute_residuals():
    grid = _map()
    prep = PreparedMap(grid=grid, lsb_m=0.01)
    lik = TerrainLikelihood(prep, sigma_m=0.7)
    patch = _patch_at(grid, 300.0, 350.0, bias=5.0)
    patch = SonarPatch(patch.depth_m + np.random.default_rng(1).normal(0, 0.3, patch.depth_m.shape), NODE)
    result = lik.patch(np.array([300.0, 330.0]), np.array([350.0, 350.0]), patch)
    for k, (x, y) in enumerate([(300.0, 350.0), (330.0, 350.0)]):
        row, col = (int(round(v)) for v in grid.row_col(x, y))
        d = (np.round(grid.depth_m[row - 4 : row + 5, col - 4 : col + 5] / 0.01) - np.round(patch.depth_m / 0.01)) * 0.01
        by_hand = -math.sqrt(2.0) * np.abs(d - d.mean()).sum() / 0.7
        assert result.log_likelihood[k] == pytest.approx(by_hand, rel=1e-3)
    gaussian = TerrainLikelihood(prep, sigma_m=0.7, form="gaussian").patch(np.array([300.0]), np.array([350.0]), patch)
    row, col = (int(round(v)) for v in grid.row_col(300.0, 350.0))
    d = (np.round(grid.depth_m[row - 4 : row + 5, col - 4 : col + 5] / 0.01) - np.round(patch.depth_m / 0.01)) * 0.01
    assert gaussian.log_likelihood[0] == pytest.approx(-((d - d.mean()) ** 2).sum() / (2 * 0.7**2), rel=1e-6)


def test_off_the_map_the_likelihood_is_flat_and_typical_not_good():
    grid = _map()
    lik = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0)
    patch = _patch_at(grid, 100.0, 400.0)
    x = np.array([100.0, -300.0, -500.0])
    result = lik.patch(x, np.full(3, 400.0), patch)
    assert result.informative.tolist() == [True, False, False]
    assert result.log_likelihood[1] == result.log_likelihood[2] < result.log_likelihood[0]


def _track(f, grid, start, steps, *, velocity=(0.0, 10.0), seen=None):
    """Move a filter ``steps`` records north at 10 m/s from ``start``; the patches are cut where ``seen`` says (default: the truth)."""
    position = np.asarray(start, float)
    for _ in range(steps):
        position = position + velocity
        f.predict(Motion(dt_s=1.0, velocity_mps=np.asarray(velocity, float)))
        at = position if seen is None else seen(position)
        f.update(_observation(_patch_at(grid, *at)))
    return position


def test_particle_and_point_mass_filters_agree_on_a_unimodal_case():
    grid = _map(shape=(100, 100))
    truth = np.array([500.0, 400.0])
    params = _quiet(initial_sigma_m=20.0, velocity_bias_sigma_mps=0.0, velocity_bias_walk_mps=0.0, position_floor_nodes=0.01,
                    pmf_min_cell_m=0.5, usable_sigma_nodes=10.0)
    lik = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=300.0)
    filters = [PointMassFilter(lik, params, grid=grid), ParticleFilter(lik, params, grid=grid, seed=3)]
    for f in filters:
        f.start(0.0, truth + (15.0, -10.0), _observation())
        _track(f, grid, truth, 3)
    pmf, pf = (f.estimate() for f in filters)
    assert np.sqrt(np.diag(pmf.covariance)).max() > 2.0  # broad enough to compare shapes, not cells
    assert np.hypot(*(pmf.position - pf.position)) < 0.1 * np.sqrt(np.trace(pmf.covariance))
    np.testing.assert_allclose(pf.covariance, pmf.covariance, rtol=0.15, atol=0.1 * np.trace(pmf.covariance))


def test_systematic_resampling_keeps_each_particle_in_proportion():
    rng = np.random.default_rng(0)
    weights = np.array([0.5, 0.25, 0.125, 0.125])
    counts = np.bincount(systematic_resample(np.repeat(weights, 250) / 250, rng) // 250, minlength=4)
    assert counts.tolist() == [500, 250, 125, 125]


def test_nis_of_a_linear_gaussian_update_is_the_innovations():
    prior_cov, r = np.diag([4.0, 9.0]), np.eye(2)
    innovation = np.array([1.0, -2.0])
    gain = prior_cov @ np.linalg.inv(prior_cov + r)
    post_cov = prior_cov - gain @ prior_cov
    expected = innovation @ np.linalg.solve(prior_cov + r, innovation)
    assert nis(np.zeros(2), prior_cov, gain @ innovation, post_cov) == pytest.approx(expected, rel=1e-4)


def test_the_ins_error_model_is_eq_6_2():
    w = 2 * math.pi / SCHULER_PERIOD_S
    t = 3000.0
    gyro, accel = 1e-7, 5e-4
    by_hand = math.hypot(9.81 * t / w**2 * (1 - math.sin(w * t) / (w * t)) * gyro, (1 - math.cos(w * t)) / w**2 * accel)
    assert float(ins_position_sigma(t, gyro_bias_rps=gyro, accel_bias_mps2=accel)) == pytest.approx(by_hand)
    # Early on the accelerometer term is B t**2 / 2; it peaks at half a Schuler period.
    assert float(ins_position_sigma(10.0, gyro_bias_rps=0.0, accel_bias_mps2=accel)) == pytest.approx(accel * 50.0, rel=1e-3)
    peak = ins_position_sigma(SCHULER_PERIOD_S / 2, gyro_bias_rps=0.0, accel_bias_mps2=accel)
    assert float(peak) == pytest.approx(2 * accel / w**2)


@pytest.mark.parametrize("a", [0.0, 0.3])
def test_eq_5_2_the_ml_variance_on_ar1_terrain_within_1_5_and_falling_as_1_over_n(a):
    variances = {n: ml_offset_variance(a, n, 0.1, trials=600, seed=n) for n in (25, 100)}
    for n, variance in variances.items():
        assert 1 / 1.5 <= variance / nygren_ml_variance(a, n, 0.1) <= 1.5
    assert variances[100] / variances[25] == pytest.approx(0.25, rel=0.35)


# On the map = floor (short_exact_map): RMS under half a 10 m node, NEES in band 0.8. On the 30 m survey map (short,
# seed 5) the filters are worse, and these bounds are what they do there with a margin: over seeds 5-14 of `short`,
# the PMF's RMS is 6.4 m median, 24 m p90 (seed 5: 14.7 m), NEES in band 0.88 / 0.56 at the
# 10th percentile (seed 5: 0.56, 93 false fixes); the PF's 4.7 m / 33 m (seed 5: 13.1 m), NEES in band 0.57 median
# (seed 5: 0.54); converged within 84 s on every seed.
@pytest.mark.parametrize("scenario_name, rms_m, nees_in_band", [("short_exact_map", 5.0, 0.8), ("short", 20.0, 0.45)])
def test_the_nees_of_the_filters_on_the_short_tow_lies_in_its_band(scenario_name, rms_m, nees_in_band):
    from lost.host.report import summarize
    from lost.host.scenario import builtin_scenario_path, load_scenario, simulate

    scenario = load_scenario(builtin_scenario_path(scenario_name))
    grid, records = simulate(scenario)
    result = navigate(records, grid, NavParameters(**scenario.navigation), estimators=("pmf", "pf"))
    summary = summarize(result, name=scenario_name, parameters={})
    band = (chi2.ppf(0.025, 2), chi2.ppf(0.975, 2))
    for name in ("pmf", "pf"):
        figures = summary["methods"][name]
        assert figures["converged"] and figures["convergence_time_s"] < 120.0, (name, figures)
        assert figures["rms_m"] < rms_m and figures["nees_in_band"] >= nees_in_band, (name, figures, band)


def test_the_bilinear_read_matches_scipy_and_knows_where_it_is_valid():
    from scipy import ndimage

    from lost.host.nav.likelihood import _bilinear

    rng = np.random.default_rng(0)
    values, valid = rng.normal(size=(7, 9)), rng.random((7, 9)) > 0.1
    row, col = rng.uniform(-1, 7, 5000), rng.uniform(-1, 9, 5000)
    value, ok = _bilinear(np.where(valid, values, 0.0), valid, row, col)
    coords = [row, col]
    expected = ndimage.map_coordinates(np.where(valid, values, 0.0), coords, order=1, mode="constant", cval=0.0)
    share = ndimage.map_coordinates(valid.astype(float), coords, order=1, mode="constant", cval=0.0)
    np.testing.assert_array_equal(ok, share > 1 - 1e-9)
    np.testing.assert_allclose(value[ok], expected[ok], atol=1e-12)
    # Every node, the last row and column included, reads back as itself.
    rows, cols = np.meshgrid(np.arange(7.0), np.arange(9.0), indexing="ij")
    value, ok = _bilinear(values, np.ones((7, 9), bool), rows.ravel(), cols.ravel())
    assert ok.all() and np.array_equal(value, values.ravel())


def test_the_likelihood_peaks_between_placements_where_the_patch_was_taken():
    """A patch sounded 4 m and 3 m off the nodes peaks there, not on a node (bilinear reads would snap to one)."""
    from scipy import ndimage

    grid = _map(seed=7)
    lik = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=0.5)
    truth = np.array([404.0, 397.0])
    row, col = grid.row_col(*truth)
    offsets = np.arange(-4, 5)
    rows, cols = np.meshgrid(row + offsets, col + offsets, indexing="ij")
    patch = SonarPatch(ndimage.map_coordinates(grid.depth_m, [rows, cols], order=1), NODE)
    x, y = np.meshgrid(np.arange(390.0, 420.0, 0.5), np.arange(385.0, 410.0, 0.5))
    result = lik.patch(x, y, patch)
    best = np.unravel_index(np.argmax(result.log_likelihood), x.shape)
    assert math.hypot(x[best] - truth[0], y[best] - truth[1]) <= 1.5
    # Through the placements themselves the interpolation is exact: the correlator's value.
    on_nodes = lik.patch(np.array([400.0]), np.array([400.0]), patch).log_likelihood[0]
    assert on_nodes == pytest.approx(result.log_likelihood[(x == 400.0) & (y == 400.0)][0], rel=1e-9)


def _point_tow(kind, grid, depth_bias_sigma_m, *, bias=4.0, steps=100):
    """A point-form tow (one ocean depth a record) whose depths read ``bias`` deeper than the map: errors of the last 30."""
    from scipy import ndimage

    rng = np.random.default_rng(2)
    params = _quiet(matching="point", initial_sigma_m=40.0, depth_bias_sigma_m=depth_bias_sigma_m, depth_bias_walk_m=0.0,
                    usable_updates=5)
    lik = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=0.5, depth_sigma_m=0.5)
    f = PointMassFilter(lik, params, grid=grid) if kind == "pmf" else ParticleFilter(lik, params, grid=grid, seed=1)
    truth = np.array([500.0, 200.0])
    f.start(0.0, truth + (20.0, -25.0), _observation())
    errors = []
    for k in range(steps):
        truth = truth + (3.0, 9.0)
        f.predict(Motion(dt_s=1.0, velocity_mps=np.array([3.0, 9.0])))
        row, col = grid.row_col(*truth)
        depth = float(ndimage.map_coordinates(grid.depth_m, [[row], [col]], order=1)[0]) + bias + rng.normal(0.0, 0.3)
        f.update(Observation(t_s=float(k), frame=None, patch=None, ocean_depth_m=depth, vehicle_depth_m=0.0, slant_range_m=np.nan))
        errors.append(np.hypot(*(f.estimate().position - truth)))
    return f, np.array(errors[-30:])


@pytest.mark.parametrize("kind", ["pmf", "pf"])
def test_the_point_form_estimates_a_depth_bias_and_is_lost_without_it(kind):
    grid = _map(shape=(160, 100))
    f, errors = _point_tow(kind, grid, depth_bias_sigma_m=4.0)
    mean, sigma = f.depth_bias_m
    assert abs(mean - 4.0) < 0.3 and sigma < 0.5
    assert f.estimate().depth_bias_m == mean  # what track.csv's <name>_depth_bias_m reports
    assert np.sqrt(np.mean(errors**2)) < 3.0
    # Without the state the 4 m reads as terrain elsewhere: tens of metres off, refusals, a re-initialization.
    f, errors = _point_tow(kind, grid, depth_bias_sigma_m=0.0)
    assert np.sqrt(np.mean(errors**2)) > 10.0 and f.counts["rejected_gate"] > 5


def test_a_velocity_bias_misplaces_a_realtime_patch_by_bias_times_age_and_the_particles_shift_it_back():
    """The model behind ``SonarPatch.age_s``: on a tow whose velocity reads 5 and -4 cm/s off, the patches fit best b * age from the truth."""
    from lost.host.scenario import builtin_scenario_path, exact_map, load_scenario, simulate

    scenario = exact_map(load_scenario(builtin_scenario_path("usbl_nav")))  # the patch's placement to half a metre needs the map to be the floor
    grid, records = simulate(replace(scenario, duration_s=500.0))
    bias = np.array([0.05, -0.04])  # the scenario's [sensors.velocity] bias
    lik = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=0.6)
    offsets, ages = [], []
    for n in range(200, 500, 20):
        patch = records.sonar[n]
        truth = np.array([records.truth_x_m[n], records.truth_y_m[n]])
        x, y = np.meshgrid(truth[0] + np.arange(-10.0, 10.01, 0.5), truth[1] + np.arange(-10.0, 10.01, 0.5))
        ell = lik.patch(x, y, patch).log_likelihood
        best = np.unravel_index(np.argmax(ell), x.shape)
        offsets.append((x[best] - truth[0], y[best] - truth[1]))
        ages.append(patch.age_s)
    assert 30.0 < np.mean(ages) < 60.0  # the centre ping lies half a patch diagonal (71 m) behind at 1.5 m/s
    east, north = np.mean(offsets, axis=0)
    expected = bias * np.mean(ages)
    # Along the track (east) to half a metre; across it the track keeps one northing, whose sub-node phase adds its own bias.
    assert abs(east - expected[0]) < 0.5 and north < 0 and abs(north - expected[1]) < 1.2
    # A particle carrying the true bias reads the patch where it lies.
    pf = ParticleFilter(lik, _quiet(), grid=grid)
    pf._b = np.tile(bias[:, None], (1, 3))
    shift_x, shift_y = pf._patch_shift(40.0)
    np.testing.assert_allclose([shift_x[0], shift_y[0]], bias * 40.0)


def test_the_point_mass_filter_learns_its_bias_from_every_correction_and_moves_its_patches_by_it():
    """A range's correction and the terrain's that follows are one drift: learning from the terrain's alone
    read a range-versus-terrain tug of war as a bias of the opposite sign."""
    grid = _map()
    params = _quiet(estimate_velocity_bias=True, bias_learning_updates=1)
    pmf = PointMassFilter(TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0), params, grid=grid)
    truth = np.array([400.0, 400.0])
    pmf.start(0.0, truth, _observation())
    pmf.update(_observation(_patch_at(grid, *truth)))
    truth = _track(pmf, grid, truth, 1)  # narrow for one update: the bias filter anchors its sum here
    assert pmf.estimate().usable and np.all(pmf.velocity_bias_mps == 0.0) and pmf._velocity_bias.following
    pmf._since_bias_update_s = 10.0
    posterior, cov = pmf._p_grid.copy(), 4.0 * np.eye(2)
    pmf._accept(posterior, cov, np.array([2.0, 0.0]), terrain=False)  # a range pulls 2 m east
    np.testing.assert_array_equal(pmf.velocity_bias_mps, 0.0)  # a range alone teaches nothing yet
    pmf._accept(posterior, cov, np.array([-5.0, 1.0]), terrain=True)  # the terrain pulls 5 m back west
    # Net 3 m west and 1 m north in 10 s: the measured velocity ran fast east and slow north, about three to
    # one (five to one from the terrain's alone), by less than the 0.3 m/s one pair of fixes would say.
    bias = pmf.velocity_bias_mps
    assert 0.0 < bias[0] < 0.3 and np.isclose(bias[0] / bias[1], -3.0, rtol=0.1)
    np.testing.assert_allclose(pmf._patch_shift(40.0), 40.0 * bias)


@pytest.mark.parametrize("kind", ["pmf", "pf"])
def test_an_update_reports_its_own_posterior_and_the_next_prediction_restores_the_floor(kind):
    """The floor is process noise: P(k|k) is reported as the update made it, P(k+1|k) is at least the floor."""
    grid = _map()
    likelihood = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=0.3)
    params = _quiet(initial_sigma_m=6.0, position_floor_nodes=0.0, position_floor_m=3.0, position_floor_tracking_m=3.0, pf_floor_tracking_m=3.0)
    f = PointMassFilter(likelihood, params, grid=grid) if kind == "pmf" else ParticleFilter(likelihood, params, grid=grid, seed=5)
    truth = np.array([400.0, 400.0])
    f.start(0.0, truth, _observation())
    f.update(_observation(_patch_at(grid, *truth)))
    narrowest = math.sqrt(np.linalg.eigvalsh(f.estimate().covariance)[0])
    assert narrowest < 0.8 * 3.0  # the match placed it better than the floor, and the estimate says so
    f.predict(Motion(dt_s=1.0, velocity_mps=np.zeros(2)))
    assert math.sqrt(np.linalg.eigvalsh(f.estimate().covariance)[0]) == pytest.approx(3.0, rel=0.1)


def test_a_lookalike_lowers_the_usable_flag_but_only_a_refusal_brings_the_acquisition_floor_back():
    from lost.host.nav.trust import Trust

    params = _quiet(usable_updates=2)
    trust = Trust(params, node_m=NODE)
    narrow = np.eye(2)
    trust.accepted(narrow)
    assert not trust.usable and not trust.settled
    trust.accepted(narrow)
    assert trust.usable and trust.settled
    trust.usable, trust.good_in_row = False, 0  # what a look-alike check does
    trust.watch(400.0 * np.eye(2))  # and a covariance grown on smooth ground
    assert not trust.usable and trust.settled
    trust.rejected("misfit")
    assert not trust.settled


def test_each_filter_settles_on_its_own_tracking_floor():
    """The particle filter's matches carry more correlated error (its bias is learned slowly): a wider floor."""
    grid = _map()
    likelihood = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0)
    params = _quiet(position_floor_nodes=0.0, position_floor_tracking_m=0.5, pf_floor_tracking_m=2.0)
    assert PointMassFilter(likelihood, params, grid=grid)._floor_var_tracking == pytest.approx(0.25)
    assert ParticleFilter(likelihood, params, grid=grid, seed=1)._floor_var_tracking == pytest.approx(4.0)


def test_the_particles_keep_their_bias_prior_until_usable_and_a_reinitialization_keeps_what_they_learned():
    """Selection on position alone says nothing of the bias: before the cloud is usable its resampling
    would otherwise fix the bias at the few survivors' values (on two_hour 8 cm/s off, spread 1.4 mm/s)."""
    grid = _map()
    params = _quiet(usable_updates=3, velocity_bias_sigma_mps=0.05)
    pf = ParticleFilter(TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0), params, grid=grid, seed=2)
    pf.start(0.0, np.array([400.0, 400.0]), _observation())
    pf._w[:] = 0.0
    pf._w[:5] = 0.2  # five survivors
    pf._resample()
    assert np.std(pf._b, axis=1) == pytest.approx([0.05, 0.05], rel=0.05)  # drawn afresh, not five values
    pf._trust.usable = True
    pf._w[:] = 0.0
    pf._w[:5] = 0.2
    pf._resample()
    assert len(np.unique(pf._b[0])) == 5  # usable: the survivors' biases are kept
    learned = np.unique(pf._b[0])
    pf._reinitialize()
    assert set(np.unique(pf._b[0])) <= set(learned)  # the sensor's bias, not the place's: kept


def test_the_point_mass_filter_learns_its_bias_only_once_its_density_has_been_narrow_for_a_few_updates():
    """Before, its corrections are the acquisition's own moves, not a drift."""
    grid = _map()
    params = _quiet(estimate_velocity_bias=True, usable_updates=30, bias_learning_updates=3)
    pmf = PointMassFilter(TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0), params, grid=grid)
    truth = np.array([400.0, 400.0])
    pmf.start(0.0, truth, _observation())
    truth = _track(pmf, grid, truth, 2)
    narrow_pull = (pmf._p_grid.copy(), 4.0 * np.eye(2), np.array([-5.0, 0.0]))
    pmf._since_bias_update_s = 10.0
    pmf._accept(*narrow_pull, terrain=True)  # narrow for 2 updates: not yet
    assert not pmf._velocity_bias.following and np.all(pmf.velocity_bias_mps == 0.0)
    truth = _track(pmf, grid, truth, 1)
    assert not pmf.estimate().usable  # 3 of the 30 a usable flag needs
    pmf._accept(*narrow_pull, terrain=True)  # narrow for 3 updates: the sum of corrections is anchored here
    assert pmf._velocity_bias.following and np.all(pmf.velocity_bias_mps == 0.0)
    pmf._since_bias_update_s = 10.0
    pmf._accept(*narrow_pull, terrain=True)
    bias = pmf.velocity_bias_mps
    assert bias[0] > 0.0 and bias[1] == 0.0  # pulled west: the measured velocity ran fast east


def test_the_point_mass_filter_keeps_its_density_as_wide_as_an_unlearned_bias_may_misplace_a_patch():
    grid = _map()
    likelihood = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0)
    learning = PointMassFilter(likelihood, _quiet(estimate_velocity_bias=True, velocity_bias_sigma_mps=0.05), grid=grid)
    blind = PointMassFilter(likelihood, _quiet(estimate_velocity_bias=False, velocity_bias_sigma_mps=0.05), grid=grid)
    for f in (learning, blind):
        f._patch_age_s = 60.0
    base = blind._floor_var
    assert base < (0.05 * 60.0) ** 2 and blind._misplacement_var() == 0.0
    assert learning._misplacement_var() == pytest.approx((0.05 * 60.0) ** 2)
    narrow = 0.01 * np.eye(2)
    learning._keep_floor(narrow)
    owed = learning._pending_var + learning._pending_axes
    np.testing.assert_allclose(owed, (0.05 * 60.0) ** 2 - 0.01)  # the larger of the two, not their sum
    learning._pending_var, learning._pending_axes = 0.0, np.zeros(2)
    learning._patch_age_s = 1.0
    learning._keep_floor(narrow)
    assert learning._pending_var == pytest.approx(base - 0.01) and not learning._pending_axes.any()


def test_each_filter_reports_its_velocity_bias_with_its_sigma():
    grid = _map()
    likelihood = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0)
    pf = ParticleFilter(likelihood, _quiet(pf_particles=100), grid=grid, seed=1)
    pf.start(0.0, np.array([400.0, 400.0]), _observation())
    pf._b = np.array([[0.0] * 50 + [0.1] * 50, [0.02] * 100])
    pf._w = np.full(100, 0.01)
    estimate = pf.estimate()
    np.testing.assert_allclose(estimate.velocity_bias_mps, [0.05, 0.02])
    np.testing.assert_allclose(estimate.velocity_bias_sigma_mps, [0.05, 0.0], atol=1e-12)  # the weighted spread
    pmf = PointMassFilter(likelihood, _quiet(estimate_velocity_bias=True, velocity_bias_sigma_mps=0.03), grid=grid)
    pmf.start(0.0, np.array([400.0, 400.0]), _observation())
    np.testing.assert_allclose(pmf.estimate().velocity_bias_sigma_mps, [0.03, 0.03])  # the prior, nothing learned yet
    blind = PointMassFilter(likelihood, _quiet(estimate_velocity_bias=False), grid=grid)
    blind.start(0.0, np.array([400.0, 400.0]), _observation())
    assert np.isnan(blind.estimate().velocity_bias_sigma_mps).all()


def test_a_cloud_resampled_onto_one_particle_reports_the_floors_width_not_a_zero_covariance():
    grid = _map()
    pf = ParticleFilter(TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0), _quiet(pf_particles=500), grid=grid, seed=2)
    pf.start(0.0, np.array([400.0, 400.0]), _observation())
    one = np.zeros(500)
    one[17] = 1.0  # one particle took all the weight
    pf._accept(one, np.zeros((2, 2)), np.zeros(2), terrain=True)
    _, cov = pf._moments()
    floor = pf._floor_var
    assert np.linalg.eigvalsh(cov).min() > 0.5 * floor and np.all(np.diag(cov) < 2.0 * floor)
    assert np.all(np.isfinite(pf.estimate().covariance)) and np.linalg.det(pf.estimate().covariance) > 0
    assert pf.counts["resampled_collapsed"] == 1


def test_the_bias_misplacement_floor_widens_only_the_directions_narrower_than_it():
    """Where a range holds one axis and the terrain hardly the other, an isotropic lift by what is not known of the
    velocity bias widened the poorly held axis at every update (``shelf_canyon``)."""
    grid = _map()
    params = _quiet(estimate_velocity_bias=True, velocity_bias_sigma_mps=0.05, initial_sigma_m=20.0, pmf_min_cell_m=0.5,
                    position_floor_nodes=0.0, position_floor_m=0.5, position_floor_tracking_m=0.5)
    pmf = PointMassFilter(TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0), params, grid=grid)
    pmf.start(0.0, np.array([400.0, 400.0]), _observation())
    pmf._patch_age_s = 60.0  # 0.05 m/s of bias not yet known: the patch may lie 3 m from where it was reckoned
    x, y, _ = pmf.density
    narrow_east = np.exp(-0.5 * (((x - 400.0) / 1.0) ** 2 + ((y - 400.0) / 10.0) ** 2))  # 1 m east, 10 m north
    pmf._p_grid = narrow_east / narrow_east.sum()
    before = pmf.estimate().covariance
    pmf._keep_floor(before)
    pmf.predict(Motion(dt_s=1.0, velocity_mps=np.zeros(2)))
    after = pmf.estimate().covariance
    assert math.sqrt(after[0, 0]) == pytest.approx(3.0, rel=0.1)  # east lifted to the misplacement
    assert after[1, 1] == pytest.approx(before[1, 1], rel=0.05)  # north, already wider, left as it was


def test_a_settled_cloud_whose_corrections_are_small_walks_its_bias_slower_and_an_ins_walk_is_kept():
    """Covariance matching of the bias's walk (``ParticleFilter._adapt_walk``): shifts a ninth of their expected spread
    take a walk set far above an INS/DVL's down to its least share; corrections as expected keep it; an INS/DVL's walk
    is never adapted under itself."""
    from lost.host.nav.parameters import INS_VELOCITY_BIAS_WALK_MPS
    from lost.host.nav.pf import WALK_SCALE_MIN

    grid = _map()
    likelihood = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0)
    prior, post = np.diag([25.0, 25.0]), np.diag([16.0, 16.0])

    def walked(walk: float, shift_sigma: float, settled: bool = True) -> float:
        pf = ParticleFilter(likelihood, _quiet(pf_particles=100, usable_updates=30, velocity_bias_walk_mps=walk), grid=grid, seed=1)
        pf.start(0.0, np.array([400.0, 400.0]), _observation())
        pf._trust.settled = settled
        rng = np.random.default_rng(3)
        for _ in range(400):
            pf._trust.note_correction(rng.normal(0.0, shift_sigma, 2), prior, post)
            last = pf._adapt_walk()
        return last

    assert walked(0.1, 1.0) == pytest.approx(0.1 * WALK_SCALE_MIN)
    assert walked(0.1, 1.0, settled=False) == 0.1  # acquiring: the walk as configured, to follow the tow's lag
    assert walked(0.1, 3.0) > 0.5 * 0.1
    assert walked(INS_VELOCITY_BIAS_WALK_MPS, 1.0) == INS_VELOCITY_BIAS_WALK_MPS
    assert walked(0.0, 1.0) == 0.0
