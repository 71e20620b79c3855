"""Slant ranges in the Bayesian filters: the innovation gate and its learned scale, the ring over coarse cells."""

import math

import numpy as np
import pytest

from lost.host.nav.likelihood import TerrainLikelihood
from lost.host.nav.mapprep import PreparedMap
from lost.host.nav.pf import ParticleFilter
from lost.host.nav.pmf import PointMassFilter

from .test_filters import _map, _observation, _quiet, _track


def _tracked(kind: str, **changes):
    """A filter of ``kind`` over a 120 x 80 map, tracked eight records north from (400, 300) with slant ranges on."""
    grid = _map(shape=(120, 80))
    lik = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0)
    params = _quiet(use_slant_range=True, velocity_bias_sigma_mps=0.0, velocity_bias_walk_mps=0.0, **changes)
    f = PointMassFilter(lik, params, grid=grid) if kind == "pmf" else ParticleFilter(lik, params, grid=grid, seed=2)
    f.start(0.0, np.array([400.0, 300.0]), _observation())
    return f, grid, params, _track(f, grid, (400.0, 300.0), 8)


@pytest.mark.parametrize("kind", ["pmf", "pf"])
def test_a_slant_range_outlier_is_refused_by_its_innovation(kind):
    """A range 40 m off (a multipath reply) is refused and counted; a good one is used. The moment NIS alone passed such ranges."""
    from lost.host.nav.stages import TrackFrame

    f, grid, params, position = _tracked(kind)
    ship = TrackFrame(400.0, 300.0 + 1000.0, 180.0)  # 1000 m north of the vehicle's start, the vehicle behind it
    before = f.estimate().position
    truth_range = math.hypot(*(position - (ship.ship_x_m, ship.ship_y_m)))
    f.update(_observation(slant=truth_range - 40.0, frame=ship))
    assert f.counts["range_rejected_innovation"] == 1 and "innovation" in f.estimate().rejected
    np.testing.assert_allclose(f.estimate().position, before, atol=1e-9)
    f.update(_observation(slant=truth_range + 0.5, frame=ship))
    assert f.counts["range_updates"] == 1


def test_a_range_rules_out_only_the_cells_it_misses_when_they_are_wider_than_its_sigma():
    from lost.host.nav.bayes import ring_log_likelihood

    sigma = 3.0
    r = np.array([-40.0, -12.0, -2.0, 0.0, 5.0, 12.0, 20.0])
    assert np.allclose(ring_log_likelihood(r, sigma, 2.5), -0.5 * (r / sigma) ** 2)  # fine cells: the Gaussian
    coarse = ring_log_likelihood(r, sigma, 12.5)
    assert np.all(coarse[1:-1] == 0.0)  # every cell the ring crosses alike
    assert np.allclose(coarse[[0, -1]], -0.5 * ((np.abs(r[[0, -1]]) - 12.5) / sigma) ** 2)


def test_twenty_ranges_across_coarse_cells_keep_every_cell_the_ring_crosses():
    """A 3 m ring across 25 m cells: read at the centres, the cells it crosses off-centre would empty."""
    from lost.host.nav.stages import TrackFrame

    grid = _map(shape=(300, 300))
    params = _quiet(use_slant_range=True, initial_sigma_m=300.0, pmf_cells=96)
    pmf = PointMassFilter(TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0), params, grid=grid)
    centre = np.array([1500.0, 1500.0])
    pmf.start(0.0, centre, _observation())
    x, y, before = (a.copy() for a in pmf.density)
    cell = x[0, 1] - x[0, 0]
    assert cell > 4.0 * params.slant_range_sigma_m
    ship = TrackFrame(centre[0] - 1000.0, centre[1], 90.0)
    for _ in range(20):
        pmf.update(_observation(slant=1000.0, frame=ship))
    assert pmf.counts["range_updates"] == 20
    _, _, after = pmf.density
    off_ring = np.abs(np.hypot(x - ship.ship_x_m, y - ship.ship_y_m) - 1000.0)
    crossed = (off_ring <= cell / 2.0) & (np.abs(y - centre[1]) < 150.0)
    kept = after[crossed] / before[crossed]
    assert crossed.sum() >= 12 and kept.max() / kept.min() < 1.0 + 1e-9
    assert after[off_ring > cell / 2.0 + 3.0 * params.slant_range_sigma_m].sum() < 1e-6


