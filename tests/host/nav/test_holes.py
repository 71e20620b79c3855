"""Map holes under a patch: only holes under the patch's own soundings refuse a placement."""

from dataclasses import replace

import numpy as np
import pytest

from lost.host.grid import Grid
from lost.host.nav import NavParameters
from lost.host.nav.estimator import Motion, Observation
from lost.host.nav.likelihood import TerrainLikelihood
from lost.host.nav.mapprep import PreparedMap
from lost.host.nav.pf import ParticleFilter
from lost.host.nav.pmf import PointMassFilter
from lost.host.records import SonarPatch
from lost.host.terrain import synthetic_terrain

NODE = 10.0
TRACK_X = 400.0  # the tow runs north along this easting: map column 40
HALF = 4  # 9 x 9 patches
EMPTY_WEST = 3  # the patch's three west columns hold no sounding (one side of a swath)


def _floor():
    return synthetic_terrain((120, 80), seed=4, roughness_m=10.0, hurst=0.5)


def _patch(floor, y):
    """A patch cut from the floor around (TRACK_X, y), its west columns empty."""
    row, col = int(round(y / NODE)), int(round(TRACK_X / NODE))
    depth = floor[row - HALF : row + HALF + 1, col - HALF : col + HALF + 1] + 2.0
    depth[:, :EMPTY_WEST] = np.nan
    return SonarPatch(depth, NODE)


def _observation(patch=None):
    return Observation(t_s=0.0, frame=None, patch=patch, ocean_depth_m=np.nan, vehicle_depth_m=0.0, slant_range_m=np.nan)


def _map_with_holes(floor, first_col, last_col):
    depth = floor.copy()
    depth[:, first_col : last_col + 1] = np.nan
    return Grid(depth, 0.0, 0.0, NODE)


def _params():
    return NavParameters(velocity_noise_mps=0.0, gyro_bias_rps=0.0, accel_bias_mps2=0.0, use_slant_range=False,
                         usable_updates=3, estimate_velocity_bias=False, initial_sigma_m=30.0)


def _tow(kind, grid, floor, steps=12):
    likelihood = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0)
    params = _params()
    f = PointMassFilter(likelihood, params, grid=grid) if kind == "pmf" else ParticleFilter(likelihood, params, grid=grid, seed=3)
    y = 300.0
    f.start(0.0, np.array([TRACK_X + 15.0, y]), _observation())  # 15 m off at the start
    for _ in range(steps):
        y += 10.0
        f.predict(Motion(dt_s=1.0, velocity_mps=np.array([0.0, 10.0])))
        f.update(_observation(_patch(floor, y)))
    return f, np.array([TRACK_X, y])


def test_the_likelihood_is_informative_where_the_holes_lie_only_under_the_patchs_empty_part():
    floor = _floor()
    west = int(TRACK_X / NODE) - HALF  # the patch's first column at the truth
    band = _map_with_holes(floor, west, west + EMPTY_WEST - 1)
    under_soundings = _map_with_holes(floor, west + EMPTY_WEST, west + EMPTY_WEST + 1)
    patch = _patch(floor, 500.0)
    x, y = np.array([TRACK_X]), np.array([500.0])
    assert TerrainLikelihood(PreparedMap(grid=band), sigma_m=1.0).patch(x, y, patch).informative.all()
    refused = TerrainLikelihood(PreparedMap(grid=under_soundings), sigma_m=1.0).patch(x, y, patch)
    assert not refused.informative.any() and refused.on_holes


@pytest.mark.parametrize("kind", ["pmf", "pf"])
def test_a_tow_over_a_hole_band_under_the_patchs_empty_part_navigates(kind):
    floor = _floor()
    west = int(TRACK_X / NODE) - HALF
    # Holes under the two west-most empty columns and 20 m beyond: the whole window's rule refuses every placement
    # within 4 nodes of the truth. The third empty column stays a depth: a placement one node west of the truth
    # keeps its soundings off the holes, so a narrow density does not straddle them (see test below).
    f, truth = _tow(kind, _map_with_holes(floor, west - 2, west + EMPTY_WEST - 2), floor)
    estimate = f.estimate()
    assert f.counts["terrain_updates"] == 12 and f.counts["patch_on_holes"] == 0
    assert estimate.usable and np.hypot(*(estimate.position - truth)) < 3.0


@pytest.mark.parametrize("kind", ["pmf", "pf"])
def test_holes_under_the_patchs_soundings_are_refused_and_counted(kind):
    floor = _floor()
    west = int(TRACK_X / NODE) - HALF
    # Holes from the patch's first sounding column eastwards, wider than the density: no placement it spans is valid.
    # Where the truth's soundings fall on holes its placement is unknown: the density, mostly there, is left to dead
    # reckoning as at the map's edge (the valid placements beside the holes would pull it away).
    f, truth = _tow(kind, _map_with_holes(floor, west + EMPTY_WEST, 75), floor, steps=6)
    assert f.counts["patch_at_map_edge"] == 6 and f.counts["terrain_updates"] == 0
    assert not f.estimate().usable and f.estimate().stage == "off_map"
    assert np.hypot(*(f.estimate().position - truth - (15.0, 0.0))) < 1.0  # the start's offset, dead-reckoned
    # With a density narrower than the holes, none of its placements is valid: counted as holes, not as off the map.
    likelihood = TerrainLikelihood(PreparedMap(grid=_map_with_holes(floor, west + EMPTY_WEST, 75)), sigma_m=1.0)
    g = PointMassFilter(likelihood, replace(_params(), initial_sigma_m=3.0), grid=likelihood._grid)
    g.start(0.0, np.array([TRACK_X, 300.0]), _observation())
    g.update(_observation(_patch(_floor(), 300.0)))
    assert g.counts["patch_on_holes"] == 1 and g.counts["terrain_updates"] == 0


def test_the_gaussian_form_follows_the_same_rule():
    floor = _floor()
    west = int(TRACK_X / NODE) - HALF
    grid = _map_with_holes(floor, west, west + EMPTY_WEST - 1)
    gaussian = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0, form="gaussian")
    assert gaussian.patch(np.array([TRACK_X]), np.array([500.0]), _patch(floor, 500.0)).informative.all()


def test_a_patch_without_empty_nodes_keeps_the_whole_window_rule():
    floor = _floor()
    west = int(TRACK_X / NODE) - HALF
    grid = _map_with_holes(floor, west, west)
    full = replace(_patch(floor, 500.0), depth_m=floor[46:55, 36:45] + 2.0)
    result = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0).patch(np.array([TRACK_X]), np.array([500.0]), full)
    assert not result.informative.any()
