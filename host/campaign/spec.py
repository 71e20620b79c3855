"""A campaign's specification: scenarios x seeds x parameter values x estimators, from a TOML file.

::

    name = "shelf_sweep"
    scenarios = ["short", "my_tow.toml"]      # shipped names or files (relative to this file)
    seeds = 10                                # 0..9; or a list: [1, 7, 42]
    estimators = ["pmf", "pf"]                # default: every estimator
    [parameters]                              # every combination of these values is run
    "navigation.k" = [100.0, 300.0]           # any [navigation] field
    "map.noise_m" = [0.5, 1.0]                # any [map], [terrain], ship, cable, vehicle field ...
    "sensors.sonar.noise" = [0.2]             # ... or a sensor's

A run is one scenario with one seed and one value of each parameter; every estimator of the list runs on the
same records of that run. Each run has an identity (:attr:`RunTask.run_id`) made of its scenario, seed and
values, so a campaign started again runs only what it has not finished.
"""

from __future__ import annotations

import hashlib
import itertools
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..config import ConfigError, PositiveInt, read_toml, validate_fields

__all__ = ["CampaignSpec", "RunTask", "load_campaign", "MAX_RUNS"]

#: A campaign expanding to more runs than this is refused (a typo in a seed count, not a plan).
MAX_RUNS = 1_000_000


@dataclass(frozen=True, kw_only=True)
class CampaignSpec:
    """The fields of a campaign file (module docstring); ``base_dir`` is the file's folder."""

    name: str = "campaign"
    scenarios: tuple[str, ...] = ()
    seeds: PositiveInt | tuple[int, ...] = 1
    estimators: tuple[str, ...] = ()
    parameters: dict[str, tuple[Any, ...]] = field(default_factory=dict)
    base_dir: Path = Path(".")

    def seed_list(self) -> tuple[int, ...]:
        return tuple(range(self.seeds)) if isinstance(self.seeds, int) else tuple(self.seeds)

    def tasks(self) -> list[RunTask]:
        """Every run of the campaign, in a fixed order (scenario, then values, then seed)."""
        names = sorted(self.parameters)
        grids = [self.parameters[name] for name in names]
        return [RunTask(scenario=scenario, seed=seed, values=dict(zip(names, combo)), estimators=self.estimators, base_dir=str(self.base_dir))
                for scenario in self.scenarios for combo in itertools.product(*grids) for seed in self.seed_list()]


@dataclass(frozen=True, kw_only=True)
class RunTask:
    """One run: a scenario (a shipped name or a file), its seed, the parameter values, the estimators."""

    scenario: str
    seed: int
    values: dict[str, Any]
    estimators: tuple[str, ...]
    base_dir: str = "."

    @property
    def run_id(self) -> str:
        """A stable identity of the run (scenario, seed, values, estimators), the name of its row file."""
        key = json.dumps([self.scenario, self.seed, sorted(self.values.items()), list(self.estimators)], sort_keys=True, default=str)
        return hashlib.sha256(key.encode()).hexdigest()[:16]


def load_campaign(path: str | Path) -> CampaignSpec:
    """Read and check a campaign file.

    Raises
    ------
    ConfigError
        Unknown fields, wrong types, no scenario, an empty or non-list parameter, an estimator LOST does not
        have, or more than :data:`MAX_RUNS` runs; the message names the file and the field.
    """
    from ..nav import ESTIMATORS

    path = Path(path)
    data = read_toml(path, "campaign file")
    try:
        fields = validate_fields(CampaignSpec, {k: v for k, v in data.items() if k != "parameters"}, "")
        parameters = data.get("parameters", {})
        if not isinstance(parameters, dict):
            raise ConfigError(f"[parameters] must be a table of lists of values, got {parameters!r}")
        for name, values in parameters.items():
            if not isinstance(values, list) or not values:
                raise ConfigError(f"parameters.{name}: must be a non-empty list of values, got {values!r}")
        if not fields.get("scenarios"):
            raise ConfigError("scenarios: a campaign needs at least one scenario (a shipped name or a TOML file)")
        unknown = sorted(set(fields.get("estimators", ())) - set(ESTIMATORS))
        if unknown:
            raise ConfigError(f"estimators: {unknown} are not estimators of LOST (known: {list(ESTIMATORS)})")
    except ConfigError as error:
        raise ConfigError(f"{path}: {error}") from None
    spec = CampaignSpec(**fields, parameters={k: tuple(v) for k, v in parameters.items()}, base_dir=path.parent)
    if not spec.estimators:
        spec = CampaignSpec(**{**fields, "estimators": tuple(ESTIMATORS)}, parameters=spec.parameters, base_dir=path.parent)
    runs = len(spec.scenarios) * len(spec.seed_list())
    for values in spec.parameters.values():
        runs *= len(values)
    if runs > MAX_RUNS:
        raise ConfigError(f"{path}: the campaign expands to {runs:,} runs; the limit is {MAX_RUNS:,}")
    return spec
