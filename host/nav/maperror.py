"""The map's own error at every node: what a patch node sees of the map besides the true floor.

A map node is not the floor under it. Three things part them, and each is estimated per node:

- survey noise: the sounding error left in the gridded depth. A grid's own per-node standard deviation
  is used when it carries one (a gridding tool's or a BAG's uncertainty layer); otherwise one number,
  ``survey_sigma_m``.
- the slope the node cannot place: the correlator compares a patch node with map nodes at whole-node
  placements, and the vehicle lies a fraction of a node from one. Over an offset uniform within half a
  node each way, a slope s misplaces the depth by s * L / sqrt(12) per axis (L the node spacing).
- the relief the node cannot show: a map node is a cell's mean (and interpolation runs straight between
  nodes), so the floor's curvature within the cell is lost: about |laplacian| * L**2 / 16, the
  bilinear interpolation error of a quadratic surface at mid-cell, halved over the cell.

Slope and curvature come from the map itself, by central differences at its own scale, so a smooth shelf
gets a small error and a canyon wall a large one. The likelihood (:mod:`lost.host.nav.likelihood`) takes,
for each placement, the mean of these variances over the patch's window plus the sonar's own noise:
its scale follows the terrain under the patch, not one number for the run.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

__all__ = ["node_terms", "node_variance", "check_node_sigma", "window_variance"]


def check_node_sigma(node_sigma_m: np.ndarray, depth_m: np.ndarray) -> np.ndarray:
    """A per-node standard deviation layer, checked against its map: float array, map's shape, >= 0, finite on every depth node.

    Raises
    ------
    ValueError
        Naming the problem: not an array of numbers, another shape than the map's, a negative value,
        a NaN or infinite value where the map has a depth (NaN is accepted on the map's holes).
    """
    sigma = np.asarray(node_sigma_m)
    if sigma.dtype.kind not in "fiu":
        raise ValueError(f"the map's uncertainty layer must hold numbers (metres), got dtype {sigma.dtype}")
    sigma = sigma.astype(np.float64)
    if sigma.shape != depth_m.shape:
        raise ValueError(f"the map's uncertainty layer is {sigma.shape[0] if sigma.ndim else 0} x "
                         f"{sigma.shape[1] if sigma.ndim > 1 else 0} nodes but its depth grid {depth_m.shape[0]} x {depth_m.shape[1]}"
                         if sigma.ndim == 2 else f"the map's uncertainty layer must be 2-D like its depth grid {depth_m.shape}, got shape {sigma.shape}")
    has_depth = np.isfinite(depth_m)
    bad = has_depth & ~np.isfinite(sigma)
    if bad.any():
        r, c = (int(v[0]) for v in np.nonzero(bad))
        raise ValueError(f"the map's uncertainty layer has {int(bad.sum())} NaN or infinite value(s) on nodes with a depth "
                         f"(first at row {r}, column {c}); a node without a sigma needs one, or no depth")
    negative = np.isfinite(sigma) & (sigma < 0)
    if negative.any():
        r, c = (int(v[0]) for v in np.nonzero(negative))
        raise ValueError(f"the map's uncertainty layer has {int(negative.sum())} negative standard deviation(s) "
                         f"(first {float(sigma[r, c])!r} m at row {r}, column {c})")
    return np.where(has_depth, sigma, 0.0)


def node_terms(depth_m: np.ndarray, node_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The two terms of each node's map error the map itself gives, m**2: the slope the node cannot place and the relief
    it cannot show (see the module docstring); and the map's holes, where the nearest depth stands in."""
    depth = np.asarray(depth_m, np.float64)
    holes = ~np.isfinite(depth)
    if holes.any():
        # Nearest depth at holes, so that differences next to them stay finite (their placements are not valid anyway).
        nearest = ndimage.distance_transform_edt(holes, return_distances=False, return_indices=True)
        depth = depth[tuple(nearest)]
    if min(depth.shape) >= 3:
        grad_y, grad_x = np.gradient(depth, node_m)
        # Second differences of the first: exact for a plane up to the edges (one-sided there), and for a quadratic inside.
        laplacian = np.gradient(grad_x, node_m, axis=1) + np.gradient(grad_y, node_m, axis=0)
    else:
        grad_y = grad_x = laplacian = np.zeros_like(depth)
    return (grad_x**2 + grad_y**2) * node_m**2 / 12.0, (laplacian * node_m**2 / 16.0) ** 2, holes


def node_variance(depth_m: np.ndarray, node_m: float, survey_sigma_m: float | np.ndarray) -> np.ndarray:
    """Each node's map error variance, m**2 (see the module docstring); holes get the median of the rest."""
    slope_var, relief_var, holes = node_terms(depth_m, node_m)
    variance = np.asarray(survey_sigma_m, np.float64) ** 2 + slope_var + relief_var
    variance = np.broadcast_to(variance, holes.shape).copy()
    if holes.any() and (~holes).any():
        variance[holes] = float(np.median(variance[~holes]))
    return variance


def window_variance(node_var_m2: np.ndarray, patch_shape: tuple[int, int]) -> np.ndarray:
    """The mean node variance under an h x w window at every placement, shape (H - h + 1, W - w + 1)."""
    h, w = patch_shape
    prefix = np.zeros((node_var_m2.shape[0] + 1, node_var_m2.shape[1] + 1))
    prefix[1:, 1:] = np.cumsum(np.cumsum(node_var_m2, axis=0), axis=1)
    total = prefix[h:, w:] - prefix[:-h, w:] - prefix[h:, :-w] + prefix[:-h, :-w]
    return np.maximum(total / (h * w), 0.0)


def uniform_equivalent(node_var_m2: np.ndarray) -> float:
    """The one sigma (m) that stands for a per-node variance layer: the root of its median."""
    return math.sqrt(float(np.median(node_var_m2)))
