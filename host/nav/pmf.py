"""The point-mass filter of Nygren's report (sections 2-5): the position density on a grid of cells.

The grid
--------
``N x N`` square cells (at most ``pmf_cells`` a side) centred on the estimate, covering
``pmf_sigmas`` standard deviations each way (at least three map nodes), with cells no smaller than
``pmf_min_cell_m`` (default a fifth of a map node: a posterior that collapsed into one node-sized
cell would leave an error floor of a node over sqrt 6). The density is kept at least
``position_floor_nodes`` wide (see NavParameters): narrower, it is widened by a Gaussian blur. The grid follows the density: it is laid anew
(the density interpolated onto it) when the estimate drifts a quarter of the way to its edge or the
covariance outgrows or shrinks well inside it. So it widens by itself while no update arrives.

Motion (eq. 3.3)
----------------
The grid moves with the measured velocity (less the estimated velocity bias) exactly, by its origin;
the motion's uncertainty (velocity noise, INS error growth of eq. 6.2) is a Gaussian convolution,
applied once the accumulated variance reaches a quarter of a cell (smaller steps would round away).

Measurement (eq. 3.5)
---------------------
The patch likelihood of :mod:`lost.host.nav.likelihood` at every cell centre, multiplied in and
normalized; the slant range as a Gaussian in the horizontal range to the ship. Gated as
:mod:`lost.host.nav.trust` says. The estimate is the mean (MMSE) with its covariance (section 4);
``map_position`` the densest cell (MAP). After a re-initialization the prior is flat over the widened
grid: the update is then the maximum-likelihood estimate of section 5 (stage ``acquisition``).

Velocity bias
-------------
A real-time patch's centre is reckoned back with the measured velocity, so a velocity bias b shifts
every match by b times the patch's age, and the prediction drifts by b per second. As Nygren advises
(section 5), the bias is estimated separately: each accepted update's correction of the mean, divided
by the time since the previous one, is averaged with a time constant ``velocity_bias_time_s``.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from ..grid import Grid
from .estimator import Estimate, Motion, Observation
from .likelihood import TerrainLikelihood
from .trust import Trust, moments, nis

__all__ = ["PointMassFilter"]


class PointMassFilter:
    """Recursive Bayesian terrain navigation on a grid of point masses (see the module docstring).

    Parameters
    ----------
    likelihood : TerrainLikelihood
        Patch and depth likelihoods against the map.
    params : NavParameters
        The filter's settings (``pmf_*``, the trust rules, noise levels).
    name : str
        Its name in the outputs.
    """

    def __init__(self, likelihood: TerrainLikelihood, params, *, grid: Grid, name: str = "pmf") -> None:
        self.name = name
        self._lik = likelihood
        self._p = params
        self._grid = grid
        self._trust = Trust(params, node_m=grid.node_m)
        self.counts = self._trust.counts
        self._min_cell = params.pmf_min_cell_m if params.pmf_min_cell_m is not None else grid.node_m / 5.0
        self._floor_var = (params.position_floor_nodes * grid.node_m) ** 2
        self._min_half = 3.0 * grid.node_m
        self.velocity_bias_mps = np.zeros(2)
        self._pending_var = 0.0
        self._since_bias_update_s = 0.0
        self._stage = "uninitialized"
        self._nis = float("nan")
        self._rejected = ""

    # -- the grid ---------------------------------------------------------------------------------

    def _cells(self) -> tuple[np.ndarray, np.ndarray]:
        offsets = (np.arange(self._n) - (self._n - 1) / 2.0) * self._cell
        return self._centre[0] + offsets[None, :], self._centre[1] + offsets[:, None]

    def _lay(self, centre: np.ndarray, half_width_m: float, density: np.ndarray | None) -> None:
        """Lay a grid of cells around ``centre``; carry ``density`` over from the old grid, or flat if None."""
        half = max(half_width_m, self._min_half)
        n = int(min(self._p.pmf_cells, max(math.ceil(2.0 * half / self._min_cell), 8)))
        old = (self._centre, self._cell, self._n) if density is not None else None
        self._centre, self._n, self._cell = np.asarray(centre, float).copy(), n, 2.0 * half / n
        if old is None:
            self._p_grid = np.full((n, n), 1.0 / n**2)
            return
        carried = self._splat(density, *old)
        total = carried.sum()
        self._p_grid = carried / total if total > 0 else np.full((n, n), 1.0 / n**2)
        self.counts["regrids"] += 1
        # A coarse cell's mass was spread over the cell, not on its centre: keep that spread on finer cells.
        old_cell = old[1]
        if old_cell > self._cell:
            self._pending_var += (old_cell**2 - self._cell**2) / 12.0
            self._diffuse()

    def _splat(self, density: np.ndarray, old_centre: np.ndarray, old_cell: float, old_n: int) -> np.ndarray:
        """The old grid's masses moved onto the new cells, each split bilinearly among the four around it.

        Conservative, unlike interpolating the density: a mode narrower than a cell keeps its mass
        whatever the new grid's offset, so equal look-alike modes stay equal through re-gridding.
        """
        offsets = (np.arange(old_n) - (old_n - 1) / 2.0) * old_cell
        x = (old_centre[0] + offsets[None, :] - self._centre[0]) / self._cell + (self._n - 1) / 2.0
        y = (old_centre[1] + offsets[:, None] - self._centre[1]) / self._cell + (self._n - 1) / 2.0
        x, y = (a.ravel() for a in np.broadcast_arrays(x, y))
        mass = density.ravel()
        carried = np.zeros((self._n + 2, self._n + 2))  # one cell of margin each side, dropped after
        c0, r0 = np.floor(x).astype(int), np.floor(y).astype(int)
        fc, fr = x - c0, y - r0
        inside = (c0 >= -1) & (c0 <= self._n - 1) & (r0 >= -1) & (r0 <= self._n - 1) & (mass > 0)
        for dr, dc, share in ((0, 0, (1 - fr) * (1 - fc)), (0, 1, (1 - fr) * fc), (1, 0, fr * (1 - fc)), (1, 1, fr * fc)):
            np.add.at(carried, (r0[inside] + dr + 1, c0[inside] + dc + 1), mass[inside] * share[inside])
        return carried[1:-1, 1:-1]

    def _follow(self) -> None:
        """Re-lay the grid when the density drifts toward its edge or its width no longer fits it."""
        mean, cov = self._moments()
        sigma = math.sqrt(max(float(np.linalg.eigvalsh(cov)[-1]), 0.0))
        wanted = max(self._p.pmf_sigmas * sigma, self._min_half)
        half = self._n * self._cell / 2.0
        drift = float(np.max(np.abs(mean - self._centre)))
        if drift > 0.25 * half or not 0.6 <= wanted / half <= 1.5:
            self._lay(mean, wanted, self._p_grid)

    def _moments(self) -> tuple[np.ndarray, np.ndarray]:
        x, y = self._cells()
        x, y = np.broadcast_arrays(x, y)
        mean, cov = moments(self._p_grid, x, y)
        return mean, cov + np.eye(2) * self._cell**2 / 12.0  # each cell's own spread

    # -- the estimator interface --------------------------------------------------------------------

    def start(self, t_s: float, position: np.ndarray, observation: Observation) -> None:
        sigma = self._p.initial_sigma_m
        self._centre, self._cell, self._n = np.asarray(position, float), 1.0, 1
        self._lay(position, self._p.pmf_sigmas * sigma, None)
        # A Gaussian prior of initial_sigma_m around the start.
        x, y = self._cells()
        prior = np.exp(-0.5 * (((x - position[0]) / sigma) ** 2 + ((y - position[1]) / sigma) ** 2))
        self._p_grid = prior / prior.sum()
        self._stage = "initialization"

    def predict(self, motion: Motion) -> None:
        shift = (np.asarray(motion.velocity_mps, float) - self.velocity_bias_mps) * motion.dt_s
        self._centre = self._centre + shift
        self._pending_var += self._trust.growth_variance(motion.dt_s)
        self._trust.moved(motion.dt_s, float(np.hypot(*shift)))
        self._since_bias_update_s += motion.dt_s
        if self._pending_var >= (0.5 * self._cell) ** 2:
            self._diffuse()
        self._follow()
        self._stage, self._nis, self._rejected = "dead_reckoning", float("nan"), ""

    def _diffuse(self) -> None:
        sigma_cells = math.sqrt(self._pending_var) / self._cell
        blurred = ndimage.gaussian_filter(self._p_grid, sigma_cells, mode="constant", truncate=3.0)
        total = blurred.sum()
        if total > 0:
            self._p_grid = blurred / total
        # Mass that spread past the edge is gone from the grid; its variance is not: add it to the cells.
        self._pending_var = 0.0

    def update(self, observation: Observation) -> None:
        if observation.patch is not None and self._p.matching == "patch":
            self._terrain_update(observation)
        elif self._p.matching == "point" and math.isfinite(observation.ocean_depth_m):
            self._depth_update(observation.ocean_depth_m)
        if self._p.use_slant_range and math.isfinite(observation.slant_range_m) and observation.frame is not None:
            self._range_update(observation)
        self._trust.watch(self._moments()[1])

    def _apply(self, log_likelihood: np.ndarray, *, terrain: bool) -> bool:
        """Multiply a likelihood in, gated by its NIS; counts and stages follow. True when it was used."""
        prior_mean, prior_cov = self._moments()
        ell = log_likelihood - log_likelihood.max()
        posterior = self._p_grid * np.exp(ell)
        total = posterior.sum()
        if not total > 0:
            self._reject("underflow", terrain)
            return False
        before = self._p_grid
        self._p_grid = posterior / total
        post_mean, post_cov = self._moments()
        value = nis(prior_mean, prior_cov, post_mean, post_cov)
        if terrain:
            self._nis = value
        if value > self._p.gate_nis:
            self._p_grid = before
            self._reject("gate", terrain)
            return False
        self._keep_floor(post_cov)
        if terrain:
            self._learn_bias(post_mean - prior_mean)
            self._trust.accepted(post_cov)
            self._stage = "tracking" if self._trust.usable else "acquisition"
            self.counts["terrain_updates"] += 1
        else:
            self.counts["range_updates"] += 1
            self._trust.range_outcome(refused=False)
        self._follow()
        return True

    def _keep_floor(self, covariance: np.ndarray) -> None:
        """Blur the density back to the floor's width where an update made it narrower."""
        missing = self._floor_var - float(np.linalg.eigvalsh(covariance)[0])
        if missing > 0:
            self._pending_var += missing
            self._diffuse()

    def _reject(self, reason: str, terrain: bool) -> None:
        self._rejected = reason if not self._rejected else f"{self._rejected},{reason}"
        if not terrain:
            self.counts[f"range_rejected_{reason}"] += 1
            self._trust.range_outcome(refused=True)
            return
        self._stage = "rejected"
        if self._trust.rejected(reason):
            self._reinitialize()

    def _reinitialize(self) -> None:
        mean, _ = self._moments()
        self._lay(mean, self._p.pmf_sigmas * self._p.initial_sigma_m, None)  # flat: maximum likelihood next
        self._stage = "reinitialized"

    def _learn_bias(self, correction_m: np.ndarray) -> None:
        """Average the implied velocity error (see the module docstring); only once the estimate is usable."""
        tau = self._p.velocity_bias_time_s
        if tau is None or not self._trust.usable or self._since_bias_update_s <= 0:
            self._since_bias_update_s = 0.0
            return
        implied = -correction_m / self._since_bias_update_s
        gain = min(self._since_bias_update_s / tau, 1.0)
        self.velocity_bias_mps = self.velocity_bias_mps + gain * implied
        self._since_bias_update_s = 0.0

    def _terrain_update(self, observation: Observation) -> None:
        patch = observation.patch
        x, y = np.broadcast_arrays(*self._cells())
        length = max(patch.depth_m.shape) * patch.node_m
        result = self._lik.patch(x, y, patch, weight=self._trust.patch_weight(length),
                                sigma_scale=self._trust.misfit_level, spacing_m=self._cell)
        if result is None:
            self.counts["patch_too_sparse"] += 1
            return
        if result.valid_nodes < self._p.min_valid_fraction * patch.depth_m.size:
            self.counts["patch_too_sparse"] += 1
            return
        if not result.informative.any():
            self.counts["patch_off_map"] += 1
            self._stage = "off_map"
            return
        on_map = float(self._p_grid[result.informative].sum())
        if self._trust.at_edge(on_map, self._moments()[1]):
            self.counts["patch_at_map_edge"] += 1
            self._stage = "off_map"
            return
        # A patch that fits nowhere is refused only where the map covers most of where the vehicle may be.
        if self._trust.misfit_refused(result.misfit) and on_map > 0.5:
            self._reject("misfit", terrain=True)
            return
        if self._apply(result.log_likelihood, terrain=True):
            self._trust.note_misfit(result.misfit)
            self._trust.look_alike(self._lik, *self._moments(), patch)
            self._stage = "tracking" if self._trust.usable else "acquisition"

    def _depth_update(self, ocean_depth_m: float) -> None:
        x, y = np.broadcast_arrays(*self._cells())
        sigma = self._lik.depth_sigma_m
        ell, informative = self._lik.depth(x, y, ocean_depth_m, sigma_m=sigma)
        if not informative.any():
            self.counts["depth_off_map"] += 1
            self._stage = "off_map"
            return
        self._apply(ell * self._p.likelihood_weight, terrain=True)

    def _range_update(self, observation: Observation) -> None:
        frame = observation.frame
        vertical = observation.vehicle_depth_m - self._p.reference_depth_m
        horizontal_sq = observation.slant_range_m**2 - vertical**2
        if not (math.isfinite(horizontal_sq) and horizontal_sq > 0):
            self.counts["range_shorter_than_depth"] += 1
            return
        x, y = np.broadcast_arrays(*self._cells())
        distance = np.hypot(x - frame.ship_x_m, y - frame.ship_y_m)
        ell = -0.5 * ((distance - math.sqrt(horizontal_sq)) / self._p.slant_range_sigma_m) ** 2
        self._apply(ell, terrain=False)

    def estimate(self) -> Estimate:
        mean, cov = self._moments()
        return Estimate(position=mean, covariance=cov, usable=self._trust.usable, stage=self._stage, nis=self._nis, rejected=self._rejected)

    @property
    def map_position(self) -> np.ndarray:
        """The densest cell's centre (the MAP estimate of section 4)."""
        x, y = np.broadcast_arrays(*self._cells())
        k = int(np.argmax(self._p_grid))
        return np.array([x.ravel()[k], y.ravel()[k]])

    @property
    def density(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The grid's cell centres (x, y) and their probabilities."""
        x, y = np.broadcast_arrays(*self._cells())
        return x, y, self._p_grid
