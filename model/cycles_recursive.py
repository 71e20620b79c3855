"""Cycle model of the recursive-adder correlator (:mod:`lost.hdl.recursive`).

With ``surface.ready`` and ``best.ready`` held high and the patch and map loaded, counting from the
edge on which the ``start`` beat transfers (cycle 0):

* cycles ``1 .. 2*h*w`` read the patch memory twice, one word per clock, each word registered two
  cycles later: the first pass counts ``n`` and sums the patch, the second registers ``f * S`` and
  appends each valid node with its centred depth to the compact node list on the cycle after; the
  generator forms its first map read request on the clock after the last append and registers it,
  and the sequencer takes it on the edge after: ``T0 = 2*h*w + 5``;
* then one request per clock, ``n`` (the valid nodes) per placement in either mode, placements in
  raster order, followed by one flush round of ``n`` requests: request ``q`` transfers on edge
  ``T0 + q``;
* its word reaches the step stage on the next edge (``T0 + q + 1``), which sums it into placement
  ``q // n``'s window and fetches the word of the same node of the previous placement; the term unit
  takes that on the edge after (``T0 + q + 2``) and passes it through its fetched-word, product,
  difference, magnitude and accumulator stages on the next five. The last term of placement ``p``
  comes with request ``(p + 2) * n - 1`` and fills the output register (``T0 + q + 6``), which
  transfers one edge later: cycle
  ``2*h*w + 11 + (p + 2) * n``;
* the best beat follows the last surface beat by :func:`lost.model.cycles.reducer_latency`.
"""

from __future__ import annotations

import numpy as np

from .cycles import Schedule, reducer_latency
from .widths import placement_widths

__all__ = ["requests_per_placement", "schedule"]


def requests_per_placement(mask: np.ndarray, mean_compensation: bool) -> int:
    """Map reads (and clocks) per placement: ``n``, the valid nodes, in either mode."""
    return int(np.count_nonzero(mask))


def schedule(map_shape, patch_shape, mask=None, mean_compensation=True, *, exclusion_radius=1) -> Schedule:
    """The cycle of every surface beat and of the best beat of one correlation.

    Parameters
    ----------
    map_shape, patch_shape : (int, int)
        ``(H, W)`` and ``(h, w)``.
    mask : (h, w) bool array, optional
        The valid patch nodes; all when omitted.
    mean_compensation : bool
        The mode of the start command.
    exclusion_radius : int
        The reducer's radius (its final scan does not depend on it, its row store does).

    Raises
    ------
    ValueError
        A patch larger than the map, a mask of another shape or with no valid node.
    """
    (H, W), (h, w) = map_shape, patch_shape
    placement_widths(map_shape, patch_shape)  # validates the shapes
    if mask is None:
        mask = np.ones((h, w), dtype=bool)
    mask = np.asarray(mask)
    if mask.shape != (h, w) or mask.dtype != np.bool_:
        raise ValueError(f"mask must be a boolean array of shape {(h, w)}, got {mask.dtype} {mask.shape}")
    if not mask.any():
        raise ValueError("mask has no valid node: there is nothing to correlate")
    rows, cols = H - h + 1, W - w + 1
    n = requests_per_placement(mask, mean_compensation)
    placements = np.arange(rows * cols, dtype=np.int64)
    surface = 2 * h * w + 11 + (placements + 2) * n
    best = int(surface[-1]) + reducer_latency((rows, cols), 1, exclusion_radius)
    return Schedule(surface=surface, best=best)
