"""Tempering by the residuals' correlation, and the velocity bias learned only from a narrow density."""

from dataclasses import replace

import numpy as np
import pytest
from scipy import ndimage

from lost.host.grid import Grid
from lost.host.nav import NavParameters
from lost.host.nav.estimator import Observation
from lost.host.nav.likelihood import MIN_INDEPENDENT_SHARE, TerrainLikelihood
from lost.host.nav.mapprep import PreparedMap
from lost.host.nav.pmf import PointMassFilter
from lost.host.nav.trust import SHARE_EVERY, Trust
from lost.host.records import SonarPatch
from lost.host.terrain import synthetic_terrain

NODE = 10.0
SIDE = 15


def _map(seed=4):
    return Grid(synthetic_terrain((80, 80), seed=seed, roughness_m=10.0, hurst=0.5), 0.0, 0.0, NODE)


def _cut(grid, x, y, error=None):
    row, col = (int(round(v)) for v in grid.row_col(x, y))
    half = SIDE // 2
    depth = grid.depth_m[row - half : row + half + 1, col - half : col + half + 1] + 2.0
    return SonarPatch(depth if error is None else depth + error, NODE)


def _ar1(rho, seed):
    """A separable first-order autoregressive field of unit variance, SIDE x SIDE."""
    rng = np.random.default_rng(seed)
    field = rng.standard_normal((SIDE, SIDE))
    for axis in (0, 1):
        field = np.moveaxis(field, axis, 0)
        for k in range(1, SIDE):
            field[k] = rho * field[k - 1] + np.sqrt(1.0 - rho**2) * field[k]
        field = np.moveaxis(field, 0, axis)
    return field


@pytest.mark.parametrize("rho", [0.0, 0.5, 0.8])
def test_the_independent_share_follows_the_residuals_correlation(rho):
    """N_eff / n = ((1 - rho) / (1 + rho))**2 for a separable AR(1) residual, the median over patches within 35 %."""
    grid = _map()
    lik = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0)
    centre = np.array([400.0, 400.0])
    shares = [lik.independent_share(centre, _cut(grid, *centre, 0.5 * _ar1(rho, seed))) for seed in range(40)]
    expected = max(((1.0 - rho) / (1.0 + rho)) ** 2, MIN_INDEPENDENT_SHARE)
    assert np.median(shares) == pytest.approx(expected, rel=0.35)
    assert all(MIN_INDEPENDENT_SHARE <= s <= 1.0 for s in shares)


def test_a_sub_node_misplacement_is_not_counted_as_correlated_map_error():
    """A patch a third of a node from the placement: its residual is the slope times the shift, which the fit takes out."""
    grid = _map()
    rows, cols = np.mgrid[0:80, 0:80]
    depth = grid.depth_m
    shifted = Grid(ndimage.map_coordinates(depth, [rows + 0.0, cols + 0.33], order=3, mode="nearest"), 0.0, 0.0, NODE)
    lik = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0)
    rng = np.random.default_rng(1)
    centre = np.array([400.0, 400.0])
    shares = [lik.independent_share(centre, _cut(shifted, *centre, 0.3 * rng.standard_normal((SIDE, SIDE)))) for _ in range(20)]
    assert np.median(shares) > 0.6


def test_the_independent_share_is_nan_off_the_map_and_over_holes():
    grid = _map()
    lik = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0)
    assert np.isnan(lik.independent_share(np.array([5.0, 5.0]), _cut(grid, 400.0, 400.0)))
    patch = _cut(grid, 400.0, 400.0)
    holed = SonarPatch(np.where(np.arange(SIDE)[:, None] < SIDE - 2, np.nan, patch.depth_m), NODE)
    assert np.isnan(lik.independent_share(np.array([400.0, 400.0]), holed))


def test_the_share_tempers_only_a_wide_density_and_is_learned_only_by_a_narrow_one():
    params = NavParameters()
    trust = Trust(params, node_m=NODE)
    trust.travelled_m = 1e9
    narrow, wide = np.eye(2) * 4.0, np.eye(2) * (3.0 * NODE) ** 2

    class Fixed:
        calls = 0

        def independent_share(self, centre, patch):
            Fixed.calls += 1
            return 0.1

    trust.note_independence(Fixed(), np.zeros(2), wide, None)
    assert Fixed.calls == 0 and trust.independent_share == 1.0  # a wide density's residual is the terrain's mismatch
    for _ in range(2 * SHARE_EVERY):
        trust.note_independence(Fixed(), np.zeros(2), narrow, None)
    assert Fixed.calls == 2 and trust.independent_share == pytest.approx(0.1)
    assert trust.patch_weight(100.0, wide) == pytest.approx(0.1)
    assert trust.patch_weight(100.0, narrow) == pytest.approx(1.0)
    off = Trust(replace(params, temper_by_correlation=False), node_m=NODE)
    off.note_independence(Fixed(), np.zeros(2), narrow, None)
    assert off.independent_share == 1.0 and Fixed.calls == 2


