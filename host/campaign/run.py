"""One run of a campaign: a scenario with its seed and parameter values simulated and measured, as table rows.

:func:`run_task` is what a Dask worker executes. It never raises for a run that fails: the failure is a row
with its error, so one bad combination never ends a campaign.
"""

from __future__ import annotations

import dataclasses
import subprocess
import time
import traceback
from functools import cache
from pathlib import Path
from typing import Any

from ..config import ConfigError, validate_fields
from .spec import RunTask

__all__ = ["run_task", "scenario_with"]


@cache
def _commit() -> str | None:
    """The source's git commit, or None outside a checkout."""
    try:
        out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=Path(__file__).parent, capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip() or None


def scenario_with(scenario: Any, values: dict[str, Any]) -> Any:
    """``scenario`` with each dotted field replaced (``"navigation.k"``, ``"map.noise_m"``, ``"sensors.sonar.noise"``, ``"seed"``).

    Values are checked by the same strict schema as a scenario file's; the scenario's own checks run again.

    Raises
    ------
    ConfigError
        A path that names no field, or a value of the wrong type or range (the path named).
    """
    for path, value in values.items():
        scenario = _replaced(scenario, path.split("."), value, path)
    return scenario


def _replaced(obj: Any, parts: list[str], value: Any, path: str) -> Any:
    head, rest = parts[0], parts[1:]
    if isinstance(obj, dict):
        if not rest:
            return {**obj, head: value}  # a [navigation] value: NavParameters checks it when the run builds them
        if head not in obj:
            raise ConfigError(f"{path}: {head!r} is not one of {sorted(obj)}")
        return {**obj, head: _replaced(obj[head], rest, value, path)}
    if not dataclasses.is_dataclass(obj) or head not in {f.name for f in dataclasses.fields(obj)}:
        raise ConfigError(f"{path}: {head!r} names no field here")
    if rest:
        return dataclasses.replace(obj, **{head: _replaced(getattr(obj, head), rest, value, path)})
    required = {f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)
                if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING and f.name != head}  # a schema asks for them
    checked = validate_fields(type(obj), {**required, head: value}, ".".join(path.split(".")[:-1]))
    try:
        return dataclasses.replace(obj, **{head: checked[head]})
    except (TypeError, ValueError) as error:
        raise ConfigError(f"{path}: {error}") from None


def _rows(task: RunTask) -> list[dict[str, Any]]:
    from .systems import load_system_scenario, system_rows

    scenario = scenario_with(load_system_scenario(task.system, Path(task.base_dir) / task.scenario), {"seed": task.seed, **task.values})
    return system_rows(task.system, scenario, task.estimators)


def run_task(task: RunTask) -> list[dict[str, Any]]:
    """The rows of one run: one per estimator, or one with the error when the run failed."""
    base = {"run_id": task.run_id, "system": task.system, "case": task.case, "scenario": task.scenario, "seed": task.seed, "commit": _commit(),
            **{f"param.{name}": value for name, value in task.values.items()}}
    start = time.perf_counter()
    try:
        rows = _rows(task)
    except Exception as error:  # a failed run is a row, never the end of the campaign
        last = traceback.extract_tb(error.__traceback__)[-1]
        return [{**base, "estimator": None, "error": f"{type(error).__name__}: {error} ({Path(last.filename).name}:{last.lineno})",
                 "elapsed_s": time.perf_counter() - start}]
    return [{**base, **row, "error": None, "elapsed_s": time.perf_counter() - start} for row in rows]
