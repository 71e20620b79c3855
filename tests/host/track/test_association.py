"""Joint integrated PDA: one track is IPDA by formula, shared detections against a brute-force sum over joint events."""

import itertools

import numpy as np
import pytest

from lost.host.track.association import associate
from lost.host.track.kalman import GATE_PROBABILITY, ContactState, innovations, pda_update

R = np.diag([4.0, np.radians(1.5) ** 2])


def test_one_track_is_integrated_pda():
    state = ContactState(np.array([0.0, 300.0, 0.0, 0.0]), np.diag([9.0, 9.0, 0.5, 0.5]))
    z = np.array([[301.0, 0.002], [296.0, -0.01], [450.0, 0.3]])
    inn = innovations(state, z, R, np.zeros(2), 0.0)
    r, pd, clutter = 0.3, 0.8, 0.01
    joint = associate(inn.density[None], inn.gated[None], np.array([r]), np.array([pd]), clutter)
    gated = inn.gated
    delta = pd * GATE_PROBABILITY - pd * inn.density[gated].sum() / clutter
    assert joint.existence[0] == pytest.approx((1 - delta) * r / (1 - delta * r), rel=1e-12)
    # Given existence, the association probabilities are PDA's.
    _, pda = pda_update(state, z, R, np.zeros(2), 0.0, pd=pd, clutter_density=clutter)
    np.testing.assert_allclose(joint.beta[0, pda.gated], pda.beta, rtol=1e-12)
    assert joint.beta_none[0] == pytest.approx(pda.beta_none, rel=1e-12)
    assert joint.beta[0, 2] == 0 and not gated[2]


def _events(weights_none, weights):
    """Every joint event (each detection to at most one track) with its weight."""
    k = weights.shape[0]
    for choice in itertools.product(*[[-1, *np.flatnonzero(weights[t] > 0)] for t in range(k)]):
        taken = [j for j in choice if j >= 0]
        if len(taken) == len(set(taken)):
            yield choice, np.prod([weights_none[t] if j < 0 else weights[t, j] for t, j in enumerate(choice)])


def _jpda_star_events(weights_none, weights):
    """The likeliest event of each group that detects the same tracks with the same detections (Blom & Bloem 2000)."""
    best = {}
    for choice, w in _events(weights_none, weights):
        group = (tuple(j >= 0 for j in choice), frozenset(j for j in choice if j >= 0))
        if w > best.get(group, (None, -1.0))[1]:
            best[group] = (choice, w)
    return best.values()


def _brute_force(weights_none, weights, events=_events):
    """Marginals by listing the joint events."""
    k, m = weights.shape
    none, marginal, total = np.zeros(k), np.zeros((k, m)), 0.0
    for choice, w in events(weights_none, weights):
        total += w
        for t, j in enumerate(choice):
            if j < 0:
                none[t] += w
            else:
                marginal[t, j] += w
    return none / total, marginal / total


def test_tracks_sharing_detections_match_the_sum_over_joint_events():
    rng = np.random.default_rng(3)
    density = rng.uniform(0.5, 3.0, (3, 4))
    gated = np.array([[1, 1, 0, 0], [0, 1, 1, 0], [0, 0, 1, 1]], dtype=bool)  # a chain: one cluster of three
    r, pd, clutter = np.array([0.9, 0.5, 0.99]), np.array([0.9, 0.9, 0.6]), 0.02
    joint = associate(density, gated, r, pd, clutter, permutation_pruning=False)
    weights = np.where(gated, r[:, None] * pd[:, None] * density / clutter, 0.0)
    none, marginal = _brute_force(1 - r * pd * GATE_PROBABILITY, weights)
    q = pd * GATE_PROBABILITY
    exists = none * r * (1 - q) / (1 - r * q) + marginal.sum(axis=1)
    np.testing.assert_allclose(joint.existence, exists, rtol=1e-12)
    np.testing.assert_allclose(joint.beta, marginal / exists[:, None], rtol=1e-12)
    np.testing.assert_allclose(joint.claimed, marginal.sum(axis=0), rtol=1e-12)
    assert np.all(joint.claimed <= 1 + 1e-12) and joint.approximated == 0


