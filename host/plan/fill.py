"""How full a real-time swath patch is along a route: the share of its nodes that a sounding falls in.

A real-time patch (``lost.host.scenario``'s and a live survey's) is centred on the latest earlier position at least half
the patch's diagonal behind the vehicle (the start until the vehicle has gone that far) and holds the pings received so
far within half that diagonal of its centre, each a line of soundings ``swath_width_m`` wide across the motion, binned
into the patch's nodes. A swath narrower than the patch leaves its sides empty on a straight line, a turn fills them; the
first patch of a tow fills as the vehicle leaves the start. The navigation does not correlate a patch under
``NavParameters.min_valid_fraction`` of its nodes: the route model makes no terrain update there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..io.sonar import grid_soundings, patch_pings

__all__ = ["Sweep", "patch_fill"]


@dataclass(frozen=True, kw_only=True)
class Sweep:
    """A swath sonar's real-time patch: ``shape`` (rows, columns) of ``node_m`` nodes, its swath ``swath_width_m`` wide
    (None: the patch's larger side, the scenarios' default), its pings looked for at most ``max_window_s`` away."""

    shape: tuple[int, int]
    node_m: float
    swath_width_m: float | None = None
    max_window_s: float = 300.0

    def __post_init__(self) -> None:
        if len(self.shape) != 2 or min(self.shape) < 1:
            raise ValueError(f"the patch needs a positive number of rows and columns, got {self.shape!r}")
        for name in ("node_m", "swath_width_m", "max_window_s"):
            value = getattr(self, name)
            if value is not None and not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value!r}")

    @property
    def width_m(self) -> float:
        return self.swath_width_m if self.swath_width_m is not None else max(self.shape) * self.node_m

    @property
    def half_diagonal_m(self) -> float:
        return math.hypot(*self.shape) * self.node_m / 2.0


def patch_fill(xy: np.ndarray, interval_s: float, sweep: Sweep) -> np.ndarray:
    """The share of the patch's nodes sounded at each of the positions ``xy`` (one a ping, ``interval_s`` apart)."""
    xy = np.asarray(xy, dtype=np.float64)
    n = len(xy)
    if n == 0:
        return np.zeros(0)
    heading = np.gradient(xy, axis=0) if n > 1 else np.array([[0.0, 1.0]])
    norm = np.hypot(heading[:, 0], heading[:, 1])
    heading = np.where(norm[:, None] > 1e-9, heading / np.maximum(norm, 1e-9)[:, None], (0.0, 1.0))
    starboard = np.column_stack([heading[:, 1], -heading[:, 0]])
    # soundings half a node apart across the swath touch every node its band crosses, as the beams do
    across = np.linspace(-sweep.width_m / 2.0, sweep.width_m / 2.0, int(np.ceil(2.0 * sweep.width_m / sweep.node_m)) + 1)
    spots = xy[:, None, :] + across[None, :, None] * starboard[:, None, :]  # (pings, beams, 2)
    window = max(int(np.ceil(sweep.max_window_s / interval_s)), 1)
    half = sweep.half_diagonal_m
    fill = np.empty(n)
    for k in range(n):
        centre, pings = patch_pings(xy, k, window, half)
        offsets = spots[pings].reshape(-1, 2) - xy[centre]
        gridded = grid_soundings(offsets[:, 0], offsets[:, 1], np.zeros(len(offsets)), patch_shape=sweep.shape, node_m=sweep.node_m)
        fill[k] = np.isfinite(gridded.patch.depth_m).mean()
    return fill
