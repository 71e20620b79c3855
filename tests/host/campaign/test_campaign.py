"""Campaigns: the spec, one run's rows, and the engine on a local cluster and on a real scheduler with its worker."""

from __future__ import annotations

import contextlib
import json
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from lost.host.campaign import CAMPAIGN_MARKER, CampaignSpec, load_campaign, read_rows, run_campaign, run_task, scenario_with
from lost.host.campaign.spec import RunTask
from lost.host.config import ConfigError
from lost.host.runfolder import RunFolderError
from lost.host.scenario import builtin_scenario_path, load_scenario


def _tiny(folder: Path) -> None:
    # Imported here, not at the top: a dask worker started on its own imports this module by name to run the stand-in
    # tasks below, and the tests' shared inputs are not on its path.
    from tiny import TINY_SCENARIO

    (folder / "tiny.toml").write_text(TINY_SCENARIO)


def _spec(tmp_path: Path, text: str) -> CampaignSpec:
    _tiny(tmp_path)
    path = tmp_path / "campaign.toml"
    path.write_text(text)
    return load_campaign(path)


def test_a_spec_expands_to_every_combination_with_stable_identities(tmp_path):
    spec = _spec(tmp_path, 'name = "a"\nscenarios = ["tiny.toml", "short"]\nseeds = 3\nestimators = ["pmf"]\n'
                           '[parameters]\n"navigation.k" = [100.0, 300.0]\n')
    tasks = spec.tasks()
    assert len(tasks) == 2 * 3 * 2 and len({t.run_id for t in tasks}) == len(tasks)
    assert {t.seed for t in tasks} == {0, 1, 2} and {t.values["navigation.k"] for t in tasks} == {100.0, 300.0}
    assert all(t.values["terrain.seed"] is None and t.values["map.seed"] is None for t in tasks)  # each seed a new floor
    assert [t.run_id for t in tasks] == [t.run_id for t in load_campaign(tmp_path / "campaign.toml").tasks()]
    assert _spec(tmp_path, 'scenarios = ["short"]\nseeds = [4, 9]\n').estimators == ("lost", "pmf", "pf")
    cased = _spec(tmp_path, 'scenarios = ["short"]\nvary_floor = false\n[[case]]\nname = "survey"\nscenario = "short"\n'
                            'values = { "map.noise_m" = 0.7 }\n')
    assert [(t.case, t.values) for t in cased.tasks()] == [("short", {}), ("survey", {"map.noise_m": 0.7})]


@pytest.mark.parametrize(("text", "message"), [
    ('scenarios = []', "needs at least one scenario"),
    ('scenarios = ["short"]\n[[case]]\nname = "short"\nscenario = "short"', "case names must differ"),
    ('[[case]]\nname = "a"', "case[0]: needs a name and a scenario"),
    ('scenarios = ["short"]\nseed = 3', "unknown field(s) ['seed']"),
    ('scenarios = ["short"]\nseeds = 0', "seeds"),
    ('scenarios = ["short"]\nestimators = ["kalman"]', "['kalman'] are not estimators of the nav system"),
    ('scenarios = ["short"]\n[parameters]\n"navigation.k" = []', "parameters.navigation.k: must be a non-empty list"),
    ('scenarios = ["short"]\nseeds = 100000\n[parameters]\n"navigation.k" = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0]', "the limit is"),
])
def test_a_bad_spec_is_named(tmp_path, text, message):
    with pytest.raises(ConfigError, match="campaign.toml") as info:
        _spec(tmp_path, text)
    assert message in str(info.value)


def test_values_replace_fields_by_path_and_are_checked_strictly():
    scenario = load_scenario(builtin_scenario_path("short"))
    changed = scenario_with(scenario, {"seed": 7, "navigation.k": 300.0, "map.noise_m": 0.75, "sensors.sonar.noise": 0.4})
    assert (changed.seed, changed.navigation["k"], changed.map.noise_m, changed.sensors["sonar"].noise) == (7, 300.0, 0.75, 0.4)
    assert scenario.seed != 7 or scenario.map.noise_m != 0.75  # the original is untouched
    with pytest.raises(ConfigError, match="map.noise_m .*greater than or equal to 0"):
        scenario_with(scenario, {"map.noise_m": -1.0})
    with pytest.raises(ConfigError, match="map.colour: 'colour' names no field"):
        scenario_with(scenario, {"map.colour": 1})
    with pytest.raises(ConfigError, match="sensors.sonr.noise: 'sonr' is not one of"):
        scenario_with(scenario, {"sensors.sonr.noise": 0.1})


