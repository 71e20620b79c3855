"""Regular grids resampled onto square metric nodes and scattered soundings gridded, holes kept as holes."""

from __future__ import annotations

import math

import numpy as np

from ..grid import Grid
from .crs import _same_crs, _target_crs, as_crs, transformer

# Above this many nodes a grid is almost surely a mistaken node_m (1e8 float64 nodes are 800 MB).
_MAX_NODES = 100_000_000

def _regular_to_grid(values, xs, ys, file_crs, *, crs, node_m, sigma=None) -> Grid:
    """A regular (possibly geographic, possibly non-square) grid onto square metric nodes.

    ``sigma``, the depth's standard deviation per node (or None), is kept node for node or resampled as the
    depth is (bilinear; NaN where a NaN of the layer carries weight).
    """
    target = _target_crs(file_crs, crs, xs, ys)
    reproject = file_crs is not None and target is not None and not _same_crs(file_crs, target)
    if xs.size < 2 or ys.size < 2:
        raise ValueError(f"a grid needs at least 2 x 2 nodes to be georeferenced, got {ys.size} x {xs.size}")
    dx, dy = (float(c[-1] - c[0]) / (c.size - 1) for c in (xs, ys))
    # Uniform when every node lies within a thousandth of a node, or a float32 rounding, of its place:
    # float32 coordinate variables (common in NetCDF) must not force a resampling.
    slack_x, slack_y = _slack(xs, dx), _slack(ys, dy)
    uniform = _off_place(xs, dx) <= slack_x and _off_place(ys, dy) <= slack_y
    if not reproject:
        # Square when one spacing, the better known of the two, puts every node of both axes within its slack.
        node = dx if slack_x / (xs.size - 1) <= slack_y / (ys.size - 1) else dy
        square = abs(node - dx) * (xs.size - 1) <= slack_x and abs(node - dy) * (ys.size - 1) <= slack_y
        if uniform and square and (node_m is None or math.isclose(node_m, node, rel_tol=1e-9)):
            return Grid(depth_m=values, x0_m=float(xs[0]), y0_m=float(ys[0]), node_m=node, crs=target, sigma_m=sigma)
        node_m = node_m or min(dx, dy)
        x_lo, x_hi, y_lo, y_hi = xs[0], xs[-1], ys[0], ys[-1]
        to_target = None
    else:
        to_target = transformer(file_crs, target)
        if node_m is None:
            # The file's finer spacing, measured in metres at its centre.
            xc, yc = xs[xs.size // 2], ys[ys.size // 2]
            px, py = to_target.transform([xc, xc + dx, xc], [yc, yc, yc + dy])
            node_m = min(math.hypot(px[1] - px[0], py[1] - py[0]), math.hypot(px[2] - px[0], py[2] - py[0]))
        x_lo, y_lo, x_hi, y_hi = to_target.transform_bounds(xs[0], ys[0], xs[-1], ys[-1], densify_pts=101)
    x0 = math.ceil(x_lo / node_m - 1e-9) * node_m
    y0 = math.ceil(y_lo / node_m - 1e-9) * node_m
    cols = math.floor((x_hi - x0) / node_m + 1e-9) + 1
    rows = math.floor((y_hi - y0) / node_m + 1e-9) + 1
    if rows < 1 or cols < 1:
        raise ValueError(f"node_m={node_m} m leaves no node inside the grid's extent")
    if rows * cols > _MAX_NODES:
        raise ValueError(f"node_m={node_m:g} m would make a {rows} x {cols} grid; pass a coarser node_m")
    node_x = x0 + np.arange(cols) * node_m
    node_y = y0 + np.arange(rows) * node_m
    qx, qy = np.meshgrid(node_x, node_y)
    if to_target is not None:
        from pyproj.enums import TransformDirection

        qx, qy = to_target.transform(qx, qy, direction=TransformDirection.INVERSE)
        if as_crs(file_crs).is_geographic:
            # PROJ answers longitudes in [-180, 180); a file may run 0 to 360.
            qx = xs[0] + np.mod(np.asarray(qx) - xs[0], 360.0)
    depth = _interpolate_keeping_holes(values, xs, ys, np.asarray(qx), np.asarray(qy))
    if sigma is not None:
        sigma = _interpolate_keeping_holes(sigma, xs, ys, np.asarray(qx), np.asarray(qy))
        sigma[np.isnan(depth)] = np.nan
    return Grid(depth_m=depth, x0_m=float(x0), y0_m=float(y0), node_m=float(node_m), crs=target, sigma_m=sigma)


def _slack(coords: np.ndarray, step: float) -> float:
    return max(1e-3 * abs(step), float(np.spacing(np.float32(np.max(np.abs(coords))))))


def _off_place(coords: np.ndarray, step: float) -> float:
    """How far the farthest node lies from a uniform spacing of ``step``."""
    return float(np.max(np.abs(coords - (coords[0] + np.arange(coords.size) * step))))


def _interpolate_keeping_holes(values, xs, ys, qx, qy) -> np.ndarray:
    """Bilinear interpolation; NaN wherever a hole carries weight or the point lies outside."""
    from scipy.interpolate import RegularGridInterpolator

    holes = np.isnan(values)
    filled = np.where(holes, 0.0, values)
    points = np.stack([qy.ravel(), qx.ravel()], axis=-1)
    depth = RegularGridInterpolator((ys, xs), filled, bounds_error=False, fill_value=np.nan)(points)
    if holes.any():
        hole_weight = RegularGridInterpolator((ys, xs), holes.astype(np.float64), bounds_error=False, fill_value=1.0)(points)
        depth[hole_weight > 1e-9] = np.nan
    return depth.reshape(qx.shape)


def _lattice(x: np.ndarray, y: np.ndarray, z: np.ndarray):
    """``(values, xs, ys)`` when the soundings sit on a regular lattice (a gridded export), holes NaN; else None."""
    xs, ys = np.unique(x), np.unique(y)
    if xs.size < 2 or ys.size < 2:
        return None
    dx, dy = float(np.min(np.diff(xs))), float(np.min(np.diff(ys)))
    col, row = (x - xs[0]) / dx, (y - ys[0]) / dy
    on_lattice = np.allclose(col, np.round(col), rtol=0, atol=1e-3) and np.allclose(row, np.round(row), rtol=0, atol=1e-3)
    cols, rows = int(round((xs[-1] - xs[0]) / dx)) + 1, int(round((ys[-1] - ys[0]) / dy)) + 1
    # Mostly full, or scattered soundings written with few decimals would pass for a fine lattice.
    if not on_lattice or x.size < 0.5 * rows * cols or rows * cols > _MAX_NODES:
        return None
    r, c = np.round(row).astype(np.int64), np.round(col).astype(np.int64)
    sums, counts = np.zeros((rows, cols)), np.zeros((rows, cols))
    np.add.at(sums, (r, c), z)
    np.add.at(counts, (r, c), 1)  # repeated soundings of a node: their mean
    with np.errstate(invalid="ignore"):
        values = np.where(counts > 0, sums / counts, np.nan)
    return values, xs[0] + np.arange(cols) * dx, ys[0] + np.arange(rows) * dy


def _grid_soundings(x, y, z, *, node_m, max_gap_m, crs, name) -> Grid:
    import pandas as pd
    from scipy.interpolate import LinearNDInterpolator
    from scipy.spatial import Delaunay, QhullError, cKDTree
    from threadpoolctl import threadpool_limits

    # Repeated positions would make a degenerate triangulation; their mean is the honest depth.
    merged = pd.DataFrame({"x": x, "y": y, "z": z}).groupby(["x", "y"], sort=False, as_index=False)["z"].mean()
    x, y, z = (merged[c].to_numpy() for c in ("x", "y", "z"))
    if z.size < 3:
        raise ValueError(f"{name}: soundings at {z.size} distinct position(s); gridding needs at least 3")
    tree = cKDTree(np.column_stack([x, y]))
    if node_m is None:
        node_m = float(np.median(tree.query(np.column_stack([x, y]), k=2)[0][:, 1]))
    # By default a triangle may not bridge more than two nodes; an explicit max_gap_m is the user's one rule.
    longest_side_m = 2 * node_m if max_gap_m is None else math.inf
    max_gap_m = node_m if max_gap_m is None else max_gap_m
    x0 = math.ceil(x.min() / node_m - 1e-9) * node_m
    y0 = math.ceil(y.min() / node_m - 1e-9) * node_m
    cols = math.floor((x.max() - x0) / node_m + 1e-9) + 1
    rows = math.floor((y.max() - y0) / node_m + 1e-9) + 1
    if rows * cols > _MAX_NODES:
        raise ValueError(f"{name}: node_m={node_m:g} m would make a {rows} x {cols} grid; pass a coarser node_m")
    qx, qy = np.meshgrid(x0 + np.arange(cols) * node_m, y0 + np.arange(rows) * node_m)
    # Only nodes with a sounding within max_gap_m get a depth; the others stay holes, never interpolated.
    gap = tree.query(np.column_stack([qx.ravel(), qy.ravel()]), k=1, distance_upper_bound=max_gap_m * (1 + 1e-9))[0]
    near = np.isfinite(gap).reshape(qx.shape)
    depth = np.full(qx.shape, np.nan)
    try:
        # Delaunay's barycentric transforms call LAPACK once per triangle, where BLAS threads only
        # contend (20 times slower on a busy 2-core machine).
        with threadpool_limits(limits=1, user_api="blas"):
            triangles = Delaunay(np.column_stack([x, y]))
            # A triangle with a side longer than two nodes spans a hole or a concave edge of the survey:
            # the nodes it covers are not bridged, even when one of its corners is near.
            corners = triangles.points[triangles.simplices]
            longest = np.max(np.hypot(*(corners - np.roll(corners, 1, axis=1)).transpose(2, 0, 1)), axis=1)
            within = triangles.find_simplex(np.column_stack([qx[near], qy[near]]))
            bridged = np.zeros(qx.shape, dtype=bool)
            bridged[near] = (within >= 0) & (longest[within] <= longest_side_m * (1 + 1e-9))
            depth[bridged] = LinearNDInterpolator(triangles, z)(qx[bridged], qy[bridged])
    except QhullError:
        raise ValueError(f"{name}: the soundings cannot be triangulated (are they all on one line?)") from None
    return Grid(depth_m=depth, x0_m=float(x0), y0_m=float(y0), node_m=float(node_m), crs=crs)
