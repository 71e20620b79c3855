"""The navigation map a survey makes of the true floor.

Each node of the floor is one sounding. A survey's errors are put on the soundings (:func:`survey_soundings`):
survey lines with an offset each, an error wandering along each line, the outer beams bent by a sound-speed
error, noise per sounding; stripes between lines that no swath reached and patches never surveyed are left
without soundings. The map grids them (:func:`grid_soundings`): the mean or median of the soundings in each
map cell, their spread as the node's standard deviation, a hole where none fell; then a datum offset and
noise per node. Real maps are made so (MB-System's mbgrid, GMT's blockmean and blockmedian) and are wrong
so: correlated along the survey lines, coarser than the floor, with holes.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy import ndimage

from ..config import ConfigError
from ..grid import Grid
from .floor import scenario_floor
from .spec import MapSpec, Scenario, check_map_node

__all__ = ["survey_map", "scenario_grid", "exact_map", "survey_soundings", "grid_soundings", "planned_map_shape", "check_patch_fits"]


def survey_map(floor: Grid, spec: MapSpec, seed: int) -> Grid:
    """The navigation map a survey would make of ``floor`` (see :class:`MapSpec`), with its per-node standard
    deviation (``sigma_m``) when it is gridded from the floor's soundings (``node_m`` given)."""
    factor = 1
    if spec.node_m is not None:
        check_map_node(spec.node_m, floor.node_m, "the floor's node")
        factor = int(round(spec.node_m / floor.node_m))
    depth, x0, y0, node, sigma = floor.depth_m, floor.x0_m, floor.y0_m, floor.node_m, None
    soundings = survey_soundings(floor, spec, np.random.default_rng([seed, 28])) if spec.surveyed else depth
    if spec.node_m is not None:
        depth, sigma = grid_soundings(soundings, factor, spec.gridding)
        # A map node stands at the centre of the floor nodes it grids.
        x0, y0, node = x0 + (factor - 1) / 2 * node, y0 + (factor - 1) / 2 * node, spec.node_m
    else:
        depth = soundings
    if not np.isfinite(depth).any():
        raise ConfigError(f"the survey leaves no sounding on the map (map.swath_width_m = {spec.swath_width_m!r} m between lines "
                          f"{spec.line_spacing_m!r} m apart, map.hole_fraction = {spec.hole_fraction:g}, a floor of {floor.node_m:g} m nodes): "
                          "widen the swath or survey more")
    depth = depth + spec.offset_m + np.random.default_rng(seed).normal(0.0, spec.noise_m, depth.shape)
    grid = Grid(depth, x0, y0, node, floor.crs, sigma)
    return grid if spec.extent_m is None else _cut(grid, spec.extent_m)


def survey_soundings(floor: Grid, spec: MapSpec, rng: np.random.Generator) -> np.ndarray:
    """One sounding per floor node, with the survey's errors; NaN where no sounding fell."""
    depth = floor.depth_m.copy()
    rows, cols = depth.shape
    x = floor.x0_m + np.arange(cols) * floor.node_m
    y = floor.y0_m + np.arange(rows) * floor.node_m
    if spec.line_spacing_m is not None:
        depth += _line_errors(x, y, floor.node_m, spec, rng)
    if spec.sounding_noise_m > 0:
        depth += rng.normal(0.0, spec.sounding_noise_m, depth.shape)
    if spec.hole_fraction > 0:
        depth[_unsurveyed(depth.shape, floor.node_m, spec, rng)] = np.nan
    return depth


