"""``lost plan MAP [--route WAYPOINTS.csv] [--config SCENARIO.toml] --out DIR``: where terrain navigation will work.

Writes ``accuracy.nc`` (the predicted 1-sigma horizontal error of one correlation at every node, metres; read it with
``lost.host.io.read_grid(path, variable="accuracy_m")``; beside it the look-alike layers: ``false_lock_probability``,
``lookalike_separation``, ``lookalike_distance_m``), ``accuracy.png``, and with ``--route`` the predicted error
along the route (``route.csv``, ``route.png``); ``summary.json`` last. The model: ``lost.host.plan``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from ..runfolder import run_folder, write_summary
from .common import output_options, positive_metres, warnings_collected

__all__ = ["register", "run_plan", "scenario_motion", "scenario_sonar"]


def scenario_sonar(scenario, node_m: float):
    """The sonar model of a scenario's ``[sensors.sonar]`` on a map of ``node_m``: its patch, its noise per sounding, and for
    a swath binned into the nodes the soundings a node averages (the beams across its width a node holds, times the pings
    along a node at the ship's speed, less the beams without a return)."""
    from ..plan import SonarModel
    from ..plan.fill import Sweep
    from ..scenario.spec import KNOT_MPS

    spec = scenario.sensors["sonar"]
    soundings = 1.0
    if spec.mode == "swath":
        width_m = Sweep(shape=tuple(spec.shape), node_m=node_m, swath_width_m=spec.swath_width_m).width_m
        pings = node_m / (scenario.ship.speed_kn * KNOT_MPS * spec.interval_s)
        soundings = max(spec.beams * node_m / width_m * pings * (1.0 - spec.missing_beam_rate), 1.0)
    return SonarModel(shape=tuple(spec.shape), noise_m=max(spec.noise, 1e-3), binned=spec.mode == "swath", realtime=spec.realtime,
                      soundings_per_node=soundings)


def scenario_motion(scenario, node_m: float | None = None) -> dict:
    """What a scenario tells the route model beside its navigation: the ship's speed, the sonar's interval, the
    velocity sensor's own noise and bias where the vehicle carries one (else the ship's velocity, whose errors are
    the tow's, not a sensor's), whether the filters take a slant range, and, on a map of ``node_m``, how a real-time
    swath sweeps its patch."""
    from ..nav import NavParameters
    from ..plan import Sweep
    from ..scenario.spec import KNOT_MPS

    spec = scenario.sensors["sonar"]
    motion = {"speed_mps": scenario.ship.speed_kn * KNOT_MPS, "interval_s": spec.interval_s}
    velocity = scenario.sensors.get("velocity")
    if scenario.vehicle.has_velocity_sensor and velocity is not None:
        bias = np.broadcast_to(np.asarray(velocity.bias, dtype=np.float64), (2,))
        motion.update(sensor_velocity_noise_mps=float(velocity.noise), sensor_velocity_bias_mps=(float(bias[0]), float(bias[1])))
    ranges = scenario.sensors.get("slant_range")
    if ranges is not None and ranges.enabled and NavParameters(**scenario.navigation).use_slant_range:
        motion["slant_range"] = True
    if node_m is not None and spec.mode == "swath" and spec.realtime:
        motion["sweep"] = Sweep(shape=tuple(spec.shape), node_m=node_m, swath_width_m=spec.swath_width_m, max_window_s=spec.max_window_s)
    return motion


def _models(args: argparse.Namespace, node_m: float):
    """The sonar and route models: the defaults, a scenario's sonar, ship and navigation (``--config``), then the options."""
    import dataclasses

    from ..nav import NavParameters
    from ..plan import RouteModel, SonarModel

    sonar, motion, params = SonarModel(), {}, NavParameters()
    if args.config is not None:
        from ..scenario import load_scenario

        scenario = load_scenario(args.config)
        params = NavParameters(**scenario.navigation)
        sonar = scenario_sonar(scenario, node_m)
        motion = scenario_motion(scenario, node_m)
    if args.sonar_noise_m is not None:
        sonar = dataclasses.replace(sonar, noise_m=args.sonar_noise_m)
    if args.speed_mps is not None:
        motion["speed_mps"] = args.speed_mps
    if args.initial_error_m is not None:
        motion["initial_error_m"] = args.initial_error_m
    model = RouteModel.from_navigation(params, node_m, patch_nodes=float(np.sqrt(np.prod(sonar.shape))), patch_lag_m=sonar.lag_m(node_m), **motion)
    return sonar, model, params.lookalike_radius_m if args.lookalike_radius_m is None else args.lookalike_radius_m


def run_plan(args: argparse.Namespace) -> int:
    """The handler of ``lost plan``."""
    from ..io import read_grid
    from ..plan import accuracy_grid, held_grid, held_sigma, lookalike_grid, map_sigma, predict_route, read_route
    from ..plan.output import lookalike_layers, plan_plots, write_accuracy_netcdf, write_route_csv
    from ..plotting import draw_plots

    out = args.out = args.out or Path("runs") / "plan" / Path(args.map).stem
    with run_folder(out, replace=args.replace, command="plan") as folder, warnings_collected() as warnings:
        grid = read_grid(args.map, node_m=args.node_m)
        sonar, model, radius_m = _models(args, grid.node_m)
        waypoints = read_route(args.route) if args.route is not None else None
        start = time.perf_counter()
        sigma = map_sigma(grid, args.map_sigma_m)
        accuracy = accuracy_grid(grid, sonar, sigma)
        bound_s = time.perf_counter() - start
        lookalike = lookalike_grid(grid, sonar, sigma, radius_m=radius_m)
        layers = lookalike_layers(lookalike)
        held = None if waypoints is None else held_grid(grid, sonar, sigma, held_sigma(grid, sonar, args.map_sigma_m))
        route = None if waypoints is None else predict_route(accuracy, waypoints, model, lookalike, held)
        elapsed = (bound_s, time.perf_counter() - start - bound_s)
        write_accuracy_netcdf(folder / "accuracy.nc", accuracy, layers)
        if route is not None:
            write_route_csv(folder / "route.csv", route)
        draw_plots(folder, plan_plots(accuracy, route, Path(args.map).stem, layers["false_lock_probability"]), warnings)
        summary = _summary(args, grid, accuracy, sonar, model, route, elapsed, layers)
        summary["warnings"] = list(warnings)
        write_summary(folder / "summary.json", summary)
    _print(summary, out)
    return 0


def _summary(args, grid, accuracy, sonar, model, route, elapsed: tuple[float, float], layers: dict) -> dict:
    bound = accuracy.depth_m[np.isfinite(accuracy.depth_m)]
    false_lock = layers["false_lock_probability"]
    summary = {"map": str(args.map), "shape": list(grid.shape), "node_m": grid.node_m, "crs": grid.crs, "sonar": {"shape": list(sonar.shape),
               "noise_m": sonar.noise_m}, "survey_sigma_m": args.map_sigma_m, "compute_s": round(elapsed[0], 3),
               "lookalike_compute_s": round(elapsed[1], 3),
               "false_lock_share": None if not np.isfinite(false_lock).any() else float(np.nanmean(false_lock > 0.5)),
               "nodes_with_a_bound": int(bound.size), "usable_sigma_m": model.usable_sigma_m,
               "usable_share": float(np.mean(accuracy.depth_m <= model.usable_sigma_m)),
               "bound_m": None if not bound.size else {q: float(np.percentile(bound, p)) for q, p in (("p10", 10), ("median", 50), ("p90", 90))}}
    if route is not None:
        summary["route"] = {"route": str(args.route), "updates": int(len(route["t_s"])), "duration_s": float(route["t_s"][-1]),
                            "usable_share": float(route["usable"].mean()), "predicted_median_m": float(np.median(route["predicted_m"])),
                            "predicted_max_m": float(route["predicted_m"].max()),
                            "unlocked_at_end": float(route["unlocked"][-1]), "first_lock_s": _first_lock(route)}
    return summary


def _first_lock(route: dict) -> float | None:
    """When the prediction first holds the lock with at least even odds (seconds along the route), or None."""
    held = np.flatnonzero(route["unlocked"] < 0.5)
    return float(route["t_s"][held[0]]) if held.size else None


def _print(summary: dict, out: Path) -> None:
    bound = summary["bound_m"]
    print(f"{summary['map']}: {summary['shape'][0]} x {summary['shape'][1]} nodes of {summary['node_m']:g} m, bound computed in "
          f"{summary['compute_s']:.2f} s, look-alikes in {summary['lookalike_compute_s']:.2f} s")
    if bound:
        print(f"one fix's 1-sigma bound: median {bound['median']:.2f} m (10 % of nodes below {bound['p10']:.2f} m, 90 % below {bound['p90']:.2f} m); "
              f"usable (<= {summary['usable_sigma_m']:g} m) on {summary['usable_share']:.0%} of the map")
    if summary["false_lock_share"] is not None:
        print(f"a patch more likely to lock on a look-alike than on the truth on {summary['false_lock_share']:.0%} of the map")
    route = summary.get("route")
    if route:
        lock = "never" if route["first_lock_s"] is None else f"from {route['first_lock_s']:.0f} s"
        print(f"route: {route['duration_s']:.0f} s, terrain usable on {route['usable_share']:.0%} of it, the lock held {lock}; predicted error "
              f"median {route['predicted_median_m']:.1f} m, at most {route['predicted_max_m']:.1f} m")
    for warning in summary["warnings"]:
        print(f"warning: {warning}")
    print(f"wrote {out}/accuracy.nc" + (", route.csv" if route else "") + ", summary.json and plots")


def register(commands, parents: list[argparse.ArgumentParser]) -> None:
    """Add ``lost plan``."""
    sub = commands.add_parser("plan", parents=parents, help="predict from a map where terrain navigation will fix the position, and how well")
    sub.add_argument("map", type=Path, help="bathymetry grid (any file read_grid reads)")
    sub.add_argument("--route", type=Path, default=None, help="waypoints CSV (east_m, north_m in the map's CRS): the predicted error along it")
    sub.add_argument("--config", type=Path, default=None, help="a scenario TOML: its sonar patch and noise, ship speed and [navigation]")
    sub.add_argument("--node-m", type=positive_metres, default=None, help="node spacing of the map, metres (default: the file's)")
    sub.add_argument("--map-sigma-m", type=float, default=None,
                     help="the map's survey noise, 1 sigma, metres, when the grid carries no uncertainty layer (default 0.5); the slope and "
                          "relief a node cannot show are added from the map itself, as the filters do")
    sub.add_argument("--sonar-noise-m", type=positive_metres, default=None, help="the sonar's 1-sigma depth noise, metres (default 0.5, or the scenario's)")
    sub.add_argument("--initial-error-m", type=positive_metres, default=None,
                     help="the start's expected horizontal error, metres (a lay-back model's): what the estimate shows while the filters search "
                          "(default: their prior, initial_sigma_m each axis)")
    sub.add_argument("--speed-mps", type=positive_metres, default=None, help="speed along the route, m/s (default 1.5, or the scenario ship's)")
    sub.add_argument("--lookalike-radius-m", type=positive_metres, default=None,
                     help="how far from each node look-alikes are searched, metres (default the navigation's lookalike_radius_m, 600)")
    output_options(sub, "runs/plan/MAP")
    sub.set_defaults(handler=run_plan)