@pytest.mark.parametrize("kind", ["pmf", "pf"])
def test_a_range_outlier_inside_the_stated_gate_is_refused_once_the_ranges_have_shown_their_real_spread(kind):
    """A range a few sigma off that the stated innovation variance passes (a 14 m outlier on seamount_ridges took both filters
    10-16 m off while usable) is refused after fifty ranges whose innovations were a tenth of what was stated."""
    from lost.host.nav.stages import TrackFrame

    f, grid, params, position = _tracked(kind, slant_range_sigma_m=6.0)
    ship = TrackFrame(400.0, 300.0 + 1000.0, 180.0)
    truth_range = math.hypot(*(position - (ship.ship_x_m, ship.ship_y_m)))
    f.update(_observation(slant=truth_range + 17.0, frame=ship))  # innovation about 2.8 stated sigmas: inside 10.8
    assert f.counts["range_updates"] == 1 and f.counts["range_rejected_innovation"] == 0
    f, grid, params, position = _tracked(kind, slant_range_sigma_m=6.0)
    truth_range = math.hypot(*(position - (ship.ship_x_m, ship.ship_y_m)))
    for _ in range(50):
        f.update(_observation(slant=truth_range + 0.3, frame=ship))
    before = f.estimate().position
    f.update(_observation(slant=truth_range + 17.0, frame=ship))
    assert f.counts["range_rejected_innovation"] == 1 and "innovation" in f.estimate().rejected
    np.testing.assert_allclose(f.estimate().position, before, atol=1e-9)


@pytest.mark.parametrize("kind", ["pmf", "pf"])
def test_ranges_alone_do_not_widen_the_axis_across_them(kind):
    """Off the map, ranges from a ship to the west hold the east axis; the floor is not owed after them, so the north axis
    (no motion noise here) keeps its width, where the shortfall of the east axis blurred into it at every range."""
    from lost.host.nav.estimator import Motion
    from lost.host.nav.stages import TrackFrame

    f, grid, params, position = _tracked(kind, slant_range_sigma_m=1.0)
    ship = TrackFrame(position[0] - 1000.0, position[1], 90.0)  # due west: the range holds the east axis alone
    f.predict(Motion(dt_s=1.0, velocity_mps=np.zeros(2)))
    f.update(_observation(slant=1000.0, frame=ship))
    north_before = f.estimate().covariance[1, 1]
    for _ in range(20):
        f.predict(Motion(dt_s=1.0, velocity_mps=np.zeros(2)))
        f.update(_observation(slant=1000.0, frame=ship))
    assert f.counts["range_updates"] == 21
    estimate = f.estimate()
    assert estimate.covariance[0, 0] < params.position_floor_nodes**2 * grid.node_m**2  # the range holds east under the floor
    assert estimate.covariance[1, 1] < 1.5 * north_before



def _off_the_map_with_ranges(**changes):
    """The PMF tracked on the map, then 60 s without terrain under ranges (1 m) from a ship 1 km away 8 degrees north of
    east: the RMS of the mean's moves along the range and across it, the last cell width and the narrow axis' sigma."""
    from lost.host.nav.estimator import Motion
    from lost.host.nav.stages import TrackFrame

    # The Gaussian ring: what is measured is the cells' geometry, not the range's tails.
    f, grid, params, position = _tracked("pmf", slant_range_sigma_m=1.0, velocity_noise_mps=0.2, slant_range_dof=math.inf, **changes)
    rng = np.random.default_rng(7)
    u = np.array([math.cos(math.radians(8.0)), math.sin(math.radians(8.0))])
    moves = []
    for _ in range(60):
        f.predict(Motion(dt_s=1.0, velocity_mps=np.zeros(2)))
        before = f.estimate().position
        f.update(_observation(slant=1000.0 + rng.normal(0.0, 1.0), frame=TrackFrame(*(position + 1000.0 * u), 270.0)))
        moves.append(f.estimate().position - before)
    moves = np.array(moves)
    along, across = (float(np.sqrt(np.mean((moves @ axis) ** 2))) for axis in (u, np.array([-u[1], u[0]])))
    x, _, _ = f.density
    narrow = math.sqrt(np.linalg.eigvalsh(f.estimate().covariance)[0])
    assert f.counts["range_updates"] == 60 and f.counts["terrain_updates"] == 8
    return along, across, float(x[0, 1] - x[0, 0]), narrow


