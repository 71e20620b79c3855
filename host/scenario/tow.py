"""The tow: the ship on its waypoints, the vehicle on its cable, and the records its sensors make of it."""

from __future__ import annotations

import math

import numpy as np

from ..grid import Grid
from ..records import NavRecords
from .floor import floor_depth, scenario_floor
from .map import check_before_simulating, check_patch_fits, planned_map_shape, survey_map
from .sensors import read, usbl_pings
from .spec import KNOT_MPS, Scenario
from .swath import SwathSoundings, sonar_patches

__all__ = ["simulate", "simulate_with_swath"]


def simulate(scenario: Scenario) -> tuple[Grid, NavRecords]:
    """Simulate a tow: the navigation map and the records (with the truth) of the scenario, reproducible by its seed.

    The vehicle, its altimeter and its sonar see the true floor (:func:`scenario_floor`); the map
    returned is the survey of it that ``[map]`` describes.
    """
    return _simulate(scenario, None)


def simulate_with_swath(scenario: Scenario) -> tuple[Grid, NavRecords, SwathSoundings | None]:
    """:func:`simulate`, and the soundings its ``"swath"`` sonar gridded into the records' patches (None for another sonar).

    The map and records are :func:`simulate`'s, bit for bit: the soundings are handed out, not drawn again. An exporter
    writes them (:func:`lost.host.io.simulated.simulated_pings`) so that a file's pings are the very pings of the patches.
    """
    sounded: list[SwathSoundings] = []
    grid, records = _simulate(scenario, sounded)
    return grid, records, sounded[0] if sounded else None


def _simulate(scenario: Scenario, sounded: list[SwathSoundings] | None) -> tuple[Grid, NavRecords]:
    check_before_simulating(scenario)
    floor = scenario_floor(scenario)
    check_patch_fits(scenario, planned_map_shape(scenario, floor.shape, floor.node_m))
    grid = survey_map(floor, scenario.map, scenario.seed + 1 if scenario.map.seed is None else scenario.map.seed)
    rng = np.random.default_rng(scenario.seed)
    t = np.arange(int(round(scenario.duration_s * scenario.rate_hz))) / scenario.rate_hz
    ship_x, ship_y, heading = _ship_track(scenario, t)
    truth, depths = _vehicle_track(scenario, floor, ship_x, ship_y, heading)
    return grid, _records(scenario, rng, floor, grid.node_m, t, np.column_stack([ship_x, ship_y]), heading, truth, depths, sounded)


