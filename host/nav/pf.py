"""The particle filter: the same likelihood as the point-mass filter, carried by weighted samples.

State of each particle: position (east, north), the velocity sensor's bias (east, north) and, for
the single-depth form, the mean of its depth-bias estimate (Rao-Blackwellized, see
``BayesFilter._depth_update``), so the
bias that shifts every real-time match is estimated inside the filter (the point-mass filter
estimates it beside itself). Motion: ``x += (v_measured - b) dt`` plus the error growth of
:mod:`lost.host.nav.trust`; the bias walks by ``velocity_bias_walk_mps`` per square-root second.
Measurement: the log-likelihood of :mod:`lost.host.nav.likelihood` at each particle, added to its log
weight. Systematic resampling when the effective sample size falls below half the particles, then
roughening (Gordon et al. 1993: a jitter of ``K E N^(-1/d)`` per dimension, E the particles' spread
in it, K = 0.2; positions only, the bias walking alone) so that copies of one particle spread again. Gating, the usable flag and
re-initialization follow :mod:`lost.host.nav.trust`, as for the point-mass filter.
"""

from __future__ import annotations

import math

import numpy as np

from ..grid import Grid
from .bayes import BayesFilter
from .estimator import Motion, Observation
from .likelihood import TerrainLikelihood
from .moments import eigenvalues_2x2, moments
from .parameters import INS_VELOCITY_BIAS_WALK_MPS

__all__ = ["ParticleFilter", "systematic_resample"]

ROUGHENING_K = 0.2
#: A resampled cloud narrower than this along an axis (metres) has collapsed onto one particle.
COLLAPSED_M = 1e-6
#: The adapted walk's memory (terrain updates) and its least share of the configured walk (see ``_adapt_walk``).
WALK_MEMORY = 30.0
WALK_SCALE_MIN = 0.3