def test_jpda_star_updates_from_the_likeliest_permutation_and_keeps_the_full_existence():
    rng = np.random.default_rng(5)
    density = rng.uniform(0.5, 3.0, (3, 4))
    gated = np.array([[1, 1, 1, 0], [1, 1, 0, 1], [0, 1, 1, 1]], dtype=bool)
    r, pd, clutter = np.array([0.95, 0.6, 0.99]), np.array([0.9, 0.9, 0.7]), 0.02
    joint = associate(density, gated, r, pd, clutter)
    full = associate(density, gated, r, pd, clutter, permutation_pruning=False)
    weights = np.where(gated, r[:, None] * pd[:, None] * density / clutter, 0.0)
    none, marginal = _brute_force(1 - r * pd * GATE_PROBABILITY, weights, _jpda_star_events)
    q = pd * GATE_PROBABILITY
    exists = none * r * (1 - q) / (1 - r * q) + marginal.sum(axis=1)
    np.testing.assert_allclose(joint.beta, marginal / exists[:, None], rtol=1e-12)
    np.testing.assert_allclose(joint.beta_none, none * r * (1 - q) / (1 - r * q) / exists, rtol=1e-12)
    np.testing.assert_allclose(joint.existence, full.existence, rtol=1e-12)
    np.testing.assert_allclose(joint.claimed, full.claimed, rtol=1e-12)
    assert not np.allclose(joint.beta, full.beta, rtol=1e-3)  # the pruning changed the updates


def test_jpda_star_keeps_two_close_tracks_apart():
    """Two tracks on two nearly alike detections: JPDA pulls both toward the middle, JPDA* gives each its own."""
    density = np.array([[2.0, 1.8], [1.8, 2.0]])
    gated = np.ones((2, 2), bool)
    r, pd = np.ones(2) * 0.999, np.full(2, 0.9)
    star = associate(density, gated, r, pd, 0.001)
    full = associate(density, gated, r, pd, 0.001, permutation_pruning=False)
    assert 0.4 < full.beta[0, 1] < full.beta[0, 0] < 0.6  # coalescence: about as much of each
    assert star.beta[0, 0] > 0.9 and star.beta[1, 1] > 0.9 and star.beta[0, 1] < 0.05


def test_one_detection_between_two_tracks_is_not_given_to_both():
    density = np.array([[2.0], [2.0]])
    joint = associate(density, np.ones((2, 1), bool), np.array([0.99, 0.99]), np.array([0.9, 0.9]), 0.01)
    np.testing.assert_allclose(joint.beta[0], joint.beta[1])
    assert joint.claimed[0] <= 1.0
    # Apart, each would take it almost surely; together, at most one does.
    alone = associate(density[:1], np.ones((1, 1), bool), np.array([0.99]), np.array([0.9]), 0.01)
    assert alone.beta[0, 0] > 0.99 and joint.beta[0, 0] * joint.existence[0] < 0.51


def test_a_track_outside_the_sector_keeps_its_existence():
    joint = associate(np.array([[1.0]]), np.array([[True]]), np.array([0.7]), np.array([0.0]), 0.01)
    assert joint.existence[0] == pytest.approx(0.7) and joint.beta[0, 0] == 0 and joint.claimed[0] == 0


def test_a_cluster_with_too_many_events_is_solved_track_by_track_and_counted():
    density = np.ones((3, 5))
    joint = associate(density, np.ones((3, 5), bool), np.full(3, 0.9), np.full(3, 0.9), 0.01, max_events=100)
    assert joint.approximated == 1
    single = associate(density[:1], np.ones((1, 5), bool), np.array([0.9]), np.array([0.9]), 0.01)
    np.testing.assert_allclose(joint.existence, single.existence[0])
