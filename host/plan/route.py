"""The predicted error along a route: the map's bound at each update, and the growth between informative stretches.

The vehicle follows the waypoints at a constant speed and correlates a patch every ``interval_s``. Between updates the
error grows as the dead reckoning's does: the velocity noise as a random walk (``velocity_noise_mps``) and a free
INS's bias terms (Nygren eq. 6.2, ``lost.host.nav.trust.ins_position_sigma``) from the last update, added in
variance. An update whose bound (:mod:`lost.host.plan.accuracy`) is within ``usable_sigma_m`` fuses as a Gaussian
measurement (``1/P = 1/P_prior + 1/bound^2``, per axis); a larger bound is no fix (terrain that says too little), and
the error keeps growing. ``usable`` says where the prediction trusts the terrain. The filters keep their density at
least ``floor_m`` wide (``NavParameters``' position floor: ``hypot(position_floor_nodes * node, position_floor_tracking_m)``),
so no update takes the prediction below it.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..grid import Grid

__all__ = ["RouteModel", "read_route", "route_points", "predict_route", "predict_along"]


@dataclass(frozen=True, kw_only=True)
class RouteModel:
    """The motion and dead-reckoning assumptions of a route prediction."""

    speed_mps: float = 1.5
    interval_s: float = 1.0
    initial_sigma_m: float = 50.0
    velocity_noise_mps: float = 0.05
    gyro_bias_rps: float = float(np.radians(0.01) / 3600.0)
    accel_bias_mps2: float = 10e-6 * 9.81
    usable_sigma_m: float = 10.0
    floor_m: float = 0.0

    @classmethod
    def from_navigation(cls, params: Any, node_m: float, **motion: float) -> RouteModel:
        """The model the navigation's parameters (``NavParameters``) imply on a map of ``node_m``: its dead reckoning's
        noise and biases, its usable threshold and its density's floor; ``motion`` sets speed_mps, interval_s and initial_sigma_m."""
        return cls(velocity_noise_mps=params.velocity_noise_mps, gyro_bias_rps=params.gyro_bias_rps, accel_bias_mps2=params.accel_bias_mps2,
                   usable_sigma_m=params.usable_sigma_nodes * node_m,
                   floor_m=float(np.hypot(params.position_floor_nodes * node_m, params.position_floor_tracking_m)), **motion)

    def __post_init__(self) -> None:
        for name in ("speed_mps", "interval_s", "initial_sigma_m", "usable_sigma_m"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value!r}")


def read_route(path: Path) -> np.ndarray:
    """Waypoints from a CSV with ``east_m`` and ``north_m`` columns (a header row), in the map's projected CRS.

    Raises
    ------
    ValueError
        A missing column, a non-number, fewer than two waypoints: the file and line named.
    """
    with open(path, newline="", encoding="utf-8") as handle:
        reader = csv.DictReader(handle)
        columns = {name.strip().lower(): name for name in reader.fieldnames or ()}
        if not {"east_m", "north_m"} <= set(columns):
            raise ValueError(f"{path}: a route needs the columns east_m and north_m, it has {sorted(columns) or 'none'}")
        points = []
        for line, row in enumerate(reader, start=2):
            try:
                points.append((float(row[columns["east_m"]]), float(row[columns["north_m"]])))
            except (TypeError, ValueError):
                raise ValueError(f"{path}, line {line}: east_m and north_m must be numbers, got {row}") from None
    route = np.asarray(points, dtype=np.float64)
    if len(route) < 2 or not np.isfinite(route).all():
        raise ValueError(f"{path}: a route needs at least two finite waypoints, got {len(route)}")
    return route


def route_points(waypoints: np.ndarray, model: RouteModel) -> tuple[np.ndarray, np.ndarray]:
    """Times and positions of the updates along the waypoints at ``model.speed_mps``, every ``model.interval_s``."""
    legs = np.diff(waypoints, axis=0)
    distance = np.concatenate(([0.0], np.cumsum(np.hypot(*legs.T))))
    t = np.arange(0.0, distance[-1] / model.speed_mps + 1e-9, model.interval_s)
    along = t * model.speed_mps
    return t, np.column_stack([np.interp(along, distance, waypoints[:, 0]), np.interp(along, distance, waypoints[:, 1])])


def predict_route(accuracy: Grid, waypoints: np.ndarray, model: RouteModel) -> dict[str, np.ndarray]:
    """The predicted 1-sigma horizontal error at every update along the waypoints, with the map's bound there."""
    t, xy = route_points(waypoints, model)
    return predict_along(accuracy, t, xy, model)


def predict_along(accuracy: Grid, t: np.ndarray, xy: np.ndarray, model: RouteModel) -> dict[str, np.ndarray]:
    """The predicted 1-sigma horizontal error at updates at times ``t`` and positions ``xy`` (a track already known)."""
    from ..nav.trust import ins_position_sigma

    row, col = accuracy.row_col(xy[:, 0], xy[:, 1])
    finite = np.isfinite(row) & np.isfinite(col)
    r, c = np.rint(np.where(finite, row, -1)).astype(int), np.rint(np.where(finite, col, -1)).astype(int)
    on_map = finite & (r >= 0) & (r < accuracy.shape[0]) & (c >= 0) & (c < accuracy.shape[1])
    bound = np.full(len(t), np.inf)
    bound[on_map] = accuracy.depth_m[r[on_map], c[on_map]]
    usable = bound <= model.usable_sigma_m
    variance = np.empty(len(t))  # per axis
    p_fix, last_fix, previous = model.initial_sigma_m**2 / 2, float(t[0]) if len(t) else 0.0, None
    for n, time_s in enumerate(t):
        since = time_s - last_fix
        step = model.interval_s if previous is None else max(time_s - previous, 0.0)
        ins = float(ins_position_sigma(since, gyro_bias_rps=model.gyro_bias_rps, accel_bias_mps2=model.accel_bias_mps2))
        p = p_fix + model.velocity_noise_mps**2 * since * step + ins**2
        if usable[n]:
            p = max(1.0 / (1.0 / p + 2.0 / bound[n] ** 2), model.floor_m**2 / 2)  # the bound is horizontal: half its variance on each axis
            p_fix, last_fix = p, time_s
        variance[n], previous = p, time_s
    return {"t_s": np.asarray(t), "east_m": xy[:, 0], "north_m": xy[:, 1], "bound_m": bound, "usable": usable, "predicted_m": np.sqrt(2.0 * variance)}