def _line_errors(x: np.ndarray, y: np.ndarray, node_m: float, spec: MapSpec, rng: np.random.Generator) -> np.ndarray:
    """Each sounding's error from its survey line (the nearest one): the line's offset, its along-line drift, the
    refraction of its outer beams; NaN beyond the swath (a narrower swath than the spacing leaves stripes)."""
    azimuth = math.radians(spec.line_azimuth_deg)
    across_all = x[None, :] * math.cos(azimuth) - y[:, None] * math.sin(azimuth)  # to starboard of the line direction
    along = x[None, :] * math.sin(azimuth) + y[:, None] * math.cos(azimuth)
    line = np.rint(across_all / spec.line_spacing_m).astype(np.int64)
    across = across_all - line * spec.line_spacing_m
    line -= line.min()
    lines = int(line.max()) + 1
    half_swath = (spec.swath_width_m if spec.swath_width_m is not None else spec.line_spacing_m) / 2
    error = rng.normal(0.0, spec.line_offset_m, lines)[line]
    # A sound-speed error bends the outer beams one way on a line; the sign changes with the water, line by line.
    error += spec.refraction_m * rng.choice((-1.0, 1.0), lines)[line] * (across / half_swath) ** 2
    if spec.line_drift_m > 0:
        start = along.min()
        samples = int((along.max() - start) / node_m) + 2
        drift = ndimage.gaussian_filter1d(rng.normal(0.0, 1.0, (lines, samples)), spec.along_m / node_m / 2, axis=1, mode="wrap")
        drift *= spec.line_drift_m / max(float(drift.std()), 1e-12)
        error += drift[line, ((along - start) / node_m).astype(np.int64)]
    error[np.abs(across) > half_swath + 1e-9] = np.nan
    return error


