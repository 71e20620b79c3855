"""Joint integrated probabilistic data association (JIPDA): which detection is whose, and whether each track exists.

Every track carries the probability ``r`` that its contact exists (Musicki, Evans & Stankovic 1994,
integrated PDA; Musicki & Evans 2004, joint IPDA). At each ping, for the tracks whose gates share
detections (a *cluster*), every joint event is weighed (each detection assigned to at most one track,
each track to at most one detection, the rest clutter):

- track ``t`` given detection ``j``: ``r_t * pd_t * g_tj / lambda``, with ``g_tj`` the Gaussian density of
  the detection about the track's prediction and ``lambda`` the clutter density (false alarms per
  metre-radian);
- track ``t`` given none: ``1 - r_t * pd_t * P_G`` (it exists and was missed, or it does not exist);

the event's weight is the product over the cluster's tracks. Summed over the events, these give each
track's marginal probabilities ``w_t0`` (no detection) and ``w_tj``. Then

- existence after the ping: ``r_t' = w_t0 * r_t (1 - pd_t P_G) / (1 - r_t pd_t P_G) + sum_j w_tj``;
- the state update's association probabilities, given that the contact exists: ``beta_tj = w_tj / r_t'``
  and ``beta_t0 = 1 - sum_j beta_tj``, used as in PDA (:func:`.kalman.pda_combine`) (from JPDA*'s events
  by default, below);
- the probability that detection ``j`` is some track's: ``sum_t w_tj`` (what the search cloud is spared).

JPDA* (Blom & Bloem 2000). Two tracks on contacts closer than their gates, each with a detection, have
two joint events of like weight (each takes its own detection, or they swap); averaged over both, each
track's update moves toward the other's detection and the two tracks are pulled together (JPDA's
coalescence), until one is merged away. With ``permutation_pruning`` the state updates (``beta``) come from
the events kept when, of every group of events that detect the same tracks with the same detections, only
the likeliest is kept; the existence and the claims still come from every event (the pruning decides who
took which detection, not whether a track was detected).

For one track alone this is integrated PDA exactly (``r' = (1 - delta) r / (1 - delta r)``,
``delta = pd P_G - sum_j pd g_j / lambda``). Two contacts closer than their gates share detections; the
joint events keep one detection from feeding both, so they stay two tracks. A cluster with more joint
events than ``max_events`` (dense clutter over many crossing tracks) is solved track by track (IPDA),
and counted in :attr:`JointAssociation.approximated`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .kalman import GATE_PROBABILITY

__all__ = ["JointAssociation", "associate"]


@dataclass(frozen=True)
class JointAssociation:
    """The result of one ping's joint association over ``T`` tracks and ``n`` detections.

    Attributes
    ----------
    beta : ndarray (T, n)
        Probability that detection ``j`` is track ``t``'s, given that the track's contact exists.
    beta_none : ndarray (T,)
        Probability that no detection is the track's, given that it exists.
    existence : ndarray (T,)
        Each track's probability of existence after the ping.
    claimed : ndarray (n,)
        Probability that each detection belongs to some track.
    approximated : int
        Clusters solved track by track because they held more than ``max_events`` joint events.
    """

    beta: np.ndarray
    beta_none: np.ndarray
    existence: np.ndarray
    claimed: np.ndarray
    approximated: int


def _clusters(gated: np.ndarray) -> list[np.ndarray]:
    """Groups of tracks linked through shared gated detections (connected components of ``gated`` (T, n))."""
    tracks = gated.shape[0]
    label = np.arange(tracks)
    for j in np.flatnonzero(gated.sum(axis=0) > 1):
        members = np.flatnonzero(gated[:, j])
        roots = {int(label[m]) for m in members}
        low = min(roots)
        label[np.isin(label, list(roots))] = low
    return [np.flatnonzero(label == k) for k in np.unique(label)]


def _enumerate(weights_none: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Marginal weights of every track's 'none' and each detection: over all joint events, and over JPDA*'s.

    ``weights`` (k, m) are the cluster's track-detection weights over its m detections, zero outside the
    gates. Depth-first over the tracks, each taking no detection or a free gated one. The events that
    detect the same tracks with the same detections differ only by a permutation of the detections among
    those tracks; JPDA* (Blom & Bloem 2000) keeps only the likeliest of each such group. Returns the
    normalized ``(none, marginal)`` over all events, then over the kept ones.
    """
    k, m = weights.shape
    marginal_none = np.zeros(k)
    marginal = np.zeros((k, m))
    options = [np.flatnonzero(weights[t] > 0) for t in range(k)]
    chosen = np.full(k, -1)
    used = np.zeros(m, dtype=bool)
    best: dict[tuple[tuple[bool, ...], tuple[bool, ...]], tuple[float, tuple[int, ...]]] = {}

    def walk(t: int, product: float) -> float:
        if t == k:
            for s in range(k):
                if chosen[s] < 0:
                    marginal_none[s] += product
                else:
                    marginal[s, chosen[s]] += product
            group = (tuple(chosen >= 0), tuple(used))
            if product > best.get(group, (-1.0, ()))[0]:
                best[group] = (product, tuple(chosen))
            return product
        total = walk(t + 1, product * weights_none[t])
        for j in options[t]:
            if not used[j]:
                used[j], chosen[t] = True, j
                total += walk(t + 1, product * weights[t, j])
                used[j], chosen[t] = False, -1
        return total

    total = walk(0, 1.0)
    kept_none, kept = np.zeros(k), np.zeros((k, m))
    for product, assignment in best.values():
        for s, j in enumerate(assignment):
            if j < 0:
                kept_none[s] += product
            else:
                kept[s, j] += product
    kept_total = sum(product for product, _ in best.values())
    return marginal_none / total, marginal / total, kept_none / kept_total, kept / kept_total


