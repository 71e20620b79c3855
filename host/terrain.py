"""Seeded synthetic sea floors, generated in code, for the demo, the tests and the scenarios.

Three kinds of relief add up to a floor: the random surface of :func:`synthetic_terrain` (a power law or
the von Karman spectrum, with an optional smooth region), the regional shape of a shelf and its slope
(:func:`shelf_profile`), and isolated strong features, winding canyons, ridges and seamounts
(:func:`feature_relief`). :func:`refine` puts fractal detail under a coarse grid (a DEM), so a real map
can serve as a floor finer than itself. Depths are metres, positive down; arrays are (rows north,
columns east) with node (0, 0) at the south-west.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy import ndimage

__all__ = ["synthetic_terrain", "shelf_profile", "Feature", "feature_relief", "refine", "node_scale_relief"]


def _fractal(shape: tuple[int, int], rng: np.random.Generator, hurst: float, *, corner_nodes: float | None = None,
             aspect: float = 1.0, azimuth_deg: float = 0.0) -> np.ndarray:
    """Unit-variance random surface by spectral synthesis.

    Without ``corner_nodes``: a pure power law, power ~ k**-(2 * hurst + 2). With it: the anisotropic
    von Karman spectrum of Goff and Jordan (1988), the standard statistical model of sea-floor
    morphology, power ~ (1 + (k / k0)**2)**-(hurst + 1) with k0 = 1 / corner_nodes: flat beyond the
    corner wavelength, the same power law below it. ``aspect`` > 1 stretches the features along
    ``azimuth_deg`` (clockwise from north, i.e. from the row axis), as abyssal hills are elongated.
    """
    ky = np.fft.fftfreq(shape[0])[:, None]
    kx = np.fft.rfftfreq(shape[1])[None, :]
    if aspect != 1.0:
        a = np.radians(azimuth_deg)
        along = ky * np.cos(a) + kx * np.sin(a)
        across = -ky * np.sin(a) + kx * np.cos(a)
        ky, kx = along * aspect, across
    k = np.hypot(ky, kx)
    if corner_nodes is None:
        k[0, 0] = np.inf  # no mean
        amplitude = k ** (-(hurst + 1.0))
    else:
        amplitude = (1.0 + (k * corner_nodes) ** 2) ** (-(hurst + 1.0) / 2.0)
        amplitude[0, 0] = 0.0
    phase = rng.uniform(0.0, 2.0 * np.pi, amplitude.shape)
    surface = np.fft.irfft2(amplitude * np.exp(1j * phase), s=shape)
    return surface / surface.std()


def synthetic_terrain(
    shape: tuple[int, int] = (501, 501),
    *,
    seed: int = 0,
    mean_depth_m: float = 1000.0,
    relief_m: float = 60.0,
    roughness_m: float = 8.0,
    smooth_fraction: float = 0.0,
    hurst: float = 0.8,
    corner_nodes: float | None = None,
    aspect: float = 1.0,
    azimuth_deg: float = 0.0,
    repeat_nodes: tuple[int, int] | None = None,
) -> np.ndarray:
    """A sea floor in metres (positive down), one value per map node.

    Parameters
    ----------
    shape : (rows, cols)
        Map nodes; the node spacing is the caller's (10 m in the paper).
    seed : int
        The same seed gives the same floor on every machine.
    mean_depth_m : float
        Mean depth.
    relief_m : float
        Standard deviation of the long-wavelength relief (hills and basins).
    roughness_m : float
        Standard deviation of the short-wavelength roughness where the floor is rough.
    smooth_fraction : float
        Fraction of the columns, from the east edge, where the roughness fades to nothing: terrain
        on which a correlator has little to hold on to.
    hurst : float
        Hurst exponent of the roughness; lower is rougher at the smallest scales.
    corner_nodes, aspect, azimuth_deg : float
        With ``corner_nodes``, the roughness follows the von Karman spectrum of Goff and Jordan (corner
        wavelength in nodes, elongation and its direction; see ``_fractal``) instead of a pure power law.
    repeat_nodes : (rows, cols), optional
        Build a tile of this many nodes and repeat it over the floor: terrain that looks alike every
        tile, on which a terrain navigator must not claim a fix it cannot tell apart.

    Raises
    ------
    ValueError
        A non-2-D shape, or a smooth fraction outside [0, 1].
    """
    if len(shape) != 2 or min(shape) < 2:
        raise ValueError(f"shape must be two sides of at least 2 nodes, got {shape!r}")
    if not 0.0 <= smooth_fraction <= 1.0:
        raise ValueError(f"smooth_fraction must lie in [0, 1], got {smooth_fraction!r}")
    if aspect <= 0 or (corner_nodes is not None and corner_nodes <= 0):
        raise ValueError(f"aspect and corner_nodes must be positive, got {aspect!r} and {corner_nodes!r}")
    if repeat_nodes is not None:
        tile = tuple(int(n) for n in repeat_nodes)
        if len(tile) != 2 or min(tile) < 2:
            raise ValueError(f"repeat_nodes must be two sides of at least 2 nodes, got {repeat_nodes!r}")
        floor = synthetic_terrain(tile, seed=seed, mean_depth_m=mean_depth_m, relief_m=relief_m, roughness_m=roughness_m,
                                  hurst=hurst, corner_nodes=corner_nodes, aspect=aspect, azimuth_deg=azimuth_deg)
        reps = (-(-shape[0] // tile[0]), -(-shape[1] // tile[1]))
        return np.tile(floor, reps)[: shape[0], : shape[1]]
    rng = np.random.default_rng(seed)
    relief = _fractal(shape, rng, hurst=1.5)
    rough = _fractal(shape, rng, hurst=hurst, corner_nodes=corner_nodes, aspect=aspect, azimuth_deg=azimuth_deg)
    cols = np.arange(shape[1]) / max(shape[1] - 1, 1)
    # A smooth ramp between the rough and the smooth region, so the roughness has no seam.
    edge = 1.0 - smooth_fraction
    envelope = np.clip((edge - cols) / 0.1 + 0.5, 0.0, 1.0) if smooth_fraction > 0 else np.ones_like(cols)
    return mean_depth_m + relief_m * relief + roughness_m * rough * envelope[None, :]


def shelf_profile(shape: tuple[int, int], node_m: float, *, gradient: float, downslope_deg: float, break_m: float | None = None,
                  slope_gradient: float = 0.06, break_width_m: float = 400.0) -> np.ndarray:
    """The regional shape of a continental margin, zero at the floor's centre, metres added to the depth.

    The floor deepens toward ``downslope_deg`` (clockwise from north) by ``gradient`` (metres per metre,
    a shelf's 0.001-0.01); beyond ``break_m`` (distance from the centre along that direction) by
    ``slope_gradient`` (a continental slope's 0.03-0.1), the change spread over ``break_width_m``
    (a softplus, so the break has no kink).
    """
    rows, cols = shape
    azimuth = np.radians(downslope_deg)
    x = (np.arange(cols) - (cols - 1) / 2) * node_m
    y = (np.arange(rows) - (rows - 1) / 2) * node_m
    along = x[None, :] * np.sin(azimuth) + y[:, None] * np.cos(azimuth)
    depth = gradient * along
    if break_m is not None:
        width = max(break_width_m, node_m)
        # softplus: 0 on the shelf, (along - break) beyond it, smooth over the break's width.
        bend = np.logaddexp(0.0, (along - break_m) / width) - np.logaddexp(0.0, -break_m / width)  # 0 at the centre
        depth = depth + (slope_gradient - gradient) * width * bend
    return depth


@dataclass(frozen=True, kw_only=True)
class Feature:
    """One isolated strong feature of the floor.

    kind : "canyon" (cut into the floor), "ridge" or "seamount" (raised above it).
    path_m : (east, north) points, metres in the floor's frame, that a canyon or ridge follows (at least two).
    at_m : (east, north) centre of a seamount.
    height_m : a canyon's incision, a ridge's or a seamount's height.
    width_m : a canyon's half width at its floor's edge (a flat floor, steep walls: height / (1 + (d / width)**4)),
        a ridge's 1/e half width (Gaussian cross-section), a seamount's 1/e radius (Gaussian).
    meander_m, meander_wavelength_m : a canyon's (or ridge's) winding: a smooth random offset across its path,
        of this amplitude (its standard deviation times the square root of 2, a sine's peak), with bends of about
        this wavelength.
    """

    kind: Literal["canyon", "ridge", "seamount"]
    height_m: float
    width_m: float
    path_m: tuple[tuple[float, float], ...] = ()
    at_m: tuple[float, float] | None = None
    meander_m: float = 0.0
    meander_wavelength_m: float = 2000.0

    def __post_init__(self) -> None:
        if self.kind not in ("canyon", "ridge", "seamount"):
            raise ValueError(f"a feature's kind must be 'canyon', 'ridge' or 'seamount', got {self.kind!r}")
        if not (self.width_m > 0 and self.height_m >= 0 and self.meander_m >= 0 and self.meander_wavelength_m > 0):
            raise ValueError(f"a {self.kind}'s width_m and meander_wavelength_m must be positive, height_m and meander_m not negative, "
                             f"got {self.width_m!r}, {self.meander_wavelength_m!r}, {self.height_m!r}, {self.meander_m!r}")
        if self.kind == "seamount" and self.at_m is None:
            raise ValueError("a seamount needs its centre, at_m = [east, north]")
        if self.kind != "seamount" and len(self.path_m) < 2:
            raise ValueError(f"a {self.kind} needs a path_m of at least two [east, north] points, got {self.path_m!r}")


def feature_relief(shape: tuple[int, int], node_m: float, features: Sequence[Feature], *, seed: int, x0_m: float = 0.0,
                   y0_m: float = 0.0) -> np.ndarray:
    """Metres added to the depth by ``features`` (a canyon deepens the floor, a ridge or seamount raises it).

    Seeded: a canyon's meanders are drawn from ``seed`` and the feature's index.

    Raises
    ------
    ValueError
        A feature that lies wholly off the floor (it would change nothing: a mistyped coordinate, not a floor).
    """
    total = np.zeros(shape)
    for index, feature in enumerate(features):
        rng = np.random.default_rng([seed, 29, index])
        if feature.kind == "seamount":
            x = x0_m + np.arange(shape[1]) * node_m - feature.at_m[0]
            y = y0_m + np.arange(shape[0]) * node_m - feature.at_m[1]
            # The centre's distance from the floor (0 inside it): beyond three widths the seamount raises nothing.
            if np.hypot(max(x.min(), -x.max(), 0.0), max(y.min(), -y.max(), 0.0)) > 3.0 * feature.width_m:
                raise ValueError(_off_floor(index, feature, shape, node_m, x0_m, y0_m))
            total -= feature.height_m * np.exp(-(x[None, :] ** 2 + y[:, None] ** 2) / feature.width_m**2)
            continue
        reach = 4.0 * feature.width_m if feature.kind == "ridge" else 6.0 * feature.width_m
        box, distance = _distance_to_path(shape, node_m, _winding_path(feature, node_m, rng), reach, x0_m, y0_m)
        if box is None:
            raise ValueError(_off_floor(index, feature, shape, node_m, x0_m, y0_m))
        if feature.kind == "canyon":
            total[box] += feature.height_m / (1.0 + (distance / feature.width_m) ** 4)
        else:
            total[box] -= feature.height_m * np.exp(-((distance / feature.width_m) ** 2))
    return total


def _off_floor(index: int, feature: Feature, shape: tuple[int, int], node_m: float, x0_m: float, y0_m: float) -> str:
    where = f"at_m = {feature.at_m}" if feature.kind == "seamount" else f"path_m = {feature.path_m}"
    return (f"terrain.features[{index}], a {feature.kind} ({where}), lies wholly off the floor (east {x0_m:g} to "
            f"{x0_m + (shape[1] - 1) * node_m:g} m, north {y0_m:g} to {y0_m + (shape[0] - 1) * node_m:g} m)")


def _winding_path(feature: Feature, node_m: float, rng: np.random.Generator) -> np.ndarray:
    """Points every half node along the feature's path, offset across it by a random sinuous meander."""
    corners = np.asarray(feature.path_m, float)
    legs = np.hypot(*np.diff(corners, axis=0).T)
    along = np.concatenate([[0.0], np.cumsum(legs)])
    s = np.arange(0.0, along[-1] + node_m / 2, node_m / 2)
    points = np.column_stack([np.interp(s, along, corners[:, 0]), np.interp(s, along, corners[:, 1])])
    if feature.meander_m > 0:
        # A smoothed random walk across the path: bends of about the wavelength that neither repeat nor keep one size.
        step = node_m / 2
        white = rng.normal(0.0, 1.0, s.size + 4 * int(feature.meander_wavelength_m / step))
        offset = ndimage.gaussian_filter1d(white, feature.meander_wavelength_m / (2 * np.pi * step), mode="wrap")[: s.size]
        offset *= feature.meander_m / max(float(np.std(offset)), 1e-12) / np.sqrt(2.0)
        offset -= np.linspace(offset[0], offset[-1], s.size)  # the path still starts and ends where it is told
        direction = np.gradient(points, axis=0)
        across = np.column_stack([direction[:, 1], -direction[:, 0]]) / np.maximum(np.hypot(*direction.T), 1e-12)[:, None]
        points = points + offset[:, None] * across
    return points


def _distance_to_path(shape: tuple[int, int], node_m: float, points: np.ndarray, reach_m: float, x0_m: float,
                      y0_m: float) -> tuple[tuple[slice, slice] | None, np.ndarray]:
    """Distance (metres) from each node within ``reach_m`` of the path's box to the path: an exact Euclidean
    distance transform of the path drawn on the nodes (a fraction of a node off at most)."""
    col = (points[:, 0] - x0_m) / node_m
    row = (points[:, 1] - y0_m) / node_m
    margin = int(np.ceil(reach_m / node_m))
    r0, r1 = max(int(np.floor(row.min())) - margin, 0), min(int(np.ceil(row.max())) + margin + 1, shape[0])
    c0, c1 = max(int(np.floor(col.min())) - margin, 0), min(int(np.ceil(col.max())) + margin + 1, shape[1])
    if r0 >= r1 or c0 >= c1:
        return None, np.empty(0)
    off_path = np.ones((r1 - r0, c1 - c0), bool)
    r, c = np.rint(row).astype(int) - r0, np.rint(col).astype(int) - c0
    inside = (r >= 0) & (r < r1 - r0) & (c >= 0) & (c < c1 - c0)
    if not inside.any():
        return None, np.empty(0)
    off_path[r[inside], c[inside]] = False
    return (slice(r0, r1), slice(c0, c1)), ndimage.distance_transform_edt(off_path, sampling=node_m)


def node_scale_relief(depth_m: np.ndarray) -> float:
    """A grid's own relief at its node scale: the standard deviation of its departure from the 3 x 3 mean
    around each node (a plane, a slope, leaves none)."""
    filled = np.where(np.isfinite(depth_m), depth_m, np.nanmean(depth_m))
    residual = filled - ndimage.uniform_filter(filled, size=3, mode="nearest")
    valid = ndimage.minimum_filter(np.isfinite(depth_m), size=3, mode="nearest")
    return float(np.std(residual[1:-1, 1:-1][valid[1:-1, 1:-1]])) if valid[1:-1, 1:-1].any() else 0.0


def refine(depth_m: np.ndarray, factor: int, *, seed: int, detail_m: float | None = None, hurst: float = 0.8) -> np.ndarray:
    """A coarse grid refined ``factor`` times, with fractal detail below its own node: a floor finer than its map.

    The coarse grid is interpolated by a cubic spline onto nodes ``factor`` times closer (node (0, 0) stays
    node (0, 0); the last coarse node is the last fine one), then a random surface is added whose spectrum is a
    power law (``hurst``) at wavelengths shorter than two coarse nodes and zero beyond them, so a coarse cell's
    mean keeps the coarse depth. ``detail_m`` is its standard deviation; None: the coarse grid's own relief at its
    node scale (:func:`node_scale_relief`), the power law carried on below it. Holes stay holes (a fine node
    next to a coarse hole is NaN).
    """
    if factor < 1:
        raise ValueError(f"the refinement factor must be a whole number of at least 1, got {factor!r}")
    depth_m = np.asarray(depth_m, float)
    if factor == 1:
        return depth_m.copy()
    rows, cols = (np.array(depth_m.shape) - 1) * factor + 1
    fine_row = np.arange(rows) / factor
    fine_col = np.arange(cols) / factor
    grid_rows, grid_cols = np.meshgrid(fine_row, fine_col, indexing="ij")
    holes = ~np.isfinite(depth_m)
    filled = depth_m
    if holes.any():
        # The spline needs numbers everywhere: each hole takes its nearest depth, then the hole is put back.
        nearest = ndimage.distance_transform_edt(holes, return_distances=False, return_indices=True)
        filled = depth_m[tuple(nearest)]
    fine = ndimage.map_coordinates(filled, [grid_rows, grid_cols], order=3, mode="nearest")
    if holes.any():
        fine[np.isnan(ndimage.map_coordinates(depth_m, [grid_rows, grid_cols], order=1, mode="nearest"))] = np.nan
    scale = node_scale_relief(depth_m) if detail_m is None else detail_m
    if scale > 0:
        fine = fine + scale * _detail((rows, cols), np.random.default_rng([seed, 31]), hurst=hurst, longest_nodes=2.0 * factor)
    return fine


def _detail(shape: tuple[int, int], rng: np.random.Generator, *, hurst: float, longest_nodes: float) -> np.ndarray:
    """Unit-variance power-law relief with no wavelength longer than ``longest_nodes`` (a smooth cut over a factor 1.5)."""
    ky = np.fft.fftfreq(shape[0])[:, None]
    kx = np.fft.rfftfreq(shape[1])[None, :]
    k = np.hypot(ky, kx)
    k[0, 0] = np.inf
    cut = 1.0 / longest_nodes
    taper = np.clip((k - cut) / (0.5 * cut), 0.0, 1.0)  # 0 below the cut, 1 from 1.5 times it on
    amplitude = k ** (-(hurst + 1.0)) * np.sin(0.5 * np.pi * taper) ** 2
    surface = np.fft.irfft2(amplitude * np.exp(1j * rng.uniform(0.0, 2.0 * np.pi, amplitude.shape)), s=shape)
    return surface / max(surface.std(), 1e-12)
