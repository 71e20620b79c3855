"""The terrain likelihood of Nygren's recursive estimation (eqs. 3.2-3.5) from the exact correlator.

For a sonar patch of n valid nodes the correlator gives, at every placement, V = n * sum |d_k - mean d|
in depth words (ARCHITECTURE.md), d the map-minus-sonar depths: the sum of absolute residuals after
the patch's mean is removed is ``V * lsb / n`` metres. With the residuals independent and
Laplace-distributed with standard deviation sigma (scale b = sigma / sqrt 2), the log-likelihood of a
placement is, up to a constant::

    log L = -sqrt(2) * (V * lsb / n) / sigma                      (Laplace: what the hardware gives)
    log L = -sum (d_k - mean d)**2 / (2 sigma**2)                  (Gaussian, eq. 3.4: computed on the host)

sigma**2 = depth_noise**2 + map_error**2: the sonar's error per patch node and the map's error where
the patch samples it (survey noise, and the interpolation the map's node spacing leaves). Mean
compensation makes both blind to a constant depth offset (tide, pressure depth), as eq. 8.1 intends.

Tempering. Successive real-time patches share most of their soundings, so their likelihoods are far
from independent; multiplying them all in would make the posterior overconfident. Each log-likelihood
is multiplied by a weight w in (0, 1]: the share of the patch that is new since the last update used,
``w = min(1, distance travelled / patch length)``, times ``likelihood_weight`` (default 1; lower for
map errors correlated over several nodes).

Between placements. The correlator gives the likelihood at whole-node placements of the patch; the vehicle lies
anywhere between. A map node and a patch node are block means of the floor; a fraction f of a node apart they differ by
the relief within that fraction, which grows like a cusp from f = 0, so a surface sampled a node apart and read
between by a spline peaks near a placement: the estimate locks to the map's lattice (measured on ``demo`` seed 1
across the track: its error 0.12 node, 0.05 with the locking's share taken out). Where the patch carries its soundings
they are gridded again on lattices moved by 1/K, ..., (K-1)/K of a node (``phases`` K, :func:`lost.host.nav.motion.lattice_moved`),
each correlated like the patch, and the spline reads a surface sampled every 1/K node.

No information. A placement that leaves the map or puts a sounding on a hole carries no information about where
the vehicle is: the terrain there is unknown. Such candidates get the median log-likelihood of the
placements around (those the candidates span): flat, as likely as a typical wrong placement, so that
a map's edge neither attracts the estimate nor repels it, and a placement that really fits still
wins. (The mean likelihood over the map would be the textbook value for unknown terrain, but the
placement the patch came from dominates that mean and would make the unknown nearly as good as it.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage, signal

from ..records import SonarPatch
from .maperror import window_variance
from .mapprep import PreparedMap
from .motion import MAX_PHASES, lattice_moved

__all__ = ["TerrainLikelihood", "PatchLikelihood", "LIKELIHOODS", "MAX_PHASES", "MIN_INDEPENDENT_SHARE", "map_error_estimate"]

LIKELIHOODS = ("laplace", "gaussian")
#: The least share of a patch's nodes counted independent (:meth:`TerrainLikelihood.independent_share`).
MIN_INDEPENDENT_SHARE = 0.2


def map_error_estimate(depth_m: np.ndarray) -> float:
    """A default map error, metres: half the RMS difference between a node and the mean of its 4 neighbours.

    The difference from the neighbours' mean is the error of interpolating a node from one node
    away; a patch node lies at most half a node from a map node, where that error is roughly halved.
    A heuristic, stated as such: give ``map_error_m`` when the survey's error is known.
    """
    d = np.asarray(depth_m, float)
    if min(d.shape) < 3:
        return 0.0
    centre = d[1:-1, 1:-1]
    neighbours = (d[:-2, 1:-1] + d[2:, 1:-1] + d[1:-1, :-2] + d[1:-1, 2:]) / 4.0
    difference = (centre - neighbours)[np.isfinite(centre - neighbours)]
    return 0.5 * float(np.sqrt(np.mean(difference**2))) if difference.size else 0.0


def _corners(shape: tuple[int, int], row: np.ndarray, col: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each fractional (row, col)'s cell on a ``shape`` lattice of at least 2 x 2: the flat index of its first corner,
    the fractions across it, and whether it lies inside."""
    rows, cols = shape
    r0 = np.minimum(np.floor(row), rows - 2)  # a point on the last row or column uses the cell before it
    c0 = np.minimum(np.floor(col), cols - 2)
    fr, fc = row - r0, col - c0
    inside = (r0 >= 0) & (c0 >= 0) & (fr <= 1.0) & (fc <= 1.0)
    return np.where(inside, r0 * cols + c0, 0).astype(np.intp), fr, fc, inside


