"""The paper's filter, exactly: Guilmain & Sharma's particle filter on range/bearing sonar detections.

Section 4 of the paper, step by step, as :meth:`DiverParticleFilter.step` does it:

1. Particles start at random range and bearing across the field of view (uniform in range on
   [0, max range] and in bearing on [-half FOV, +half FOV]).
2. At every ping each particle is moved with the platform's motion: it keeps its place in the world
   (GPS east/north) and its range and bearing are recomputed from the sonar's new position and heading.
3. Prediction: ``r_new = r_old + n_r``, ``theta_new = theta_old + n_theta``, zero-mean Gaussian, standard
   deviations 3 m and 3 degrees ("typical values" in the paper).
4. Measurement update: weighted resampling with replacement (multinomial), each particle weighted with a
   Gaussian bias toward the detections close to it in range and bearing:
   ``w_i = floor + sum_j exp(-((r_i - r_j)**2 / sr**2 + (theta_i - theta_j)**2 / st**2) / 2)``.
5. The estimate is the mean of the particles' positions (with their covariance).

Where the paper is silent, the choice is ours and named:

- The bias widths ``sr``, ``st`` are not given; the paper ties the noise to "the accuracy of the sonar
  detector", so they default to the prediction noise, 3 m and 3 degrees.
- ``floor`` is 0 in the paper (a particle far from every detection has no weight). A positive floor is
  the standard likelihood of a detection among Poisson clutter with detection probability ``pd``:
  ``(1 - pd) + pd * sum_j N(z_j; x_i) / clutter_density``, scaled; :func:`clutter_floor` computes it. Without
  it a single missed detection of the diver sends the whole cloud to that ping's clutter.
- A ping whose weights are all zero (no detection, or none near any particle with ``floor = 0``) leaves the
  particles unresampled.
- A particle diffused out of the sector is drawn again at random in it (the sonar cannot see there, so
  nothing would ever pull it back); the count is kept in ``redrawn``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .detections import Ping
from .geometry import Sonar, polar_to_world, world_to_polar

__all__ = ["PaperParameters", "DiverParticleFilter", "ParticleEstimate", "gaussian_bias", "clutter_floor"]


@dataclass(frozen=True, kw_only=True)
class PaperParameters:
    """The paper's particle filter, its values as defaults.

    Parameters
    ----------
    particles : int
        Size of the particle pool (the paper does not say; 10,000 here, the issue's speed goal).
    range_noise_m : float
        Standard deviation of the prediction's range noise n_r (paper: 3 m).
    bearing_noise_deg : float
        Standard deviation of the prediction's bearing noise n_theta (paper: 3 degrees).
    bias_range_m, bias_bearing_deg : float
        Widths of the Gaussian bias toward detections (paper: not stated; the detector's accuracy, 3 m, 3 degrees).
    floor : float
        Weight of a particle near no detection, relative to 1 at a detection (paper: 0; see :func:`clutter_floor`).
    """

    particles: int = 10_000
    range_noise_m: float = 3.0
    bearing_noise_deg: float = 3.0
    bias_range_m: float = 3.0
    bias_bearing_deg: float = 3.0
    floor: float = 0.0

    def __post_init__(self) -> None:
        if self.particles < 1:
            raise ValueError(f"The filter needs at least one particle, got {self.particles!r}.")
        widths = (self.range_noise_m, self.bearing_noise_deg, self.bias_range_m, self.bias_bearing_deg)
        if min(widths) < 0 or min(widths[2:]) == 0:
            raise ValueError(f"Noise levels must not be negative and bias widths must be positive, got {widths!r}.")
        if self.floor < 0:
            raise ValueError(f"The weight floor must not be negative, got {self.floor!r}.")

    def as_dict(self) -> dict:
        return asdict(self)


def clutter_floor(*, pd: float, clutter_per_ping: float, sonar: Sonar, bias_range_m: float, bias_bearing_deg: float) -> float:
    """The floor that turns the paper's Gaussian bias into the likelihood of detections among Poisson clutter.

    With ``kappa = clutter_per_ping / (range x field of view)`` the clutter density in range-bearing space,
    the likelihood of a ping's detections given a target at a particle is proportional to
    ``(1 - pd) + pd / kappa * sum_j N(z_j; x)``; dividing by the Gaussian's peak factor ``pd / (kappa 2 pi sr st)``
    leaves the paper's sum plus this floor.
    """
    if not (0 < pd <= 1) or clutter_per_ping <= 0:
        raise ValueError(f"pd must be in (0, 1] and clutter_per_ping positive, got {pd!r} and {clutter_per_ping!r}.")
    kappa = clutter_per_ping / sonar.polar_extent
    return float((1 - pd) * kappa * 2 * np.pi * bias_range_m * np.radians(bias_bearing_deg) / pd)


def gaussian_bias(range_m: np.ndarray, bearing_deg: np.ndarray, det_range_m: np.ndarray, det_bearing_deg: np.ndarray,
                  *, bias_range_m: float, bias_bearing_deg: float, floor: float = 0.0,
                  detection_weights: np.ndarray | None = None) -> np.ndarray:
    """Each particle's weight: ``floor`` plus a Gaussian of its range/bearing distance to every detection, summed.

    ``detection_weights`` scale each detection's Gaussian (a tracker's amplitude likelihood ratios); the paper's are all 1.
    """
    weights = np.full(range_m.shape, floor, dtype=float)
    scales = np.ones(len(det_range_m)) if detection_weights is None else np.asarray(detection_weights, float)
    for r, b, scale in zip(det_range_m, det_bearing_deg, scales):
        d2 = ((range_m - r) / bias_range_m) ** 2 + ((bearing_deg - b) / bias_bearing_deg) ** 2
        weights += scale * np.exp(-0.5 * d2)
    return weights


@dataclass(frozen=True)
class ParticleEstimate:
    """The filter's estimate after a ping: the particle mean and covariance, world east/north metres."""

    t_s: float
    mean_xy: np.ndarray
    covariance: np.ndarray
    resampled: bool


class DiverParticleFilter:
    """The paper's single-diver particle filter (module docstring), stepping ping by ping.

    Parameters
    ----------
    sonar : Sonar
        The sector particles are drawn in.
    parameters : PaperParameters
        Noise, bias and pool size.
    rng : numpy.random.Generator
        The only source of randomness (seed it for a repeatable run).
    """

    def __init__(self, *, sonar: Sonar, parameters: PaperParameters, rng: np.random.Generator) -> None:
        self._sonar, self._parameters, self._rng = sonar, parameters, rng
        self.xy: np.ndarray | None = None
        self.redrawn = 0

    @property
    def parameters(self) -> PaperParameters:
        return self._parameters

    def draw(self, n: int, ping: Ping) -> np.ndarray:
        """``n`` world positions at random range and bearing across the sector at ``ping`` (step 1)."""
        r = self._rng.uniform(0.0, self._sonar.max_range_m, n)
        b = self._rng.uniform(-self._sonar.half_fov_deg, self._sonar.half_fov_deg, n)
        return polar_to_world(ping.platform_xy, ping.heading_deg, r, b)

    def predict(self, ping: Ping) -> tuple[np.ndarray, np.ndarray]:
        """Steps 1-3: the particles' range and bearing from the sonar at ``ping``, diffused."""
        p = self._parameters
        if self.xy is None:
            self.xy = self.draw(p.particles, ping)
        r, b = world_to_polar(ping.platform_xy, ping.heading_deg, self.xy)
        r = r + self._rng.normal(0.0, p.range_noise_m, r.size)
        b = b + self._rng.normal(0.0, p.bearing_noise_deg, b.size)
        outside = ~self._sonar.inside(r, b)
        if outside.any():
            n = int(outside.sum())
            self.redrawn += n
            r[outside] = self._rng.uniform(0.0, self._sonar.max_range_m, n)
            b[outside] = self._rng.uniform(-self._sonar.half_fov_deg, self._sonar.half_fov_deg, n)
        return r, b

    def step(self, ping: Ping, *, range_m: np.ndarray | None = None, bearing_deg: np.ndarray | None = None,
             detection_weights: np.ndarray | None = None) -> ParticleEstimate:
        """One ping: move, diffuse, weight toward the detections, resample; the particle mean and covariance.

        ``range_m``/``bearing_deg`` replace the ping's detections (a tracker passes the ones no track claimed);
        ``detection_weights`` scale each one's pull (:func:`gaussian_bias`).
        """
        p = self._parameters
        det_r = ping.range_m if range_m is None else range_m
        det_b = ping.bearing_deg if bearing_deg is None else bearing_deg
        r, b = self.predict(ping)
        weights = gaussian_bias(r, b, det_r, det_b, bias_range_m=p.bias_range_m, bias_bearing_deg=p.bias_bearing_deg, floor=p.floor,
                                detection_weights=detection_weights)
        total = weights.sum()
        resampled = bool(total > 0 and np.isfinite(total) and det_r.size)
        if resampled:
            keep = self._rng.choice(r.size, size=r.size, replace=True, p=weights / total)
            r, b = r[keep], b[keep]
        self.xy = polar_to_world(ping.platform_xy, ping.heading_deg, r, b)
        return ParticleEstimate(ping.t_s, self.xy.mean(axis=0), np.cov(self.xy.T), resampled)

    def run(self, pings: list[Ping]) -> list[ParticleEstimate]:
        """Step through every ping; the estimate after each."""
        return [self.step(ping) for ping in pings]
