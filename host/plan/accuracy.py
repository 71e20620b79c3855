"""How well the correlator can fix a position anywhere on a map: the Cramer-Rao bound of a patch centred at each node.

A sonar patch of ``h x w`` beams measures ``z_k = m(p_k + x) + d + e_k`` at its nodes ``p_k``: the map ``m`` shifted by
the position error ``x``, plus a depth offset ``d`` (the tide, the vehicle's depth error: the correlator's mean
compensation removes it) and noise ``e_k`` of variance ``s_k^2 = sigma_sonar^2 + sigma_map,k^2`` (the sonar's noise and
the map's own uncertainty at that node). The Fisher information of ``x`` with ``d`` unknown (the Schur complement of
the offset) is

    I = sum_k g_k g_k^T / s_k^2  -  (sum_k g_k / s_k^2)(sum_k g_k / s_k^2)^T / (sum_k 1 / s_k^2),

``g_k`` the map's gradient at ``p_k``: a plane's slope tells nothing, since shifting along it looks like an offset.
The bound on the horizontal error is ``sqrt(trace(I^-1))`` (Nygren 2002, eq. 5.1; eq. 5.2 is its value for an AR(1)
profile, which ``lost.host.nav.theory`` checks by Monte Carlo). Every sum is a box filter over the patch, so a
2000 x 2000 map takes seconds. A node whose patch touches a hole, or whose information is singular (a flat or
uniformly sloping patch), has no bound (infinity).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from ..grid import Grid

__all__ = ["SonarModel", "accuracy_grid", "held_grid", "information", "map_sigma", "survey_sigma", "held_sigma"]


@dataclass(frozen=True, kw_only=True)
class SonarModel:
    """What the planner assumes of the sonar: the patch (nodes of the map), its depth noise (1 sigma, metres), and whether
    its patch is a swath binned into the map's cells (``binned``, as ``lost.host.io.sonar`` grids soundings: each node the
    mean of its cell's soundings) or sampled at points (a simulator's ``gridded`` patch); ``realtime``: the patch of an
    update holds only the pings received by then, centred half its diagonal behind the vehicle (:meth:`lag_m`).
    ``soundings_per_node``: how many soundings a binned node averages (:attr:`node_noise_m`); ``noise_m`` stays the
    weight the bound gives a node, as the filters' likelihood takes a node at a sounding's noise or more."""

    shape: tuple[int, int] = (10, 10)
    noise_m: float = 0.5
    binned: bool = True
    realtime: bool = False
    soundings_per_node: float = 1.0

    @property
    def node_noise_m(self) -> float:
        """The sonar's own error of a patch node: a binned node is the mean of its soundings, a sampled one a sounding."""
        return self.noise_m / np.sqrt(self.soundings_per_node) if self.binned else self.noise_m

    def lag_m(self, node_m: float) -> float:
        """How far behind the vehicle its patch is centred, metres: half the patch's diagonal for a real-time patch (the
        latest earlier position that far back, as ``lost.host.scenario`` and a live survey gather it), else 0."""
        return float(np.hypot(*self.shape) * node_m / 2.0) if self.realtime else 0.0

    def __post_init__(self) -> None:
        if len(self.shape) != 2 or min(self.shape) < 2:
            raise ValueError(f"the sonar patch needs at least 2 x 2 nodes, got {self.shape!r}")
        if not (np.isfinite(self.noise_m) and self.noise_m > 0):
            raise ValueError(f"the sonar's noise must be a positive number of metres, got {self.noise_m!r}")
        if not (np.isfinite(self.soundings_per_node) and self.soundings_per_node >= 1):
            raise ValueError(f"a patch node averages at least one sounding, got soundings_per_node = {self.soundings_per_node!r}")


def _survey_sigma_given(survey_sigma_m: float | np.ndarray | None) -> float | np.ndarray:
    """``survey_sigma_m``, or the navigation's default (``NavParameters.survey_sigma_m``) when None."""
    from ..nav.parameters import NavParameters

    return NavParameters().survey_sigma_m if survey_sigma_m is None else survey_sigma_m


def survey_sigma(grid: Grid, survey_sigma_m: float | np.ndarray | None = None) -> np.ndarray | float:
    """The survey's 1-sigma error at every node: the grid's ``sigma_m`` when it carries one (its holes the median of the
    rest), else ``survey_sigma_m``, else NavParameters' default."""
    survey = getattr(grid, "sigma_m", None)
    if survey is None:
        return _survey_sigma_given(survey_sigma_m)
    return np.where(np.isfinite(survey), survey, np.nanmedian(survey) if np.isfinite(survey).any() else 0.0)


