"""A simulated INS+USBL tow described in TOML: the tow's course, the IMU's errors, the USBL's array, noise and
faults, the sound-speed cast. Unknown keys are errors and types are strict (``lost.host.config.validate_fields``:
``"2"`` is no number, NaN no value); the shipped scenarios live in ``lost/host/usbl/scenarios``.

Layout (every table and key optional except ``name``; the defaults are the dataclasses' below)::

    name = "usbl_turns"
    seed = 14
    duration_s = 1800.0
    ping_interval_s = 2.0
    imu_rate_hz = 10.0
    origin = [18.0, 115.5]              # latitude, longitude of the start (deg)
    cast = "scs_june"                   # a shipped cast's name, or a CSV path (relative to the TOML)
    [tow]     speed_m_s, depth_m, depth_swing_m, layback_m, heading_deg, course = [[seconds, turn rate deg/s], ...]
    [imu]     gyro_bias_deg_h, accel_bias_mg, angle_random_walk_deg_sqrt_h, velocity_random_walk_mg_sqrt_hz, ...
    [usbl]    frequency_hz, baseline_m, lever_arm_m, phase_noise_rad, travel_time_noise_s, ...
    [faults]  dropout_rate, dropout_rate_turning, bad_fix_rate, bad_fix_rate_turning, ...
    [ocean]   fine_step_m, cast_age_h, surface_warming_c_per_h, warm_layer_m, internal_wave_m, internal_wave_period_s
              (the simulator's truth beside the logged cast: lost.host.usbl.ocean)
    [processing]  UsblConfig's settings for processing the simulated log (what the operator knows of the cast:
              cast_age_h, sound_speed_sigma_m_s, ...; UsblScenario.processing_config())
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import Field

from ..config import ConfigError, Fraction, NonNegativeFloat, NonNegativeInt, PositiveFloat, build, read_toml, validate_fields
from ..shipped import shipped_names, shipped_path
from .filter import ImuNoise
from .fix import UsblArray

__all__ = ["TowSpec", "ImuSpec", "ReplyFaultSpec", "OceanSpec", "UsblScenario", "load_usbl_scenario", "load_processing_config",
           "processing_config_toml", "builtin_usbl_scenarios", "shipped_cast_path"]

DEG_PER_HOUR = np.radians(1.0) / 3600.0
MILLI_G = 9.80665e-3

#: A probability strictly between 0 and 1 (the chi-square gate: 1 would accept everything, 0 nothing).
OpenFraction = Annotated[float, Field(gt=0, lt=1)]

#: The simulator holds the whole tow in memory, about 1 kB per IMU sample: a million samples (27.8 h at 10 Hz) is its limit.
MAX_IMU_SAMPLES = 1_000_000


@dataclass(frozen=True)
class TowSpec:
    """The towfish's course: constant speed, depth with a slow swing, the ship ``layback_m`` ahead on the same
    track; ``course`` is a program of (seconds, turn rate in deg/s) segments (positive turns to starboard)."""

    speed_m_s: PositiveFloat = 1.5
    depth_m: PositiveFloat = 1000.0
    depth_swing_m: NonNegativeFloat = 2.0
    layback_m: NonNegativeFloat = 700.0
    heading_deg: float = 90.0
    course: tuple[tuple[float, float], ...] = ((600.0, 0.0), (600.0, 0.3), (300.0, 0.0), (300.0, -0.3), (300.0, 0.0))
    roll_swing_deg: float = 1.0
    pitch_swing_deg: float = 0.5
    ship_roll_swing_deg: float = 3.0
    ship_pitch_swing_deg: float = 2.0

    def __post_init__(self) -> None:
        if not self.speed_m_s > 0.0:
            raise ValueError(f"tow speed_m_s must be positive (the ship leads the towfish by layback_m / speed_m_s), got {self.speed_m_s}")
        if not self.depth_m > 0.0:
            raise ValueError(f"tow depth_m must be positive (below the surface), got {self.depth_m}")


@dataclass(frozen=True)
class ImuSpec:
    """The towfish IMU's errors: turn-on biases (one sigma, drawn per run), white noise, bias random walks."""

    gyro_bias_deg_h: float = 0.05
    accel_bias_mg: float = 0.1
    angle_random_walk_deg_sqrt_h: float = 0.005
    velocity_random_walk_mg_sqrt_hz: float = 0.03
    gyro_bias_walk_deg_h_sqrt_h: float = 0.002
    accel_bias_walk_mg_sqrt_h: float = 0.005
    alignment_tilt_deg: float = 0.02
    alignment_heading_deg: float = 0.1

    def noise(self) -> ImuNoise:
        """The same errors as the filter's continuous-time densities (SI units)."""
        return ImuNoise(velocity_random_walk=self.velocity_random_walk_mg_sqrt_hz * MILLI_G,
                        angle_random_walk=np.radians(self.angle_random_walk_deg_sqrt_h) / 60.0,
                        gyro_bias_walk=self.gyro_bias_walk_deg_h_sqrt_h * DEG_PER_HOUR / 60.0,
                        accel_bias_walk=self.accel_bias_walk_mg_sqrt_h * MILLI_G / 60.0)


