"""The true sea floor of a scenario, and its depth anywhere: what the vehicle, its altimeter and its sonar see."""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from ..grid import Grid
from ..terrain import synthetic_terrain
from .spec import Scenario

__all__ = ["scenario_floor", "floor_depth", "cell_mean_depth"]


def scenario_floor(scenario: Scenario) -> Grid:
    """The scenario's true sea floor: its grid file, or its seeded synthetic floor."""
    spec = scenario.terrain
    if spec.file is not None:
        from ..io import read_grid  # lazily: the file readers and their dependencies load only when used

        return read_grid(scenario.base_dir / spec.file, positive=spec.positive, nodata=spec.nodata)
    depth = synthetic_terrain(
        spec.shape,
        seed=scenario.seed if spec.seed is None else spec.seed,
        mean_depth_m=spec.mean_depth_m,
        relief_m=spec.relief_m,
        roughness_m=spec.roughness_m,
        smooth_fraction=spec.smooth_fraction,
        hurst=spec.hurst,
        corner_nodes=None if spec.corner_m is None else spec.corner_m / spec.node_m,
        aspect=spec.aspect,
        azimuth_deg=spec.azimuth_deg,
        repeat_nodes=None if spec.repeat_m is None else tuple(max(int(round(m / spec.node_m)), 2) for m in spec.repeat_m),
    )
    return Grid(depth, spec.x0_m, spec.y0_m, spec.node_m)



def floor_depth(grid: Grid, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The true sea floor between nodes: bilinear, NaN off the map or next to a hole."""
    row, col = grid.row_col(x, y)
    coords = np.stack([np.ravel(row), np.ravel(col)])
    depth = ndimage.map_coordinates(grid.depth_m, coords, order=1, mode="constant", cval=np.nan)
    return depth.reshape(np.shape(x))



def cell_mean_depth(floor: Grid, x: np.ndarray, y: np.ndarray, node_m: float) -> np.ndarray:
    """The floor's mean depth over square cells of ``node_m`` centred on (x, y): what binning soundings gives."""
    f = max(int(round(node_m / floor.node_m)), 1)
    if f == 1:
        return floor_depth(floor, x, y)
    offsets = (np.arange(f) - (f - 1) / 2) * floor.node_m
    total = np.zeros(np.shape(x))
    for dy in offsets:
        for dx in offsets:
            total += floor_depth(floor, x + dx, y + dy)
    return total / f**2
