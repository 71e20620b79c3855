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

__all__ = ["GATE_CHI2", "ContactState", "Innovations", "predict", "measurement", "innovations", "pda_combine", "pda_update"]

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


@dataclass(frozen=True)
class Innovations:
    """A track's predicted measurement against a ping's detections: Jacobian, innovation covariance, residuals."""

    H: np.ndarray  # (2, 4)
    S: np.ndarray  # (2, 2)
    nu: np.ndarray  # (n, 2): range m, bearing rad (wrapped)
    distance2: np.ndarray  # (n,) squared Mahalanobis distance

    @property
    def gated(self) -> np.ndarray:
        """Which detections lie in the 99 % gate."""
        return self.distance2 < GATE_CHI2

    @property
    def density(self) -> np.ndarray:
        """Gaussian density of each detection about the prediction, per metre-radian."""
        return np.exp(-0.5 * self.distance2) / (2 * np.pi * np.sqrt(np.linalg.det(self.S)))


def innovations(state: ContactState, z: np.ndarray, R: np.ndarray, platform_xy: np.ndarray, heading_deg: float) -> Innovations:
    """The residuals of detections ``z`` (n, 2: range m, bearing rad) about ``state``'s predicted measurement."""
    z_hat, H = measurement(state.x, platform_xy, heading_deg)
    S = H @ state.P @ H.T + R
    nu = z - z_hat
    nu[:, 1] = (nu[:, 1] + np.pi) % (2 * np.pi) - np.pi
    d2 = np.einsum("ni,ij,nj->n", nu, np.linalg.inv(S), nu)
    return Innovations(H, S, nu, d2)


def pda_combine(state: ContactState, inn: Innovations, beta: np.ndarray, beta_none: float) -> ContactState:
    """The PDA update of ``state`` with association probabilities ``beta`` (one per detection) and ``beta_none``.

    The mean moves by the gain times the probability-weighted innovation; the covariance is the missed
    case's and the updated one's, mixed, plus the spread of the innovations (Bar-Shalom, Daum & Huang 2009).
    """
    used = np.flatnonzero(beta > 0)
    if used.size == 0:
        return state
    K = state.P @ inn.H.T @ np.linalg.inv(inn.S)
    nu, b = inn.nu[used], beta[used]
    combined = b @ nu
    spread = (nu * b[:, None]).T @ nu - np.outer(combined, combined)
    P = state.P - (1 - beta_none) * K @ inn.S @ K.T + K @ spread @ K.T
    return ContactState(state.x + K @ combined, 0.5 * (P + P.T))


def pda_update(state: ContactState, z: np.ndarray, R: np.ndarray, platform_xy: np.ndarray, heading_deg: float,
               *, pd: float, clutter_density: float) -> tuple[ContactState, Association]:
    """Probabilistic data association of a ping's detections ``z`` (n, 2: range m, bearing rad) to one contact.

    ``clutter_density`` is false alarms per metre-radian of range-bearing space; ``pd`` the probability the
    contact is detected at this ping (0 outside the sector).
    """
    inn = innovations(state, z, R, platform_xy, heading_deg)
    gated = np.flatnonzero(inn.gated)
    if gated.size == 0 or pd == 0:
        return state, Association(np.empty(0, int), np.empty(0), 1.0, inn.distance2)
    ratio = pd * inn.density[gated] / max(clutter_density, 1e-300)
    none = 1.0 - pd * GATE_PROBABILITY
    total = none + ratio.sum()
    beta = np.zeros(z.shape[0])
    beta[gated] = ratio / total
    updated = pda_combine(state, inn, beta, none / total)
    return updated, Association(gated, beta[gated], float(none / total), inn.distance2)
