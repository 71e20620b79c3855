"""One run of a campaign: a scenario with its seed and parameter values simulated and navigated, as table rows.

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

__all__ = ["run_task", "scenario_with", "FIGURES"]

#: The figures of each estimator a row carries (``summary.json``'s ``methods``), then the row's own.
FIGURES = ("rms_m", "p95_m", "max_m", "nees_in_band", "false_fixes", "usable_fraction", "convergence_time_s", "ms_per_update")


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
    checked = validate_fields(type(obj), {head: value}, ".".join(path.split(".")[:-1]))
    try:
        return dataclasses.replace(obj, **checked)
    except (TypeError, ValueError) as error:
        raise ConfigError(f"{path}: {error}") from None


def _scenario_path(task: RunTask) -> Path:
    from ..scenario import builtin_scenario_path

    path = Path(task.base_dir) / task.scenario
    return path if task.scenario.endswith(".toml") or path.exists() else builtin_scenario_path(task.scenario)


def _rows(task: RunTask) -> list[dict[str, Any]]:
    from ..nav import NavParameters, navigate
    from ..report import summarize
    from ..scenario import load_scenario, simulate

    scenario = scenario_with(load_scenario(_scenario_path(task)), {"seed": task.seed, **task.values})
    grid, records = simulate(scenario)
    params = NavParameters(**scenario.navigation)
    start = time.perf_counter()
    result = navigate(records, grid, params, estimators=task.estimators)
    summary = summarize(result, name=scenario.name, parameters={}, run_time_s=time.perf_counter() - start)
    rows = []
    for estimator in task.estimators:
        figures = summary["methods"].get(estimator, {})
        row = {name: figures.get(name) for name in FIGURES}
        if estimator == "lost":
            row["convergence_time_s"] = summary["convergence"].get("time_s")
        rms = row["rms_m"]
        rows.append({"estimator": estimator, "node_m": grid.node_m, "rms_nodes": None if rms is None else rms / grid.node_m, **row,
                     "records": summary["records"], "run_time_s": summary["run_time_s"]})
    return rows


def run_task(task: RunTask) -> list[dict[str, Any]]:
    """The rows of one run: one per estimator, or one with the error when the run failed."""
    base = {"run_id": task.run_id, "case": task.case, "scenario": task.scenario, "seed": task.seed, "commit": _commit(),
            **{f"param.{name}": value for name, value in task.values.items()}}
    start = time.perf_counter()
    try:
        rows = _rows(task)
    except Exception as error:  # a failed run is a row, never the end of the campaign
        last = traceback.extract_tb(error.__traceback__)[-1]
        return [{**base, "estimator": None, "error": f"{type(error).__name__}: {error} ({Path(last.filename).name}:{last.lineno})",
                 "elapsed_s": time.perf_counter() - start}]
    return [{**base, **row, "error": None, "elapsed_s": time.perf_counter() - start} for row in rows]
