"""A campaign's specification: scenarios x seeds x parameter values x estimators, from a TOML file.

::

    name = "shelf_sweep"
    system = "nav"                            # nav (default), track or usbl: whose scenarios and figures
    scenarios = ["short", "my_tow.toml"]      # the system's shipped names or files (relative to this file)
    seeds = 10                                # 0..9; or a list: [1, 7, 42]
    estimators = ["pmf", "pf"]                # default: every estimator (track: ours; gm_phd, jpda; usbl: fused)
    vary_floor = true                         # each seed a new floor and map (default); false: only the sensors
    [parameters]                              # every combination of these values is run
    "navigation.k" = [100.0, 300.0]           # any [navigation] field
    "map.noise_m" = [0.5, 1.0]                # any [map], [terrain], ship, cable, vehicle field ...
    "sensors.sonar.noise" = [0.2]             # ... or a sensor's
    [[case]]                                  # a named variant of a scenario, beside the plain scenarios
    name = "short_survey_map"
    scenario = "short"
    values = { "map.node_m" = 30.0, "map.noise_m" = 0.7, "map.offset_m" = 2.5 }

A run is one case (a scenario, or a ``[[case]]`` with its fixed values) with one seed and one value of each
parameter; every estimator of the list runs on the same records of that run. With ``vary_floor`` the run's seed
also draws the floor and the map of a navigation scenario (their own ``seed`` fields are cleared), so seeds are
different sea floors. The systems and their figures: :mod:`lost.host.campaign.systems`. Each
run has an identity (:attr:`RunTask.run_id`) made of its case, seed and values, so a campaign started again runs
only what it has not finished.
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
    system: str = "nav"
    scenarios: tuple[str, ...] = ()
    seeds: PositiveInt | tuple[int, ...] = 1
    estimators: tuple[str, ...] = ()
    vary_floor: bool = True
    parameters: dict[str, tuple[Any, ...]] = field(default_factory=dict)
    cases: tuple[Case, ...] = ()
    base_dir: Path = Path(".")

    def seed_list(self) -> tuple[int, ...]:
        return tuple(range(self.seeds)) if isinstance(self.seeds, int) else tuple(self.seeds)

    def all_cases(self) -> tuple[Case, ...]:
        """The plain scenarios as cases of their own name, then the ``[[case]]`` tables."""
        return tuple(Case(name=scenario, scenario=scenario) for scenario in self.scenarios) + self.cases

    def tasks(self) -> list[RunTask]:
        """Every run of the campaign, in a fixed order (case, then values, then seed)."""
        names = sorted(self.parameters)
        grids = [self.parameters[name] for name in names]
        floor = {"terrain.seed": None, "map.seed": None} if self.vary_floor and self.system == "nav" else {}
        return [RunTask(case=case.name, scenario=case.scenario, seed=seed, values={**floor, **case.values, **dict(zip(names, combo))},
                        estimators=self.estimators, base_dir=str(self.base_dir), system=self.system)
                for case in self.all_cases() for combo in itertools.product(*grids) for seed in self.seed_list()]


@dataclass(frozen=True, kw_only=True)
class Case:
    """A named scenario with fixed values (``[[case]]``)."""

    name: str
    scenario: str
    values: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True, kw_only=True)
class RunTask:
    """One run: a case (a scenario, a shipped name or a file, with values), its seed, the parameter values, the estimators."""

    case: str
    scenario: str
    seed: int
    values: dict[str, Any]
    estimators: tuple[str, ...]
    base_dir: str = "."
    system: str = "nav"

    @property
    def run_id(self) -> str:
        """A stable identity of the run (system, scenario, seed, values, estimators), the name of its row file."""
        key = [self.case, self.scenario, self.seed, sorted(self.values.items()), list(self.estimators)]
        key = json.dumps(key if self.system == "nav" else [self.system, *key], sort_keys=True, default=str)
        return hashlib.sha256(key.encode()).hexdigest()[:16]


def load_campaign(path: str | Path) -> CampaignSpec:
    """Read and check a campaign file.

    Raises
    ------
    ConfigError
        Unknown fields, wrong types, no scenario, an empty or non-list parameter, an estimator LOST does not
        have, or more than :data:`MAX_RUNS` runs; the message names the file and the field.
    """
    from .systems import SYSTEMS, estimators_of

    path = Path(path)
    data = read_toml(path, "campaign file")
    try:
        fields = validate_fields(CampaignSpec, {k: v for k, v in data.items() if k not in ("parameters", "case")}, "")
        parameters = _parameters(data.get("parameters", {}))
        cases = tuple(_case(table, n) for n, table in enumerate(_tables(data.get("case", []))))
        if not fields.get("scenarios") and not cases:
            raise ConfigError("scenarios: a campaign needs at least one scenario (a shipped name or a TOML file) or [[case]]")
        system = fields.get("system", "nav")
        if system not in SYSTEMS:
            raise ConfigError(f"system: {system!r} is not one of {list(SYSTEMS)}")
        known, default = estimators_of(system)
        unknown = sorted(set(fields.get("estimators", ())) - set(known))
        if unknown:
            raise ConfigError(f"estimators: {unknown} are not estimators of the {system} system (known: {list(known)})")
        names = [c.name for c in cases] + list(fields.get("scenarios", ()))
        if len(set(names)) != len(names):
            raise ConfigError(f"case names must differ from each other and from the scenarios', got {names}")
    except ConfigError as error:
        raise ConfigError(f"{path}: {error}") from None
    fields.setdefault("estimators", default)
    spec = CampaignSpec(**fields, parameters=parameters, cases=cases, base_dir=path.parent)
    runs = len(spec.all_cases()) * len(spec.seed_list())
    for values in spec.parameters.values():
        runs *= len(values)
    if runs > MAX_RUNS:
        raise ConfigError(f"{path}: the campaign expands to {runs:,} runs; the limit is {MAX_RUNS:,}")
    return spec


def _parameters(parameters: Any) -> dict[str, tuple[Any, ...]]:
    if not isinstance(parameters, dict):
        raise ConfigError(f"[parameters] must be a table of lists of values, got {parameters!r}")
    for name, values in parameters.items():
        if not isinstance(values, list) or not values:
            raise ConfigError(f"parameters.{name}: must be a non-empty list of values, got {values!r}")
    return {k: tuple(v) for k, v in parameters.items()}


def _tables(cases: Any) -> list[dict]:
    if not isinstance(cases, list) or not all(isinstance(c, dict) for c in cases):
        raise ConfigError(f"[[case]] must be an array of tables, got {cases!r}")
    return cases


def _case(table: dict, n: int) -> Case:
    unknown = sorted(set(table) - {"name", "scenario", "values"})
    if unknown or not isinstance(table.get("name"), str) or not isinstance(table.get("scenario"), str):
        raise ConfigError(f"case[{n}]: needs a name and a scenario (strings) and may have values (a table); got {sorted(table)}")
    values = table.get("values", {})
    if not isinstance(values, dict):
        raise ConfigError(f"case[{n}].values: must be a table of dotted field names and values, got {values!r}")
    return Case(name=table["name"], scenario=table["scenario"], values=dict(values))
