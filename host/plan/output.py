"""The files of ``lost plan``: ``accuracy.nc`` (a grid ``lost.host.io.read_grid`` reads), the route's CSV, the pictures."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..grid import Grid
from ..plotting import map_figure_size, pyplot

__all__ = ["write_accuracy_netcdf", "write_route_csv", "plan_plots", "lookalike_layers", "ACCURACY_VARIABLE", "LOOKALIKE_ATTRS"]

#: The NetCDF variable of the predicted 1-sigma horizontal error (``read_grid(path, variable=ACCURACY_VARIABLE)``).
ACCURACY_VARIABLE = "accuracy_m"

#: The look-alike layers of ``accuracy.nc`` and their attributes.
LOOKALIKE_ATTRS = {
    "false_lock_probability": {"long_name": "chance that one patch here prefers a look-alike within the search radius over the truth",
                               "units": "1"},
    "lookalike_separation": {"long_name": "the runner-up's separation n D / s^2 (the look-alike beyond two nodes that fits best)", "units": "1"},
    "lookalike_distance_m": {"long_name": "the runner-up's distance from the truth", "units": "m"},
}


def lookalike_layers(lookalike) -> dict[str, np.ndarray]:
    """The grids ``accuracy.nc`` carries of a :class:`~lost.host.plan.ambiguity.Lookalike`."""
    from .route import false_lock_probability

    separation, distance = lookalike.best()
    return {"false_lock_probability": false_lock_probability(lookalike), "lookalike_separation": separation,
            "lookalike_distance_m": distance}


def write_accuracy_netcdf(path: Path, accuracy: Grid, lookalikes: dict[str, np.ndarray] | None = None) -> None:
    """``accuracy.nc``: CF coordinates ``x``/``y`` (metres, the map's CRS), the bound in metres (NaN where there is none),
    and the look-alike layers (:func:`lookalike_layers`) when given."""
    import xarray as xr

    rows, cols = accuracy.shape
    values = np.where(np.isfinite(accuracy.depth_m), accuracy.depth_m, np.nan)
    attrs = {"long_name": "predicted 1-sigma horizontal error of one correlation (Cramer-Rao bound)", "units": "m", "positive": "down"}
    layers = {name: (("y", "x"), values.astype(np.float32), dict(LOOKALIKE_ATTRS[name])) for name, values in (lookalikes or {}).items()}
    data = xr.Dataset(
        {ACCURACY_VARIABLE: (("y", "x"), values, attrs), **layers},
        coords={"x": ("x", accuracy.x0_m + np.arange(cols) * accuracy.node_m, {"units": "m", "standard_name": "projection_x_coordinate"}),
                "y": ("y", accuracy.y0_m + np.arange(rows) * accuracy.node_m, {"units": "m", "standard_name": "projection_y_coordinate"})},
        attrs={"Conventions": "CF-1.8", "title": "LOST terrain-navigation accuracy", **({"crs": accuracy.crs} if accuracy.crs else {})},
    )
    data.to_netcdf(path)


def write_route_csv(path: Path, route: dict[str, np.ndarray]) -> None:
    """One row per update: time, position, the map's bound there, usable, the predicted error."""
    import pandas as pd

    pd.DataFrame(route).to_csv(path, index=False, float_format="%.4f")


def plan_plots(accuracy: Grid, route: dict[str, np.ndarray] | None, name: str,
               false_lock: np.ndarray | None = None) -> dict[str, Callable[[Path], None]]:
    """``accuracy.png`` (the bound over the map, log colour, the route on it; beside it the false-lock probability) and
    ``route.png`` (the error along it)."""
    plots = {"accuracy.png": lambda path: _accuracy_png(path, accuracy, route, name, false_lock)}
    if route is not None:
        plots["route.png"] = lambda path: _route_png(path, route, name)
    return plots


def _accuracy_png(path: Path, accuracy: Grid, route: dict[str, np.ndarray] | None, name: str, false_lock: np.ndarray | None) -> None:
    from matplotlib.colors import LogNorm

    rows, cols = accuracy.shape
    extent = (accuracy.x0_m, accuracy.x0_m + (cols - 1) * accuracy.node_m, accuracy.y0_m, accuracy.y0_m + (rows - 1) * accuracy.node_m)
    finite = accuracy.depth_m[np.isfinite(accuracy.depth_m) & (accuracy.depth_m > 0)]
    width, height = map_figure_size(extent[1] - extent[0], extent[3] - extent[2])
    panels = 1 if false_lock is None else 2
    fig, axes = pyplot().subplots(panels, 1, figsize=(width, height * panels), layout="constrained", squeeze=False)
    ax = axes[0, 0]
    norm = LogNorm(vmin=max(float(np.percentile(finite, 1)), 1e-3), vmax=float(np.percentile(finite, 99))) if finite.size else None
    image = ax.imshow(np.where(np.isfinite(accuracy.depth_m), accuracy.depth_m, np.nan), origin="lower", extent=extent, cmap="magma_r", norm=norm)
    fig.colorbar(image, ax=ax, label="predicted 1-sigma error of one fix (m)")
    if route is not None:
        ax.plot(route["east_m"], route["north_m"], color="cyan", lw=1.2, label="route")
        ax.legend(loc="upper right", fontsize="small")
    ax.set(xlabel="easting (m)", ylabel="northing (m)", title=f"{name}: where the terrain fixes the position (grey: no fix)", aspect="equal")
    ax.set_facecolor("0.8")
    if false_lock is not None:
        ax = axes[1, 0]
        image = ax.imshow(false_lock, origin="lower", extent=extent, cmap="Reds", vmin=0.0, vmax=1.0)
        fig.colorbar(image, ax=ax, label="chance one patch prefers a look-alike")
        if route is not None:
            ax.plot(route["east_m"], route["north_m"], color="tab:blue", lw=1.2)
        ax.set(xlabel="easting (m)", ylabel="northing (m)", title="where the terrain looks alike: do not trust a lock taken here", aspect="equal")
        ax.set_facecolor("0.8")
    fig.savefig(path, dpi=110)


def _route_png(path: Path, route: dict[str, np.ndarray], name: str) -> None:
    fig, ax = pyplot().subplots(figsize=(10, 4), layout="constrained")
    ax.plot(route["t_s"], route["predicted_m"], color="tab:blue", label="predicted RMS error")
    if "locked_m" in route:
        ax.plot(route["t_s"], route["locked_m"], color="tab:green", lw=0.8, label="holding the lock")
        twin = ax.twinx()
        twin.plot(route["t_s"], route["unlocked"], color="tab:red", lw=0.8)
        twin.set(ylabel="chance of not holding the lock", ylim=(0.0, 1.02))
    bound = np.where(np.isfinite(route["bound_m"]), route["bound_m"], np.nan)
    ax.plot(route["t_s"], bound, color="0.5", lw=0.6, label="one fix's bound at the position")
    unusable = ~route["usable"]
    if unusable.any():
        top = float(np.nanmax(route["predicted_m"]))
        ax.fill_between(route["t_s"], 0.0, top, where=unusable, color="tab:red", alpha=0.12, lw=0, label="terrain not usable")
    ax.set(xlabel="time along the route (s)", ylabel="metres", yscale="log", title=f"{name}: predicted error along the route")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    fig.savefig(path, dpi=110)
