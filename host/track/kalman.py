"""One contact's state and its filter: nearly constant velocity in the world, range/bearing measurements, PDA in clutter.

State ``x = (east, north, v_east, v_north)`` in metres and m/s. Motion: white-noise acceleration of
spectral density ``accel_sigma**2`` (the simulator's model, so the covariance can be checked against the
truth). Measurement: range and bearing from the sonar at the ping (bearing in radians inside the filter),
linearized at the prediction (extended Kalman filter). Association: probabilistic data association
(Bar-Shalom & Tse 1975; Bar-Shalom, Daum & Huang 2009, eqs. 38-44), with the detection probability ``pd``
and the Poisson clutter density of the sonar model: every detection in a track's gate updates it in
proportion to how likely it is the contact's rather than clutter, the chance that none is the contact
included, and the covariance grows by the spread of the innovations.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["GATE_CHI2", "ContactState", "predict", "measurement", "pda_update"]

#: 99 % gate of a 2-D innovation (chi-square, 2 degrees of freedom).
GATE_CHI2 = 9.21
GATE_PROBABILITY = 0.99


@dataclass
class ContactState:
    """Mean ``x`` (4,) and covariance ``P`` (4, 4) of one contact, world frame."""

    x: np.ndarray
    P: np.ndarray


def transition(dt: float, accel_sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """``F`` and ``Q`` of the nearly-constant-velocity model over ``dt`` seconds."""
    F = np.eye(4)
    F[0, 2] = F[1, 3] = dt
    block = accel_sigma**2 * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    Q = np.zeros((4, 4))
    Q[np.ix_([0, 2], [0, 2])] = block
    Q[np.ix_([1, 3], [1, 3])] = block
    return F, Q


def predict(state: ContactState, dt: float, accel_sigma: float) -> ContactState:
    """The state ``dt`` seconds later."""
    F, Q = transition(dt, accel_sigma)
    return ContactState(F @ state.x, F @ state.P @ F.T + Q)


def measurement(x: np.ndarray, platform_xy: np.ndarray, heading_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Predicted (range m, bearing rad from the sonar axis) of state ``x`` and its Jacobian ``H`` (2, 4)."""
    dx, dy = x[0] - platform_xy[0], x[1] - platform_xy[1]
    r2 = max(dx * dx + dy * dy, 1e-6)
    r = np.sqrt(r2)
    bearing = np.arctan2(dx, dy) - np.radians(heading_deg)
    bearing = (bearing + np.pi) % (2 * np.pi) - np.pi
    H = np.array([[dx / r, dy / r, 0.0, 0.0], [dy / r2, -dx / r2, 0.0, 0.0]])
    return np.array([r, bearing]), H


@dataclass(frozen=True)
class Association:
    """What one PDA update used: which detections were in the gate and their association probabilities."""

    gated: np.ndarray  # indices into the ping's detections
    beta: np.ndarray  # one per gated detection
    beta_none: float
    distance2: np.ndarray  # squared Mahalanobis distance of every detection from the prediction


def pda_update(state: ContactState, z: np.ndarray, R: np.ndarray, platform_xy: np.ndarray, heading_deg: float,
               *, pd: float, clutter_density: float) -> tuple[ContactState, Association]:
    """Probabilistic data association of a ping's detections ``z`` (n, 2: range m, bearing rad) to one contact.

    ``clutter_density`` is false alarms per metre-radian of range-bearing space; ``pd`` the probability the
    contact is detected at this ping (0 outside the sector).
    """
    z_hat, H = measurement(state.x, platform_xy, heading_deg)
    S = H @ state.P @ H.T + R
    S_inv = np.linalg.inv(S)
    nu = z - z_hat
    nu[:, 1] = (nu[:, 1] + np.pi) % (2 * np.pi) - np.pi
    d2 = np.einsum("ni,ij,nj->n", nu, S_inv, nu)
    gated = np.flatnonzero(d2 < GATE_CHI2)
    if gated.size == 0 or pd == 0:
        return state, Association(np.empty(0, int), np.empty(0), 1.0, d2)
    likelihood = np.exp(-0.5 * d2[gated]) / (2 * np.pi * np.sqrt(np.linalg.det(S)))
    ratio = pd * likelihood / max(clutter_density, 1e-300)
    none = 1.0 - pd * GATE_PROBABILITY
    total = none + ratio.sum()
    beta, beta_none = ratio / total, none / total
    K = state.P @ H.T @ S_inv
    nu_g = nu[gated]
    combined = beta @ nu_g
    spread = (nu_g * beta[:, None]).T @ nu_g - np.outer(combined, combined)
    P = state.P - (1 - beta_none) * K @ S @ K.T + K @ spread @ K.T
    return ContactState(state.x + K @ combined, 0.5 * (P + P.T)), Association(gated, beta, float(beta_none), d2)
