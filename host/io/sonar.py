"""Sonar soundings around the vehicle, gridded into the patch the correlator matches.

A swath or multibeam sonar returns soundings scattered around the vehicle: for each, its east and
north offset from the vehicle (metres, grid axes) and the sea-floor depth there. :func:`grid_soundings`
bins them onto the ``h x w`` nodes of a :class:`~lost.host.records.SonarPatch` centred on the vehicle,
or on any other point given by its offset from the vehicle (``centre_m``): a swath gathered in real
time lies behind the vehicle, and :func:`soundings_centre` centres the patch on what was sounded.

- node ``(k, l)`` sits at north offset ``(k - (h - 1) / 2) * node_m`` and east offset
  ``(l - (w - 1) / 2) * node_m`` from the centre (row grows north, column east, like the map);
- a sounding belongs to the node nearest to it (a half-node tie goes to the higher index);
- a node's depth is the mean of its soundings; a node no beam reached is NaN (never interpolated,
  so the correlator's valid mask says exactly where the sonar saw the floor);
- soundings beyond the patch are not used and are counted, so the caller can report them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..records import PatchSoundings, SonarPatch

__all__ = ["GriddedSoundings", "grid_soundings", "patch_pings", "soundings_centre"]


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
    centre_m: tuple[float, float] = (0.0, 0.0),
    age_s: float | np.ndarray = 0.0,
    soundings: PatchSoundings | None = None,
) -> GriddedSoundings:
    """Bin soundings (offsets from the vehicle) into a patch around ``centre_m``, mean per node.

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
    centre_m : (east, north)
        The patch centre's offset from the vehicle, metres; the patch's ``centre_offset_m``.
    age_s : float or (n,) array
        How long before the record each sounding was taken, seconds (negative: after it); the patch's
        ``age_s`` is the mean over the soundings it uses.
    soundings : PatchSoundings, optional
        These soundings (all of them, with their ages) for the patch to carry, so that the navigation can grid
        them again with each placed by its own age (:mod:`lost.host.nav.motion`).

    Returns
    -------
    GriddedSoundings

    Raises
    ------
    ValueError
        The arrays differ in length or hold NaN/infinite values (the caller filters and counts
        those), the shape is not two positive integers, ``node_m`` is not a positive number, or
        ``centre_m`` is not two finite numbers.
    """
    h, w = _check_shape(patch_shape)
    if not (np.isfinite(node_m) and node_m > 0):
        raise ValueError(f"node_m must be a positive number of metres, got {node_m!r}")
    east, north, depth = (np.asarray(a, dtype=np.float64).ravel() for a in (east_m, north_m, depth_m))
    if not (east.size == north.size == depth.size):
        raise ValueError(f"east_m, north_m and depth_m have {east.size}, {north.size} and {depth.size} soundings")
    if not (np.all(np.isfinite(east)) and np.all(np.isfinite(north)) and np.all(np.isfinite(depth))):
        raise ValueError("soundings must be finite; filter NaN readings (and count them) before gridding")
    centre = np.asarray(centre_m, dtype=np.float64).ravel()
    if centre.size != 2 or not np.all(np.isfinite(centre)):
        raise ValueError(f"centre_m must be two finite numbers (east, north) in metres, got {centre_m!r}")
    k = np.floor((north - centre[1]) / node_m + (h - 1) / 2 + 0.5).astype(np.int64)
    l = np.floor((east - centre[0]) / node_m + (w - 1) / 2 + 0.5).astype(np.int64)
    inside = (k >= 0) & (k < h) & (l >= 0) & (l < w)
    node = k[inside] * w + l[inside]
    if np.ndim(age_s) == 0:
        patch_age = float(age_s)
    else:
        ages = np.broadcast_to(np.asarray(age_s, dtype=np.float64), east.shape)[inside]
        patch_age = float(ages.mean()) if ages.size else 0.0
    counts = np.bincount(node, minlength=h * w)
    sums = np.bincount(node, weights=depth[inside], minlength=h * w)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(counts > 0, sums / np.maximum(counts, 1), np.nan)
    return GriddedSoundings(
        patch=SonarPatch(depth_m=mean.reshape(h, w), node_m=float(node_m), centre_offset_m=(float(centre[0]), float(centre[1])),
                         age_s=patch_age, soundings=soundings),
        used=int(inside.sum()),
        outside=int((~inside).sum()),
    )


def patch_pings(positions: np.ndarray, record: int, window: int, half_diagonal_m: float, realtime: bool = True) -> tuple[int, np.ndarray]:
    """The pings a swath patch of ``record`` gathers, by their ``positions`` (one row a ping, metres): its centre ping and
    the pings within ``half_diagonal_m`` of it, looked for at most ``window`` pings away.

    A real-time patch holds only the pings up to ``record`` and is centred on the latest earlier ping at least half a
    diagonal behind it (where the vehicle has not gone that far within ``window``, the earliest in the window: a partly
    filled patch); any other is centred on ``record`` and takes later pings too.
    """
    centre, last = record, len(positions) - 1
    if realtime:
        earlier = np.arange(max(record - window, 0), record + 1)
        behind = earlier[np.hypot(*(positions[earlier] - positions[record]).T) >= half_diagonal_m]
        centre, last = (int(behind.max()) if behind.size else int(earlier[0])), record
    nearby = np.arange(max(centre - window, 0), min(centre + window, last) + 1)
    return centre, nearby[np.hypot(*(positions[nearby] - positions[centre]).T) <= half_diagonal_m]


def soundings_centre(east_m: np.ndarray, north_m: np.ndarray) -> tuple[float, float]:
    """The middle of the soundings' extent (east, north), metres from the vehicle: a patch centre that they fill.

    Raises
    ------
    ValueError
        No sounding, or a NaN/infinite offset.
    """
    east, north = (np.asarray(a, dtype=np.float64).ravel() for a in (east_m, north_m))
    if east.size == 0 or east.size != north.size:
        raise ValueError(f"the centre of the soundings needs at least one sounding with both offsets, got {east.size} east and {north.size} north")
    if not (np.all(np.isfinite(east)) and np.all(np.isfinite(north))):
        raise ValueError("sounding offsets must be finite; filter NaN readings (and count them) first")
    return float(east.min() + east.max()) / 2, float(north.min() + north.max()) / 2


def _check_shape(patch_shape) -> tuple[int, int]:
    try:
        h, w = (int(v) for v in patch_shape)
    except (TypeError, ValueError):
        raise ValueError(f"patch_shape must be two positive integers (rows, cols), got {patch_shape!r}") from None
    if h < 1 or w < 1 or (h, w) != tuple(patch_shape):
        raise ValueError(f"patch_shape must be two positive integers (rows, cols), got {patch_shape!r}")
    return h, w
