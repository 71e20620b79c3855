"""The golden model of the terrain correlator: the executable specification.

The correlation of a sonar patch ``S`` (``h x w``, optional valid mask) against a terrain map ``M``
(``H x W``) is the surface ``V`` over every placement ``(i, j)`` that keeps the patch inside the map,
shape ``(H - h + 1, W - w + 1)``, ``(i, j)`` being the map node under the patch's top-left node. With
``n`` the number of valid patch nodes:

* without mean compensation: ``V(i, j) = sum_valid |M[i+k, j+l] - S[k, l]|``
* with mean compensation (Nygren eq. 8.1 made exact)::

      V(i, j) = sum_valid | n * (M[i+k, j+l] - S[k, l]) - (sum_valid M[i+., j+.] - sum_valid S) |

  which is ``n`` times the sum of absolute differences of the mean-removed depths, with no division
  and no rounding.

This module is deliberately plain: one ``numpy`` slice per patch node, int64 throughout, so that it can
be audited against the definition line by line. Speed lives beside it, in ``lost.host``; every backend
and every hardware variant must return these integers bit for bit. The bit widths every intermediate
needs are derived in :mod:`lost.model.widths`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "DEPTH_MIN",
    "DEPTH_MAX",
    "BestFit",
    "Placement",
    "best_fit",
    "check_inputs",
    "correlate",
]

# The hardware's map and patch words are 16-bit two's complement.
DEPTH_MIN = -(2**15)
DEPTH_MAX = 2**15 - 1


def _check_depth_array(name: str, array: np.ndarray) -> None:
    if not isinstance(array, np.ndarray):
        raise ValueError(f"{name} must be a numpy array, got {type(array).__name__}")
    if array.ndim != 2:
        raise ValueError(f"{name} must be 2-D, got {array.ndim}-D with shape {array.shape}")
    if array.dtype.kind not in "iu":
        raise ValueError(
            f"{name} must be an integer array (int16 depth words), got dtype {array.dtype}; "
            "quantize metres with lost.model.quantize first"
        )
    if array.size == 0:
        raise ValueError(f"{name} is empty (shape {array.shape})")
    if array.dtype.itemsize >= 2 and array.dtype != np.int16:
        lo, hi = int(array.min()), int(array.max())
        if lo < DEPTH_MIN or hi > DEPTH_MAX:
            raise ValueError(
                f"{name} has values in [{lo}, {hi}], outside the 16-bit depth word "
                f"[{DEPTH_MIN}, {DEPTH_MAX}]"
            )


def check_inputs(
    terrain: np.ndarray, patch: np.ndarray, mask: np.ndarray | None, mean_compensation: bool = True
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validate correlator inputs; return them as ``int16`` terrain, ``int16`` patch, ``bool`` mask.

    Every correlator backend calls this, so that all of them refuse the same inputs with the same
    message.

    Raises
    ------
    ValueError
        Non-array or non-2-D inputs, a non-integer dtype, values outside the 16-bit depth word, a patch
        larger than the map, a mask that is not boolean or not of the patch's shape, a mask with no
        valid node, a ``mean_compensation`` that is not a boolean (``"False"`` or ``None`` would
        otherwise pick a mode by truthiness).
    """
    if not isinstance(mean_compensation, bool | np.bool_):
        raise ValueError(
            f"mean_compensation must be True or False, got {mean_compensation!r} ({type(mean_compensation).__name__}); "
            "it is not taken by truthiness"
        )
    _check_depth_array("terrain", terrain)
    _check_depth_array("patch", patch)
    (H, W), (h, w) = terrain.shape, patch.shape
    if h > H or w > W:
        raise ValueError(f"patch of shape {patch.shape} is larger than the terrain map of shape {terrain.shape}")
    if mask is None:
        mask = np.ones(patch.shape, dtype=bool)
    else:
        if not isinstance(mask, np.ndarray):
            raise ValueError(f"mask must be a numpy array, got {type(mask).__name__}")
        if mask.dtype != np.bool_:
            raise ValueError(f"mask must be a boolean array, got dtype {mask.dtype}")
        if mask.shape != patch.shape:
            raise ValueError(f"mask has shape {mask.shape}, but the patch has shape {patch.shape}")
        if not mask.any():
            raise ValueError("mask has no valid node: there is nothing to correlate")
    return terrain.astype(np.int16, copy=False), patch.astype(np.int16, copy=False), mask


