"""The scenario's tables as settings: one frozen dataclass per TOML table, validated when built.

Every field is optional and has the default shown; :func:`lost.host.scenario.load_scenario` reads a file
into a :class:`Scenario`. An unknown field is an error, so a typo cannot silently fall back to a default.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import Field

from ..config import ConfigError, Fraction, NonNegativeFloat, NonNegativeInt, PositiveFloat, PositiveInt
from ..terrain import Feature

__all__ = ["Scenario", "TerrainSpec", "MapSpec", "FaultSpec", "ShipSpec", "CableSpec", "CurrentSpec", "VehicleSpec", "SensorSpec",
           "SonarSpec", "SlantRangeSpec", "UsblSpec", "Feature", "SENSORS", "check_map_node", "MIN_RECORDS", "MAX_SCENARIO_BYTES", "KNOT_MPS"]

KNOT_MPS = 1852.0 / 3600.0


@dataclass(frozen=True, kw_only=True)
class TerrainSpec:
    """``[terrain]``: a seeded synthetic sea floor, or a grid file.

    file : path of a grid file read by ``lost.host.io.read_grid`` (relative to the scenario); when
        given, the synthetic fields are ignored (the shelf's and the features', which shape only a synthetic
        floor, are refused). positive ("up" for elevations, "down" for depths)
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
    gradient, downslope_deg, break_m, slope_gradient, break_width_m : a shelf and its slope under the random
        relief (``lost.host.terrain.shelf_profile``): the floor deepens toward ``downslope_deg`` by ``gradient``
        (metres per metre), beyond ``break_m`` from the floor's centre by ``slope_gradient``; mean_depth_m is
        then the depth at the floor's centre. gradient = 0 and no break_m: no regional shape.
    features : ``[[terrain.features]]`` tables, isolated strong features on the synthetic floor: a winding
        canyon, a ridge, a seamount (``lost.host.terrain.Feature``: kind, height_m, width_m, path_m or at_m,
        meander_m, meander_wavelength_m), in the floor's metres.
    refine_node_m : with ``file``, the floor is the file's grid refined to this node (a whole fraction of the
        file's) with fractal detail below the file's node (``lost.host.terrain.refine``), so a real DEM serves
        as a floor finer than a map made from it; detail_m is the detail's standard deviation (None: the
        file's own relief at its node scale), hurst its spectrum.

    A smooth shelf with a few strong features: ``relief_m`` and ``roughness_m`` of a metre or two,
    ``gradient``, ``features``. This is the true sea floor, which the sonar, altimeter and depth follow;
    the navigation map is made from it by ``[map]``.
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
    gradient: NonNegativeFloat = 0.0
    downslope_deg: float = 90.0
    break_m: float | None = None
    slope_gradient: NonNegativeFloat = 0.06
    break_width_m: PositiveFloat = 400.0
    features: tuple[Feature, ...] = ()
    refine_node_m: PositiveFloat | None = None
    detail_m: NonNegativeFloat | None = None


