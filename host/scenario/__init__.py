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
  ``lost.host.io.sonar`` produces from real soundings) every ``interval_s``, with missing beams; a
  real-time swath patch is centred behind the vehicle, on the pings already received.
- USBL (``[sensors.usbl]``, off by default): the ship's USBL replies ray-traced through a sound-speed
  cast with range-dependent noise, dropouts and multipath, and the fixes ``lost.host.usbl`` makes of
  them with their covariance (:class:`UsblSpec`); its own random stream, so a scenario's other
  readings do not change when it is switched on.

The package, one concept a module: ``spec`` (the tables as settings), ``load`` (files and the shipped
scenarios), ``floor`` (the true sea floor), ``map`` (the survey of it that navigates), ``tow`` (ship,
cable, vehicle, and :func:`simulate`), ``sensors`` (readings and the USBL), ``swath`` (the sonar's patches).
"""

from .floor import scenario_floor
from .load import builtin_descriptions, builtin_scenario_path, builtin_scenarios, load_scenario
from .map import exact_map, scenario_grid, survey_map
from .sensors import usbl_profile
from .spec import (
    KNOT_MPS,
    MAX_SCENARIO_BYTES,
    CableSpec,
    CurrentSpec,
    FaultSpec,
    Feature,
    MapSpec,
    Scenario,
    SensorSpec,
    ShipSpec,
    SlantRangeSpec,
    SonarSpec,
    TerrainSpec,
    UsblSpec,
    VehicleSpec,
)
from .tow import simulate

__all__ = [
    "Scenario", "TerrainSpec", "ShipSpec", "CableSpec", "CurrentSpec", "VehicleSpec", "SensorSpec", "SonarSpec", "SlantRangeSpec",
    "UsblSpec", "usbl_profile", "MapSpec", "Feature", "FaultSpec", "load_scenario", "scenario_floor", "survey_map", "scenario_grid",
    "exact_map", "builtin_scenarios", "builtin_scenario_path", "builtin_descriptions", "simulate", "KNOT_MPS", "MAX_SCENARIO_BYTES",
]