def correlate(
    terrain: np.ndarray,
    patch: np.ndarray,
    *,
    mask: np.ndarray | None = None,
    mean_compensation: bool = True,
) -> np.ndarray:
    """Correlate a sonar patch against a terrain map, exactly.

    Parameters
    ----------
    terrain : (H, W) integer array
        The map, in 16-bit depth words.
    patch : (h, w) integer array
        The sonar patch, in the same depth words; ``h <= H`` and ``w <= W``.
    mask : (h, w) bool array, optional
        The valid patch nodes; all nodes when omitted.
    mean_compensation : bool
        Remove the mean depth of map window and patch before comparing (Nygren eq. 8.1), scaled by
        ``n`` so that the result stays an exact integer.

    Returns
    -------
    (H - h + 1, W - w + 1) int64 array
        The surface ``V``; its smallest value is the best fit.

    Raises
    ------
    ValueError
        See :func:`check_inputs`.
    """
    terrain, patch, mask = check_inputs(terrain, patch, mask, mean_compensation)
    M = terrain.astype(np.int64)
    S = patch.astype(np.int64)
    (H, W), (h, w) = M.shape, S.shape
    rows, cols = H - h + 1, W - w + 1
    nodes = list(zip(*np.nonzero(mask)))

    def window(k: int, l: int) -> np.ndarray:
        """M[i + k, j + l] for every placement (i, j)."""
        return M[k : k + rows, l : l + cols]

    V = np.zeros((rows, cols), dtype=np.int64)
    if not mean_compensation:
        for k, l in nodes:
            V += np.abs(window(k, l) - S[k, l])
        return V

    n = len(nodes)
    window_sum = np.zeros((rows, cols), dtype=np.int64)
    for k, l in nodes:
        window_sum += window(k, l)
    patch_sum = sum(S[k, l] for k, l in nodes)
    for k, l in nodes:
        V += np.abs(n * (window(k, l) - S[k, l]) - (window_sum - patch_sum))
    return V


@dataclass(frozen=True)
class Placement:
    """One placement of the patch on the map and its correlation value."""

    i: int
    j: int
    value: int


@dataclass(frozen=True)
class BestFit:
    """The best fit of a surface and the runner-up outside its exclusion radius.

    Attributes
    ----------
    i, j, value : int
        The smallest value of ``V`` and its placement, the first in raster order on ties.
    runner_up : Placement or None
        The smallest value among placements farther than ``exclusion_radius`` from the best fit in
        Chebyshev distance (``max(|di|, |dj|) > exclusion_radius``), first in raster order on ties;
        ``None`` when the radius covers the whole surface. It measures ambiguity: a runner-up close
        in value to the best fit means the terrain matches nearly as well elsewhere.
    exclusion_radius : int
        The radius the runner-up was searched outside of, in map nodes.
    """

    i: int
    j: int
    value: int
    runner_up: Placement | None
    exclusion_radius: int

    @property
    def best(self) -> Placement:
        return Placement(self.i, self.j, self.value)


def best_fit(surface: np.ndarray, *, exclusion_radius: int = 1) -> BestFit:
    """Find the best fit (smallest value, first in raster order) and the runner-up of a surface.

    Parameters
    ----------
    surface : 2-D integer array
        A correlation surface ``V``.
    exclusion_radius : int
        Placements within this Chebyshev distance of the best fit are not runner-up candidates; ``0``
        excludes only the best fit itself.

    Raises
    ------
    ValueError
        A surface that is not a non-empty 2-D integer array, or a negative radius.
    """
    if not isinstance(surface, np.ndarray) or surface.ndim != 2 or surface.size == 0:
        raise ValueError("surface must be a non-empty 2-D numpy array")
    if surface.dtype.kind not in "iu":
        raise ValueError(f"surface must be an integer array, got dtype {surface.dtype}")
    if isinstance(exclusion_radius, bool) or not isinstance(exclusion_radius, (int, np.integer)) or exclusion_radius < 0:
        raise ValueError(f"exclusion_radius must be a non-negative integer, got {exclusion_radius!r}")
    r = int(exclusion_radius)
    # argmin on the C-ordered flat array returns the first minimum in raster order.
    i, j = np.unravel_index(int(np.argmin(surface)), surface.shape)
    rows, cols = np.indices(surface.shape)
    outside = np.maximum(np.abs(rows - i), np.abs(cols - j)) > r
    runner_up = None
    if outside.any():
        # Indices ascend, so argmin over the candidates keeps raster order on ties.
        flat = np.flatnonzero(outside.ravel())
        k = flat[int(np.argmin(surface.ravel()[flat]))]
        ri, rj = np.unravel_index(int(k), surface.shape)
        runner_up = Placement(int(ri), int(rj), int(surface[ri, rj]))
    return BestFit(int(i), int(j), int(surface[i, j]), runner_up, r)