def systematic_resample(weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Indices of a systematic resampling of normalized ``weights`` (one uniform draw, N even strides)."""
    n = weights.size
    positions = (rng.random() + np.arange(n)) / n
    cumulative = np.cumsum(weights)
    cumulative[-1] = 1.0  # rounding must not leave the last stride past the end
    return np.searchsorted(cumulative, positions)


class ParticleFilter(BayesFilter):
    """Recursive Bayesian terrain navigation with particles (see the module docstring).

    Parameters
    ----------
    likelihood : TerrainLikelihood
    params : NavParameters
        ``pf_particles``, ``velocity_bias_*``, the trust rules and noise levels.
    grid : Grid
        The map (for its node spacing).
    seed : int
        The filter's random stream: the same seed gives the same track.
    """

    def __init__(self, likelihood: TerrainLikelihood, params, *, grid: Grid, seed: int = 0, name: str = "pf") -> None:
        super().__init__(likelihood, params, grid=grid, name=name)
        self._rng = np.random.default_rng(seed)
        self._n = int(params.pf_particles)
        self._pending_var = 0.0  # floor variance owed to the cloud, spread in the next prediction
        self._acquiring = True
        self._cached: tuple[np.ndarray, np.ndarray] | None = None
        self._search: tuple[np.ndarray, float, float | None] | None = None  # after a re-initialization: the square to search, the prior
        self._walk_scale = 1.0

    def _spawn(self, centre: np.ndarray, half_width_m: float | None, sigma_m: float | None, depth_bias_m: float = 0.0,
               velocity_bias: np.ndarray | None = None) -> None:
        """Particles around ``centre``: Gaussian of ``sigma_m``, or flat over a square of ``half_width_m``.

        Their velocity biases are ``velocity_bias`` (a learned one, kept), or drawn from the prior until the
        cloud has found its place (see ``_resample``).
        """
        n = self._n
        self._depth_bias = np.full(n, depth_bias_m)
        if sigma_m is not None:
            xy = centre + self._rng.normal(0.0, sigma_m, (n, 2))
        else:
            xy = centre + self._rng.uniform(-half_width_m, half_width_m, (n, 2))
        self._x, self._y = xy[:, 0].copy(), xy[:, 1].copy()
        self._acquiring = velocity_bias is None
        self._b = self._prior_bias() if velocity_bias is None else velocity_bias
        self._w = np.full(n, 1.0 / n)
        self._pending_var, self._cached = 0.0, None

    @staticmethod
    def _tracking_floor_m(params) -> float:
        return params.pf_floor_tracking_m

    def _spacing(self) -> float:
        """The particles' typical spacing, metres: a square of four sigma a side shared among them."""
        _, cov = self._moments()
        return 4.0 * math.sqrt(max(math.sqrt(max(np.linalg.det(cov), 0.0)), 0.0) / self._n)

    def _moments(self) -> tuple[np.ndarray, np.ndarray]:
        """Mean and covariance of the cloud, cached until it changes (the floor it is owed belongs to the next prediction)."""
        if self._cached is None:
            self._cached = moments(self._w, self._x, self._y)
        return self._cached

    @property
    def velocity_bias_mps(self) -> np.ndarray:
        return self._b @ self._w

    @property
    def velocity_bias_sigma_mps(self) -> np.ndarray:
        """The particles' weighted spread of their biases."""
        mean = self._b @ self._w
        return np.sqrt(np.maximum((self._b * self._b) @ self._w - mean * mean, 0.0))

    def start(self, t_s: float, position: np.ndarray, observation: Observation) -> None:
        self._spawn(np.asarray(position, float), None, self._p.initial_sigma_m)
        self._stage = "initialization"

    def predict(self, motion: Motion) -> None:
        dt = motion.dt_s
        v = np.asarray(motion.velocity_mps, float)
        sigma = math.sqrt(self._trust.growth_variance(dt) + self._pending_var)
        self._pending_var, self._cached = 0.0, None
        walk = self._adapt_walk() * math.sqrt(dt)
        noise = self._rng.standard_normal((4 if walk > 0 else 2, self._n))  # rows contiguous: one draw a step
        self._x += (v[0] - self._b[0]) * dt + sigma * noise[0]
        self._y += (v[1] - self._b[1]) * dt + sigma * noise[1]
        if walk > 0:
            self._b += walk * noise[2:]
        self._depth_bias_var += self._p.depth_bias_walk_m**2 * dt
        self._moved(dt, float(np.hypot(*v)) * dt)

    def _adapt_walk(self) -> float:
        """The bias's walk for the next prediction, m/s per square-root second: the configured one while acquiring;
        once settled, scaled to the terrain's corrections (covariance matching: the drift window's shifts against their
        expected spread, :meth:`Trust.shift_share`, about 1 for a consistent cloud).

        A walk set far above an INS/DVL's (a tow moved by the ship's velocity, whose towfish lags and catches up) lets the
        cloud follow the lag at the start, and holds it several times wider than its error for the rest of the tow
        (``short``: NEES in band 0.62, median NEES 0.09). The scale follows the shifts' share (its memory
        ``WALK_MEMORY`` updates), between ``WALK_SCALE_MIN`` and 1, and never takes the walk under an INS/DVL's: there the
        particles' biases, never roughened, would lose their spread.
        """
        configured = self._p.velocity_bias_walk_mps
        share = self._trust.shift_share()
        if not self._trust.settled or not np.isfinite(share):
            self._walk_scale = 1.0
        else:
            self._walk_scale = min(max(self._walk_scale * share ** (1.0 / WALK_MEMORY), WALK_SCALE_MIN), 1.0)
        return max(configured * self._walk_scale, min(configured, INS_VELOCITY_BIAS_WALK_MPS))

    def _keep_floor(self, covariance: np.ndarray) -> None:
        """Owe the cloud the variance an update took below the floor's width; the next prediction spreads it.

        The estimate reports the cloud's own covariance (see ``PointMassFilter._keep_floor``).
        """
        missing = self._floor_var - eigenvalues_2x2(covariance)[0]
        if missing > self._pending_var:
            self._pending_var, self._cached = missing, None

    def _prior_bias(self) -> np.ndarray:
        """Velocity biases drawn from their prior, rows east and north."""
        sigma = self._p.velocity_bias_sigma_mps
        return self._rng.normal(0.0, sigma, (2, self._n)) if sigma > 0 else np.zeros((2, self._n))

    def _resample(self) -> None:
        index = systematic_resample(self._w, self._rng)
        # Positions are roughened; the bias only walks: jitter on a weakly observed state adds up to a drift.
        xy = np.column_stack([self._x[index], self._y[index]])
        spread = xy.max(axis=0) - xy.min(axis=0)
        jitter = ROUGHENING_K * spread * self._n ** (-1.0 / 2)
        # A cloud resampled onto one particle (one weight took everything) has no spread to roughen by: it would report a
        # zero covariance (an infinite NEES) until the next prediction. Such an axis is spread by the floor's width.
        if np.any(spread < COLLAPSED_M):
            jitter = np.where(spread < COLLAPSED_M, math.sqrt(self._floor_var), jitter)
            self.counts["resampled_collapsed"] += 1
        xy += self._rng.standard_normal(xy.shape) * jitter
        self._x, self._y, self._b = xy[:, 0].copy(), xy[:, 1].copy(), self._b[:, index]
        self._acquiring = self._acquiring and not self._trust.usable
        if self._acquiring:
            # Until the cloud has found its place, resampling selects on position, which says nothing of
            # the bias: the few survivors' biases would fix it by chance (two_hour: 8 cm/s off with a spread
            # of 1.4 mm/s after 30 s, walked back over an hour). So the bias keeps its prior until then. Corrections
            # that trail one way (``Trust.trailing``) keep the flag down but do not end this: learning from them cost
            # shelf_canyon's PF, narrow across its shelf's ranges at times, 0.418 -> 0.543 node (median of seeds 0, 3, 7).
            self._b = self._prior_bias()
        self._depth_bias = self._depth_bias[index]
        self._w, self._cached = np.full(self._n, 1.0 / self._n), None
        self.counts["resamples"] += 1

    def _candidates(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self._x, self._y, self._w

    def _patch_shift(self, age_s: float) -> tuple[np.ndarray, np.ndarray]:
        return self._b[0] * age_s, self._b[1] * age_s

    def _reweigh(self, log_likelihood: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        log_w = np.log(np.maximum(self._w, 1e-300)) + log_likelihood
        w = np.exp(log_w - log_w.max())
        w /= w.sum()
        return w, *moments(w, self._x, self._y)

    def _accept(self, posterior: np.ndarray, post_cov: np.ndarray, correction_m: np.ndarray, terrain: bool, floored: bool = True) -> None:
        self._w, self._cached = posterior, None
        if 1.0 / np.sum(posterior * posterior) < 0.5 * self._n:
            self._resample()
        if floored:
            self._keep_floor(post_cov)

    def _reinitialize(self) -> None:
        centre, sigma = self._search_prior()
        half = self._search_half_m
        # The depth bias was learned where the cloud was: its mean stays, its confidence goes. The velocity
        # bias is the sensor's, not the place's: the particles keep the cloud's (drawn by weight) if it was learned.
        learned = None if self._acquiring else self._b[:, systematic_resample(self._w, self._rng)]
        self._spawn(centre, half, sigma, depth_bias_m=self.depth_bias_m[0], velocity_bias=learned)
        self._depth_bias_var = max(self._depth_bias_var, self._p.depth_bias_sigma_m**2)
        self._search = (centre, half, sigma)

    def _before_patch(self, patch, weight: float) -> None:
        """After a re-initialization, draw the cloud where the next patch fits (importance sampling).

        A flat cloud over kilometres is too sparse to land on a narrow peak, so the particles are drawn
        from the patch's likelihood over a lattice of cells covering the search square, and weighted
        by the prior over that density: the update that follows multiplies the likelihood in, and the
        two cancel, leaving samples of the prior times the likelihood (with a flat prior, the ML mode of
        section 5).
        """
        if self._search is None:
            return
        (cx, cy), half, sigma = self._search
        self._search = None
        cells = self._p.pmf_cells
        size = 2.0 * half / cells
        centres = (np.arange(cells) - (cells - 1) / 2.0) * size
        x, y = np.meshgrid(cx + centres, cy + centres)
        result = self._lik.patch(x, y, patch, weight=weight, sigma_scale=self._trust.misfit_level, spacing_m=size)
        if result is None:
            return
        q = np.exp(result.log_likelihood - result.log_likelihood.max()).ravel()
        q /= q.sum()
        pick = self._rng.choice(q.size, size=self._n, p=q)
        jitter = self._rng.uniform(-size / 2.0, size / 2.0, (2, self._n))
        self._x, self._y = x.ravel()[pick] + jitter[0], y.ravel()[pick] + jitter[1]
        prior = 1.0 if sigma is None else np.exp(-0.5 * ((self._x - cx) ** 2 + (self._y - cy) ** 2) / sigma**2)
        self._w = prior / q[pick]
        self._w /= self._w.sum()
        self._cached = None
        self.counts["redrawn_from_likelihood"] += 1
