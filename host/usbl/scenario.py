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
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..config import ConfigError, build, read_toml
from ..shipped import shipped_names, shipped_path
from .filter import ImuNoise
from .fix import UsblArray

__all__ = ["TowSpec", "ImuSpec", "FaultSpec", "UsblScenario", "load_usbl_scenario", "load_processing_config", "builtin_usbl_scenarios",
           "shipped_cast_path"]

DEG_PER_HOUR = np.radians(1.0) / 3600.0
MILLI_G = 9.80665e-3


@dataclass(frozen=True)
class TowSpec:
    """The towfish's course: constant speed, depth with a slow swing, the ship ``layback_m`` ahead on the same
    track; ``course`` is a program of (seconds, turn rate in deg/s) segments (positive turns to starboard)."""

    speed_m_s: float = 1.5
    depth_m: float = 1000.0
    depth_swing_m: float = 2.0
    layback_m: float = 700.0
    heading_deg: float = 90.0
    course: tuple[tuple[float, float], ...] = ((600.0, 0.0), (600.0, 0.3), (300.0, 0.0), (300.0, -0.3), (300.0, 0.0))
    roll_swing_deg: float = 1.0
    pitch_swing_deg: float = 0.5
    ship_roll_swing_deg: float = 3.0
    ship_pitch_swing_deg: float = 2.0


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
class FaultSpec:
    """USBL dropouts and bad fixes per ping; the ``*_turning`` rates are added in proportion to the ship's turn
    rate over ``turn_rate_full_deg_s``. A bad fix is either a phase outlier (one channel off by
    ``bad_phase_rad``, a uniform range) or a multipath delay (``bad_delay_s``)."""

    dropout_rate: float = 0.03
    dropout_rate_turning: float = 0.25
    bad_fix_rate: float = 0.02
    bad_fix_rate_turning: float = 0.2
    turn_rate_full_deg_s: float = 0.3
    bad_phase_rad: tuple[float, float] = (0.15, 0.8)
    bad_delay_s: tuple[float, float] = (0.015, 0.1)


@dataclass(frozen=True)
class UsblScenario:
    name: str
    description: str = ""
    seed: int = 0
    duration_s: float = 1800.0
    ping_interval_s: float = 2.0
    imu_rate_hz: float = 10.0
    origin: tuple[float, float] = (18.0, 115.5)
    cast: str = "scs_june"
    gate_probability: float = 0.999
    tow: TowSpec = field(default_factory=TowSpec)
    imu: ImuSpec = field(default_factory=ImuSpec)
    usbl: UsblArray = field(default_factory=UsblArray)
    faults: FaultSpec = field(default_factory=FaultSpec)
    folder: Path | None = None

    def __post_init__(self) -> None:
        if not self.duration_s > 0.0 or not self.ping_interval_s > 0.0:
            raise ValueError(f"scenario {self.name}: duration_s and ping_interval_s must be positive")
        if self.imu_rate_hz < 10.0:
            raise ValueError(f"scenario {self.name}: imu_rate_hz {self.imu_rate_hz} is below 10 Hz")
        steps = self.ping_interval_s * self.imu_rate_hz
        if abs(steps - round(steps)) > 1e-9:
            raise ValueError(f"scenario {self.name}: ping_interval_s must be a whole number of IMU samples")

    def cast_path(self) -> Path:
        if self.cast.endswith(".csv"):
            path = Path(self.cast)
            return path if path.is_absolute() or self.folder is None else self.folder / path
        return shipped_cast_path(self.cast)


def shipped_cast_path(name: str) -> Path:
    return shipped_path("lost.host.usbl", name, what="cast (give a CSV path instead)", folder="data", suffix=".csv")


#: Fields the loader sets, never a file.
_INTERNAL = {"folder"}


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


def load_usbl_scenario(path: str | Path) -> UsblScenario:
    """Read a scenario TOML (a file, or the name of a shipped scenario such as ``usbl_turns``)."""
    path = Path(path)
    if not path.exists() and path.suffix == "":
        path = shipped_path("lost.host.usbl", path.name, what="usbl scenario, nor a scenario file,")
    table = read_toml(path, "usbl scenario file")
    parts = {"tow": TowSpec, "imu": ImuSpec, "usbl": UsblArray, "faults": FaultSpec}
    built = {key: _build(cls, table.pop(key), path, key) for key, cls in parts.items() if key in table}
    return replace(_build(UsblScenario, table, path), folder=path.parent, **built)


def load_processing_config(path: str | Path) -> dict[str, Any]:
    """The processing settings of a recorded tow from TOML: tables ``[usbl]`` (:class:`UsblArray`) and ``[imu]``
    (:class:`ImuSpec`), keys ``gate_probability``, ``align_window_s`` and ``earth_rotation``; returned as keyword arguments of
    :class:`lost.host.usbl.pipeline.UsblConfig`."""
    path = Path(path)
    table = read_toml(path, "usbl processing config")
    unknown = sorted(set(table) - {"usbl", "imu", "gate_probability", "align_window_s", "earth_rotation"})
    if unknown:
        raise ValueError(f"config file {path}: unknown key(s) {unknown}; known: align_window_s, earth_rotation, gate_probability, imu, usbl")
    settings: dict[str, Any] = {k: table[k] for k in ("gate_probability", "align_window_s", "earth_rotation") if k in table}
    if "usbl" in table:
        settings["array"] = _build(UsblArray, table["usbl"], path, "usbl")
    if "imu" in table:
        settings["imu"] = _build(ImuSpec, table["imu"], path, "imu")
    return settings


def builtin_usbl_scenarios() -> list[str]:
    return shipped_names("lost.host.usbl")
