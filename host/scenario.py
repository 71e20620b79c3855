"""The tow simulator: a scenario TOML file in, a bathymetric :class:`Grid` and :class:`NavRecords` out.

A scenario is a TOML file with the tables below; every field is optional and has the default shown
in the dataclass that reads it (:class:`TerrainSpec`, :class:`ShipSpec`, ...). An unknown field is an
error, so a typo cannot silently fall back to a default. The shipped scenarios live in
``lost/host/scenarios/`` (:func:`builtin_scenarios`).

The physics, kept simple and stated
-----------------------------------
- Ship: sails the waypoints in order (and back to the first after the last) at a constant speed,
  turning toward the next waypoint at a limited rate; a waypoint is reached within one turn radius.
  The ship's course over ground is its heading.
- Cable: the vehicle keeps a horizontal distance ``catenary_factor * sqrt(out**2 - depth**2)`` from
  the ship (the cable's sag shortens the lay-back that a straight cable would give) and is dragged
  toward it like a trailer, so it cuts inside turns and lags behind them.
- Current: the vehicle drifts with the water; in the water's frame it trails the ship's water
  track, so a cross current puts it ``layback * c / sqrt(v**2 + c**2)`` off the ship's track.
- Vehicle depth: follows the sea floor at the target altitude through a first-order lag.
- Sensors: each with Gaussian noise, a bias, dropouts (NaN) and outliers at its own rate. The sonar
  swath is delivered gridded on the map's nodes as an h x w patch centred on the vehicle (what
  ``lost.host.sonar`` produces from real soundings) every ``interval_s``, with missing beams; a
  real-time swath patch is centred behind the vehicle, on the pings already received.
- USBL (``[sensors.usbl]``, off by default): the ship's USBL replies ray-traced through a sound-speed
  cast with range-dependent noise, dropouts and multipath, and the fixes ``lost.host.usbl`` makes of
  them with their covariance (:class:`UsblSpec`); its own random stream, so a scenario's other
  readings do not change when it is switched on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import Field
from scipy import ndimage

from .config import (
    ConfigError,
    Fraction,
    NonNegativeFloat,
    NonNegativeInt,
    PositiveFloat,
    PositiveInt,
    build,
    navigation_parameters,
    read_toml,
    validate_fields,
)
from .grid import Grid
from .records import NavRecords, SonarPatch
from .shipped import shipped_names, shipped_path
from .terrain import synthetic_terrain

__all__ = [
    "Scenario",
    "TerrainSpec",
    "ShipSpec",
    "CableSpec",
    "CurrentSpec",
    "VehicleSpec",
    "SensorSpec",
    "SonarSpec",
    "SlantRangeSpec",
    "UsblSpec",
    "usbl_profile",
    "MapSpec",
    "FaultSpec",
    "load_scenario",
    "scenario_floor",
    "survey_map",
    "builtin_scenarios",
    "builtin_scenario_path",
    "simulate",
    "KNOT_MPS",
]

KNOT_MPS = 1852.0 / 3600.0


@dataclass(frozen=True, kw_only=True)
class TerrainSpec:
    """``[terrain]``: a seeded synthetic sea floor, or a grid file.

    file : path of a grid file read by ``lost.host.io.read_grid`` (relative to the scenario); when
        given, the synthetic fields are ignored. positive ("up" for elevations, "down" for depths)
        and nodata, as read_grid takes them, for a file that does not say.
    seed : terrain seed (default: the scenario's seed).
    shape : (rows, cols) of the synthetic floor; node_m : its node spacing, metres.
    x0_m, y0_m : easting/northing of node (0, 0).
    mean_depth_m, relief_m, roughness_m, smooth_fraction, hurst : see ``synthetic_terrain``;
        ``smooth_fraction`` of the columns at the east edge are smooth, the rest rough.
    corner_m, aspect, azimuth_deg : with ``corner_m``, the roughness follows the von Karman spectrum
        of Goff and Jordan (corner wavelength in metres, elongation, its direction) rather than a pure
        power law: the statistical model of real sea-floor morphology.
    repeat_m : (north, east) size of a tile repeated over the whole floor (look-alike terrain).

    This is the true sea floor, which the sonar, altimeter and depth follow; the navigation map is
    made from it by ``[map]``.
    """

    file: str | None = None
    positive: Literal["up", "down"] | None = None
    nodata: float | None = None
    seed: NonNegativeInt | None = None
    shape: tuple[PositiveInt, PositiveInt] = (400, 700)
    node_m: PositiveFloat = 10.0
    x0_m: float = 0.0
    y0_m: float = 0.0
    mean_depth_m: float = 1000.0
    relief_m: NonNegativeFloat = 60.0
    roughness_m: NonNegativeFloat = 8.0
    smooth_fraction: Fraction = 0.0
    hurst: Annotated[float, Field(gt=0, le=1)] = 0.8
    corner_m: PositiveFloat | None = None
    aspect: PositiveFloat = 1.0
    azimuth_deg: float = 0.0
    repeat_m: tuple[PositiveFloat, PositiveFloat] | None = None


@dataclass(frozen=True, kw_only=True)
class MapSpec:
    """``[map]``: the navigation map, made from the true floor as a survey makes one.

    node_m : the map's node spacing, a whole multiple of ``terrain.node_m``; each map node is the mean
        of the floor's nodes in its cell, as a gridded multibeam survey is. None (the default): the
        map is the true floor itself, node for node, as in a simulation that knows too much.
    noise_m : 1-sigma survey noise of each map node (independent from node to node).
    offset_m : a constant added to every map depth (a datum or tide error).
    extent_m : (west, south, east, north), metres: the map covers only this box (a map that stops
        before the survey does); None: the whole floor.
    seed : the noise's seed (default: the scenario's seed + 1).
    """

    node_m: PositiveFloat | None = None
    noise_m: NonNegativeFloat = 0.0
    offset_m: float = 0.0
    extent_m: tuple[float, float, float, float] | None = None
    seed: NonNegativeInt | None = None


@dataclass(frozen=True, kw_only=True)
class FaultSpec:
    """``[fault]``: a navigation fault injected into the records.

    position_jump_m : (east, north), metres the dead reckoning jumps at ``at_s`` (added to the measured
        velocity of the record at that time, as after a long DVL outage the INS has drifted that far).
    at_s : when; None: no fault.
    """

    position_jump_m: tuple[float, float] = (0.0, 0.0)
    at_s: NonNegativeFloat | None = None


@dataclass(frozen=True, kw_only=True)
class ShipSpec:
    """``[ship]``: waypoints_m, a list of [east, north] in metres; speed_kn; turn_rate_dps, degrees/s."""

    waypoints_m: tuple[tuple[float, float], ...] = ((1000.0, 2000.0), (6000.0, 2000.0))
    speed_kn: PositiveFloat = 3.0
    turn_rate_dps: PositiveFloat = 0.5


@dataclass(frozen=True, kw_only=True)
class CableSpec:
    """``[cable]``: out_m, cable paid out, metres; catenary_factor in (0, 1], the true lay-back's share of a straight cable's."""

    out_m: PositiveFloat = 1500.0
    catenary_factor: Annotated[float, Field(gt=0, le=1)] = 0.9


@dataclass(frozen=True, kw_only=True)
class CurrentSpec:
    """``[current]``: speed_kn and the direction it flows toward, toward_deg, degrees clockwise from north."""

    speed_kn: NonNegativeFloat = 0.0
    toward_deg: float = 0.0


@dataclass(frozen=True, kw_only=True)
class VehicleSpec:
    """``[vehicle]``: altitude_m, the target height above the floor; depth_time_constant_s, its depth lag;
    has_velocity_sensor: an INS/DVL on board (else the pipeline gets the ship's velocity)."""

    altitude_m: PositiveFloat = 80.0
    depth_time_constant_s: PositiveFloat = 60.0
    has_velocity_sensor: bool = True


@dataclass(frozen=True, kw_only=True)
class SensorSpec:
    """``[sensors.gps]``, ``[sensors.heading]``, ``[sensors.depth]``, ``[sensors.altimeter]``, ``[sensors.velocity]``.

    noise : 1-sigma Gaussian noise (metres, degrees for the heading, m/s for the velocity).
    bias : a constant added to every reading (a pair [east, north] for the velocity).
    dropout_rate : probability that a record has no reading (NaN).
    outlier_rate, outlier : probability of a gross error, uniform in [-outlier, +outlier].
    """

    noise: NonNegativeFloat = 0.0
    bias: float | tuple[float, float] = 0.0
    dropout_rate: Fraction = 0.0
    outlier_rate: Fraction = 0.0
    outlier: NonNegativeFloat = 0.0


@dataclass(frozen=True, kw_only=True)
class SonarSpec(SensorSpec):
    """``[sensors.sonar]``: SensorSpec fields (metres, per sounding) plus

    enabled; shape (h, w) of the patch; interval_s between patches; missing_beam_rate, the share of
    soundings with no return; mode:

    - ``"gridded"``: the patch arrives sampled on the map's nodes around the true position;
    - ``"swath"``: a multibeam swath of ``beams`` soundings across ``swath_width_m`` (default the
      patch's larger side) perpendicular to the vehicle's motion at every record; the patch of record n
      bins, with ``lost.host.sonar.grid_soundings``, the soundings of the pings (within
      ``max_window_s`` before and after n) whose position lies within half a patch diagonal of the
      vehicle's, all placed relative to the vehicle by dead reckoning on the measured velocity (so
      its errors distort the patch, as on a real tow). Using later pings makes this a
      post-processing patch. With ``realtime = true`` the patch of record n uses only the pings
      up to n: it is centred on the reckoned position of the latest earlier record at least half a
      patch diagonal behind the vehicle (``SonarPatch.centre_offset_m`` says where), so that the
      pings already received fill it (or, when the vehicle has not gone that far within
      ``max_window_s``, on the earliest record in that window: a partly filled patch).
    """

    enabled: bool = True
    shape: tuple[PositiveInt, PositiveInt] = (10, 10)
    interval_s: PositiveFloat = 1.0
    missing_beam_rate: Fraction = 0.0
    mode: Literal["gridded", "swath"] = "gridded"
    beams: Annotated[int, Field(ge=2)] = 64
    swath_width_m: PositiveFloat | None = None
    max_window_s: PositiveFloat = 300.0
    realtime: bool = False


@dataclass(frozen=True, kw_only=True)
class SlantRangeSpec(SensorSpec):
    """``[sensors.slant_range]``: SensorSpec fields (metres) plus enabled (False: no range is measured)."""

    enabled: bool = True


@dataclass(frozen=True, kw_only=True)
class UsblSpec:
    """``[sensors.usbl]``: the ship's USBL pinging the vehicle's transponder through a sound-speed profile.

    enabled : False (the default) simulates no USBL, and draws nothing from the scenario's random stream.
    cast : a shipped cast's name (``lost.host.usbl`` data, e.g. ``"scs_june"``) or a cast CSV path (relative to
        the scenario; layout in ``lost.host.usbl.sound``); it must reach the vehicle's depth.
    interval_s : seconds between pings (a reply lands on the record of its ping).
    transducer_depth_m : depth of the ship's transducer (the navigation's ``reference_depth_m`` should match).
    travel_time_noise_s : 1-sigma noise of the one-way travel time.
    phase_noise_rad, noise_growth_per_km, frequency_hz, baseline_m : the array (``lost.host.usbl.UsblArray``): the
        phase noise grows by ``1 + noise_growth_per_km * slant range in km``.
    tilt_noise_deg : 1-sigma noise of the ship's roll and pitch (the true ones are zero: a level ship).
    dropout_rate, dropout_rate_per_km : probability that a ping has no reply: ``dropout_rate +
        dropout_rate_per_km * slant range in km``.
    outlier_rate, outlier_delay_s : probability of a multipath reply, late by uniform [0, outlier_delay_s].

    Each reply is traced through the cast's layers (``lost.host.usbl.reply_from_geometry``) from the true ship
    to the true vehicle at the ping's record (the vehicle's motion during the travel time is neglected), then
    noised; the fix is ``lost.host.usbl.usbl_fix`` on the noisy reply with the ship's recorded GPS position,
    heading and the vehicle's recorded depth, whose noise levels (``[sensors.gps]``, ``[sensors.heading]``,
    ``[sensors.depth]``) go into its covariance. A ping whose recorded inputs are missing has a travel time but no fix.
    """

    enabled: bool = False
    cast: str = "scs_june"
    interval_s: PositiveFloat = 2.0
    transducer_depth_m: NonNegativeFloat = 5.0
    travel_time_noise_s: PositiveFloat = 2e-5
    phase_noise_rad: PositiveFloat = 0.008
    noise_growth_per_km: NonNegativeFloat = 0.5
    frequency_hz: PositiveFloat = 20000.0
    baseline_m: PositiveFloat = 0.035
    tilt_noise_deg: NonNegativeFloat = 0.02
    dropout_rate: Fraction = 0.05
    dropout_rate_per_km: NonNegativeFloat = 0.0
    outlier_rate: Fraction = 0.0
    outlier_delay_s: NonNegativeFloat = 0.05


_SENSORS = {"gps": SensorSpec, "heading": SensorSpec, "depth": SensorSpec, "altimeter": SensorSpec,
            "velocity": SensorSpec, "sonar": SonarSpec, "slant_range": SlantRangeSpec, "usbl": UsblSpec}


@dataclass(frozen=True, kw_only=True)
class Scenario:
    """A whole scenario: top-level name, description, seed, duration_s, rate_hz, the tables above, and
    ``[navigation]``, keyword arguments of :class:`lost.host.nav.NavParameters` (the pipeline's settings)."""

    name: str = "scenario"
    description: str = ""
    seed: NonNegativeInt = 0
    duration_s: PositiveFloat = 600.0
    rate_hz: PositiveFloat = 1.0
    terrain: TerrainSpec = field(default_factory=TerrainSpec)
    map: MapSpec = field(default_factory=MapSpec)
    fault: FaultSpec = field(default_factory=FaultSpec)
    ship: ShipSpec = field(default_factory=ShipSpec)
    cable: CableSpec = field(default_factory=CableSpec)
    current: CurrentSpec = field(default_factory=CurrentSpec)
    vehicle: VehicleSpec = field(default_factory=VehicleSpec)
    sensors: dict[str, SensorSpec] = field(default_factory=dict)
    navigation: dict[str, Any] = field(default_factory=dict)
    base_dir: Path = Path(".")

    def __post_init__(self) -> None:
        if not (self.duration_s > 0 and self.rate_hz > 0):
            raise ValueError(f"duration_s and rate_hz must be positive, got {self.duration_s!r} and {self.rate_hz!r}.")
        if len(self.ship.waypoints_m) < 2:
            raise ValueError("The ship needs at least two waypoints.")
        if not (self.ship.speed_kn > 0 and self.ship.turn_rate_dps > 0):
            raise ValueError("The ship's speed and turn rate must be positive.")
        if not 0 < self.cable.catenary_factor <= 1:
            raise ValueError(f"cable.catenary_factor must lie in (0, 1], got {self.cable.catenary_factor!r}.")
        sensors = {name: self.sensors.get(name, spec()) for name, spec in _SENSORS.items()}
        for name, spec in sensors.items():
            for rate in ("dropout_rate", "outlier_rate") + (("missing_beam_rate",) if name == "sonar" else ()):
                if not 0.0 <= getattr(spec, rate) <= 1.0:
                    raise ValueError(f"sensors.{name}.{rate} must lie in [0, 1], got {getattr(spec, rate)!r}.")
        sonar = sensors["sonar"]
        if sonar.mode not in ("gridded", "swath"):
            raise ValueError(f"sensors.sonar.mode must be 'gridded' or 'swath', got {sonar.mode!r}.")
        if sonar.realtime and sonar.mode != "swath":
            raise ValueError("sensors.sonar.realtime applies to mode = 'swath' (a patch gathered ping by ping); the gridded patch has no pings.")
        if sonar.beams < 2 or not (sonar.swath_width_m is None or sonar.swath_width_m > 0):
            raise ValueError(f"sensors.sonar needs at least 2 beams and a positive swath width, got {sonar.beams!r} and {sonar.swath_width_m!r}.")
        if not sonar.interval_s > 0:
            raise ValueError(f"sensors.sonar.interval_s must be positive, got {sonar.interval_s!r}.")
        object.__setattr__(self, "sensors", sensors)
        _check_physics(self)
        if self.map.node_m is not None:
            ratio = self.map.node_m / self.terrain.node_m
            if not (ratio >= 1 and abs(ratio - round(ratio)) < 1e-9):
                raise ValueError(f"map.node_m must be a whole multiple of terrain.node_m ({self.terrain.node_m} m), got {self.map.node_m!r}.")
        if self.map.noise_m < 0:
            raise ValueError(f"map.noise_m must not be negative, got {self.map.noise_m!r}.")
        if self.map.extent_m is not None and not (len(self.map.extent_m) == 4 and self.map.extent_m[0] < self.map.extent_m[2]
                                                  and self.map.extent_m[1] < self.map.extent_m[3]):
            raise ValueError(f"map.extent_m must be (west, south, east, north) with west < east and south < north, got {self.map.extent_m!r}.")


#: A scenario needing more memory than this (records, patches, floor) is refused before it starts.
MAX_SCENARIO_BYTES = 4e9


def _check_physics(scenario: Scenario) -> None:
    """Refuse what no tow can be, and what no machine can hold, before simulating."""
    terrain, vehicle, cable = scenario.terrain, scenario.vehicle, scenario.cable
    if terrain.file is None and cable.out_m <= terrain.mean_depth_m - vehicle.altitude_m:
        raise ValueError(
            f"cable.out_m ({cable.out_m:g} m) is shorter than the vehicle's depth (about {terrain.mean_depth_m - vehicle.altitude_m:g} m: "
            "terrain.mean_depth_m less vehicle.altitude_m); the vehicle cannot reach its altitude"
        )
    records = scenario.duration_s * scenario.rate_hz
    sonar = scenario.sensors["sonar"]
    h, w = sonar.shape
    patches = records / max(sonar.interval_s * scenario.rate_hz, 1.0) if sonar.enabled else 0.0
    beams = records * sonar.beams * 3 if sonar.enabled and sonar.mode == "swath" else 0.0
    needed = 8.0 * (records * 24 + patches * h * w + beams + 3 * terrain.shape[0] * terrain.shape[1])
    if needed > MAX_SCENARIO_BYTES:
        raise ValueError(
            f"this scenario would need about {needed / 1e9:,.0f} GB of memory ({records:,.0f} records from duration_s = {scenario.duration_s:g} "
            f"and rate_hz = {scenario.rate_hz:g}, a {terrain.shape[0]} x {terrain.shape[1]} floor, {h} x {w} sonar patches); "
            f"the limit is {MAX_SCENARIO_BYTES / 1e9:g} GB: lower rate_hz or duration_s, or a smaller terrain.shape"
        )


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario file.

    Raises
    ------
    ValueError
        Invalid TOML, an unknown table or field, or a value out of range.
    """
    path = Path(path)
    data = read_toml(path, "scenario file")
    tables = {"terrain": TerrainSpec, "map": MapSpec, "fault": FaultSpec, "ship": ShipSpec, "cable": CableSpec, "current": CurrentSpec,
              "vehicle": VehicleSpec}
    top = {"name", "description", "seed", "duration_s", "rate_hz", "sensors", "navigation", *tables}
    unknown = sorted(set(data) - top)
    if unknown:
        raise ValueError(f"{path} has unknown top-level field(s) {unknown}; known ones are {sorted(top)}.")
    scalars = {key: data[key] for key in ("name", "description", "seed", "duration_s", "rate_hz") if key in data}
    try:
        kwargs: dict[str, Any] = validate_fields(Scenario, scalars, "")
        navigation_parameters(data.get("navigation", {}))  # the pipeline's settings, checked as strictly, here
    except ConfigError as error:
        raise ConfigError(f"{path.name}: {error}") from None
    kwargs.setdefault("name", path.stem)
    sensors = data.get("sensors", {})
    unknown = sorted(set(sensors) - set(_SENSORS)) if isinstance(sensors, dict) else []
    if unknown:
        raise ValueError(f"{path.name}: [sensors] has unknown sensor(s) {unknown}; known ones are {sorted(_SENSORS)}.")
    try:
        for key, cls in tables.items():
            if key in data:
                kwargs[key] = build(cls, data[key], key)
        if not isinstance(sensors, dict):
            raise ConfigError(f"[sensors] must be a table of sensor tables, got {sensors!r}")
        kwargs["sensors"] = {name: build(_SENSORS[name], table, f"sensors.{name}") for name, table in sensors.items()}
        kwargs["navigation"] = dict(data.get("navigation", {}))
        kwargs["base_dir"] = path.parent
        return Scenario(**kwargs)
    except ValueError as error:
        raise type(error)(f"{path.name}: {error}") from None


def builtin_scenarios() -> list[str]:
    """Names of the scenarios shipped in the package."""
    return shipped_names("lost.host")


def builtin_scenario_path(name: str) -> Path:
    """Path of a shipped scenario by name (``"demo"``)."""
    return shipped_path("lost.host", name, what="scenario")


def scenario_floor(scenario: Scenario) -> Grid:
    """The scenario's true sea floor: its grid file, or its seeded synthetic floor."""
    spec = scenario.terrain
    if spec.file is not None:
        from .io import read_grid  # lazily: the file readers and their dependencies load only when used

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


def _floor_depth(grid: Grid, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The true sea floor between nodes: bilinear, NaN off the map or next to a hole."""
    row, col = grid.row_col(x, y)
    coords = np.stack([np.ravel(row), np.ravel(col)])
    depth = ndimage.map_coordinates(grid.depth_m, coords, order=1, mode="constant", cval=np.nan)
    return depth.reshape(np.shape(x))


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


def _read(rng: np.random.Generator, truth: np.ndarray, spec: SensorSpec) -> np.ndarray:
    """One sensor's readings of a true series: noise, bias, outliers, dropouts.

    For a 2-D series (rows of components) an outlier or a dropout hits a whole row.
    """
    truth = np.asarray(truth, float)
    reading = truth + np.asarray(spec.bias, float) + rng.normal(0.0, 1.0, truth.shape) * spec.noise
    outliers = rng.random(truth.shape[0]) < spec.outlier_rate
    reading[outliers] += rng.uniform(-spec.outlier, spec.outlier, reading[outliers].shape)
    reading[rng.random(truth.shape[0]) < spec.dropout_rate] = np.nan
    return reading


def simulate(scenario: Scenario) -> tuple[Grid, NavRecords]:
    """Simulate a tow: the navigation map and the records (with the truth) of the scenario, reproducible by its seed.

    The vehicle, its altimeter and its sonar see the true floor (:func:`scenario_floor`); the map
    returned is the survey of it that ``[map]`` describes.
    """
    floor = scenario_floor(scenario)
    grid = survey_map(floor, scenario.map, scenario.seed + 1 if scenario.map.seed is None else scenario.map.seed)
    rng = np.random.default_rng(scenario.seed)
    dt = 1.0 / scenario.rate_hz
    t = np.arange(int(round(scenario.duration_s * scenario.rate_hz))) * dt
    ship_x, ship_y, heading = _ship_track(scenario, t)

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
    depth = float(_floor_depth(floor, position[0], position[1])) - vehicle.altitude_m
    depth = depth if np.isfinite(depth) else float(np.nanmean(floor.depth_m)) - vehicle.altitude_m
    position = position - layback(depth) * water_track / np.linalg.norm(water_track)
    truth = np.empty((t.size, 2))
    depths = np.empty(t.size)
    for n in range(t.size):
        if n:
            position = position + current * dt
            ship = np.array([ship_x[n], ship_y[n]])
            towline = ship - position
            position = ship - layback(depth) * towline / max(np.linalg.norm(towline), 1e-9)
        below = float(_floor_depth(floor, position[0], position[1]))
        if np.isfinite(below):
            depth += (below - vehicle.altitude_m - depth) * min(dt / vehicle.depth_time_constant_s, 1.0)
        truth[n], depths[n] = position, depth
    floor_below = _floor_depth(floor, truth[:, 0], truth[:, 1])
    velocity = np.gradient(truth, dt, axis=0)

    sensors = scenario.sensors
    # A GPS fix (and its outliers) is one reading of both coordinates; the heading has its own sensor.
    gps = _read(rng, np.column_stack([ship_x, ship_y]), sensors["gps"])
    ship_heading = _read(rng, heading, sensors["heading"]) % 360.0
    if vehicle.has_velocity_sensor:
        measured_velocity = _read(rng, velocity, sensors["velocity"])
    else:
        ship_velocity = np.gradient(np.column_stack([ship_x, ship_y]), dt, axis=0)
        measured_velocity = _read(rng, ship_velocity, sensors["velocity"])
    # A dropped velocity reading loses both components.
    measured_velocity[np.isnan(measured_velocity).any(axis=1)] = np.nan
    if scenario.fault.at_s is not None:
        n = min(int(round(scenario.fault.at_s * scenario.rate_hz)), t.size - 1)
        measured_velocity[n] = np.nan_to_num(measured_velocity[n]) + np.asarray(scenario.fault.position_jump_m, float) / dt
    slant_spec = sensors["slant_range"]
    if slant_spec.enabled:
        true_range = np.sqrt(np.sum((truth - np.column_stack([ship_x, ship_y])) ** 2, axis=1) + depths**2)
        slant = _read(rng, true_range, slant_spec)
    else:
        slant = np.full(t.size, np.nan)
    recorded = {"ship": gps, "heading_deg": ship_heading, "depth_m": _read(rng, depths, sensors["depth"])}
    usbl = _usbl_pings(scenario, np.column_stack([ship_x, ship_y]), heading, truth, depths, recorded)

    return grid, NavRecords(
        t_s=t,
        ship_x_m=gps[:, 0],
        ship_y_m=gps[:, 1],
        ship_heading_deg=ship_heading,
        vehicle_depth_m=recorded["depth_m"],
        altitude_m=_read(rng, floor_below - depths, sensors["altimeter"]),
        vel_x_mps=measured_velocity[:, 0],
        vel_y_mps=measured_velocity[:, 1],
        slant_range_m=slant,
        cable_out_m=np.full(t.size, cable.out_m),
        sonar=_sonar_patches(rng, floor, grid.node_m, truth, measured_velocity, sensors["sonar"], scenario.rate_hz),
        truth_x_m=truth[:, 0],
        truth_y_m=truth[:, 1],
        **usbl,
    )


def usbl_profile(scenario: Scenario):
    """The sound-speed profile of the scenario's ``[sensors.usbl]`` cast, or None when it has no USBL."""
    spec = scenario.sensors["usbl"]
    if not spec.enabled:
        return None
    from .usbl.scenario import shipped_cast_path
    from .usbl.sound import SoundSpeedProfile, read_cast

    path = scenario.base_dir / spec.cast if spec.cast.endswith(".csv") else shipped_cast_path(spec.cast)
    # The layers keep every sample within 5 cm/s of the cast: what lost.host.usbl's own simulator uses.
    return SoundSpeedProfile.from_cast(read_cast(path), tolerance_m_s=0.05)


def _usbl_array(scenario: Scenario):
    from .usbl.fix import UsblArray

    spec, sensors = scenario.sensors["usbl"], scenario.sensors
    # The fix's covariance takes the recorded inputs' noise; UsblArray needs it positive, a millimetre is none.
    return UsblArray(frequency_hz=spec.frequency_hz, baseline_m=spec.baseline_m, lever_arm_m=(0.0, 0.0, spec.transducer_depth_m),
                     antenna_height_m=0.0, phase_noise_rad=spec.phase_noise_rad, travel_time_noise_s=spec.travel_time_noise_s,
                     tilt_noise_rad=math.radians(spec.tilt_noise_deg), heading_noise_rad=math.radians(sensors["heading"].noise),
                     gnss_noise_m=max(sensors["gps"].noise, 1e-3), depth_noise_m=max(sensors["depth"].noise, 1e-3),
                     noise_growth_per_km=spec.noise_growth_per_km)


def _usbl_pings(scenario: Scenario, ship: np.ndarray, heading_deg: np.ndarray, truth: np.ndarray, depth: np.ndarray,
                recorded: dict) -> dict[str, np.ndarray]:
    """The ``[sensors.usbl]`` series of NavRecords (empty without a USBL): travel times and fixes (see UsblSpec)."""
    spec = scenario.sensors["usbl"]
    if not spec.enabled:
        return {}
    from .usbl.fix import reply_from_geometry, usbl_fix

    profile, array = usbl_profile(scenario), _usbl_array(scenario)
    if depth.max() > profile.bottom_m or depth.min() <= spec.transducer_depth_m:
        raise ValueError(f"sensors.usbl.cast {spec.cast!r} spans {profile.depth_m[0]:g}-{profile.bottom_m:g} m but the vehicle goes from "
                         f"{depth.min():.0f} to {depth.max():.0f} m (the transducer at {spec.transducer_depth_m:g} m): use a deeper cast")
    rng = np.random.default_rng([scenario.seed, 14])  # its own stream: the other sensors' draws do not change
    n = truth.shape[0]
    out = {name: np.full(n, np.nan) for name in ("usbl_travel_time_s", "usbl_x_m", "usbl_y_m", "usbl_sxx", "usbl_syy", "usbl_sxy")}
    every = max(int(round(spec.interval_s * scenario.rate_hz)), 1)
    tilt = math.radians(spec.tilt_noise_deg)
    for k in range(0, n, every):
        slant_km = math.hypot(math.hypot(*(truth[k] - ship[k])), depth[k] - spec.transducer_depth_m) / 1000.0
        if rng.random() < spec.dropout_rate + spec.dropout_rate_per_km * slant_km:
            continue
        travel, phase_x, phase_y = reply_from_geometry(profile, array, roll_rad=0.0, pitch_rad=0.0, heading_rad=math.radians(heading_deg[k]),
                                                       antenna_north_m=ship[k, 1], antenna_east_m=ship[k, 0], target_north_m=truth[k, 1],
                                                       target_east_m=truth[k, 0], target_depth_m=depth[k])
        noise = array.phase_noise_at(slant_km * 1000.0)
        travel += rng.normal(0.0, spec.travel_time_noise_s) + (rng.uniform(0.0, spec.outlier_delay_s) if rng.random() < spec.outlier_rate else 0.0)
        phase_x, phase_y = phase_x + rng.normal(0.0, noise), phase_y + rng.normal(0.0, noise)
        roll, pitch = rng.normal(0.0, tilt, 2)
        out["usbl_travel_time_s"][k] = travel
        inputs = (recorded["ship"][k, 0], recorded["ship"][k, 1], recorded["heading_deg"][k], recorded["depth_m"][k])
        if not np.all(np.isfinite(inputs)):
            continue
        try:
            fix = usbl_fix(profile, array, travel_time_s=travel, roll_rad=roll, pitch_rad=pitch, heading_rad=math.radians(inputs[2]),
                           antenna_north_m=inputs[1], antenna_east_m=inputs[0], target_depth_m=inputs[3], phase_x_rad=phase_x, phase_y_rad=phase_y)
        except ValueError:  # a reply the depth cannot explain (a late multipath one, say) gives no fix, as on a real USBL
            continue
        (syy, sxy), (_, sxx) = fix.covariance_ne  # (north, east) to (east, north)
        out["usbl_x_m"][k], out["usbl_y_m"][k] = fix.east_m, fix.north_m
        out["usbl_sxx"][k], out["usbl_syy"][k], out["usbl_sxy"][k] = sxx, syy, sxy
    return out


def _sonar_patches(
    rng: np.random.Generator, floor: Grid, node_m: float, truth: np.ndarray, measured_velocity: np.ndarray, spec: SonarSpec, rate_hz: float
) -> tuple:
    """Patches on the map's nodes (``node_m``) of soundings of the true ``floor``."""
    if not spec.enabled:
        return ()
    every = max(int(round(spec.interval_s * rate_hz)), 1)
    at = np.arange(0, truth.shape[0], every)
    patches: list[SonarPatch | None] = [None] * truth.shape[0]
    if spec.mode == "swath":
        for n, patch in zip(at, _swath_patches(rng, floor, node_m, truth, measured_velocity, spec, rate_hz, at)):
            patches[n] = patch
        return tuple(patches)
    h, w = spec.shape
    north = (np.arange(h) - (h - 1) / 2) * node_m
    east = (np.arange(w) - (w - 1) / 2) * node_m
    x = truth[at, 0][:, None, None] + east[None, None, :]
    y = truth[at, 1][:, None, None] + north[None, :, None]
    x, y = np.broadcast_arrays(x, y)
    depth = _sound(rng, _cell_mean_depth(floor, x, y, node_m), spec)
    for k, n in enumerate(at):
        patches[n] = SonarPatch(depth_m=depth[k], node_m=node_m)
    return tuple(patches)


def _cell_mean_depth(floor: Grid, x: np.ndarray, y: np.ndarray, node_m: float) -> np.ndarray:
    """The floor's mean depth over square cells of ``node_m`` centred on (x, y): what binning soundings gives."""
    f = max(int(round(node_m / floor.node_m)), 1)
    if f == 1:
        return _floor_depth(floor, x, y)
    offsets = (np.arange(f) - (f - 1) / 2) * floor.node_m
    total = np.zeros(np.shape(x))
    for dy in offsets:
        for dx in offsets:
            total += _floor_depth(floor, x + dx, y + dy)
    return total / f**2


def _sound(rng: np.random.Generator, true_depth: np.ndarray, spec: SonarSpec) -> np.ndarray:
    """Soundings of true depths: bias, noise, outliers, and NaN for the beams with no return."""
    depth = true_depth + spec.bias + rng.normal(0.0, spec.noise, true_depth.shape)
    outliers = rng.random(depth.shape) < spec.outlier_rate
    depth[outliers] += rng.uniform(-spec.outlier, spec.outlier, int(outliers.sum()))
    depth[rng.random(depth.shape) < spec.missing_beam_rate] = np.nan
    return depth


def _swath_patches(
    rng: np.random.Generator, floor: Grid, node_m: float, truth: np.ndarray, measured_velocity: np.ndarray, spec: SonarSpec, rate_hz: float,
    at: np.ndarray,
) -> list[SonarPatch | None]:
    from .io.sonar import grid_soundings

    h, w = spec.shape
    dt = 1.0 / rate_hz
    velocity = np.gradient(truth, dt, axis=0)
    speed = np.hypot(velocity[:, 0], velocity[:, 1])
    # Beams across the vehicle's motion (to starboard positive); a vehicle at rest looks north.
    motion = np.where(speed[:, None] > 1e-6, velocity / np.maximum(speed, 1e-6)[:, None], (0.0, 1.0))
    starboard = np.column_stack([motion[:, 1], -motion[:, 0]])
    width = spec.swath_width_m if spec.swath_width_m is not None else max(h, w) * node_m
    across = np.linspace(-width / 2, width / 2, spec.beams)
    beam_offsets = across[None, :, None] * starboard[:, None, :]  # (pings, beams, 2)
    spots = truth[:, None, :] + beam_offsets
    depth = _sound(rng, _floor_depth(floor, spots[..., 0], spots[..., 1]), spec)
    # Where the navigation believes each ping was: dead reckoning on the measured velocity, a dropped
    # reading holding the last one.
    held = measured_velocity.copy()
    for n in range(1, held.shape[0]):
        if np.isnan(held[n]).any():
            held[n] = held[n - 1]
    held[np.isnan(held)] = 0.0
    reckoned = np.vstack([np.zeros(2), np.cumsum(held[:-1] * dt, axis=0)])
    # The pings whose reckoned position lies within half a patch diagonal of the vehicle's, looked
    # for at most max_window_s away: a slow vehicle gathers pings for longer.
    half_diagonal = math.hypot(h, w) * node_m / 2
    window = int(np.ceil(spec.max_window_s * rate_hz))
    patches: list[SonarPatch | None] = []
    for n in at:
        centre = n
        if spec.realtime:
            earlier = np.arange(max(n - window, 0), n + 1)
            behind = earlier[np.hypot(*(reckoned[earlier] - reckoned[n]).T) >= half_diagonal]
            # A vehicle too slow to have gone that far in max_window_s gets a patch as full as it can be.
            centre = int(behind.max()) if behind.size else int(earlier[0])
        nearby = np.arange(max(centre - window, 0), min(centre + window, n if spec.realtime else truth.shape[0] - 1) + 1)
        pings = nearby[np.hypot(*(reckoned[nearby] - reckoned[centre]).T) <= half_diagonal]
        offsets = beam_offsets[pings] + (reckoned[pings] - reckoned[n])[:, None, :]
        sounded = np.isfinite(depth[pings])
        ages = np.broadcast_to(((n - pings) * dt)[:, None], sounded.shape)
        patches.append(grid_soundings(
            offsets[..., 0][sounded], offsets[..., 1][sounded], depth[pings][sounded],
            patch_shape=(h, w), node_m=node_m, centre_m=tuple(reckoned[centre] - reckoned[n]), age_s=ages[sounded],
        ).patch)
    return patches