def test_a_run_gives_a_row_per_estimator_and_a_failed_run_a_row_with_its_error(tmp_path):
    _tiny(tmp_path)
    rows = run_task(RunTask(case="tiny", scenario="tiny.toml", seed=1, values={"navigation.k": 300.0}, estimators=("pmf", "pf"), base_dir=str(tmp_path)))
    assert [r["estimator"] for r in rows] == ["pmf", "pf"] and all(r["error"] is None for r in rows)
    assert all(r["param.navigation.k"] == 300.0 and r["seed"] == 1 and r["node_m"] == 10.0 for r in rows)
    assert all(r["records"] == 60 and r["ms_per_update"] is not None and r["ms_per_update"] > 0 for r in rows)
    bad = run_task(RunTask(case="tiny", scenario="tiny.toml", seed=1, values={"navigation.k": -5.0}, estimators=("pmf",), base_dir=str(tmp_path)))
    assert len(bad) == 1 and bad[0]["estimator"] is None and "k" in bad[0]["error"]


def _quick(task: RunTask) -> list[dict]:
    """A stand-in run: its rows at once, without simulating (and whether the worker runs Dask's profiler beside it)."""
    import dask

    if task.values.get("fail"):
        raise RuntimeError("a stand-in failure")
    return [{"run_id": task.run_id, "case": task.case, "scenario": task.scenario, "seed": task.seed, "estimator": "pmf", "rms_m": float(task.seed),
             "rms_nodes": task.seed / 10.0, "nees_in_band": 0.9, "false_fixes": 0, "ms_per_update": 1.0, "error": None,
             "profiled": dask.config.get("distributed.worker.profile.enabled")}]


def _quick_with_errors(task: RunTask) -> list[dict]:
    try:
        return _quick(task)
    except RuntimeError as error:
        return [{"run_id": task.run_id, "case": task.case, "scenario": task.scenario, "seed": task.seed, "estimator": None, "error": str(error)}]


@contextlib.contextmanager
def _dashboard_port_taken():
    """Dask's default dashboard port, 8787, held (by this socket, or already by something else)."""
    with socket.socket() as held:
        with contextlib.suppress(OSError):
            held.bind(("127.0.0.1", 8787))
            held.listen()
        yield


def test_a_campaign_runs_on_a_local_cluster_resumes_and_keeps_failures_as_rows(tmp_path):
    spec = CampaignSpec(name="c", scenarios=("a", "b"), seeds=4, estimators=("pmf",), parameters={"fail": (False, True)})
    out = tmp_path / "out"
    with _dashboard_port_taken():  # as a second campaign finds it: the cluster takes a free port instead
        summary = run_campaign(spec, out, workers=2, task=_quick_with_errors)
    assert (summary["runs"], summary["ran_now"], summary["finished"], summary["failed_runs"]) == (16, 16, 16, 8)
    table = pd.read_parquet(out / "results.parquet")
    assert len(table) == 16 and set(table[table.error.notna()].error) == {"a stand-in failure"}
    assert not table.profiled.dropna().any()  # the local cluster's workers leave their CPU to the runs
    assert {e["case"]: e["rms_m"]["median"] for e in summary["distributions"]} == {"a": 1.5, "b": 1.5}
    assert (out / "distributions.png").stat().st_size > 0 and json.loads((out / CAMPAIGN_MARKER).read_text())["campaign"] == "c"
    assert "| a | pmf | 4 | 1.50 / " in (out / "summary.md").read_text()  # the page's table: the successful runs of a case
    stamps = {p.name: p.stat().st_mtime_ns for p in (out / "rows").iterdir()}
    again = run_campaign(spec, out, workers=1, task=_quick_with_errors)
    assert again["ran_now"] == 0 and again["finished"] == 16
    assert {p.name: p.stat().st_mtime_ns for p in (out / "rows").iterdir()} == stamps
    with pytest.raises(RunFolderError, match="holds the campaign 'c', not 'd'"):
        run_campaign(CampaignSpec(name="d", scenarios=("a",)), out, task=_quick)


def test_a_worker_killed_mid_campaign_loses_no_finished_run(tmp_path):
    flag = tmp_path / "killed-once"

    def dies_once(task: RunTask) -> list[dict]:
        if task.seed == 5 and not flag.exists():
            flag.write_text(str(os.getpid()))
            os._exit(1)  # the worker process dies under the run, as a killed or crashed worker does
        time.sleep(0.05)
        return _quick(task)

    spec = CampaignSpec(name="k", scenarios=("a",), seeds=12, estimators=("pmf",))
    out = tmp_path / "out"
    summary = run_campaign(spec, out, workers=2, task=dies_once)
    assert flag.exists() and summary["finished"] == 12 and summary["failed_runs"] == 0
    assert sorted(r["seed"] for r in read_rows(out)) == list(range(12))


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_the_same_spec_runs_on_a_real_scheduler_and_worker(tmp_path):
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    scheduler = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", str(port),
                                  "--dashboard-address", ":0", "--no-show"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    worker = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads", "1", "--nworkers", "1",
                               "--no-dashboard"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        spec = CampaignSpec(name="remote", scenarios=("a",), seeds=3, estimators=("pmf",))
        summary = run_campaign(spec, tmp_path / "out", scheduler=address, task=_quick)
        assert summary["finished"] == 3 and summary["failed_runs"] == 0, summary["errors"]
    finally:
        for process in (worker, scheduler):
            process.terminate()
            process.wait(timeout=30)
