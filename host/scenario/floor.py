"""The true sea floor of a scenario, and its depth anywhere: what the vehicle, its altimeter and its sonar see."""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from ..config import ConfigError
from ..grid import Grid
from ..terrain import feature_relief, refine, shelf_profile, synthetic_terrain
from .spec import MAX_SCENARIO_BYTES, Scenario

__all__ = ["scenario_floor", "floor_depth", "cell_mean_depth"]


def scenario_floor(scenario: Scenario) -> Grid:
    """The scenario's true sea floor: its grid file (refined below its node with ``refine_node_m``), or its seeded
    synthetic floor: random relief, a shelf's shape and isolated features (see :class:`TerrainSpec`)."""
    spec = scenario.terrain
    seed = scenario.seed if spec.seed is None else spec.seed
    if spec.file is not None:
        return _file_floor(scenario, seed)
    depth = synthetic_terrain(
        spec.shape,
        seed=seed,
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
    if spec.gradient > 0 or spec.break_m is not None:
        depth += shelf_profile(spec.shape, spec.node_m, gradient=spec.gradient, downslope_deg=spec.downslope_deg, break_m=spec.break_m,
                               slope_gradient=spec.slope_gradient, break_width_m=spec.break_width_m)
    if spec.features:
        depth += feature_relief(spec.shape, spec.node_m, spec.features, seed=seed, x0_m=spec.x0_m, y0_m=spec.y0_m)
    return Grid(depth, spec.x0_m, spec.y0_m, spec.node_m)


def _file_floor(scenario: Scenario, seed: int) -> Grid:
    """A grid file as the floor, refined to ``terrain.refine_node_m`` when given."""
    from ..io import read_grid  # lazily: the file readers and their dependencies load only when used

    spec = scenario.terrain
    grid = read_grid(scenario.base_dir / spec.file, positive=spec.positive, nodata=spec.nodata)
    if spec.refine_node_m is None:
        return grid
    ratio = grid.node_m / spec.refine_node_m
    if not (ratio >= 1 - 1e-9 and abs(ratio - round(ratio)) < 1e-6):
        raise ValueError(f"terrain.refine_node_m ({spec.refine_node_m:g} m) must divide the node of {spec.file} ({grid.node_m:g} m) "
                         "a whole number of times")
    factor = int(round(ratio))
    rows, cols = (grid.shape[0] - 1) * factor + 1, (grid.shape[1] - 1) * factor + 1
    # The spline's coordinates, the result and the detail's spectrum: about 48 bytes a fine node.
    if 48.0 * rows * cols > MAX_SCENARIO_BYTES:
        raise ConfigError(f"{spec.file} ({grid.shape[0]} x {grid.shape[1]} nodes of {grid.node_m:g} m) refined to terrain.refine_node_m = "
                          f"{spec.refine_node_m:g} m would be {rows:,} x {cols:,} nodes, about {48.0 * rows * cols / 1e9:,.0f} GB; the limit is "
                          f"{MAX_SCENARIO_BYTES / 1e9:g} GB: refine less, or cut the file to the tow's area")
    depth = refine(grid.depth_m, factor, seed=seed, detail_m=spec.detail_m, hurst=spec.hurst)
    return Grid(depth, grid.x0_m, grid.y0_m, spec.refine_node_m, grid.crs)


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
    if f % 2:
        # Whole-node offsets: the mean of f x f bilinear reads is one bilinear read of the floor's f x f running mean
        # (NaN wherever a read would leave the floor or touch a hole, as the reads would be).
        finite = np.isfinite(floor.depth_m)
        share = ndimage.uniform_filter(finite.astype(float), f, mode="constant", cval=0.0)
        means = ndimage.uniform_filter(np.where(finite, floor.depth_m, 0.0), f, mode="constant", cval=0.0)
        means[share < 1 - 1e-9] = np.nan
        return floor_depth(Grid(means, floor.x0_m, floor.y0_m, floor.node_m), x, y)
    offsets = (np.arange(f) - (f - 1) / 2) * floor.node_m
    total = np.zeros(np.shape(x))
    for dy in offsets:
        for dx in offsets:
            total += floor_depth(floor, x + dx, y + dy)
    return total / f**2