def associate(likelihood: np.ndarray, gated: np.ndarray, existence: np.ndarray, pd: np.ndarray, clutter_density: float,
              *, max_events: int = 20_000, permutation_pruning: bool = True) -> JointAssociation:
    """Joint association of one ping (module docstring).

    Parameters
    ----------
    likelihood : ndarray (T, n)
        Gaussian density of each detection about each track's predicted measurement (per metre-radian).
    gated : ndarray of bool (T, n)
        Which detections lie in which track's gate.
    existence : ndarray (T,)
        Each track's predicted probability of existence.
    pd : ndarray (T,)
        Each track's detection probability at this ping (0 outside the sector).
    clutter_density : float
        False alarms per metre-radian.
    max_events : int
        Above this many joint events a cluster is solved track by track.
    permutation_pruning : bool
        Update the states from JPDA*'s events (the likeliest of each permutation group) rather than all of them.
    """
    tracks, n = likelihood.shape
    beta, beta_none = np.zeros((tracks, n)), np.ones(tracks)
    posterior = existence.astype(float).copy()
    claimed = np.zeros(n)
    approximated = 0
    weights = np.where(gated, existence[:, None] * pd[:, None] * likelihood / max(clutter_density, 1e-300), 0.0)
    weights_none = 1.0 - existence * pd * GATE_PROBABILITY
    for cluster in _clusters(gated):
        columns = np.flatnonzero(gated[cluster].any(axis=0))
        w = weights[np.ix_(cluster, columns)]
        events = np.prod([1 + np.count_nonzero(row) for row in w], dtype=float)
        if len(cluster) == 1 or events > max_events:
            approximated += int(len(cluster) > 1)
            totals = weights_none[cluster] + w.sum(axis=1)
            marginal_none, marginal = weights_none[cluster] / totals, w / totals[:, None]
            kept_none, kept = marginal_none, marginal
        else:
            marginal_none, marginal, kept_none, kept = _enumerate(weights_none[cluster], w)
            if not permutation_pruning:
                kept_none, kept = marginal_none, marginal
        r, q = existence[cluster], pd[cluster] * GATE_PROBABILITY
        missed = r * (1 - q) / (1 - r * q)  # probability that a track with no detection exists
        posterior[cluster] = marginal_none * missed + marginal.sum(axis=1)
        # Given existence, the association probabilities: from the kept events (all of them without pruning).
        kept_exists = np.maximum(kept_none * missed + kept.sum(axis=1), 1e-300)
        beta[np.ix_(cluster, columns)] = kept / kept_exists[:, None]
        beta_none[cluster] = kept_none * missed / kept_exists
        claimed[columns] += marginal.sum(axis=0)
    return JointAssociation(beta, beta_none, posterior, np.minimum(claimed, 1.0), approximated)
