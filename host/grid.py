"""A bathymetric grid in a projected metric frame: the host's one map type.

Every reader (``lost.host.io``) returns a :class:`Grid`, and every consumer (the scenario simulator,
the navigation pipeline, the correlator's quantization) takes one, so metres and georeferencing live
here and nowhere else.

Convention: ``depth_m[row, col]`` is the depth (metres, positive down, NaN where the map has a hole)
at easting ``x0_m + col * node_m`` and northing ``y0_m + row * node_m``: row 0 is the southern edge,
rows grow northward, columns eastward. Readers flip north-up files to this order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Grid"]


@dataclass(frozen=True)
class Grid:
    """A regular square-node bathymetric grid.

    Attributes
    ----------
    depth_m : (rows, cols) float64 array
        Depth, positive down; NaN marks a hole.
    x0_m, y0_m : float
        Easting and northing of node (0, 0), metres, in ``crs``.
    node_m : float
        Node spacing, metres, the same along both axes.
    crs : str or None
        The projected CRS (anything ``pyproj.CRS.from_user_input`` takes), or None for a local frame.
    sigma_m : (rows, cols) float64 array or None
        The standard deviation of each node's depth, metres, as gridding reports it (the spread of the
        soundings in the node's cell; a BAG's uncertainty layer); NaN where the depth is a hole, and where a
        node's single sounding has no spread (``lost run`` fills those with ``survey_sigma_m``). None: not known.
    """

    depth_m: np.ndarray
    x0_m: float
    y0_m: float
    node_m: float
    crs: str | None = None
    sigma_m: np.ndarray | None = None

    def __post_init__(self) -> None:
        depth = np.asarray(self.depth_m, dtype=np.float64)
        if depth.ndim != 2 or min(depth.shape) < 1:
            raise ValueError(f"depth_m must be a non-empty 2-D array, got shape {depth.shape}")
        if not np.isfinite(self.node_m) or self.node_m <= 0:
            raise ValueError(f"node_m must be a positive number of metres, got {self.node_m!r}")
        if not (np.isfinite(self.x0_m) and np.isfinite(self.y0_m)):
            raise ValueError(f"the grid origin must be finite, got ({self.x0_m!r}, {self.y0_m!r})")
        object.__setattr__(self, "depth_m", depth)
        if self.sigma_m is not None:
            sigma = np.asarray(self.sigma_m, dtype=np.float64)
            if sigma.shape != depth.shape:
                raise ValueError(f"sigma_m must have the depths' shape {depth.shape}, got {sigma.shape}")
            if np.any(sigma < 0):
                raise ValueError(f"sigma_m must not be negative, got a minimum of {np.nanmin(sigma)!r} m")
            object.__setattr__(self, "sigma_m", sigma)

    @property
    def shape(self) -> tuple[int, int]:
        return self.depth_m.shape

    def xy(self, row: np.ndarray | float, col: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Easting and northing of (fractional) node indices."""
        return self.x0_m + np.asarray(col) * self.node_m, self.y0_m + np.asarray(row) * self.node_m

    def row_col(self, x_m: np.ndarray | float, y_m: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Fractional node indices of eastings and northings."""
        return (np.asarray(y_m) - self.y0_m) / self.node_m, (np.asarray(x_m) - self.x0_m) / self.node_m

    def contains(self, x_m: np.ndarray | float, y_m: np.ndarray | float) -> np.ndarray:
        """Whether points lie inside the grid's node extent."""
        row, col = self.row_col(x_m, y_m)
        rows, cols = self.shape
        return (row >= 0) & (row <= rows - 1) & (col >= 0) & (col <= cols - 1)
