"""The map's per-node error and the likelihood whose scale follows it."""

import math

import numpy as np

from lost.host.grid import Grid
from lost.host.nav.likelihood import TerrainLikelihood
from lost.host.nav.maperror import node_variance, window_variance
from lost.host.nav.mapprep import PreparedMap
from lost.host.records import SonarPatch
from lost.host.terrain import synthetic_terrain

NODE = 10.0


def test_a_plane_gets_its_slope_term_and_no_relief_term():
    rows, cols = np.mgrid[0:30, 0:40].astype(float)
    slope_x, slope_y = 0.12, -0.05  # m/m
    depth = 1000.0 + slope_x * cols * NODE + slope_y * rows * NODE
    variance = node_variance(depth, NODE, 0.3)
    want = 0.3**2 + (slope_x**2 + slope_y**2) * NODE**2 / 12.0
    assert np.allclose(variance, want)


def test_a_paraboloid_gets_its_curvature_term_where_it_has_no_slope():
    rows, cols = np.mgrid[-15:16, -15:16].astype(float)
    k = 0.002  # 1/m: depth = k/2 (x**2 + y**2), laplacian 2k
    depth = 0.5 * k * ((cols * NODE) ** 2 + (rows * NODE) ** 2)
    variance = node_variance(depth, NODE, 0.0)
    assert math.isclose(variance[15, 15], (2 * k * NODE**2 / 16.0) ** 2, rel_tol=1e-9)
    # Rough ground carries a larger error than smooth: the flanks, with their slope, more than the centre.
    assert variance[15, 25] > variance[15, 15]


def test_window_variance_is_the_mean_under_each_placement():
    rng = np.random.default_rng(3)
    layer = rng.random((12, 15))
    got = window_variance(layer, (4, 5))
    assert got.shape == (9, 11)
    assert np.isclose(got[2, 3], layer[2:6, 3:8].mean())


def test_a_uniform_layer_gives_the_uniform_likelihood_up_to_a_constant():
    grid = Grid(synthetic_terrain((60, 60), seed=7, roughness_m=10.0, hurst=0.5), 0.0, 0.0, NODE)
    prepared = PreparedMap(grid=grid)
    noise, layer = 0.4, 0.8**2
    per_node = TerrainLikelihood(prepared, sigma_m=1.0, node_var_m2=np.full(grid.shape, layer), depth_noise_m=noise)
    uniform = TerrainLikelihood(prepared, sigma_m=math.sqrt(noise**2 + layer))
    patch = SonarPatch(grid.depth_m[20:29, 25:34] + 1.5, NODE)
    x, y = np.meshgrid(np.linspace(200, 380, 19), np.linspace(170, 330, 17))
    a, b = per_node.patch(x, y, patch), uniform.patch(x, y, patch)
    assert np.allclose(a.log_likelihood - a.log_likelihood.max(), b.log_likelihood - b.log_likelihood.max())
    assert math.isclose(a.misfit, b.misfit, rel_tol=1e-12)


def test_the_scale_follows_the_nodes_under_the_patch():
    """Equal residuals: the placement on nodes said to be poorly known is penalised less for them, and by its normalization."""
    grid = Grid(synthetic_terrain((60, 60), seed=7, roughness_m=10.0, hurst=0.5), 0.0, 0.0, NODE)
    prepared = PreparedMap(grid=grid)
    layer = np.full(grid.shape, 0.1)
    layer[:, 30:] = 4.0  # the east half of the map is poorly known
    lik = TerrainLikelihood(prepared, sigma_m=1.0, node_var_m2=layer, depth_noise_m=0.3)
    rng = np.random.default_rng(2)
    west = SonarPatch(grid.depth_m[20:29, 5:14] + rng.normal(0, 1.0, (9, 9)), NODE)
    east = SonarPatch(grid.depth_m[20:29, 40:49] + rng.normal(0, 1.0, (9, 9)), NODE)
    at = lambda c: (np.array([c * NODE + 4 * NODE]), np.array([24 * NODE]))  # noqa: E731
    # The same 1 m noise: a large misfit on the well-known west, about one sigma on the poorly known east.
    assert lik.patch(*at(5), west).misfit > 2.0 > lik.patch(*at(40), east).misfit
