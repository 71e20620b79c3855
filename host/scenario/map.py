"""The navigation map a survey makes of the true floor."""

from __future__ import annotations

import numpy as np

from ..grid import Grid
from .floor import scenario_floor
from .spec import MapSpec, Scenario

__all__ = ["survey_map", "scenario_grid"]


def survey_map(floor: Grid, spec: MapSpec, seed: int) -> Grid:
    """The navigation map a survey would make of ``floor`` (see :class:`MapSpec`)."""
    depth, x0, y0, node = floor.depth_m, floor.x0_m, floor.y0_m, floor.node_m
    if spec.node_m is not None:
        f = int(round(spec.node_m / node))
        rows, cols = depth.shape[0] // f, depth.shape[1] // f
        depth = depth[: rows * f, : cols * f].reshape(rows, f, cols, f).mean(axis=(1, 3))
        # A map node stands at the centre of the floor nodes it averages.
        x0, y0, node = x0 + (f - 1) / 2 * node, y0 + (f - 1) / 2 * node, spec.node_m
    depth = depth + spec.offset_m + np.random.default_rng(seed).normal(0.0, spec.noise_m, depth.shape)
    grid = Grid(depth, x0, y0, node, floor.crs)
    if spec.extent_m is None:
        return grid
    west, south, east, north = spec.extent_m
    (r0, c0), (r1, c1) = (np.floor(grid.row_col(west, south)).astype(int)), (np.ceil(grid.row_col(east, north)).astype(int))
    r0, c0 = max(r0, 0), max(c0, 0)
    r1, c1 = min(r1, depth.shape[0] - 1), min(c1, depth.shape[1] - 1)
    if r0 >= r1 or c0 >= c1:
        raise ValueError(f"map.extent_m {spec.extent_m} leaves no part of the floor")
    x, y = grid.xy(r0, c0)
    return Grid(depth[r0 : r1 + 1, c0 : c1 + 1], float(x), float(y), node, floor.crs)


def scenario_grid(scenario: Scenario) -> Grid:
    """The scenario's navigation map: the floor as ``[map]`` surveys it (the floor itself by default)."""
    floor = scenario_floor(scenario)
    seed = scenario.seed + 1 if scenario.map.seed is None else scenario.map.seed
    return survey_map(floor, scenario.map, seed)
