"""Divers (and drifting objects, and fast animals) approaching through clutter, seen from a moving platform.

A scenario is a TOML file; every field is optional and has the default of the dataclass that reads it
(:class:`SonarModel`, :class:`PlatformSpec`, :class:`TargetSpec`); an unknown field is an error. The
shipped scenarios live in ``lost/host/track/scenarios/`` (:func:`builtin_scenarios`).

::

    name = "one_diver"
    seed = 1
    duration_s = 300.0
    [sonar]     # max_range_m, half_fov_deg, ping_interval_s, range_sigma_m, bearing_sigma_deg, pd, clutter_per_ping
    [platform]  # start_m, heading_deg, speed_mps, turn_rate_dps, yaw_amplitude_deg, yaw_period_s
    [[target]]  # kind, start_range_m, start_bearing_deg, speed_mps, course_deg, accel_sigma, start_s, end_s

The physics, kept simple and stated
-----------------------------------
- Platform: moves along its heading at ``speed_mps``; the heading turns at ``turn_rate_dps`` and swings
  sinusoidally by ``yaw_amplitude_deg`` (an anchored vessel). GPS and heading are exact.
- Targets: nearly constant velocity, white-noise acceleration of spectral density ``accel_sigma**2``
  (m^2/s^3) sampled exactly per ping interval; the start is given in range and bearing from the
  platform's first ping; the course defaults to straight at the platform's start.
- Sonar: each target inside the sector is detected with probability ``pd``, its range and bearing
  perturbed by Gaussian noise (``range_sigma_m``, ``bearing_sigma_deg``); false alarms are Poisson with mean
  ``clutter_per_ping``, uniform in range and bearing over the sector (a constant false-alarm rate per
  range-bearing cell, as a CFAR detector gives).
- Strength, in dB above the detection threshold (what the tracker's amplitude model is not: it assumes
  Gaussians in dB). A target's echo power fluctuates from ping to ping as Swerling case 1 (exponential power)
  with the mean power that crosses the threshold with probability ``pd``, so a detected echo's power over
  the threshold is ``1 + Exp(-1 / ln pd)`` (memoryless): at pd 0.9, 8.6 +/- 3.9 dB, skewed; a weaker target
  (lower pd) is weaker here too. Clutter exceedances over a high threshold follow the generalized Pareto
  law (extreme-value theory's law of exceedances; a shape ``clutter_tail`` above 0 is the heavy tail of
  spiky, K-distributed reverberation): power over the threshold ``1 + GPD(clutter_tail, clutter_scale)``, at
  the defaults (0.4, 0.6) 2.3 +/- 2.1 dB with 1.5 % of the clutter stronger than the median target.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import Field

from ..config import ConfigError, NonNegativeFloat, NonNegativeInt, PositiveFloat, build, read_toml, validate_fields
from ..shipped import shipped_names, shipped_path
from .detections import Ping
from .geometry import Sonar, polar_to_world, world_to_polar

__all__ = ["SonarModel", "PlatformSpec", "TargetSpec", "TrackScenario", "Truth", "Simulation",
           "load_scenario", "simulate", "builtin_scenarios", "builtin_scenario_path", "TARGET_KINDS",
           "check_size", "MAX_SCENARIO_BYTES", "target_strength_db", "clutter_strength_db", "strength_moments",
           "tracker_model"]

#: Truth labels of simulated targets (the tracker's classes, plus what a scenario means by them).
TARGET_KINDS = ("diver", "drifting", "animal")


@dataclass(frozen=True, kw_only=True)
class SonarModel:
    """``[sonar]``: the sector (:class:`Sonar`) and the detector's noise, detection probability and clutter.

    The paper's clutter level: its Figures 3 and 5 show a handful of false detections per ping across the
    sector; 5 per ping (Poisson mean) is our reading, with ``pd = 0.9``. Measurement noise 2 m and 1.5 degrees.
    ``clutter_tail`` and ``clutter_scale``: the generalized Pareto law of the clutter's power over the
    detection threshold (module docstring).
    """

    max_range_m: PositiveFloat = 500.0
    half_fov_deg: Annotated[float, Field(gt=0, le=180)] = 45.0
    ping_interval_s: PositiveFloat = 1.3
    range_sigma_m: NonNegativeFloat = 2.0
    bearing_sigma_deg: NonNegativeFloat = 1.5
    pd: float = 0.9
    clutter_per_ping: float = 5.0
    clutter_tail: NonNegativeFloat = 0.4
    clutter_scale: PositiveFloat = 0.6

    def __post_init__(self) -> None:
        if not (0 <= self.pd <= 1 and self.clutter_per_ping >= 0 and self.range_sigma_m >= 0 and self.bearing_sigma_deg >= 0):
            raise ValueError(f"[sonar] needs pd in [0, 1] and non-negative clutter and noise, got pd={self.pd!r}, "
                             f"clutter_per_ping={self.clutter_per_ping!r}, sigmas {self.range_sigma_m!r} m, {self.bearing_sigma_deg!r} deg.")

    @property
    def sonar(self) -> Sonar:
        return Sonar(max_range_m=self.max_range_m, half_fov_deg=self.half_fov_deg, ping_interval_s=self.ping_interval_s)


@dataclass(frozen=True, kw_only=True)
class PlatformSpec:
    """``[platform]``: start_m [east, north]; heading_deg; speed_mps along the heading; turn_rate_dps;
    yaw_amplitude_deg and yaw_period_s of a sinusoidal swing."""

    start_m: tuple[float, float] = (0.0, 0.0)
    heading_deg: float = 0.0
    speed_mps: float = 0.0
    turn_rate_dps: float = 0.0
    yaw_amplitude_deg: float = 0.0
    yaw_period_s: PositiveFloat = 120.0


@dataclass(frozen=True, kw_only=True)
class TargetSpec:
    """``[[target]]``: kind (diver, drifting, animal); start_range_m, start_bearing_deg from the platform's first
    ping; speed_mps; course_deg (default: toward the platform's start); accel_sigma (m/s^1.5); alive from start_s
    to end_s (default: the whole run)."""

    kind: str = "diver"
    start_range_m: NonNegativeFloat = 450.0
    start_bearing_deg: float = 0.0
    speed_mps: float = 0.6
    course_deg: float | None = None
    accel_sigma: float = 0.005
    start_s: NonNegativeFloat = 0.0
    end_s: float | None = None

    def __post_init__(self) -> None:
        if self.kind not in TARGET_KINDS:
            raise ValueError(f"[[target]] kind must be one of {TARGET_KINDS}, got {self.kind!r}.")
        if self.speed_mps < 0 or self.accel_sigma < 0:
            raise ValueError(f"[[target]] speed_mps and accel_sigma must not be negative, got {self.speed_mps!r}, {self.accel_sigma!r}.")


@dataclass(frozen=True, kw_only=True)
class TrackScenario:
    """A whole scenario file (module docstring)."""

    name: str = "scenario"
    description: str = ""
    seed: NonNegativeInt = 0
    duration_s: PositiveFloat = 300.0
    sonar: SonarModel = field(default_factory=SonarModel)
    platform: PlatformSpec = field(default_factory=PlatformSpec)
    targets: tuple[TargetSpec, ...] = ()
    tracker: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Truth:
    """Where each target was at each ping: ``xy`` and ``velocity`` (pings, targets, 2), NaN while not alive or unseen."""

    t_s: np.ndarray
    xy: np.ndarray
    velocity: np.ndarray
    kinds: tuple[str, ...]
    in_sector: np.ndarray  # (pings, targets) bool


@dataclass(frozen=True)
class Simulation:
    """A simulated run: the pings a sonar would record, and the truth behind them."""

    scenario: TrackScenario
    pings: list[Ping]
    truth: Truth
    target_detections: int
    false_alarms: int


#: A scenario needing more memory than this (pings, their detections, the truth) is refused before it is simulated.
MAX_SCENARIO_BYTES = 2e9
#: Memory of one simulated ping beyond its detections (the Ping object and its arrays), and of one detection, bytes.
_PING_BYTES, _DETECTION_BYTES = 600, 24


def check_size(scenario: TrackScenario) -> None:
    """Refuse a scenario no machine can hold before any of it is allocated (its pings from duration_s and ping_interval_s)."""
    pings = scenario.duration_s / scenario.sonar.ping_interval_s + 1
    per_ping = _PING_BYTES + _DETECTION_BYTES * (scenario.sonar.clutter_per_ping + len(scenario.targets)) + 64 * len(scenario.targets)
    needed = pings * per_ping
    if needed > MAX_SCENARIO_BYTES:
        raise ConfigError(
            f"this tracking scenario would need about {needed / 1e9:,.1f} GB of memory ({pings:,.0f} pings from duration_s = "
            f"{scenario.duration_s:g} s and sonar.ping_interval_s = {scenario.sonar.ping_interval_s:g} s); the limit is "
            f"{MAX_SCENARIO_BYTES / 1e9:g} GB: lower duration_s or run it in parts"
        )


_TOP_LEVEL = ("name", "description", "seed", "duration_s")
_TABLES = {"sonar": SonarModel, "platform": PlatformSpec}


def load_scenario(path: str | Path) -> TrackScenario:
    """Read and validate a tracking scenario file (strict types, unknown fields refused, its size checked).

    Raises
    ------
    ConfigError
        Invalid TOML, an unknown table or field, a value of the wrong type or out of range (named by its
        path and unit, prefixed with the file's name), or a scenario too large to simulate.
    """
    path = Path(path)
    data = read_toml(path, "tracking scenario file")
    top = {*_TOP_LEVEL, *_TABLES, "target", "tracker"}
    unknown = sorted(set(data) - top)
    if unknown:
        raise ConfigError(f"{path.name} has unknown top-level field(s) {unknown}; known ones are {sorted(top)}.")
    try:
        kwargs: dict[str, Any] = validate_fields(TrackScenario, {key: data[key] for key in _TOP_LEVEL if key in data}, "")
        for key, cls in _TABLES.items():
            if key in data:
                kwargs[key] = build(cls, data[key], key)
        targets = data.get("target", [])
        if not isinstance(targets, list):
            raise ConfigError(f"target must be an array of tables ([[target]]), got {targets!r}")
        kwargs["targets"] = tuple(build(TargetSpec, t, f"target.{n}") for n, t in enumerate(targets))
        kwargs["tracker"] = _tracker_table(data.get("tracker", {}))
        kwargs.setdefault("name", path.stem)
        scenario = TrackScenario(**kwargs)
        check_size(scenario)
    except ValueError as error:
        raise ConfigError(f"{path.name}: {error}") from None
    return scenario


def _tracker_table(table: Any) -> dict:
    """``[tracker]``: overrides of TrackerParameters, checked here by the same strict schema the tracker is built with."""
    from .tracker import TrackerParameters

    validate_fields(TrackerParameters, table, "tracker")
    return dict(table)


def builtin_scenarios() -> list[str]:
    """Names of the tracking scenarios shipped in the package."""
    return shipped_names("lost.host.track")


def builtin_scenario_path(name: str) -> Path:
    """Path of a shipped tracking scenario by name (``"one_diver"``)."""
    return shipped_path("lost.host.track", name, what="tracking scenario")


def _platform(spec: PlatformSpec, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    heading = spec.heading_deg + spec.turn_rate_dps * t + spec.yaw_amplitude_deg * np.sin(2 * np.pi * t / spec.yaw_period_s)
    # Integrate the course over each interval (trapezoid) so turns move the platform as they should.
    step_heading = np.radians(np.concatenate(([heading[0]], (heading[1:] + heading[:-1]) / 2)))
    dt = np.diff(t, prepend=t[0])
    xy = np.asarray(spec.start_m, float) + np.cumsum(np.column_stack((np.sin(step_heading), np.cos(step_heading))) * (spec.speed_mps * dt)[:, None], axis=0)
    return xy, heading


def _target_paths(scenario: TrackScenario, t: np.ndarray, platform_xy: np.ndarray, heading: np.ndarray,
                  rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    n, dt = t.size, scenario.sonar.ping_interval_s
    xy = np.full((n, len(scenario.targets), 2), np.nan)
    vel = np.full_like(xy, np.nan)
    for k, spec in enumerate(scenario.targets):
        start = polar_to_world(platform_xy[0], heading[0], np.array([spec.start_range_m]), np.array([spec.start_bearing_deg]))[0]
        course = spec.course_deg
        if course is None:
            course = math.degrees(math.atan2(*(platform_xy[0] - start)))
        p = start.copy()
        v = spec.speed_mps * np.array([math.sin(math.radians(course)), math.cos(math.radians(course))])
        # Exact sampling of white-noise acceleration over one interval, per axis.
        q = spec.accel_sigma**2 * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
        chol = np.linalg.cholesky(q + 1e-15 * np.eye(2))
        end = math.inf if spec.end_s is None else spec.end_s
        for i in range(n):
            if spec.start_s <= t[i] <= end:
                xy[i, k], vel[i, k] = p, v
            noise = chol @ rng.standard_normal((2, 2))  # rows: position, velocity; columns: east, north
            p = p + v * dt + noise[0]
            v = v + noise[1]
    return xy, vel


def target_strength_db(pd: float, n: int, rng: np.random.Generator) -> np.ndarray:
    """Strengths (dB over the threshold) of ``n`` detected Swerling-1 echoes whose mean power crosses it with probability ``pd``."""
    mean_power = -1.0 / math.log(min(max(pd, 1e-6), 0.999))  # pd = exp(-1 / mean power); pd 1 would need infinite power
    return 10.0 * np.log10(1.0 + rng.exponential(mean_power, n))


def clutter_strength_db(tail: float, scale: float, n: int, rng: np.random.Generator) -> np.ndarray:
    """Strengths (dB over the threshold) of ``n`` false alarms: generalized Pareto exceedances of shape ``tail``, scale ``scale``."""
    u = rng.random(n)
    excess = scale * -np.log1p(-u) if tail == 0 else scale / tail * ((1.0 - u) ** -tail - 1.0)
    return 10.0 * np.log10(1.0 + excess)


def strength_moments(model: SonarModel, samples: int = 400_000) -> dict[str, float]:
    """Mean and standard deviation (dB) of the simulator's target and clutter strengths under ``model``: a Gaussian fit
    an operator could make from a labelled log, as :class:`~.tracker.TrackerParameters` fields (fixed seed, deterministic)."""
    rng = np.random.default_rng(0)
    target = target_strength_db(model.pd, samples, rng)
    clutter = clutter_strength_db(model.clutter_tail, model.clutter_scale, samples, rng)
    return {"target_strength_db": float(target.mean()), "target_strength_sigma_db": float(target.std()),
            "clutter_strength_db": float(clutter.mean()), "clutter_strength_sigma_db": float(clutter.std())}


def tracker_model(model: SonarModel) -> dict[str, float]:
    """The sonar model a tracker is told for a scenario, as :class:`~.tracker.TrackerParameters` fields: its pd and clutter
    rate (kept positive, as the tracker needs), its noise, and its strengths' Gaussian fit (:func:`strength_moments`)."""
    return {"pd": max(model.pd, 1e-3), "clutter_per_ping": max(model.clutter_per_ping, 1e-3), "range_sigma_m": model.range_sigma_m,
            "bearing_sigma_deg": model.bearing_sigma_deg, **strength_moments(model)}


def simulate(scenario: TrackScenario) -> Simulation:
    """Run a scenario: every ping's detections (targets and clutter) and the truth, from its seed alone."""
    check_size(scenario)
    rng = np.random.default_rng(scenario.seed)
    model, sonar = scenario.sonar, scenario.sonar.sonar
    t = np.arange(0.0, scenario.duration_s + 1e-9, model.ping_interval_s)
    platform_xy, heading = _platform(scenario.platform, t)
    xy, vel = _target_paths(scenario, t, platform_xy, heading, rng)
    in_sector = np.zeros(xy.shape[:2], dtype=bool)
    pings, hits, false_alarms = [], 0, 0
    for i in range(t.size):
        ranges, bearings, strengths = [], [], []
        alive = np.isfinite(xy[i, :, 0])
        if alive.any():
            r, b = world_to_polar(platform_xy[i], heading[i], xy[i, alive])
            seen = sonar.inside(r, b)
            in_sector[i, np.flatnonzero(alive)] = seen
            detected = seen & (rng.random(r.size) < model.pd)
            ranges.append(r[detected] + rng.normal(0, model.range_sigma_m, int(detected.sum())))
            bearings.append(b[detected] + rng.normal(0, model.bearing_sigma_deg, int(detected.sum())))
            strengths.append(target_strength_db(model.pd, int(detected.sum()), rng))
        clutter = rng.poisson(model.clutter_per_ping)
        ranges.append(rng.uniform(0, sonar.max_range_m, clutter))
        bearings.append(rng.uniform(-sonar.half_fov_deg, sonar.half_fov_deg, clutter))
        strengths.append(clutter_strength_db(model.clutter_tail, model.clutter_scale, clutter, rng))
        r, b, s = (np.concatenate(a) for a in (ranges, bearings, strengths))
        keep = sonar.inside(r, b)  # noise can push a detection just past the edge: the sonar would not report it
        hits += int(keep[: r.size - clutter].sum())
        false_alarms += int(keep[r.size - clutter:].sum())
        order = rng.permutation(int(keep.sum()))  # a detector does not list the target first
        pings.append(Ping(i, float(t[i]), platform_xy[i], float(heading[i]), r[keep][order], b[keep][order], s[keep][order]))
    truth = Truth(t, xy, vel, tuple(s.kind for s in scenario.targets), in_sector)
    return Simulation(scenario, pings, truth, hits, false_alarms)
