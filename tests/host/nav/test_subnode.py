"""The terrain likelihood between the correlator's placements: a patch's soundings gridded on moved lattices."""

import numpy as np
import pytest
from scipy import ndimage

from lost.host.correlator.resident import ResidentCorrelator
from lost.host.grid import Grid
from lost.host.io.sonar import grid_soundings
from lost.host.nav import NavParameters
from lost.host.nav.likelihood import TerrainLikelihood
from lost.host.nav.mapprep import PreparedMap
from lost.host.nav.motion import lattice_moved
from lost.host.records import SoundingArrays

NODE_M = 10.0
FINE_M = 1.0


def _floor(seed=3, size=400):
    """A 1 m floor with relief at every scale down to a few metres (what a 10 m block mean cannot show)."""
    rng = np.random.default_rng(seed)
    white = rng.normal(size=(size, size))
    relief = sum(ndimage.gaussian_filter(white, s) * s for s in (2.0, 5.0, 12.0))
    return 50.0 + 3.0 * relief / relief.std()


def _map(floor):
    """The floor's block means over 10 m cells: node (0, 0) is the mean of the first 10 x 10 metres."""
    k = int(NODE_M / FINE_M)
    rows, cols = (n // k for n in floor.shape)
    blocks = floor[: rows * k, : cols * k].reshape(rows, k, cols, k).mean(axis=(1, 3))
    return Grid(depth_m=blocks, x0_m=(k - 1) / 2 * FINE_M, y0_m=(k - 1) / 2 * FINE_M, node_m=NODE_M)


def _patch(floor, east_m, north_m, half_m=55.0):
    """Every floor cell within ``half_m`` of the vehicle as a sounding, gridded on an 11 x 11 patch around it."""
    ys, xs = np.mgrid[0 : floor.shape[0], 0 : floor.shape[1]] * FINE_M
    near = (np.abs(xs - east_m) <= half_m) & (np.abs(ys - north_m) <= half_m)
    east, north, depth = xs[near] - east_m, ys[near] - north_m, floor[near]
    age = np.zeros(east.size)
    return grid_soundings(east, north, depth, patch_shape=(11, 11), node_m=NODE_M, soundings=SoundingArrays(east, north, depth, age)).patch


def _peak_error_m(likelihood, patch, east_m, north_m):
    """How far the likelihood's highest candidate lies from the truth, candidates every 0.25 m within 12 m."""
    offsets = np.arange(-12.0, 12.01, 0.25)
    x, y = np.meshgrid(east_m + offsets, north_m + offsets)
    ell = likelihood.patch(x, y, patch).log_likelihood
    k = np.unravel_index(np.argmax(ell), ell.shape)
    return float(np.hypot(x[k] - east_m, y[k] - north_m))


def test_the_likelihood_peaks_at_the_truth_between_placements_where_whole_placements_lock_it_to_the_lattice():
    floor = _floor()
    prepared = PreparedMap(grid=_map(floor))
    whole = TerrainLikelihood(prepared, sigma_m=0.5, phases=1)
    thirds = TerrainLikelihood(prepared, sigma_m=0.5, phases=3)
    errors = {1: [], 3: []}
    for east, north in [(203.0, 196.0), (184.0, 217.0), (215.0, 223.0), (196.0, 184.0), (226.0, 207.0), (177.0, 174.0)]:
        patch = _patch(floor, east, north)
        errors[1].append(_peak_error_m(whole, patch, east, north))
        errors[3].append(_peak_error_m(thirds, patch, east, north))
    assert max(errors[3]) < 0.1 * NODE_M
    assert np.mean(errors[3]) < 0.6 * np.mean(errors[1])  # 0.64 m against 1.40 m


@pytest.mark.parametrize("phases", [2, 3, 4])
def test_each_moved_lattice_is_the_soundings_gridded_around_the_moved_centre_and_a_patch_without_soundings_has_none(phases):
    floor = _floor()
    patch = _patch(floor, 203.3, 196.7)
    grids = lattice_moved(patch, phases)
    assert sorted(grids) == [(a, b) for a in range(phases) for b in range(phases) if (a, b) != (0, 0)]
    east, north, depth, age = patch.soundings.arrays()
    for (a, b), grid in grids.items():
        centre = (b / phases * NODE_M, a / phases * NODE_M)
        want = grid_soundings(east, north, depth, patch_shape=(11, 11), node_m=NODE_M, centre_m=centre, age_s=age).patch
        np.testing.assert_allclose(grid.depth_m, want.depth_m, rtol=0, atol=1e-9)  # NaN where no sounding fell, in both
        assert grid.centre_offset_m == pytest.approx(centre)
    bare = grid_soundings(np.zeros(3), np.zeros(3), np.zeros(3), patch_shape=(3, 3), node_m=NODE_M).patch
    assert lattice_moved(bare, 3) == {}


def test_a_patch_without_soundings_reads_the_placements_alone():
    floor = _floor()
    prepared = PreparedMap(grid=_map(floor))
    patch = _patch(floor, 203.0, 196.0)
    bare = grid_soundings(np.zeros(1), np.zeros(1), np.zeros(1), patch_shape=patch.depth_m.shape, node_m=NODE_M).patch
    bare = type(bare)(depth_m=patch.depth_m, node_m=NODE_M)
    x, y = np.meshgrid(np.arange(190.0, 215.0, 1.3), np.arange(185.0, 210.0, 1.3))
    with_phases = TerrainLikelihood(prepared, sigma_m=0.5, phases=3).patch(x, y, bare).log_likelihood
    without = TerrainLikelihood(prepared, sigma_m=0.5, phases=1).patch(x, y, bare).log_likelihood
    np.testing.assert_array_equal(with_phases, without)


def test_a_records_patches_are_held_together_and_each_correlated_once():
    rng = np.random.default_rng(2)
    terrain = rng.integers(-3000, 3000, (80, 80)).astype(np.int16)
    resident = ResidentCorrelator(terrain, patches_held=3)
    patches = [terrain[r : r + 6, 30:36].copy() for r in (20, 21, 22)]
    mask = np.ones((6, 6), bool)
    for _caller in range(2):  # two filters asking for the record's three patches in turn
        for patch in patches:
            resident.correlation(patch, mask, (10, 20, 21, 21))
    assert resident.stats["correlations"] == 3 and resident.stats["patches"] == 3
    with pytest.raises(ValueError, match="patches_held"):
        ResidentCorrelator(terrain, patches_held=0)


def test_a_second_filter_asking_for_the_same_patch_within_the_first_span_reads_the_kept_samples():
    floor = _floor()
    prepared = PreparedMap(grid=_map(floor))
    shared = TerrainLikelihood(prepared, sigma_m=0.5, phases=3)
    patch = _patch(floor, 203.0, 196.0)
    wide_x, wide_y = np.meshgrid(np.arange(185.0, 222.0, 1.1), np.arange(180.0, 215.0, 1.1))
    shared.patch(wide_x, wide_y, patch)
    requests = prepared.resident("software").stats["requests"]
    x, y = np.meshgrid(np.arange(195.0, 208.0, 0.7), np.arange(190.0, 203.0, 0.7))
    second = shared.patch(x, y, patch, weight=0.3, sigma_scale=1.7)
    assert prepared.resident("software").stats["requests"] == requests  # no correlator request for the second caller
    fresh = TerrainLikelihood(PreparedMap(grid=_map(floor)), sigma_m=0.5, phases=3).patch(x, y, patch, weight=0.3, sigma_scale=1.7)
    np.testing.assert_array_equal(second.log_likelihood, fresh.log_likelihood)
    np.testing.assert_array_equal(second.informative, fresh.informative)
    assert second.misfit == fresh.misfit
    beyond = shared.patch(x + 40.0, y, patch)  # past the kept span: computed over the union, as a fresh one computes it
    np.testing.assert_array_equal(beyond.log_likelihood, TerrainLikelihood(PreparedMap(grid=_map(floor)), sigma_m=0.5, phases=3)
                                  .patch(x + 40.0, y, patch).log_likelihood)


@pytest.mark.parametrize("phases", [0, 5, 2.5, True])
def test_likelihood_phases_outside_one_to_four_whole_are_refused(phases):
    with pytest.raises(ValueError, match="likelihood_phases"):
        NavParameters(likelihood_phases=phases)