def _bilinear(values: np.ndarray, valid: np.ndarray, row: np.ndarray, col: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bilinear interpolation at fractional (row, col), and whether all four nodes around are inside and valid."""
    if values.shape[0] == 1 or values.shape[1] == 1:
        # One row (or column) of placements: doubled, a point on it interpolates with a zero far weight.
        reps = (2 if values.shape[0] == 1 else 1, 2 if values.shape[1] == 1 else 1)
        values, valid = np.tile(values, reps), np.tile(valid, reps)
    cols = values.shape[1]
    # Invalid nodes as NaN: one gather per corner carries both the value and its validity.
    flat = np.where(valid, values, np.nan).ravel()
    k, fr, fc, inside = _corners(values.shape, row, col)
    value = ((1 - fr) * ((1 - fc) * flat[k] + fc * flat[k + 1]) + fr * ((1 - fc) * flat[k + cols] + fc * flat[k + cols + 1]))
    ok = inside & np.isfinite(value)
    return np.where(ok, value, 0.0), ok


def _four_valid(valid: np.ndarray, row: np.ndarray, col: np.ndarray) -> np.ndarray:
    """Whether the four nodes around each fractional (row, col) are inside and valid (``_bilinear``'s rule, without
    its values), on a lattice of at least 2 x 2."""
    flat = valid.ravel()
    k, _, _, inside = _corners(valid.shape, row, col)
    cols = valid.shape[1]
    return inside & flat[k] & flat[k + 1] & flat[k + cols] & flat[k + cols + 1]


def _between_placements(ell: np.ndarray, valid: np.ndarray, neutral: float, row: np.ndarray, col: np.ndarray, *,
                        spline: bool) -> tuple[np.ndarray, np.ndarray]:
    """The log-likelihood between the correlator's placements, and where it is informative.

    A cubic spline through the placements: bilinear interpolation has its maxima on the placements
    themselves, so a density updated with it snaps to map nodes and keeps an error of up to half a
    node (on ``short``, 1-3 m biases that last minutes). The spline puts the peak between them.
    Holes are filled with the neutral value for the spline's sake; where the point's own four
    placements are not all valid, it is not informative (bilinear's rule). Bilinear where ``spline``
    is False (candidates coarser than the nodes read a cell-averaged surface, whose underflowed
    cells would make a spline ring) and with fewer than four placements a side.
    """
    if not spline or min(ell.shape) < 4:
        return _bilinear(np.where(valid, ell, 0.0), valid, row, col)
    informative = _four_valid(valid, row, col)
    value = np.zeros(np.shape(row))  # read only where informative
    if informative.any():
        value[informative] = ndimage.map_coordinates(np.where(valid, ell, neutral), np.stack([row[informative], col[informative]]),
                                                     order=3, mode="nearest")
    return value, informative


@dataclass(frozen=True)
class PatchLikelihood:
    """A patch's log-likelihood at a set of candidate vehicle positions.

    Attributes
    ----------
    log_likelihood : array, the shape of the candidates
        Tempered log-likelihood (weight included), with the no-information value where the patch
        would leave the map or put a valid node on a hole.
    informative : bool array, same shape
        Where every valid node of the patch lay on a map depth (inside the map, on no hole).
    misfit : float
        The smallest mean absolute residual over the informative candidates, in units of the
        residual expected at the true position (about 1 when the patch fits somewhere; NaN if none is
        informative).
    weight : float
        The tempering weight used.
    valid_nodes : int
    inside : bool array, same shape, or None
        Where the patch lies inside the map's bounds, holes or not (None: as ``informative``).
    """

    log_likelihood: np.ndarray
    informative: np.ndarray
    misfit: float
    weight: float
    valid_nodes: int
    inside: np.ndarray | None = None

    @property
    def on_map(self) -> np.ndarray:
        """Where the patch lies inside the map's bounds (a candidate refused for holes is on the map)."""
        return self.informative if self.inside is None else self.inside

    @property
    def on_holes(self) -> bool:
        """No candidate is informative, and some lie on the map: the patch's soundings fall on holes there."""
        return not self.informative.any() and bool(self.on_map.any())


class TerrainLikelihood:
    """Log-likelihoods of sonar patches and single depths against a prepared map.

    Parameters
    ----------
    prepared : PreparedMap
        The map in correlator words, with its holes.
    sigma_m : float
        Standard deviation of one patch node's residual (sonar and map together), metres.
    form : {"laplace", "gaussian"}
        The residual distribution; Laplace uses the correlator's V as it is.
    depth_sigma_m : float
        Standard deviation of a single ocean-depth measurement against the map, metres.
    backend : str
        Correlator backend for the Laplace form.
    node_var_m2 : (H, W) array, optional
        The map's error variance at each node (:func:`lost.host.nav.maperror.node_variance`). With it, a
        placement's residual sigma is ``sqrt(depth_noise_m**2 + mean of node_var_m2 under the patch)``,
        and the log-likelihood carries its normalization (``-n log sigma``) so that rough places, with
        their larger sigma, are not favoured for the residuals they excuse. Without it, ``sigma_m`` everywhere.
    depth_noise_m : float
        The sonar's own 1-sigma per patch node, with ``node_var_m2``.
    phases : int
        Samples of the likelihood per node and axis where the patch carries its soundings (1: the placements alone).
    """

    def __init__(self, prepared: PreparedMap, *, sigma_m: float, depth_sigma_m: float | None = None, form: str = "laplace",
                 backend: str = "software", node_var_m2: np.ndarray | None = None, depth_noise_m: float = 0.0,
                 phases: int = 1) -> None:
        if form not in LIKELIHOODS:
            raise ValueError(f"the likelihood form must be one of {LIKELIHOODS}, got {form!r}")
        if not (math.isfinite(sigma_m) and sigma_m > 0):
            raise ValueError(f"the residual standard deviation must be a positive number of metres, got {sigma_m!r}")
        self._prep = prepared
        self._grid = prepared.grid
        self.sigma_m = float(sigma_m)
        self.depth_sigma_m = float(sigma_m if depth_sigma_m is None else depth_sigma_m)
        self.form = form
        self._backend = backend
        if node_var_m2 is not None and np.shape(node_var_m2) != prepared.grid.shape:
            raise ValueError(f"the map's error variance layer is {np.shape(node_var_m2)} but the map {prepared.grid.shape}")
        self._node_var = node_var_m2
        self._depth_noise_var = float(depth_noise_m) ** 2
        self._window_sigma: dict[tuple[int, int], np.ndarray] = {}
        if int(phases) != phases or not 1 <= phases <= MAX_PHASES:
            raise ValueError(f"the likelihood's phases per node must be an integer from 1 to {MAX_PHASES}, got {phases!r}")
        self.phases = int(phases)
        self._moved: tuple[SonarPatch, dict[tuple[int, int], SonarPatch]] | None = None
        self._fine: tuple[SonarPatch, tuple[int, int, int, int], np.ndarray, np.ndarray] | None = None

    def _placement_sigma(self, patch_shape: tuple[int, int], i0: int, i1: int, j0: int, j1: int) -> np.ndarray | float:
        """The residual sigma at placements i0..i1 x j0..j1: per placement with the map's node errors, else ``sigma_m``."""
        if self._node_var is None:
            return self.sigma_m
        if patch_shape not in self._window_sigma:
            self._window_sigma[patch_shape] = np.sqrt(self._depth_noise_var + window_variance(self._node_var, patch_shape))
        return self._window_sigma[patch_shape][i0 : i1 + 1, j0 : j1 + 1]

    def patch(self, x_m: np.ndarray, y_m: np.ndarray, patch: SonarPatch, *, weight: float = 1.0,
              sigma_scale: float = 1.0, spacing_m: float = 0.0) -> PatchLikelihood | None:
        """Log-likelihood of ``patch`` were the vehicle at each (x, y); None for a patch with no valid node.

        The patch centre is placed ``patch.centre_offset_m`` from each candidate; the surface is computed
        once over the placements that the candidates span and interpolated between them by a cubic spline.
        ``sigma_scale`` multiplies the residual sigma (a filter's running estimate of how much larger
        the real residuals are than the nominal sigma); the misfit stays in nominal units.
        ``spacing_m``: the candidates' spacing. Where it is coarser than the map's nodes, the
        likelihood is averaged over a candidate's own cell before it is read there, so a narrow peak
        counts by its mass rather than by whether a candidate happens to sit on it (point-sampled,
        equal look-alike peaks would win or lose by the candidates' aliasing).
        """
        grid, prep = self._grid, self._prep
        if not math.isclose(patch.node_m, grid.node_m, rel_tol=1e-9):
            raise ValueError(f"the sonar patch has {patch.node_m} m nodes but the map {grid.node_m} m; grid the patch on the map's nodes")
        words, mask, _ = prep.quantize_patch(patch.depth_m)
        n = int(mask.sum())
        if n < 2:
            return None
        h, w = words.shape
        rows, cols = grid.shape
        if h > rows or w > cols:
            raise ValueError(f"the {h} x {w} sonar patch is larger than the {rows} x {cols} map")
        x = np.asarray(x_m, float) + patch.centre_offset_m[0]
        y = np.asarray(y_m, float) + patch.centre_offset_m[1]
        row, col = grid.row_col(x, y)
        # Placement (i, j) puts the patch centre on node (i + (h-1)/2, j + (w-1)/2).
        pi, pj = row - (h - 1) / 2, col - (w - 1) / 2
        last_i, last_j = rows - h, cols - w
        i0, i1 = max(int(np.floor(pi.min())), 0), min(int(np.ceil(pi.max())) + 1, last_i)
        j0, j1 = max(int(np.floor(pj.min())), 0), min(int(np.ceil(pj.max())) + 1, last_j)
        if i0 > i1 or j0 > j1:
            shape = np.shape(x)
            return PatchLikelihood(np.zeros(shape), np.zeros(shape, bool), float("nan"), weight, n)
        inside = (pi >= 0) & (pi <= last_i) & (pj >= 0) & (pj <= last_j)
        size = int(round(spacing_m / grid.node_m))
        moved = self._lattice_moved(patch) if size <= 1 else {}
        sigma = self._placement_sigma((h, w), i0, i1, j0, j1)
        if moved:
            k = self.phases
            per_node, valid = self._between_nodes(patch, words, mask, moved, (i0, i1, j0, j1))
            whole_per_node, whole_valid = per_node[k - 1 :: k, k - 1 :: k], valid[k - 1 :: k, k - 1 :: k]
        else:
            per_node, valid = self._residuals(words, mask, i0, i1, j0, j1)
            whole_per_node, whole_valid = per_node, valid
        if not whole_valid.any():
            shape = np.shape(x)  # every placement spanned is on the map (clipped to it): the holes refused them
            return PatchLikelihood(np.zeros(shape), np.zeros(shape, bool), float("nan"), weight, n, inside)
        expected = sigma / math.sqrt(2.0) * (n - 1) / n if self.form == "laplace" else sigma**2 * (n - 1) / n
        misfit = float(np.min((whole_per_node / expected)[whole_valid]))
        if self.form == "gaussian" and math.isfinite(misfit):
            misfit = math.sqrt(misfit)  # in residual units, like the Laplace form's
        read_i, read_j = np.ravel(pi - i0), np.ravel(pj - j0)  # where the candidates fall on the surface's samples
        if moved:
            # Sample (K i + K - 1 - a, K j + K - 1 - b) is placement (i - a/K, j - b/K): its sigma is placement i's.
            sigma = np.repeat(np.repeat(sigma, k, axis=0), k, axis=1) if np.ndim(sigma) else sigma
            read_i, read_j = read_i * k + (k - 1), read_j * k + (k - 1)
        ell = weight * self._log_likelihood(per_node, n, sigma, sigma_scale)
        if size > 1:
            top = float(ell[valid].max())
            mass = ndimage.uniform_filter(np.where(valid, np.exp(ell - top), 0.0), size=size, mode="constant")
            share_of_valid = ndimage.uniform_filter(valid.astype(np.float64), size=size, mode="constant")
            valid = share_of_valid > 0.5
            ell = np.log(np.maximum(mass / np.maximum(share_of_valid, 1e-12), 1e-300)) + top
        neutral = float(np.median(ell[valid]))
        value, informative = _between_placements(ell, valid, neutral, read_i, read_j, spline=size <= 1)
        log_likelihood = np.where(informative, value, neutral).reshape(np.shape(x))
        return PatchLikelihood(log_likelihood, informative.reshape(np.shape(x)), misfit, weight, n, inside)

    def _log_likelihood(self, per_node: np.ndarray, n: int, sigma: np.ndarray | float, sigma_scale: float) -> np.ndarray:
        """The untempered log-likelihood of ``n`` nodes whose mean |r| (or r**2) is ``per_node``, residual sigma ``sigma``."""
        if self.form == "laplace":
            ell = -math.sqrt(2.0) * n * per_node / (sigma * sigma_scale)
        else:
            ell = -n * per_node / (2.0 * (sigma * sigma_scale) ** 2)
        if self._node_var is not None:
            ell = ell - n * np.log(sigma)  # the normalization, which varies between placements
        return ell

    def _lattice_moved(self, patch: SonarPatch) -> dict[tuple[int, int], SonarPatch]:
        """The patch gridded on lattices moved by (a/K, b/K) of a node north and east, (a, b) != (0, 0); empty with
        ``phases`` 1 or a patch without soundings. The record's callers share them."""
        if self.phases == 1 or patch.soundings is None:
            return {}
        if self._moved is None or self._moved[0] is not patch:
            self._moved = (patch, lattice_moved(patch, self.phases))
        return self._moved[1]

    def _between_nodes(self, patch: SonarPatch, words: np.ndarray, mask: np.ndarray, moved: dict[tuple[int, int], SonarPatch],
                       span: tuple[int, int, int, int]) -> tuple[np.ndarray, np.ndarray]:
        """The mean |residual| (or residual**2) every 1/K node over ``span``'s placements (i0, i1, j0, j1), from the
        patch (``words``, ``mask``) and its lattice-moved grids, and which samples are valid: sample
        (K i + K - 1 - a, K j + K - 1 - b) is placement (i - a/K, j - b/K) of the patch, i and j counted from the span's
        first. A moved grid holding under half the patch's nodes is left out (its samples not valid).

        A record's filters ask for the same patch in turn: the samples are kept for the last patch and a request
        inside the span already computed is a slice of it; one beyond it is computed over the union.
        """
        k = self.phases
        requested = span
        if self._fine is not None and self._fine[0] is patch:
            (c0, c1, d0, d1), (i0, i1, j0, j1) = self._fine[1], span
            if c0 <= i0 and i1 <= c1 and d0 <= j0 and j1 <= d1:
                return self._kept_samples(span)
            span = (min(c0, i0), max(c1, i1), min(d0, j0), max(d1, j1))
        i0, i1, j0, j1 = span
        n = int(mask.sum())
        fine = np.zeros(((i1 - i0 + 1) * k, (j1 - j0 + 1) * k))
        fine_valid = np.zeros(fine.shape, bool)
        fine[k - 1 :: k, k - 1 :: k], fine_valid[k - 1 :: k, k - 1 :: k] = self._residuals(words, mask, *span)
        for (a, b), grid in moved.items():
            moved_words, moved_mask, _ = self._prep.quantize_patch(grid.depth_m)
            if int(moved_mask.sum()) < max(2, n // 2):
                continue  # too few of the soundings fall inside this lattice's nodes to stand for the patch
            # Each moved grid counts as the patch's own n nodes: the mean residual over its nodes times n.
            fine[k - 1 - a :: k, k - 1 - b :: k], fine_valid[k - 1 - a :: k, k - 1 - b :: k] = self._residuals(
                moved_words, moved_mask, *span, line=(a, b))
        self._fine = (patch, span, fine, fine_valid)
        return self._kept_samples(requested)

    def _kept_samples(self, span: tuple[int, int, int, int]) -> tuple[np.ndarray, np.ndarray]:
        """The kept samples (and their validity) of ``span``'s placements, a span inside the one kept."""
        k, (c0, _, d0, _), kept, kept_valid = self.phases, *self._fine[1:]
        i0, i1, j0, j1 = span
        rows, cols = slice(k * (i0 - c0), k * (i1 - c0 + 1)), slice(k * (j0 - d0), k * (j1 - d0 + 1))
        return kept[rows, cols], kept_valid[rows, cols]

    def margin(self, centre_m: np.ndarray, patch: SonarPatch, *, radius_m: float, exclusion_m: float) -> float:
        """How much better the patch fits near ``centre_m`` than anywhere else within ``radius_m``.

        The best log-likelihood (untempered, per valid node) within ``exclusion_m`` (Chebyshev) of the
        centre, minus the best beyond it and within ``radius_m``; on the map's placements, holes
        excluded. Near zero or negative: the terrain looks alike elsewhere, and following one mode
        would be a guess. NaN when either region has no valid placement.
        """
        grid, prep = self._grid, self._prep
        words, mask, _ = prep.quantize_patch(patch.depth_m)
        n = int(mask.sum())
        h, w = words.shape
        rows, cols = grid.shape
        if n < 2 or h > rows or w > cols:
            return float("nan")
        row, col = grid.row_col(centre_m[0] + patch.centre_offset_m[0], centre_m[1] + patch.centre_offset_m[1])
        ci, cj = float(row) - (h - 1) / 2, float(col) - (w - 1) / 2
        reach = radius_m / grid.node_m
        i0, i1 = max(int(np.floor(ci - reach)), 0), min(int(np.ceil(ci + reach)), rows - h)
        j0, j1 = max(int(np.floor(cj - reach)), 0), min(int(np.ceil(cj + reach)), cols - w)
        if i0 > i1 or j0 > j1:
            return float("nan")
        per_node, valid = self._residuals(words, mask, i0, i1, j0, j1)
        if self.form == "gaussian":
            per_node = np.sqrt(per_node)
        score = np.where(valid, -per_node / self._placement_sigma((h, w), i0, i1, j0, j1), -np.inf)  # per valid node, nominal units
        # Near: the placements within exclusion_m (Chebyshev) of the centre, a rectangle of the region.
        e = exclusion_m / grid.node_m
        r0, r1 = max(math.ceil(ci - e - 1e-9), i0) - i0, min(math.floor(ci + e + 1e-9), i1) - i0 + 1
        c0, c1 = max(math.ceil(cj - e - 1e-9), j0) - j0, min(math.floor(cj + e + 1e-9), j1) - j0 + 1
        if r0 >= r1 or c0 >= c1:
            return float("nan")
        near = float(score[r0:r1, c0:c1].max())
        score[r0:r1, c0:c1] = -np.inf
        far = float(score.max())
        if not (math.isfinite(near) and math.isfinite(far)):
            return float("nan")
        return near - far

    def independent_share(self, centre_m: np.ndarray, patch: SonarPatch) -> float:
        """The share of a patch's nodes whose residuals are independent, N_eff / n, at the placement nearest ``centre_m``.

        A survey map's error is correlated over the patch (line offsets, drift, refraction, gridding, relief
        under a node) and so is a real-time patch's (soundings placed by dead reckoning): the residuals of
        neighbouring nodes are alike, and a log-likelihood summed over n nodes as if independent is about
        n / N_eff times too peaked. For residuals correlated as a separable first-order autoregression with
        lag-one correlations rho_x, rho_y, ``N_eff / n = (1 - rho_x) / (1 + rho_x) * (1 - rho_y) / (1 + rho_y)``
        (the variance of a mean of such a series). Measured at the true place: about 0.6 on ``short``'s
        map = floor, 0.5 on its 30 m survey map, 0.09-0.11 on ``shelf_canyon`` and ``seamount_ridges``.
        Bounded to [``MIN_INDEPENDENT_SHARE``, 1]; NaN where the placement leaves the map or has too few valid
        neighbour pairs.
        """
        grid = self._grid
        depth = np.asarray(patch.depth_m, float)
        h, w = depth.shape
        row, col = grid.row_col(centre_m[0] + patch.centre_offset_m[0], centre_m[1] + patch.centre_offset_m[1])
        i, j = int(round(float(row) - (h - 1) / 2)), int(round(float(col) - (w - 1) / 2))
        rows, cols = grid.shape
        if not (0 <= i <= rows - h and 0 <= j <= cols - w):
            return float("nan")
        residual = grid.depth_m[i : i + h, j : j + w] - depth
        valid = np.isfinite(residual)
        if valid.sum() < 3 * max(h, w):
            return float("nan")
        # The estimate lies a fraction of a node from the placement: that misplacement is the map's slope times a
        # position error, correlated over the patch but not the map's error. Taken out by least squares on the
        # map's gradients (with the mean), what is left is the residual whose correlation counts.
        r0, c0 = max(i - 1, 0), max(j - 1, 0)
        grad_y, grad_x = np.gradient(grid.depth_m[r0 : i + h + 1, c0 : j + w + 1])  # NaN next to a hole: such nodes leave the fit
        grad_y, grad_x = (g[i - r0 : i - r0 + h, j - c0 : j - c0 + w] for g in (grad_y, grad_x))
        valid &= np.isfinite(grad_x) & np.isfinite(grad_y)
        if valid.sum() < 3 * max(h, w):
            return float("nan")
        design = np.stack([np.ones(int(valid.sum())), grad_x[valid], grad_y[valid]])
        try:
            fit = np.linalg.solve(design @ design.T + 1e-9 * np.eye(3), design @ residual[valid])
        except np.linalg.LinAlgError:
            return float("nan")
        residual = np.where(valid, residual, 0.0)
        residual[valid] -= fit @ design
        share = 1.0
        for axis in (0, 1):
            a, b = np.moveaxis(residual, axis, 0), np.moveaxis(valid, axis, 0)
            pair = b[1:] & b[:-1]
            x, y = a[1:][pair], a[:-1][pair]
            scale = math.sqrt(float(np.sum(x * x) * np.sum(y * y)))
            if pair.sum() < max(h, w) or scale <= 0.0:
                return float("nan")
            rho = min(max(float(np.sum(x * y)) / scale, 0.0), 0.99)
            share *= (1.0 - rho) / (1.0 + rho)
        return max(share, MIN_INDEPENDENT_SHARE)

    def _residuals(self, words: np.ndarray, mask: np.ndarray, i0: int, i1: int, j0: int, j1: int, *,
                   line: object = None) -> tuple[np.ndarray, np.ndarray]:
        """Over placements i0..i1 x j0..j1: the mean |residual| (Laplace, from the correlator) or mean residual**2
        (Gaussian, on the host), metres, and which placements are valid (the map's holes). ``line``: which of the
        record's patches (None: its own; a moved lattice's (a, b))."""
        prep = self._prep
        n = int(mask.sum())
        if self.form == "laplace":
            surface, valid = prep.surface(words, mask, (i0, j0, i1 - i0 + 1, j1 - j0 + 1), backend=self._backend, line=line)
            return surface.astype(np.float64) * prep.lsb_m / float(n) ** 2, valid
        h, w = words.shape
        valid = ~prep.placements_touching_holes((h, w), (i0, j0, i1 - i0 + 1, j1 - j0 + 1), mask)
        sub = prep.words[i0 : i1 + h, j0 : j1 + w]
        m = sub.astype(np.float64) * prep.lsb_m
        s = np.where(mask, words.astype(np.float64) * prep.lsb_m, 0.0)
        k = mask.astype(np.float64)
        sum_m = signal.correlate(m, k, mode="valid")
        sum_m2 = signal.correlate(m * m, k, mode="valid")
        sum_ms = signal.correlate(m, s, mode="valid")
        sum_s, sum_s2 = s.sum(), (s * s).sum()
        sum_d = sum_m - sum_s
        sum_d2 = sum_m2 - 2.0 * sum_ms + sum_s2
        return np.maximum(sum_d2 - sum_d**2 / n, 0.0) / n, valid

    def depth_residual(self, x_m: np.ndarray, y_m: np.ndarray, ocean_depth_m: float) -> tuple[np.ndarray, np.ndarray]:
        """The measured ocean depth minus the map's at each (x, y) (bilinear), and where the map informs it.

        Off the map or next to a hole the residual is 0 and not informative.
        """
        grid = self._grid
        row, col = grid.row_col(np.asarray(x_m, float), np.asarray(y_m, float))
        coords = np.stack([np.ravel(row), np.ravel(col)])
        depth = ndimage.map_coordinates(grid.depth_m, coords, order=1, mode="constant", cval=np.nan).reshape(np.shape(row))
        informative = np.isfinite(depth)
        return np.where(informative, ocean_depth_m - np.where(informative, depth, 0.0), 0.0), informative
