"""A patch gridded again with each sounding placed by its own age: the dead reckoning inside a patch undone.

A patch's soundings were placed by dead reckoning from each ping to the record: a measured velocity that runs
ahead of the truth by b places a sounding of age a by b * a short of where it lies (see
:class:`~lost.host.records.SonarPatch`). The filters move a patch as a whole by their own bias estimate times its
mean age; what they cannot undo is the spread of ages inside it: a minute of pings reckoned with b = 0.1 m/s is a
patch stretched or sheared by 6 m along the track, and a filter that fits it rigidly holds the error of its
misfit. :func:`compensated` moves each sounding by b (a - mean age) and grids the patch again (same shape, node and
centre): the patch a true velocity would have made, still its mean age old, so each filter's own whole-patch
shift stays its own. The patch it gives carries its soundings as placed.

The same soundings gridded on a lattice moved by a fraction of a node (:func:`lattice_moved`) are what the terrain
likelihood reads between the correlator's placements (:mod:`lost.host.nav.likelihood`): each of its nodes is then a
block mean of the floor centred where the map's would be were the vehicle that fraction off.

One bias serves the record, so that every estimator correlates the same patch once (the resident correlator
keys on the patch): :func:`record_bias` takes it from the estimators' answers at the record before, the usable
one whose bias is known best; none usable, none applied (the patch as reckoned).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from ..io.sonar import grid_soundings
from ..records import SonarPatch, SoundingArrays
from .estimator import Estimate

__all__ = ["compensated", "lattice_moved", "record_bias", "MAX_PHASES", "MIN_SHIFT_NODES"]

#: Below this largest move (in nodes) a patch is used as reckoned: gridding again would change no node's soundings.
MIN_SHIFT_NODES = 0.02
#: The most lattices a node is divided into per axis (``phases`` of :func:`lattice_moved`; each grid is one more
#: correlation of the record).
MAX_PHASES = 4


def compensated(patch: SonarPatch, bias_mps: np.ndarray) -> SonarPatch:
    """``patch`` gridded again with each sounding moved by ``bias_mps`` times its age less the patch's mean age.

    A patch without its soundings, or whose largest move is under :data:`MIN_SHIFT_NODES` of a node, comes back
    as it is.
    """
    bias = np.asarray(bias_mps, dtype=np.float64)
    if patch.soundings is None or not np.all(np.isfinite(bias)) or not bias.any():
        return patch
    east, north, depth, age = patch.soundings.arrays()
    if age.size == 0:
        return patch
    spread = np.asarray(age, dtype=np.float64) - patch.age_s
    if float(np.abs(bias).max()) * float(np.abs(spread).max()) < MIN_SHIFT_NODES * patch.node_m:
        return patch
    placed = SoundingArrays(east + bias[0] * spread, north + bias[1] * spread, depth, age)
    gridded = grid_soundings(placed.east_m, placed.north_m, depth, patch_shape=patch.depth_m.shape, node_m=patch.node_m,
                             centre_m=patch.centre_offset_m, age_s=age, soundings=placed)
    return gridded.patch


def lattice_moved(patch: SonarPatch, phases: int) -> dict[tuple[int, int], SonarPatch]:
    """``patch``'s soundings gridded on lattices moved by (a / phases, b / phases) of a node north and east, for every
    (a, b) in 0..phases-1 but (0, 0): each grid's centre, and so every node, moved by that much.

    Placed on the map's placement (i, j), grid (a, b) stands for the vehicle at placement (i - a / phases,
    j - b / phases) of ``patch``. The soundings are binned once on a lattice ``phases`` times finer and each grid sums
    its cells' blocks. Each grid's ``age_s`` is the patch's. Empty for a patch without its soundings (a snapshot, a
    patch read from a file).
    """
    if patch.soundings is None or phases < 2:
        return {}
    east, north, depth, _ = patch.soundings.arrays()
    h, w = patch.depth_m.shape
    k = int(phases)
    # Sub-cell s of a sounding: node floor((s - a) / k) of grid a, as grid_soundings bins it with the centre moved a / k.
    sub_n = np.floor(((np.asarray(north) - patch.centre_offset_m[1]) / patch.node_m + (h - 1) / 2 + 0.5) * k).astype(np.int64)
    sub_e = np.floor(((np.asarray(east) - patch.centre_offset_m[0]) / patch.node_m + (w - 1) / 2 + 0.5) * k).astype(np.int64)
    rows, cols = h * k + k - 1, w * k + k - 1
    inside = (sub_n >= 0) & (sub_n < rows) & (sub_e >= 0) & (sub_e < cols)
    cell = sub_n[inside] * cols + sub_e[inside]
    # Block sums of the cells by their integral images: grid (a, b)'s node (i, j) holds cells a + i k .. a + i k + k - 1.
    corner_rows = np.arange(k)[:, None] + k * np.arange(h + 1)[None, :]
    corner_cols = np.arange(k)[:, None] + k * np.arange(w + 1)[None, :]
    def block_sums(weights: np.ndarray | None) -> np.ndarray:
        """(k, k, h, w): grid (a, b)'s node sums of ``weights`` (None: counts)."""
        integral = np.pad(np.bincount(cell, weights=weights, minlength=rows * cols).reshape(rows, cols).cumsum(0).cumsum(1), ((1, 0), (1, 0)))
        corners = integral[corner_rows[:, None, :, None], corner_cols[None, :, None, :]]
        return np.diff(np.diff(corners, axis=2), axis=3)

    n, total = block_sums(None), block_sums(np.asarray(depth, dtype=np.float64)[inside])
    with np.errstate(invalid="ignore", divide="ignore"):
        means = np.where(n > 0.5, total / np.maximum(n, 1), np.nan)  # (k, k, h, w): grid (a, b)'s nodes
    grids = {}
    for a in range(k):
        for b in range(k):
            if a == 0 and b == 0:
                continue
            centre = (patch.centre_offset_m[0] + b / k * patch.node_m, patch.centre_offset_m[1] + a / k * patch.node_m)
            grids[(a, b)] = SonarPatch(depth_m=means[a, b], node_m=patch.node_m, centre_offset_m=centre, age_s=patch.age_s,
                                       soundings=patch.soundings)
    return grids


def record_bias(answers: Iterable[Estimate]) -> np.ndarray:
    """The velocity bias (east, north, m/s) to place a record's soundings by: the usable answer's whose bias has the
    smallest sigma; zero when no usable answer carries one."""
    best, best_sigma = np.zeros(2), np.inf
    for answer in answers:
        bias, sigma = np.asarray(answer.velocity_bias_mps, float), np.asarray(answer.velocity_bias_sigma_mps, float)
        if not (answer.usable and np.all(np.isfinite(bias)) and np.all(np.isfinite(sigma))):
            continue
        if float(sigma.max()) < best_sigma:
            best, best_sigma = bias, float(sigma.max())
    return best
