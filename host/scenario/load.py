"""Reading scenario files, and the shipped ones by name."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..config import ConfigError, build, read_toml, validate_fields
from ..nav.parameters import navigation_parameters
from ..shipped import shipped_names, shipped_path
from ..terrain import Feature
from .map import check_before_simulating
from .spec import SENSORS, CableSpec, CurrentSpec, FaultSpec, MapSpec, Scenario, ShipSpec, TerrainSpec, VehicleSpec

__all__ = ["load_scenario", "builtin_scenarios", "builtin_scenario_path", "builtin_descriptions"]


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
    unknown = sorted(set(sensors) - set(SENSORS)) if isinstance(sensors, dict) else []
    if unknown:
        raise ValueError(f"{path.name}: [sensors] has unknown sensor(s) {unknown}; known ones are {sorted(SENSORS)}.")
    try:
        for key, cls in tables.items():
            if key in data:
                kwargs[key] = _terrain(data[key]) if key == "terrain" else build(cls, data[key], key)
        if not isinstance(sensors, dict):
            raise ConfigError(f"[sensors] must be a table of sensor tables, got {sensors!r}")
        kwargs["sensors"] = {name: build(SENSORS[name], table, f"sensors.{name}") for name, table in sensors.items()}
        kwargs["navigation"] = dict(data.get("navigation", {}))
        kwargs["base_dir"] = path.parent
        scenario = Scenario(**kwargs)
        check_before_simulating(scenario)
        return scenario
    except ValueError as error:
        raise type(error)(f"{path.name}: {error}") from None


def _terrain(table: Any) -> TerrainSpec:
    """``[terrain]`` with its ``[[terrain.features]]``, each built and checked as a table of its own."""
    if not isinstance(table, dict) or "features" not in table:
        return build(TerrainSpec, table, "terrain")
    features = table["features"]
    if not isinstance(features, list):
        raise ConfigError(f"terrain.features must be an array of tables ([[terrain.features]]), got {features!r}")
    rest = {key: value for key, value in table.items() if key != "features"}
    built = tuple(build(Feature, feature, f"terrain.features[{index}]") for index, feature in enumerate(features))
    return TerrainSpec(**validate_fields(TerrainSpec, rest, "terrain"), features=built)


def builtin_scenarios() -> list[str]:
    """Names of the scenarios shipped in the package."""
    return shipped_names("lost.host")


def builtin_scenario_path(name: str) -> Path:
    """Path of a shipped scenario by name (``"demo"``)."""
    return shipped_path("lost.host", name, what="scenario")



def builtin_descriptions() -> dict[str, str]:
    """Each shipped scenario's name and its one-line ``description`` (what ``lost run --list`` prints)."""
    return {name: str(read_toml(builtin_scenario_path(name), "scenario file").get("description", "")) for name in builtin_scenarios()}
