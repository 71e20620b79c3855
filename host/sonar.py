"""Sonar soundings around the vehicle, gridded into the patch the correlator matches.

A swath or multibeam sonar returns soundings scattered around the vehicle: for each, its east and
north offset from the vehicle (metres, grid axes) and the sea-floor depth there. :func:`grid_soundings`
bins them onto the ``h x w`` nodes of a :class:`~lost.host.records.SonarPatch` centred on the vehicle:

- node ``(k, l)`` sits at north offset ``(k - (h - 1) / 2) * node_m`` and east offset
  ``(l - (w - 1) / 2) * node_m`` (row grows north, column east, like the map);
- a sounding belongs to the node nearest to it (a half-node tie goes to the higher index);
- a node's depth is the mean of its soundings; a node no beam reached is NaN (never interpolated,
  so the correlator's valid mask says exactly where the sonar saw the floor);
- soundings beyond the patch are not used and are counted, so the caller can report them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .records import SonarPatch

__all__ = ["GriddedSoundings", "grid_soundings"]


@dataclass(frozen=True)
class GriddedSoundings:
    """The patch made from one record's soundings, and what went into it.

    Attributes
    ----------
    patch : SonarPatch
        Mean depth per node, NaN where no sounding landed.
    used : int
        Soundings that fell on a node of the patch.
    outside : int
        Soundings beyond the patch's edge, not used.
    """

    patch: SonarPatch
    used: int
    outside: int


def grid_soundings(
    east_m: np.ndarray,
    north_m: np.ndarray,
    depth_m: np.ndarray,
    *,
    patch_shape: tuple[int, int],
    node_m: float,
) -> GriddedSoundings:
    """Bin soundings (offsets from the vehicle) into a vehicle-centred patch, mean per node.

    Parameters
    ----------
    east_m, north_m : (n,) arrays
        Offsets of each sounding from the vehicle, metres, grid east and grid north.
    depth_m : (n,) array
        Sea-floor depth at each sounding, metres, positive down.
    patch_shape : (h, w)
        Nodes of the patch, north by east.
    node_m : float
        Node spacing, metres; the map's, so the patch can be correlated against it.

    Returns
    -------
    GriddedSoundings

    Raises
    ------
    ValueError
        The arrays differ in length or hold NaN/infinite values (the caller filters and counts
        those), the shape is not two positive integers, or ``node_m`` is not a positive number.
    """
    h, w = _check_shape(patch_shape)
    if not (np.isfinite(node_m) and node_m > 0):
        raise ValueError(f"node_m must be a positive number of metres, got {node_m!r}")
    east, north, depth = (np.asarray(a, dtype=np.float64).ravel() for a in (east_m, north_m, depth_m))
    if not (east.size == north.size == depth.size):
        raise ValueError(f"east_m, north_m and depth_m have {east.size}, {north.size} and {depth.size} soundings")
    if not (np.all(np.isfinite(east)) and np.all(np.isfinite(north)) and np.all(np.isfinite(depth))):
        raise ValueError("soundings must be finite; filter NaN readings (and count them) before gridding")
    k = np.floor(north / node_m + (h - 1) / 2 + 0.5).astype(np.int64)
    l = np.floor(east / node_m + (w - 1) / 2 + 0.5).astype(np.int64)
    inside = (k >= 0) & (k < h) & (l >= 0) & (l < w)
    node = k[inside] * w + l[inside]
    counts = np.bincount(node, minlength=h * w)
    sums = np.bincount(node, weights=depth[inside], minlength=h * w)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(counts > 0, sums / np.maximum(counts, 1), np.nan)
    return GriddedSoundings(
        patch=SonarPatch(depth_m=mean.reshape(h, w), node_m=float(node_m)),
        used=int(inside.sum()),
        outside=int((~inside).sum()),
    )


def _check_shape(patch_shape) -> tuple[int, int]:
    try:
        h, w = (int(v) for v in patch_shape)
    except (TypeError, ValueError):
        raise ValueError(f"patch_shape must be two positive integers (rows, cols), got {patch_shape!r}") from None
    if h < 1 or w < 1 or (h, w) != tuple(patch_shape):
        raise ValueError(f"patch_shape must be two positive integers (rows, cols), got {patch_shape!r}")
    return h, w