def _unsurveyed(shape: tuple[int, int], node_m: float, spec: MapSpec, rng: np.random.Generator) -> np.ndarray:
    """Patches about ``hole_size_m`` across covering ``hole_fraction`` of the floor: a smooth random field's top share.

    The field is drawn on nodes an eighth of a patch apart and repeated onto the floor's (a patch's edge is that coarse)."""
    step = max(int(spec.hole_size_m / node_m / 8), 1)
    coarse = (-(-shape[0] // step), -(-shape[1] // step))
    field = ndimage.gaussian_filter(rng.normal(0.0, 1.0, coarse), spec.hole_size_m / (step * node_m) / 4, mode="wrap")
    holes = field > np.quantile(field, 1.0 - spec.hole_fraction)
    return np.repeat(np.repeat(holes, step, axis=0), step, axis=1)[: shape[0], : shape[1]]


def grid_soundings(soundings: np.ndarray, factor: int, gridding: str = "mean") -> tuple[np.ndarray, np.ndarray]:
    """Grid soundings ``factor`` x ``factor`` to a node: (depth, standard deviation) per cell.

    The depth is the mean (or median) of the cell's finite soundings; the standard deviation their spread
    (with the n - 1 of a sample); a cell of one sounding takes the median spread of the others, a cell of none
    is a hole (NaN in both). Rows and columns past the last whole cell are dropped.
    """
    rows, cols = soundings.shape[0] // factor, soundings.shape[1] // factor
    if rows < 1 or cols < 1:
        raise ValueError(f"a map node of {factor} floor nodes is larger than the floor ({soundings.shape[0]} x {soundings.shape[1]} nodes)")
    cells = soundings[: rows * factor, : cols * factor].reshape(rows, factor, cols, factor)
    finite = np.isfinite(cells)
    count = finite.sum(axis=(1, 3))
    if finite.all():
        mean = cells.mean(axis=(1, 3))
    else:
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = np.where(count > 0, np.where(finite, cells, 0.0).sum(axis=(1, 3)) / count, np.nan)
    spread = np.where(finite, cells - mean[:, None, :, None], 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        sigma = np.where(count > 1, np.sqrt((spread**2).sum(axis=(1, 3)) / np.maximum(count - 1, 1)), np.nan)
    lone = count == 1
    if lone.any():
        sigma[lone] = np.nanmedian(sigma) if (count > 1).any() else 0.0
    depth = mean
    if gridding == "median":
        flat = cells.transpose(0, 2, 1, 3).reshape(rows, cols, factor * factor)
        depth = np.full((rows, cols), np.nan)
        sounded = count > 0
        depth[sounded] = np.nanmedian(flat[sounded], axis=1)
    elif gridding != "mean":
        raise ValueError(f"gridding must be 'mean' or 'median', got {gridding!r}")
    return depth, sigma


def _cut(grid: Grid, extent_m: tuple[float, float, float, float]) -> Grid:
    """The part of ``grid`` inside (west, south, east, north), one node beyond where the box falls between nodes."""
    west, south, east, north = extent_m
    (r0, c0), (r1, c1) = (np.floor(grid.row_col(west, south)).astype(int)), (np.ceil(grid.row_col(east, north)).astype(int))
    r0, c0 = max(r0, 0), max(c0, 0)
    r1, c1 = min(r1, grid.shape[0] - 1), min(c1, grid.shape[1] - 1)
    if r0 >= r1 or c0 >= c1:
        raise ValueError(f"map.extent_m {extent_m} leaves no part of the floor")
    x, y = grid.xy(r0, c0)
    sigma = None if grid.sigma_m is None else grid.sigma_m[r0 : r1 + 1, c0 : c1 + 1]
    return Grid(grid.depth_m[r0 : r1 + 1, c0 : c1 + 1], float(x), float(y), grid.node_m, grid.crs, sigma)


def planned_map_shape(scenario: Scenario, floor_shape: tuple[int, int], floor_node_m: float) -> tuple[int, int]:
    """The shape of the map ``[map]`` will make of a floor of this shape and node, without making either."""
    spec, terrain = scenario.map, scenario.terrain
    factor = 1
    if spec.node_m is not None:
        check_map_node(spec.node_m, floor_node_m, "the floor's node")
        factor = int(round(spec.node_m / floor_node_m))
    rows, cols = floor_shape[0] // factor, floor_shape[1] // factor
    if rows < 1 or cols < 1:
        raise ValueError(f"map.node_m ({spec.node_m:g} m) is larger than the floor ({floor_shape[0]} x {floor_shape[1]} nodes of {floor_node_m:g} m)")
    if spec.extent_m is None:
        return rows, cols
    x0 = terrain.x0_m + (factor - 1) / 2 * floor_node_m
    y0 = terrain.y0_m + (factor - 1) / 2 * floor_node_m
    return _cut(Grid(np.zeros((rows, cols)), x0, y0, floor_node_m * factor), spec.extent_m).shape


def check_patch_fits(scenario: Scenario, map_shape: tuple[int, int]) -> None:
    """The sonar patch, in map nodes, must fit inside the map: a correlator places it wholly on the map."""
    sonar = scenario.sensors["sonar"]
    if not sonar.enabled:
        return
    h, w = sonar.shape
    if h > map_shape[0] or w > map_shape[1]:
        raise ConfigError(f"sensors.sonar.shape ({h} x {w} map nodes) is larger than the map ({map_shape[0]} x {map_shape[1]} nodes"
                          f"{'' if scenario.map.node_m is None else f' of {scenario.map.node_m:g} m'}): no placement of the patch lies on it; "
                          "use a smaller patch, a finer map.node_m, or a larger map")


def check_before_simulating(scenario: Scenario) -> None:
    """What can be refused from the settings alone, refused before any floor is made (a grid file's is checked once read)."""
    if scenario.terrain.file is None:
        node = scenario.terrain.node_m
        check_patch_fits(scenario, planned_map_shape(scenario, scenario.terrain.shape, node))


def scenario_grid(scenario: Scenario) -> Grid:
    """The scenario's navigation map: the floor as ``[map]`` surveys it (the floor itself by default)."""
    floor = scenario_floor(scenario)
    seed = scenario.seed + 1 if scenario.map.seed is None else scenario.map.seed
    return survey_map(floor, scenario.map, seed)


def exact_map(scenario: Scenario) -> Scenario:
    """The same scenario with its map equal to its floor, node for node (no survey; ``extent_m``, the map's box, kept).

    The map = floor case of any scenario: the navigation's reference, where a map knows the floor exactly. The
    sonar's patch then lies on the floor's nodes (a swath's width, when not set, follows the patch)."""
    return replace(scenario, map=MapSpec(extent_m=scenario.map.extent_m))