def _vehicle_track(scenario: Scenario, floor: Grid, ship_x: np.ndarray, ship_y: np.ndarray,
                   heading: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The vehicle's true positions (east, north) and depths: on its cable behind the ship, drifting with the water."""
    dt = 1.0 / scenario.rate_hz
    current_speed = scenario.current.speed_kn * KNOT_MPS
    toward = math.radians(scenario.current.toward_deg)
    current = current_speed * np.array([math.sin(toward), math.cos(toward)])
    speed = scenario.ship.speed_kn * KNOT_MPS
    cable, vehicle = scenario.cable, scenario.vehicle

    def layback(depth: float) -> float:
        if depth >= cable.out_m:
            # Clamping the lay-back to zero would hang the vehicle under the ship on a cable it does not have.
            raise ValueError(f"cable.out_m ({cable.out_m:g} m) is shorter than the vehicle's depth ({depth:.0f} m, the floor less "
                             "vehicle.altitude_m): the vehicle cannot reach its altitude; pay out more cable")
        return cable.catenary_factor * math.sqrt(cable.out_m**2 - depth**2)

    # Start in the steady state: trailing the ship's velocity through the water.
    ship_velocity = speed * np.array([math.sin(math.radians(heading[0])), math.cos(math.radians(heading[0]))])
    water_track = ship_velocity - current
    position = np.array([ship_x[0], ship_y[0]])
    depth = float(floor_depth(floor, position[0], position[1])) - vehicle.altitude_m
    depth = depth if np.isfinite(depth) else float(np.nanmean(floor.depth_m)) - vehicle.altitude_m
    position = position - layback(depth) * water_track / np.linalg.norm(water_track)
    truth = np.empty((ship_x.size, 2))
    depths = np.empty(ship_x.size)
    for n in range(ship_x.size):
        if n:
            position = position + current * dt
            ship = np.array([ship_x[n], ship_y[n]])
            towline = ship - position
            position = ship - layback(depth) * towline / max(np.linalg.norm(towline), 1e-9)
        below = float(floor_depth(floor, position[0], position[1]))
        if np.isfinite(below):
            depth += (below - vehicle.altitude_m - depth) * min(dt / vehicle.depth_time_constant_s, 1.0)
        truth[n], depths[n] = position, depth
    return truth, depths


def _records(scenario: Scenario, rng: np.random.Generator, floor: Grid, node_m: float, t: np.ndarray, ship: np.ndarray,
             heading: np.ndarray, truth: np.ndarray, depths: np.ndarray, sounded: list[SwathSoundings] | None = None) -> NavRecords:
    """What the sensors record of the tow (their draws from ``rng`` in a fixed order: a seed gives one tow)."""
    dt = 1.0 / scenario.rate_hz
    floor_below = floor_depth(floor, truth[:, 0], truth[:, 1])
    velocity = np.gradient(truth, dt, axis=0)
    sensors = scenario.sensors
    # A GPS fix (and its outliers) is one reading of both coordinates; the heading has its own sensor.
    gps = read(rng, ship, sensors["gps"])
    ship_heading = read(rng, heading, sensors["heading"]) % 360.0
    if scenario.vehicle.has_velocity_sensor:
        measured_velocity = read(rng, velocity, sensors["velocity"])
    else:
        measured_velocity = read(rng, np.gradient(ship, dt, axis=0), sensors["velocity"])
    # A dropped velocity reading loses both components.
    measured_velocity[np.isnan(measured_velocity).any(axis=1)] = np.nan
    if scenario.fault.at_s is not None:
        n = min(int(round(scenario.fault.at_s * scenario.rate_hz)), t.size - 1)
        measured_velocity[n] = np.nan_to_num(measured_velocity[n]) + np.asarray(scenario.fault.position_jump_m, float) / dt
    slant_spec = sensors["slant_range"]
    if slant_spec.enabled:
        true_range = np.sqrt(np.sum((truth - ship) ** 2, axis=1) + depths**2)
        slant = read(rng, true_range, slant_spec)
    else:
        slant = np.full(t.size, np.nan)
    recorded = {"ship": gps, "heading_deg": ship_heading, "depth_m": read(rng, depths, sensors["depth"])}
    usbl = usbl_pings(scenario, ship, heading, truth, depths, recorded)
    return NavRecords(
        t_s=t,
        ship_x_m=gps[:, 0],
        ship_y_m=gps[:, 1],
        ship_heading_deg=ship_heading,
        vehicle_depth_m=recorded["depth_m"],
        altitude_m=read(rng, floor_below - depths, sensors["altimeter"]),
        vel_x_mps=measured_velocity[:, 0],
        vel_y_mps=measured_velocity[:, 1],
        slant_range_m=slant,
        cable_out_m=np.full(t.size, scenario.cable.out_m),
        sonar=sonar_patches(rng, floor, node_m, truth, measured_velocity, sensors["sonar"], scenario.rate_hz, sounded),
        truth_x_m=truth[:, 0],
        truth_y_m=truth[:, 1],
        **usbl,
    )


def _ship_track(scenario: Scenario, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    ship = scenario.ship
    speed = ship.speed_kn * KNOT_MPS
    dt = 1.0 / scenario.rate_hz
    max_turn = math.radians(ship.turn_rate_dps) * dt
    turn_radius = speed / math.radians(ship.turn_rate_dps)
    waypoints = np.asarray(ship.waypoints_m, float)
    position = waypoints[0].copy()
    target = 1
    heading = math.atan2(*(waypoints[1] - waypoints[0]))  # atan2(east, north): clockwise from north
    xs, ys, hs = np.empty(t.size), np.empty(t.size), np.empty(t.size)
    for n in range(t.size):
        xs[n], ys[n], hs[n] = position[0], position[1], math.degrees(heading) % 360.0
        to_target = waypoints[target] - position
        if math.hypot(*to_target) < turn_radius:
            target = (target + 1) % len(waypoints)
            to_target = waypoints[target] - position
        wanted = math.atan2(*to_target)
        turn = (wanted - heading + math.pi) % (2 * math.pi) - math.pi
        heading += max(-max_turn, min(max_turn, turn))
        position = position + speed * dt * np.array([math.sin(heading), math.cos(heading)])
    return xs, ys, hs
