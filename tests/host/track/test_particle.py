"""The paper's filter: weights by hand on tiny cases, the platform's motion, resampling, and lock on a simulated diver."""

import numpy as np
import pytest

from lost.host.track import Ping, Sonar
from lost.host.track.metrics import pings_to_lock
from lost.host.track.particle import DiverParticleFilter, PaperParameters, clutter_floor, gaussian_bias
from lost.host.track.simulate import builtin_scenario_path, load_scenario, simulate

SONAR = Sonar()


def test_weights_match_a_hand_computation():
    r = np.array([100.0, 103.0, 100.0, 106.0])
    b = np.array([0.0, 0.0, 3.0, 3.0])
    w = gaussian_bias(r, b, np.array([100.0]), np.array([0.0]), bias_range_m=3.0, bias_bearing_deg=3.0)
    np.testing.assert_allclose(w, [1.0, np.exp(-0.5), np.exp(-0.5), np.exp(-2.5)])
    two = gaussian_bias(r, b, np.array([100.0, 106.0]), np.array([0.0, 3.0]), bias_range_m=3.0, bias_bearing_deg=3.0, floor=0.25)
    np.testing.assert_allclose(two, 0.25 + np.array([1 + np.exp(-2.5), np.exp(-0.5) + np.exp(-1.0), np.exp(-0.5) + np.exp(-2.0), np.exp(-2.5) + 1]))


def test_clutter_floor_is_the_poisson_clutter_likelihood_scaled():
    # 5 false alarms over 500 m x pi/2 rad, pd 0.9: (1 - pd) kappa 2 pi sr st / pd.
    kappa = 5 / (500 * np.pi / 2)
    expected = 0.1 * kappa * 2 * np.pi * 3.0 * np.radians(3.0) / 0.9
    assert clutter_floor(pd=0.9, clutter_per_ping=5, sonar=SONAR, bias_range_m=3, bias_bearing_deg=3) == pytest.approx(expected)
    with pytest.raises(ValueError, match="pd must be in"):
        clutter_floor(pd=0.0, clutter_per_ping=5, sonar=SONAR, bias_range_m=3, bias_bearing_deg=3)


def quiet(index, xy, heading, r=(), b=()):
    return Ping(index, 1.3 * index, xy, heading, np.array(r, float), np.array(b, float))


def test_particles_keep_their_place_in_the_world_while_the_platform_moves_and_turns():
    still = PaperParameters(particles=2000, range_noise_m=0.0, bearing_noise_deg=0.0)
    pf = DiverParticleFilter(sonar=Sonar(half_fov_deg=180.0), parameters=still, rng=np.random.default_rng(0))
    pf.step(quiet(0, (0.0, 0.0), 0.0))
    before = pf.xy.copy()
    estimate = pf.step(quiet(1, (10.0, -5.0), 30.0))
    out_of_range = np.hypot(before[:, 0] - 10.0, before[:, 1] + 5.0) > 500.0  # drawn again in the sector
    assert out_of_range.sum() == pf.redrawn > 0
    np.testing.assert_allclose(pf.xy[~out_of_range], before[~out_of_range], atol=1e-9)
    assert not estimate.resampled


def test_resampling_moves_every_particle_to_the_one_near_the_detection():
    pf = DiverParticleFilter(sonar=SONAR, parameters=PaperParameters(particles=3, range_noise_m=0.0, bearing_noise_deg=0.0),
                             rng=np.random.default_rng(0))
    pf.xy = np.array([[0.0, 100.0], [0.0, 300.0], [100.0, 300.0]])  # range 100 ahead; 300 ahead; 316 at 18.4 deg
    estimate = pf.step(quiet(0, (0.0, 0.0), 0.0, r=[101.0], b=[0.0]))
    assert estimate.resampled
    np.testing.assert_allclose(pf.xy, [[0.0, 100.0]] * 3, atol=1e-9)
    np.testing.assert_allclose(estimate.mean_xy, [0.0, 100.0], atol=1e-9)
    np.testing.assert_allclose(estimate.covariance, np.zeros((2, 2)), atol=1e-9)


def test_initial_particles_cover_the_field_of_view_uniformly_in_range_and_bearing():
    pf = DiverParticleFilter(sonar=SONAR, parameters=PaperParameters(particles=20_000, range_noise_m=0.0, bearing_noise_deg=0.0),
                             rng=np.random.default_rng(3))
    r, b = pf.predict(quiet(0, (0.0, 0.0), 90.0))
    assert r.min() >= 0 and r.max() <= 500 and np.abs(b).max() <= 45
    assert abs(r.mean() - 250) < 5 and abs(b.mean()) < 1 and abs(b.std() - 90 / np.sqrt(12)) < 0.5


def test_parameters_are_checked():
    with pytest.raises(ValueError, match="at least one particle"):
        PaperParameters(particles=0)
    with pytest.raises(ValueError, match="bias widths must be positive"):
        PaperParameters(bias_range_m=0.0)


@pytest.fixture(scope="module")
def one_diver():
    return simulate(load_scenario(builtin_scenario_path("one_diver")))


@pytest.mark.parametrize("floor", [0.0, 0.05])
def test_follows_a_simulated_diver_through_the_papers_clutter(one_diver, floor):
    pf = DiverParticleFilter(sonar=one_diver.scenario.sonar.sonar, parameters=PaperParameters(floor=floor), rng=np.random.default_rng(0))
    means = np.array([e.mean_xy for e in pf.run(one_diver.pings)])
    valid = one_diver.truth.in_sector[:, 0]
    errors = np.hypot(*(means - one_diver.truth.xy[:, 0]).T)[valid]
    first = int(np.argmax(errors <= 25.0)) + 1
    assert errors[first - 1] <= 25.0 and first <= 15  # the paper: onto the diver in fewer than 15 pings
    assert np.median(errors) < 8.0
    # As the paper states it (no floor) a missed detection sends the cloud to that ping's clutter for a ping or two;
    # the clutter floor keeps it on the diver.
    assert np.mean(errors <= 25.0) >= (0.85 if floor == 0 else 0.97)


def test_pings_to_lock_counts_to_the_last_excursion():
    errors = np.array([300.0, 10.0, 40.0, 10.0, 5.0, 99.0])
    assert pings_to_lock(errors, np.ones(6, bool)) is None
    assert pings_to_lock(errors, np.array([1, 1, 1, 1, 1, 0], bool)) == 4
    assert pings_to_lock(errors[[0, 1, 3]], np.ones(3, bool)) == 2
    assert pings_to_lock(np.array([np.nan, 1.0]), np.ones(2, bool)) == 2