@dataclass(frozen=True)
class ReplyFaultSpec:
    """USBL dropouts and bad fixes per ping; the ``*_turning`` rates are added in proportion to the ship's turn
    rate over ``turn_rate_full_deg_s``. A bad fix is either a phase outlier (one channel off by
    ``bad_phase_rad``, a uniform range) or a multipath delay (``bad_delay_s``)."""

    dropout_rate: Fraction = 0.03
    dropout_rate_turning: Fraction = 0.25
    bad_fix_rate: Fraction = 0.02
    bad_fix_rate_turning: Fraction = 0.2
    turn_rate_full_deg_s: PositiveFloat = 0.3
    bad_phase_rad: tuple[float, float] = (0.15, 0.8)
    bad_delay_s: tuple[float, float] = (0.015, 0.1)


@dataclass(frozen=True)
class OceanSpec:
    """The simulator's truth ocean beside the logged cast (``lost.host.usbl.ocean``): the resolution it is traced at,
    a surface layer that has warmed since the cast (``cast_age_h`` old at the start) and goes on warming, and internal
    waves heaving the water column. All zero: the cast itself, at ``fine_step_m``."""

    fine_step_m: PositiveFloat = 5.0
    cast_age_h: NonNegativeFloat = 0.0
    surface_warming_c_per_h: float = 0.0
    warm_layer_m: PositiveFloat = 30.0
    internal_wave_m: NonNegativeFloat = 0.0
    internal_wave_period_s: PositiveFloat = 1200.0

    def changes(self) -> bool:
        """Whether the truth differs from the cast beyond its resolution."""
        return self.surface_warming_c_per_h != 0.0 or self.internal_wave_m > 0.0


@dataclass(frozen=True)
class UsblScenario:
    name: str
    description: str = ""
    seed: NonNegativeInt = 0
    duration_s: PositiveFloat = 1800.0
    ping_interval_s: PositiveFloat = 2.0
    imu_rate_hz: PositiveFloat = 10.0
    origin: tuple[float, float] = (18.0, 115.5)
    cast: str = "scs_june"
    gate_probability: OpenFraction = 0.999
    tow: TowSpec = field(default_factory=TowSpec)
    imu: ImuSpec = field(default_factory=ImuSpec)
    usbl: UsblArray = field(default_factory=UsblArray)
    faults: ReplyFaultSpec = field(default_factory=ReplyFaultSpec)
    ocean: OceanSpec = field(default_factory=OceanSpec)
    processing: dict[str, Any] = field(default_factory=dict)
    folder: Path | None = None

    def __post_init__(self) -> None:
        if not self.duration_s > 0.0 or not self.ping_interval_s > 0.0:
            raise ValueError(f"scenario {self.name}: duration_s and ping_interval_s must be positive")
        if self.imu_rate_hz < 10.0:
            raise ValueError(f"scenario {self.name}: imu_rate_hz {self.imu_rate_hz} is below 10 Hz")
        steps = self.ping_interval_s * self.imu_rate_hz
        if abs(steps - round(steps)) > 1e-9:
            raise ValueError(f"scenario {self.name}: ping_interval_s must be a whole number of IMU samples")
        samples = (self.duration_s + self.tow.layback_m / self.tow.speed_m_s) * self.imu_rate_hz
        if samples > MAX_IMU_SAMPLES:
            raise ValueError(f"scenario {self.name}: duration_s {self.duration_s:g} s at imu_rate_hz {self.imu_rate_hz:g} (with the ship's "
                             f"{self.tow.layback_m / self.tow.speed_m_s:.0f} s lead) is {samples:,.0f} IMU samples; the simulator holds at most "
                             f"{MAX_IMU_SAMPLES:,} in memory ({MAX_IMU_SAMPLES / self.imu_rate_hz / 3600:.1f} h at this rate): simulate the tow in parts")

    def processing_config(self):
        """The settings the processing of this scenario's simulated log uses (a :class:`lost.host.usbl.pipeline.UsblConfig`):
        the scenario's array, IMU and gate, and its ``[processing]`` table (what an operator knows of the cast)."""
        from .pipeline import UsblConfig  # the pipeline imports this module

        return UsblConfig(array=self.usbl, imu=self.imu, **{"gate_probability": self.gate_probability, **self.processing})

    def cast_path(self) -> Path:
        if self.cast.endswith(".csv"):
            path = Path(self.cast)
            return path if path.is_absolute() or self.folder is None else self.folder / path
        return shipped_cast_path(self.cast)


def shipped_cast_path(name: str) -> Path:
    return shipped_path("lost.host.usbl", name, what="cast (give a CSV path instead)", folder="data", suffix=".csv")


#: Fields the loader sets, never a file (``processing`` is read as UsblConfig's settings).
_INTERNAL = {"folder", "processing"}