def test_a_wide_densitys_correction_teaches_no_velocity_bias():
    """A density wider than the usable width (after a gap off the map) moves by its prior's error, not a drift:
    the bias filter stops following and is anchored anew once the density has been narrow again."""
    grid = _map()
    params = replace(NavParameters(use_slant_range=False, usable_updates=1), bias_learning_updates=1)
    pmf = PointMassFilter(TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0), params, grid=grid)
    pmf.start(0.0, np.array([400.0, 400.0]), Observation(t_s=0.0, frame=None, patch=None, ocean_depth_m=np.nan,
                                                         vehicle_depth_m=0.0, slant_range_m=np.nan))
    pmf._trust.good_in_row = 3
    posterior, cov = pmf._p_grid.copy(), 4.0 * np.eye(2)
    pmf._since_bias_update_s = 10.0
    pmf._accept(posterior, cov, np.zeros(2), terrain=True)  # narrow: the sum is anchored here
    assert pmf._velocity_bias.following
    pmf._trust.good_in_row = 0  # the density outgrew the usable width (Trust.watch)
    pmf._since_bias_update_s = 100.0
    pmf._accept(posterior, cov, np.array([0.0, -90.0]), terrain=True)  # a 90 m move of a wide density
    np.testing.assert_array_equal(pmf.velocity_bias_mps, 0.0)
    assert not pmf._velocity_bias.following and pmf.counts["velocity_bias_paused"] == 1


def test_the_wrong_place_threshold_grows_as_the_residuals_correlate():
    """A margin of -0.8 per node is a better fit elsewhere for independent residuals (threshold 0.5) but the map's
    correlated error where only a tenth of the nodes are independent (threshold 0.5 / sqrt 0.1 = 1.58)."""

    class Margin:
        def margin(self, centre, patch, *, radius_m, exclusion_m):
            return -0.8

    narrow = np.eye(2) * 4.0
    for share, counted in ((1.0, 1), (0.1, 0)):
        trust = Trust(NavParameters(), node_m=NODE)
        trust.independent_share = share
        trust.look_alike(Margin(), np.zeros(2), narrow, None)
        assert trust.counts["fits_better_elsewhere"] == counted, share



def test_the_wrong_place_threshold_keeps_the_share_the_filter_had_when_last_usable():
    """A lock on a wrong place measures its mismatch as correlation (its share falls to 0.2, threshold 1.12): a margin
    of -0.8 still counts against it where the filter, last usable, measured a share of 0.64 (threshold 0.625)."""

    class Margin:
        def margin(self, centre, patch, *, radius_m, exclusion_m):
            return -0.8

    narrow = np.eye(2) * 4.0
    trust = Trust(NavParameters(), node_m=NODE)
    trust.independent_share = 0.2
    trust.look_alike(Margin(), np.zeros(2), narrow, None)
    assert trust.counts["fits_better_elsewhere"] == 0  # never usable: the measured share stands
    trust.usable, trust.independent_share = True, 0.64
    trust.look_alike(Margin(), np.zeros(2), narrow, None)
    assert trust.counts["fits_better_elsewhere"] == 1
    trust.usable, trust.independent_share = False, 0.2  # the flag down, the share measured at the wrong lock
    trust.look_alike(Margin(), np.zeros(2), narrow, None)
    assert trust.counts["fits_better_elsewhere"] == 2

def _margin_by_mask(lik, grid, centre, patch, radius_m, exclusion_m):
    """The look-alike margin with the near region as a Chebyshev mask over the placements (the definition)."""
    words, mask, _ = lik._prep.quantize_patch(patch.depth_m)
    h, w = words.shape
    row, col = grid.row_col(centre[0] + patch.centre_offset_m[0], centre[1] + patch.centre_offset_m[1])
    ci, cj = float(row) - (h - 1) / 2, float(col) - (w - 1) / 2
    reach = radius_m / grid.node_m
    i0, i1 = max(int(np.floor(ci - reach)), 0), min(int(np.ceil(ci + reach)), grid.shape[0] - h)
    j0, j1 = max(int(np.floor(cj - reach)), 0), min(int(np.ceil(cj + reach)), grid.shape[1] - w)
    per_node, valid = lik._residuals(words, mask, i0, i1, j0, j1)
    score = -per_node / lik._placement_sigma((h, w), i0, i1, j0, j1)
    ii, jj = np.meshgrid(np.arange(i0, i1 + 1) - ci, np.arange(j0, j1 + 1) - cj, indexing="ij")
    near = valid & (np.maximum(np.abs(ii), np.abs(jj)) * grid.node_m <= exclusion_m)
    far = valid & ~near
    return float(score[near].max() - score[far].max())


def test_the_margin_equals_its_definition_with_a_chebyshev_mask():
    grid = _map()
    depth = grid.depth_m.copy()
    depth[30:33, 50:52] = np.nan  # holes inside the region
    grid = Grid(depth, 0.0, 0.0, NODE)
    lik = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0)
    rng = np.random.default_rng(3)
    for _ in range(20):
        centre = rng.uniform(150.0, 650.0, 2)
        patch = _cut(grid, *rng.uniform(200.0, 600.0, 2), 0.3 * rng.standard_normal((SIDE, SIDE)))
        radius, exclusion = rng.uniform(100.0, 400.0), rng.uniform(10.0, 60.0)
        expected = _margin_by_mask(lik, grid, centre, patch, radius, exclusion)
        assert lik.margin(centre, patch, radius_m=radius, exclusion_m=exclusion) == pytest.approx(expected, abs=1e-12)


def test_a_patch_is_left_out_where_less_than_half_a_wide_density_lies_on_the_map():
    """Off-map candidates get the neutral likelihood, so a sliver of a wide density on the map would take all of it."""
    trust = Trust(NavParameters(), node_m=NODE)
    narrow, wide = np.eye(2) * 4.0, np.eye(2) * (5.0 * NODE) ** 2
    assert trust.at_edge(0.85, narrow) and not trust.at_edge(0.95, narrow)
    assert trust.at_edge(0.4, wide) and not trust.at_edge(0.6, wide)