def held_sigma(grid: Grid, sonar: SonarModel, survey_sigma_m: float | np.ndarray | None = None) -> np.ndarray:
    """The error of each node's depth against the sonar's patch there, as it biases a held position (not the filters'
    allowance: no term for the slope the filters cannot place, which is their density's width, not their error).

    A gridded layer's ``sigma_m`` is its soundings' spread in the cell. A patch sampled at points (``sonar.binned`` False)
    sees that whole spread against the cell's mean. A swath binned into cells (``sonar.binned``) is the mean of its own
    soundings of the cell, as the node is of the survey's: the spread (the floor's relief within the cell, each
    sounding's noise) averages out of both means, and what remains is the survey's error common to a cell's soundings
    (a line's offset and drift, the refraction of its outer beams), which the layer does not carry: the survey's one
    sigma stands for it (``survey_sigma_m``, the navigation's), with the relief the node cannot show. A map without a
    layer: the survey's one sigma (:func:`survey_sigma`) and the relief.
    """
    from ..nav.maperror import node_terms

    survey = np.asarray(survey_sigma(grid, survey_sigma_m), np.float64)
    _, relief, _ = node_terms(grid.depth_m, grid.node_m)
    if getattr(grid, "sigma_m", None) is None:
        return np.sqrt(survey**2 + relief)
    if not sonar.binned:
        return np.broadcast_to(survey, grid.shape).copy()
    common = np.asarray(_survey_sigma_given(survey_sigma_m), np.float64)
    return np.broadcast_to(np.sqrt(common**2 + relief), grid.shape).copy()


def map_sigma(grid: Grid, survey_sigma_m: float | np.ndarray | None = None) -> np.ndarray:
    """The map's own 1-sigma error at every node, as the filters' likelihood takes it (``lost.host.nav.maperror``): the
    survey's (:func:`survey_sigma`), the slope the node cannot place and the relief it cannot show."""
    from ..nav.maperror import node_variance

    return np.sqrt(node_variance(grid.depth_m, grid.node_m, survey_sigma(grid, survey_sigma_m)))


