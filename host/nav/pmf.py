"""The point-mass filter of Nygren's report (sections 2-5): the position density on a grid of cells.

The grid
--------
``N x N`` square cells (at most ``pmf_cells`` a side) centred on the estimate, covering
``pmf_sigmas`` standard deviations each way (at least two map nodes and four floor widths), with cells no smaller than
``pmf_min_cell_m`` (default a tenth of a map node or half the floor width, the coarser: a posterior that collapsed into one node-sized
cell would leave an error floor of a node over sqrt 6). The density is kept at least
``position_floor_nodes`` wide (see NavParameters): narrower after an update, the next prediction widens it by a Gaussian blur.
Off the map (no terrain for ``off_map_usable_s``) the slant ranges alone update it and owe no floor, so the cells
shrink to half the density's narrowest sigma (``pmf_cells`` bounding them) to resolve the axis the ranges hold.
The grid follows the density: it is laid anew
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
``map_position`` the densest cell (MAP). After a re-initialization the widened grid holds the start's
Gaussian prior around the lay-back position of a towed vehicle, or is flat around the estimate without
one (see ``BayesFilter._search_prior``): the update is then the maximum-likelihood estimate of section 5
(stage ``acquisition``).

Velocity bias
-------------
A real-time patch's centre is reckoned back with the measured velocity, so a velocity bias b shifts
every match by b times the patch's age, and the prediction drifts by b per second. As Nygren advises
(section 5), the bias is estimated beside the density: a Kalman filter on the drift of the density's
corrections (:mod:`lost.host.nav.velocity_bias`), every accepted correction (terrain, slant range,
fix), not the terrain's alone: where the range and the terrain disagree (a patch misplaced by b times
its age) the terrain's pull alone reads as a bias of the opposite sign. It starts once the density has
been narrow for ``bias_learning_updates`` updates (before, the corrections are the acquisition's own
moves). Each patch is moved by the estimate times its age, and the density is kept at least as wide
as the patch's misplacement that the bias's variance allows (``_misplacement_var``, in the directions narrower than
it: ``_keep_floor``): while the bias is unknown that is metres, and a narrow density on misplaced patches would be a
false fix.

Depth bias
----------
The single-depth (point) form compares the measured ocean depth with the map, so a tide or a
pressure-depth error reads as terrain elsewhere. Each cell carries its own estimate of that bias
(a scalar Kalman filter given the cell's history, Rao-Blackwellized; see ``BayesFilter._depth_update``),
moved with its mass through the motion's blur and the re-gridding.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from ..grid import Grid
from .bayes import BayesFilter
from .estimator import Motion, Observation
from .likelihood import TerrainLikelihood
from .moments import eigenvalues_2x2, largest_sigma
from .velocity_bias import VelocityBiasFilter

__all__ = ["PointMassFilter", "PMF_CELLS_PER_NODE"]

#: The finest cells a side of a map node, by default (``pmf_min_cell_m``).
PMF_CELLS_PER_NODE = 10


def _ratio(weighted: np.ndarray, mass: np.ndarray, fallback: float) -> np.ndarray:
    """``weighted / mass`` where there is mass to speak of, ``fallback`` elsewhere."""
    has_mass = mass > 1e-300
    return np.where(has_mass, weighted / np.where(has_mass, mass, 1.0), fallback)


class PointMassFilter(BayesFilter):
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
        super().__init__(likelihood, params, grid=grid, name=name)
        floor = math.sqrt(self._floor_var_acquisition)
        # Cells fine enough to resolve the floor's width, a grid wide enough for four of it.
        self._floor_cell = params.pmf_min_cell_m if params.pmf_min_cell_m is not None else max(grid.node_m / PMF_CELLS_PER_NODE, floor / 2.0)
        self._min_cell = self._floor_cell
        self._min_half = max(2.0 * grid.node_m, 4.0 * floor)
        self._velocity_bias = VelocityBiasFilter(params.velocity_bias_sigma_mps, params.velocity_bias_walk_mps)
        self._pending_var = 0.0
        self._pending_axes = np.zeros(2)  # variance owed along each axis alone, (east, north) (``_keep_floor``)
        self._since_bias_update_s = 0.0
        self._correction_since_m = np.zeros(2)
        self._patch_age_s = 0.0
        self._patch_weight = 1.0
        self._moments_kept: tuple[np.ndarray, np.ndarray, float, np.ndarray, np.ndarray] | None = None

    # -- the grid ---------------------------------------------------------------------------------

    def _cells(self) -> tuple[np.ndarray, np.ndarray]:
        offsets = (np.arange(self._n) - (self._n - 1) / 2.0) * self._cell
        return self._centre[0] + offsets[None, :], self._centre[1] + offsets[:, None]

    def _lay(self, centre: np.ndarray, half_width_m: float, density: np.ndarray | None) -> None:
        """Lay a grid of cells around ``centre``; carry ``density`` over from the old grid, or flat if None."""
        half = max(half_width_m, self._min_half)
        n = int(min(self._p.pmf_cells, max(math.ceil(2.0 * half / self._min_cell), 8)))
        old = (self._centre, self._cell, self._n) if density is not None else None
        # Only the single-depth form has a depth bias to carry; the patch form skips the work.
        carry_bias = self._p.matching == "point"
        bias_mean = self.depth_bias_m[0] if carry_bias and self._depth_bias.size > 1 else 0.0
        old_bias = self._depth_bias
        self._centre, self._n, self._cell = np.asarray(centre, float).copy(), n, 2.0 * half / n
        if old is None:
            self._p_grid = np.full((n, n), 1.0 / n**2)
            if carry_bias:
                self._depth_bias = np.full((n, n), bias_mean)
            return
        carried = self._splat(density, *old)
        total = carried.sum()
        self._p_grid = carried / total if total > 0 else np.full((n, n), 1.0 / n**2)
        if carry_bias:
            self._depth_bias = _ratio(self._splat(density * old_bias, *old), carried, bias_mean)
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
        """Re-lay the grid when the density drifts toward its edge, its width no longer fits it, or its cells no
        longer resolve it (:meth:`_wanted_cell`)."""
        mean, cov = self._moments()
        sigma = largest_sigma(cov)
        wanted = max(self._p.pmf_sigmas * sigma, self._min_half)
        half = self._n * self._cell / 2.0
        drift = float(np.max(np.abs(mean - self._centre)))
        self._min_cell = self._wanted_cell(cov)
        n = min(self._p.pmf_cells, max(math.ceil(2.0 * wanted / self._min_cell), 8))
        if drift > 0.25 * half or not 0.6 <= wanted / half <= 1.5 or not 0.7 <= 2.0 * wanted / n / self._cell <= 1.4:
            self._lay(mean, wanted, self._p_grid)

    def _wanted_cell(self, covariance: np.ndarray) -> float:
        """The finest cell the grid needs: the floor's, or half the density's narrowest sigma off the map.

        On the map every terrain update owes the density its floor, which the floor's cells resolve. Off it (no
        terrain for ``off_map_usable_s``) only the slant ranges update it, and they owe no floor: they hold the axis
        along the range to 2 m, under a 4 m cell. The ring, read at the centres of cells as wide as that axis and
        crossing them obliquely, moved the mean across the track (the axis the ranges do not hold) by more than
        along it, 0.5 m a range against 0.4 (``seamount_ridges`` seed 2, 700-780 s off the map: 8 -> 17 m across the track). The grid's
        ``pmf_cells`` over the grid's least width bound the refinement.
        """
        if self._p.pmf_min_cell_m is not None or self._trust.since_terrain_s <= self._p.off_map_usable_s:
            return self._floor_cell
        narrow, _ = eigenvalues_2x2(covariance - np.eye(2) * self._cell**2 / 12.0)
        # A density within one row of cells has no measurable width left: the finest grid then.
        return max(min(self._floor_cell, 0.5 * math.sqrt(max(narrow, 0.0))), 2.0 * self._min_half / self._p.pmf_cells)

    def _moments(self) -> tuple[np.ndarray, np.ndarray]:
        # Asked several times a record (gates, ranges, the trust, the estimate) between changes of the density: the
        # grid and its centre are replaced, never changed in place, so they name the density's state.
        kept = self._moments_kept
        if kept is None or kept[0] is not self._p_grid or kept[1] is not self._centre or kept[2] != self._cell:
            kept = self._moments_kept = (self._p_grid, self._centre, self._cell, *self._moments_of(self._p_grid))
        return kept[3].copy(), kept[4].copy()

    def _moments_of(self, density: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        # The cells are a regular grid: the moments from the marginals and one product, without n x n coordinate arrays.
        x, y = (c.ravel() for c in self._cells())
        px, py = density.sum(axis=0), density.sum(axis=1)
        mx, my = float(px @ x), float(py @ y)
        dx, dy = x - mx, y - my
        sxy = float(dy @ density @ dx)
        cov = np.array([[float(px @ (dx * dx)), sxy], [sxy, float(py @ (dy * dy))]])
        return np.array([mx, my]), cov + np.eye(2) * self._cell**2 / 12.0  # each cell's own spread

    # -- the estimator interface --------------------------------------------------------------------

    def start(self, t_s: float, position: np.ndarray, observation: Observation) -> None:
        self._centre, self._cell, self._n = np.asarray(position, float), 1.0, 1
        self._lay_prior(np.asarray(position, float), self._p.initial_sigma_m)
        self._stage = "initialization"

    def _lay_prior(self, centre: np.ndarray, sigma: float | None) -> None:
        """A grid of ``pmf_sigmas`` initial sigmas around ``centre``: a Gaussian prior of ``sigma`` on it, or flat (None)."""
        self._lay(centre, self._search_half_m, None)
        if sigma is not None:
            x, y = self._cells()
            prior = np.exp(-0.5 * (((x - centre[0]) / sigma) ** 2 + ((y - centre[1]) / sigma) ** 2))
            self._p_grid = prior / prior.sum()

    def predict(self, motion: Motion) -> None:
        shift = (np.asarray(motion.velocity_mps, float) - self.velocity_bias_mps) * motion.dt_s
        self._centre = self._centre + shift
        self._pending_var += self._trust.growth_variance(motion.dt_s) + self._bias_growth_variance(motion.dt_s)
        self._depth_bias_var += self._p.depth_bias_walk_m**2 * motion.dt_s
        self._velocity_bias.walk(motion.dt_s)
        self._since_bias_update_s += motion.dt_s
        if self._pending_var + float(self._pending_axes.max()) >= (0.5 * self._cell) ** 2:
            self._diffuse()
        self._follow()
        self._moved(motion.dt_s, float(np.hypot(*shift)))

    def _bias_growth_variance(self, dt_s: float) -> float:
        """What the velocity bias's own uncertainty adds to the position over a step without terrain, m**2.

        The predicted position moves by the measured velocity less the bias estimate; the estimate's error
        sigma_b, constant over a gap, misplaces it by sigma_b t after t seconds without an update: the variance
        grows by sigma_b**2 ((t + dt)**2 - t**2). Beyond the map's edge a learned bias of -0.18 m/s took the
        density 5-73 m off while its sigma said 1.5-10 m.
        """
        if not self._p.estimate_velocity_bias:
            return 0.0
        t = self._trust.since_update_s
        return float(self._velocity_bias.variance_mps2.max()) * ((t + dt_s) ** 2 - t**2)

    def _diffuse(self) -> None:
        sigma_cells = np.sqrt(self._pending_var + self._pending_axes[::-1]) / self._cell  # (north, east): rows, columns
        self._pending_axes = np.zeros(2)
        if sigma_cells.max() > self._n:
            # Wider than the grid: the blur leaves it flat (a Gaussian filter of 1e5 cells would not end).
            if self._p.matching == "point":
                self._depth_bias = np.full_like(self._p_grid, self.depth_bias_m[0])
            self._p_grid = np.full_like(self._p_grid, 1.0 / self._p_grid.size)
            self._pending_var = 0.0
            self.counts["diffusion_flattened"] += 1
            return
        blurred = ndimage.gaussian_filter(self._p_grid, sigma_cells, mode="constant", truncate=3.0)
        total = blurred.sum()
        if total > 0:
            if self._p.matching == "point":
                # Each cell's depth bias: the mass-weighted mean of the biases its mass came from.
                carried_bias = ndimage.gaussian_filter(self._p_grid * self._depth_bias, sigma_cells, mode="constant", truncate=3.0)
                self._depth_bias = _ratio(carried_bias, blurred, self.depth_bias_m[0])
            self._p_grid = blurred / total
        # Mass that spread past the edge is gone from the grid; its variance is not: add it to the cells.
        self._pending_var = 0.0

    def _keep_floor(self, covariance: np.ndarray) -> None:
        """Owe the density the variance an update took below the floor's width; the next prediction blurs it in.

        The floor is process noise (it stands for the matches' correlated error), so it belongs to the
        prediction, P(k+1|k), and the estimate reports the update's own posterior, P(k|k), as a Kalman
        filter does. Blurred in at once, it was reported too: NEES in band 0.84 on ``coarse_map``
        and 0.86 on ``offset``, all of it below the band (0.91 and 0.88 without).

        The shared floor lifts the density's narrowest direction and, a blur, every other by as much. Where the patch
        may truly lie given what is not yet known of the velocity bias (:meth:`_misplacement_var`) is a floor of its
        own, the larger of the two counting (the tracking floor was measured, NEES, on tows whose bias had been
        learned, so it already holds a learned bias's residual; summed, ``coarse_map``'s and ``two_hour``'s NEES fell
        below their band, 0.87 and 0.90), but it lifts only the directions narrower than it: an isotropic lift
        widened the axis the terrain holds poorly at every update where a range holds the other (``shelf_canyon``, the
        bias never learned on its shelf: PMF 0.359 node without this rule, ten seeds).
        """
        if not np.all(np.isfinite(covariance)):
            return
        narrow, wide = eigenvalues_2x2(covariance)
        shared = max(self._floor_var - narrow, 0.0)
        self._pending_var += shared
        short_narrow, short_wide = (max(self._misplacement_var() - (value + shared), 0.0) for value in (narrow, wide))
        if short_narrow > 0.0:
            # Each direction's shortfall read on the grid's axes: the narrow eigenvector's squared components are
            # (wide - sxx, wide - syy) / (wide - narrow), the wide one's the rest (closed form: eigh costs 30 us a call).
            gap = wide - narrow
            on_narrow = np.clip([(wide - covariance[0, 0]) / gap, (wide - covariance[1, 1]) / gap], 0.0, 1.0) if gap > 1e-12 * wide else np.full(2, 0.5)
            self._pending_axes += short_narrow * on_narrow + short_wide * (1.0 - on_narrow)

    def _misplacement_var(self) -> float:
        """Where the last patch may truly lie given what is not yet known of the velocity bias, m**2: 0.05 m/s over a
        46 s patch age is 2.3 m; without it ``usbl_nav`` without the USBL made 60 false fixes in its first minutes."""
        if not self._p.estimate_velocity_bias:
            return 0.0
        return self._velocity_bias.misplacement_var(self._patch_age_s)

    def _reinitialize(self) -> None:
        self._lay_prior(*self._search_prior())
        self._velocity_bias.restart()
        # The depth bias was learned where the density was: its mean stays, its confidence goes.
        self._depth_bias_var = max(self._depth_bias_var, self._p.depth_bias_sigma_m**2)

    def _candidates(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        x, y = np.broadcast_arrays(*self._cells())
        return x, y, self._p_grid

    def _spacing(self) -> float:
        return self._cell

    def _cell_half_width(self) -> float:
        return self._cell / 2.0

    def _reweigh(self, log_likelihood: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        posterior = self._p_grid * np.exp(log_likelihood - log_likelihood.max())
        total = posterior.sum()
        if not total > 0:
            return None
        posterior = posterior / total
        return (posterior, *self._moments_of(posterior))

    def _accept(self, posterior: np.ndarray, post_cov: np.ndarray, correction_m: np.ndarray, terrain: bool, floored: bool = True) -> None:
        self._p_grid = posterior
        if floored:
            self._keep_floor(post_cov)
        self._correction_since_m = self._correction_since_m + correction_m
        if terrain:
            self._learn_bias(self._correction_since_m, np.diag(post_cov))
            self._correction_since_m = np.zeros(2)
        self._follow()

    @property
    def velocity_bias_mps(self) -> np.ndarray:
        return self._velocity_bias.mean_mps

    @property
    def velocity_bias_sigma_mps(self) -> np.ndarray:
        if not self._p.estimate_velocity_bias:
            return np.full(2, np.nan)
        return np.sqrt(self._velocity_bias.variance_mps2)

    def _before_patch(self, patch, weight: float) -> None:
        self._patch_age_s, self._patch_weight = patch.age_s, weight

    def _patch_shift(self, age_s: float) -> tuple[float, float]:
        bias = self.velocity_bias_mps
        return float(bias[0] * age_s), float(bias[1] * age_s)

    def _learn_bias(self, correction_m: np.ndarray, position_var_m2: np.ndarray) -> None:
        """The bias filter's update (see the module docstring): only while the density has been narrow a while.

        A correction of a wide density (after a gap off the map, a hole, a smooth stretch) is mostly the
        prior's own error, not a drift: taken as one, a single 92 m move of a 78 m wide density after a hole
        taught ``seamount_ridges`` (seed 0) a bias of 0.2 m/s, and 120 false fixes followed. So the sum of
        corrections stops when the density widens past the usable width and is anchored anew once it has
        been narrow for ``bias_learning_updates`` again; the bias learned stays.
        """
        since, self._since_bias_update_s = self._since_bias_update_s, 0.0
        narrow = self._trust.good_in_row >= self._p.bias_learning_updates
        if not self._p.estimate_velocity_bias:
            return
        if not narrow:
            if self._velocity_bias.following:
                self._velocity_bias.restart()
                self.counts["velocity_bias_paused"] += 1
            return
        self._velocity_bias.update(correction_m, since, position_var_m2, self._patch_weight)

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