def _build(cls: type, table: Any, path: Path, section: str = "") -> Any:
    """A table of the file as ``cls``: unknown keys named here, types checked by lost.host.config's strict schema
    (``"2"`` is no number, ``2.5`` no seed, NaN no value), ranges by the class itself."""
    where = f"{path} [{section}]" if section else str(path)
    if not isinstance(table, dict):
        raise ValueError(f"{where}: expected a table, got {table!r}")
    known = {f.name for f in fields(cls)} - _INTERNAL
    unknown = sorted(set(table) - known)
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {unknown}; known: {sorted(known)}")
    try:
        return build(cls, table, section)
    except ConfigError as error:
        raise ConfigError(f"{path}: {error}") from None
    except ValueError as error:  # the class's own range checks
        raise ConfigError(f"{where}: {error}") from None


def load_usbl_scenario(path: str | Path) -> UsblScenario:
    """Read a scenario TOML (a file, or the name of a shipped scenario such as ``usbl_turns``).

    Raises
    ------
    ConfigError
        A key is unknown, a value of the wrong type or out of range, or the tow too long to simulate at once; the
        message names the file and the key.
    """
    path = Path(path)
    if not path.is_file() and path.suffix == "":  # a folder of that name (an earlier run's --out) is not the scenario
        path = shipped_path("lost.host.usbl", path.name, what="usbl scenario, nor a scenario file,")
    table = read_toml(path, "usbl scenario file")
    parts = {"tow": TowSpec, "imu": ImuSpec, "usbl": UsblArray, "faults": ReplyFaultSpec, "ocean": OceanSpec}
    built = {key: _build(cls, table.pop(key), path, key) for key, cls in parts.items() if key in table}
    if "processing" in table:
        built["processing"] = _processing_settings(table.pop("processing"), path, "processing")
    top = _build(UsblScenario, table, path)
    try:
        return replace(top, folder=path.parent, **built)
    except ValueError as error:  # the checks across tables (the tow's length)
        raise ConfigError(f"{path}: {error}") from None


def load_processing_config(path: str | Path) -> dict[str, Any]:
    """The processing settings of a recorded tow from TOML: tables ``[usbl]`` (:class:`UsblArray`) and ``[imu]``
    (:class:`ImuSpec`), and the scalar fields of :class:`lost.host.usbl.pipeline.UsblConfig` (``gate_probability``,
    ``align_window_s``, ``earth_rotation``, ...), checked strictly by type and range; returned as keyword arguments of
    :class:`~lost.host.usbl.pipeline.UsblConfig`.

    Raises
    ------
    ConfigError
        A key is unknown, or a value of the wrong type (``earth_rotation = "false"``) or out of range
        (``gate_probability = 1.5``); the message names the file and the key.
    """
    path = Path(path)
    table = read_toml(path, "usbl processing config")
    tables = {key: table.pop(key) for key in ("usbl", "imu") if key in table}
    settings = _processing_settings(table, path, "", also="imu, usbl")
    table.update(tables)
    if "usbl" in table:
        settings["array"] = _build(UsblArray, table["usbl"], path, "usbl")
    if "imu" in table:
        settings["imu"] = _build(ImuSpec, table["imu"], path, "imu")
    return settings


def processing_config_toml(config: Any) -> str:
    """A :class:`lost.host.usbl.pipeline.UsblConfig` as the TOML :func:`load_processing_config` reads back into an equal
    one: its scalar settings, then ``[usbl]`` and ``[imu]``. Floats are written by ``repr``, so they round-trip exactly;
    a setting that is None (``direction_noise``: from the phase noise) is left out, as its default is None."""
    lines = _toml_lines({f.name: getattr(config, f.name) for f in fields(config) if f.name not in ("array", "imu")})
    for table, part in (("usbl", config.array), ("imu", config.imu)):
        lines += ["", f"[{table}]", *_toml_lines({f.name: getattr(part, f.name) for f in fields(part)})]
    return "\n".join(lines) + "\n"


def _toml_lines(settings: dict[str, Any]) -> list[str]:
    return [f"{name} = {_toml_value(value)}" for name, value in settings.items() if value is not None]


def _toml_value(value: Any) -> str:
    if isinstance(value, bool | np.bool_):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, tuple | list):
        return "[" + ", ".join(_toml_value(item) for item in value) + "]"
    if isinstance(value, int | np.integer):
        return str(int(value))
    return repr(float(value))


def _processing_settings(table: Any, path: Path, where: str, also: str = "") -> dict[str, Any]:
    """The scalar settings of :class:`lost.host.usbl.pipeline.UsblConfig` in ``table``, strictly checked."""
    from .pipeline import UsblConfig  # the pipeline imports this module

    scalars = sorted(f.name for f in fields(UsblConfig) if f.name not in ("array", "imu"))
    if not isinstance(table, dict):
        raise ConfigError(f"{path}: [{where}] must be a table, got {table!r}")
    unknown = sorted(set(table) - set(scalars))
    if unknown:
        raise ConfigError(f"config file {path}{f' [{where}]' if where else ''}: unknown key(s) {unknown}; known: {', '.join(scalars)}"
                          f"{', ' + also if also else ''}")
    try:
        return validate_fields(UsblConfig, table, where)
    except ConfigError as error:
        raise ConfigError(f"{path}: {error}") from None


def builtin_usbl_scenarios() -> list[str]:
    return shipped_names("lost.host.usbl")