def _box(values: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The sum over the ``shape`` patch centred at each node (zero beyond the map's edge)."""
    return ndimage.uniform_filter(values, size=shape, mode="constant", cval=0.0) * (shape[0] * shape[1])


def information(grid: Grid, sonar: SonarModel, map_sigma_m: np.ndarray | float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The Fisher information of the position (``I_xx``, ``I_xy``, ``I_yy``, per square metre) at every node, and where it is defined.

    ``map_sigma_m`` is the map's 1-sigma uncertainty per node (an array of the grid's shape) or one number.
    """
    depth = grid.depth_m
    sigma = np.broadcast_to(np.asarray(map_sigma_m, dtype=np.float64), depth.shape)
    if not np.all(np.isfinite(sigma[np.isfinite(depth)])) or np.any(sigma < 0):
        raise ValueError("the map's uncertainty must be a finite, non-negative number of metres at every node with a depth")
    holes = ~np.isfinite(depth)
    filled = np.where(holes, np.nanmean(depth) if np.isfinite(depth).any() else 0.0, depth)
    gy, gx = np.gradient(filled, grid.node_m)  # rows are northings, columns eastings
    weight = np.where(holes, 0.0, 1.0 / (sonar.noise_m**2 + sigma**2))
    shape = sonar.shape
    w = _box(weight, shape)
    sx, sy = _box(weight * gx, shape), _box(weight * gy, shape)
    with np.errstate(invalid="ignore", divide="ignore"):
        ixx = _box(weight * gx * gx, shape) - sx * sx / w
        iyy = _box(weight * gy * gy, shape) - sy * sy / w
        ixy = _box(weight * gx * gy, shape) - sx * sy / w
    touched = _box(holes.astype(np.float64), shape) > 0.5
    inside = np.zeros(depth.shape, dtype=bool)
    h, wd = shape
    inside[h // 2: depth.shape[0] - (h - 1 - h // 2), wd // 2: depth.shape[1] - (wd - 1 - wd // 2)] = True
    return ixx, ixy, iyy, inside & ~touched


def held_grid(grid: Grid, sonar: SonarModel, weight_sigma_m: np.ndarray | float, error_sigma_m: np.ndarray | float) -> Grid:
    """The 1-sigma horizontal error (metres) of the position one patch centred at each node gives a filter that weighs its
    nodes by ``weight_sigma_m`` (the map's error as its likelihood takes it, :func:`map_sigma`) where the errors truly
    have ``error_sigma_m`` (:func:`held_sigma`), both beside the sonar's noise.

    The weighted least-squares fit of the shift and the depth offset with weights ``w_k = 1 / (s^2 + weight_k^2)`` has the
    covariance ``M^-1 N M^-1`` (the sandwich): ``M`` the information of :func:`information` with those weights and
    ``N = sum_k w_k^2 v_k c_k c_k^T``, ``v_k = n^2 + error_k^2`` the true variance (``n`` the node's own sonar noise,
    :attr:`SonarModel.node_noise_m`: a binned node averages its soundings' noise) and ``c_k = g_k - sum w g / sum w`` the
    gradient less its weighted mean (the offset taken out). With the weights the errors' own (and a node of one sounding) it
    is :func:`accuracy_grid`'s bound; where the filters weigh steep nodes down for the slope they cannot place, the shift rests on the flatter
    nodes and is worse than the bound of the errors alone. Infinity where :func:`accuracy_grid` has no bound.

    Raises
    ------
    ValueError
        Either sigma not a finite, non-negative number of metres at a node with a depth.
    """
    depth = grid.depth_m
    holes = ~np.isfinite(depth)
    weight_sigma = np.broadcast_to(np.asarray(weight_sigma_m, dtype=np.float64), depth.shape)
    error_sigma = np.broadcast_to(np.asarray(error_sigma_m, dtype=np.float64), depth.shape)
    if not np.all(np.isfinite(error_sigma[~holes])) or np.any(error_sigma < 0):
        raise ValueError("the map's error against the patch must be a finite, non-negative number of metres at every node with a depth")
    error_var = sonar.node_noise_m**2 + error_sigma**2
    filled = np.where(holes, np.nanmean(depth) if (~holes).any() else 0.0, depth)
    gy, gx = np.gradient(filled, grid.node_m)
    weight = np.where(holes, 0.0, 1.0 / (sonar.noise_m**2 + weight_sigma**2))
    spread = np.where(holes, 0.0, weight**2 * error_var)
    ixx, ixy, iyy, defined = information(grid, sonar, weight_sigma)
    shape = sonar.shape
    with np.errstate(invalid="ignore", divide="ignore"):
        total = _box(weight, shape)
        mx, my = _box(weight * gx, shape) / total, _box(weight * gy, shape) / total  # the weighted mean gradient
        ux, uy, uu = _box(spread * gx, shape), _box(spread * gy, shape), _box(spread, shape)
        nxx = _box(spread * gx * gx, shape) - 2.0 * mx * ux + mx * mx * uu
        nyy = _box(spread * gy * gy, shape) - 2.0 * my * uy + my * my * uu
        nxy = _box(spread * gx * gy, shape) - mx * uy - my * ux + mx * my * uu
        det = ixx * iyy - ixy * ixy
        scale = np.maximum(ixx + iyy, 1e-300)
        ok = defined & np.isfinite(det) & (det > 1e-12 * scale * scale)
        # M^-1 = [[iyy, -ixy], [-ixy, ixx]] / det: the trace of M^-1 N M^-1 written out
        trace = ((iyy * iyy + ixy * ixy) * nxx - 2.0 * ixy * (iyy + ixx) * nxy + (ixy * ixy + ixx * ixx) * nyy) / (det * det)
    held = np.full(grid.shape, np.inf)
    held[ok] = np.sqrt(np.maximum(trace[ok], 0.0))
    return Grid(depth_m=held, x0_m=grid.x0_m, y0_m=grid.y0_m, node_m=grid.node_m, crs=grid.crs)


def accuracy_grid(grid: Grid, sonar: SonarModel, map_sigma_m: np.ndarray | float = 0.0) -> Grid:
    """The predicted 1-sigma horizontal error (metres) of one correlation centred at each node: ``sqrt(trace(I^-1))``.

    Infinity where the patch leaves the map, touches a hole, or sees terrain that fixes no position (flat or a plane).
    """
    ixx, ixy, iyy, defined = information(grid, sonar, map_sigma_m)
    with np.errstate(invalid="ignore"):  # inside a hole wider than the patch the sums are undefined (no bound there)
        det = ixx * iyy - ixy * ixy
        scale = np.maximum(ixx + iyy, 1e-300)
    ok = defined & np.isfinite(det) & (det > 1e-12 * scale * scale)
    accuracy = np.full(grid.shape, np.inf)
    accuracy[ok] = np.sqrt((ixx[ok] + iyy[ok]) / det[ok])
    return Grid(depth_m=accuracy, x0_m=grid.x0_m, y0_m=grid.y0_m, node_m=grid.node_m, crs=grid.crs)