def test_off_the_map_the_cells_resolve_the_axis_the_ranges_hold_so_a_range_moves_the_mean_along_itself():
    """Off the map the ranges hold the axis along them under the floor's cell (1.25 m here). On cells that wide the oblique
    ring, read at their centres, moved the mean across the range, which it does not measure, more than along it."""
    along, across, cell, narrow = _off_the_map_with_ranges()
    assert cell < 1.25 and narrow < 1.25
    assert across < 0.5 * along
    along_floor_cells, across_floor_cells, cell_floor, _ = _off_the_map_with_ranges(pmf_min_cell_m=1.25)
    assert cell_floor == pytest.approx(1.25, rel=0.1)
    assert across_floor_cells > along_floor_cells


def test_a_range_read_as_a_student_t_keeps_the_flat_top_and_pulls_less_far_out():
    from lost.host.nav.bayes import ring_log_likelihood

    sigma, r = 3.0, np.array([0.0, 1.0, 3.0, 12.0, 30.0])
    gaussian, t = ring_log_likelihood(r, sigma, 2.5), ring_log_likelihood(r, sigma, 2.5, dof=6.0)
    assert np.array_equal(ring_log_likelihood(r, sigma, 2.5, dof=math.inf), gaussian)
    np.testing.assert_allclose(t[:2], gaussian[:2], atol=0.01)  # near: about the Gaussian
    assert t[-1] > gaussian[-1] / 4  # ten sigma off: a quarter of the Gaussian's penalty at most
    assert np.all(np.diff(t) < 0)
    assert np.all(ring_log_likelihood(np.array([-10.0, 5.0, 10.0]), sigma, 12.5, dof=6.0)[:] == 0.0)  # the flat top kept


@pytest.mark.parametrize("kind", ["pmf", "pf"])
def test_a_usable_filter_reads_a_range_as_a_t_and_an_acquiring_one_as_a_gaussian(kind):
    """A range 2.5 stated sigmas off (inside the 99.9 % gate) moves a usable density less when read as a t; before the
    flag rises the t is not used (the ring must rule places out), whatever ``slant_range_dof`` says."""
    from lost.host.nav.stages import TrackFrame

    moves = {}
    for dof in (math.inf, 6.0):
        f, grid, params, position = _tracked(kind, slant_range_dof=dof)
        assert f.estimate().usable
        ship = TrackFrame(400.0, 300.0 + 1000.0, 180.0)
        truth_range = math.hypot(*(position - (ship.ship_x_m, ship.ship_y_m)))
        before = f.estimate().position
        f.update(_observation(slant=truth_range + 2.5 * params.slant_range_sigma_m, frame=ship))
        assert f.counts["range_updates"] == 1
        moves[dof] = float(np.hypot(*(f.estimate().position - before)))
    assert moves[6.0] < 0.75 * moves[math.inf]
    acquiring = {}
    for dof in (math.inf, 6.0):
        grid = _map(shape=(120, 80))
        params = _quiet(use_slant_range=True, slant_range_dof=dof, initial_sigma_m=60.0)
        f = PointMassFilter(TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0), params, grid=grid)
        f.start(0.0, np.array([400.0, 300.0]), _observation())
        f.update(_observation(slant=1000.0, frame=TrackFrame(400.0, 1300.0, 180.0)))
        assert not f.estimate().usable
        acquiring[dof] = f.density[2]
    assert np.array_equal(acquiring[6.0], acquiring[math.inf])


def test_the_range_degrees_of_freedom_are_validated():
    from lost.host.nav import NavParameters

    for bad in (2.0, 0.5, -1.0, float("nan"), "6"):
        with pytest.raises(ValueError, match="slant_range_dof"):
            NavParameters(slant_range_dof=bad)