@dataclass(frozen=True, kw_only=True)
class MapSpec:
    """``[map]``: the navigation map, made from the true floor as a survey makes one.

    node_m : the map's node spacing, a whole multiple of the floor's (``terrain.node_m``, or a file's own,
        or ``terrain.refine_node_m``); each map node grids the floor's nodes in its cell, each node one
        sounding, as a gridded multibeam survey is (real maps are 3-10 times coarser than what the sonar
        resolves). None (the default): the map is the true floor itself, node for node, as in a simulation
        that knows too much.
    gridding : "mean" or "median" of the soundings in a cell. The map's per-node standard deviation
        (``Grid.sigma_m``) is their spread, as gridding tools report it (a cell of one sounding takes the
        map's median spread; a cell of none is a hole, NaN).
    line_spacing_m, line_azimuth_deg, swath_width_m : survey lines run toward ``line_azimuth_deg``
        (clockwise from north), ``line_spacing_m`` apart, each sounding a swath ``swath_width_m`` wide
        (default: the spacing, full coverage; narrower leaves unsurveyed stripes, holes in the map).
        None: no line structure (only the per-node noise below).
    line_offset_m : 1-sigma depth offset of each line as a whole (tide, heave, draft, the sound speed at the head).
    line_drift_m, along_m : 1-sigma depth error that wanders along each line, correlated over ``along_m`` (its
        autocorrelation falls to 1/e at that lag).
    refraction_m : a sound-speed error's bend of the outer beams: the error grows as (across / half swath)**2
        to this many metres at the swath's edges, up or down by line (the "smile" of a swath).
    sounding_noise_m : 1-sigma noise of each sounding (independent).
    hole_fraction, hole_size_m : a share of the area in unsurveyed patches about ``hole_size_m`` across.
    noise_m : 1-sigma noise added to each map node after gridding (independent from node to node).
    offset_m : a constant added to every map depth (a datum or tide error).
    extent_m : (west, south, east, north), metres: the map covers only this box (a map that stops
        before the survey does); None: the whole floor.
    seed : the survey's seed (default: the scenario's seed + 1).
    """

    node_m: PositiveFloat | None = None
    gridding: Literal["mean", "median"] = "mean"
    line_spacing_m: PositiveFloat | None = None
    line_azimuth_deg: float = 0.0
    swath_width_m: PositiveFloat | None = None
    line_offset_m: NonNegativeFloat = 0.0
    line_drift_m: NonNegativeFloat = 0.0
    along_m: PositiveFloat = 500.0
    refraction_m: NonNegativeFloat = 0.0
    sounding_noise_m: NonNegativeFloat = 0.0
    hole_fraction: Annotated[float, Field(ge=0, lt=1)] = 0.0
    hole_size_m: PositiveFloat = 300.0
    noise_m: NonNegativeFloat = 0.0
    offset_m: float = 0.0
    extent_m: tuple[float, float, float, float] | None = None
    seed: NonNegativeInt | None = None

    @property
    def surveyed(self) -> bool:
        """Whether the map is made of soundings (any survey error or a coarser node), not the floor as it is."""
        return self.node_m is not None or self.line_spacing_m is not None or self.sounding_noise_m > 0 or self.hole_fraction > 0


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
      bins, with ``lost.host.io.sonar.grid_soundings``, the soundings of the pings (within
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


SENSORS = {"gps": SensorSpec, "heading": SensorSpec, "depth": SensorSpec, "altimeter": SensorSpec,
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
        sensors = {name: self.sensors.get(name, spec()) for name, spec in SENSORS.items()}
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
        _check_records(self)
        _check_physics(self)
        _check_floor(self.terrain)
        floor_node_m = self.terrain.refine_node_m if self.terrain.file is not None else self.terrain.node_m
        # A file's node is known once it is read: lost.host.scenario.map checks it there.
        if self.map.node_m is not None and floor_node_m is not None:
            check_map_node(self.map.node_m, floor_node_m, "terrain.refine_node_m" if self.terrain.file is not None else "terrain.node_m")
        if self.map.noise_m < 0:
            raise ValueError(f"map.noise_m must not be negative, got {self.map.noise_m!r}.")
        if self.map.extent_m is not None and not (len(self.map.extent_m) == 4 and self.map.extent_m[0] < self.map.extent_m[2]
                                                  and self.map.extent_m[1] < self.map.extent_m[3]):
            raise ValueError(f"map.extent_m must be (west, south, east, north) with west < east and south < north, got {self.map.extent_m!r}.")


#: The fewest records a tow has: its velocities are differences of positions.
MIN_RECORDS = 2


def _check_records(scenario: Scenario) -> None:
    """A tow of fewer than two records has no velocity and nothing to navigate: refused by name, before anything runs."""
    records = int(round(scenario.duration_s * scenario.rate_hz))
    if records < MIN_RECORDS:
        raise ConfigError(f"duration_s = {scenario.duration_s:g} s at rate_hz = {scenario.rate_hz:g} Hz makes {records} record(s); a tow needs at "
                          f"least {MIN_RECORDS} (its velocity is a difference of positions): lengthen duration_s or raise rate_hz")


def _check_floor(terrain: TerrainSpec) -> None:
    """The synthetic floor's shape fields mean nothing under a file, and refinement nothing without one."""
    if terrain.file is None:
        if terrain.refine_node_m is not None or terrain.detail_m is not None:
            raise ConfigError("terrain.refine_node_m and terrain.detail_m refine a grid file: set terrain.file, or leave them out.")
        return
    shaped = [name for name in ("gradient", "break_m", "features") if getattr(terrain, name)]
    if shaped:
        raise ConfigError(f"terrain.{', terrain.'.join(shaped)} shape the synthetic floor, not a grid file (terrain.file = {terrain.file!r}).")


def check_map_node(map_node_m: float, floor_node_m: float, floor_source: str) -> None:
    """The map's node must be a whole multiple of the floor's (a map node grids whole floor cells)."""
    ratio = map_node_m / floor_node_m
    if not (ratio >= 1 - 1e-9 and abs(ratio - round(ratio)) < 1e-6):
        raise ConfigError(f"map.node_m must be a whole multiple of the floor's node, {floor_node_m:g} m ({floor_source}), got {map_node_m!r}.")


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
