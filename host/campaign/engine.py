"""Runs a campaign on Dask: each run a task, each finished run's rows kept at once, the table assembled at the end.

The campaign folder (``--out``) is resumable rather than replaced whole: ``rows/RUN_ID.json`` is written (under a
temporary name, then renamed) the moment a run finishes, so a killed worker, a killed client or a stopped
machine loses only the runs in flight, and starting the same campaign again runs only what has no row file yet.
``results.parquet``, ``summary.json``, ``summary.md`` (:mod:`lost.host.campaign.table`) and the plots are rewritten
from all row files at the end of every start. The folder is ours only with ``lost-campaign.json``; a second campaign
on it while one runs is refused (the run folder's lock).

Dask: a ``LocalCluster`` of ``workers`` single-threaded processes on this machine by default, or any running
cluster by its scheduler's address (``tcp://host:8786``); a task is a whole run and its result is rows
(``Client.map`` and ``as_completed``). A task whose worker dies is re-run by Dask on another worker; one that
kills every worker it is given (``KilledWorker``) is a row with that error.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from collections.abc import Callable, Iterator
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from ..runfolder import RunFolderError, atomic_write, folder_lock, writable_parent, write_summary
from .run import run_task
from .spec import CampaignSpec, RunTask
from .table import markdown_table

__all__ = ["run_campaign", "read_rows", "CAMPAIGN_MARKER"]

#: The file that marks a folder as a LOST campaign.
CAMPAIGN_MARKER = "lost-campaign.json"


def _claim(out: Path, spec: CampaignSpec) -> None:
    """Make ``out`` a campaign folder of ``spec``, or check that it is one already (the same name)."""
    marker = out / CAMPAIGN_MARKER
    if marker.is_file():
        try:
            name = json.loads(marker.read_text(encoding="utf-8")).get("campaign")
        except (ValueError, AttributeError):
            name = None
        if name != spec.name:
            raise RunFolderError(f"--out {out} holds the campaign {name!r}, not {spec.name!r}; choose another folder")
        return
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise RunFolderError(f"--out {out} is not an empty folder and holds no LOST campaign (no {CAMPAIGN_MARKER}); choose a new folder")
    (out / "rows").mkdir(parents=True, exist_ok=True)
    started = {"lost_campaign": 1, "campaign": spec.name, "started": datetime.now(UTC).isoformat(timespec="seconds")}
    atomic_write(marker, lambda handle: handle.write(json.dumps(started) + "\n"))


def read_rows(out: Path) -> list[dict[str, Any]]:
    """Every row of every finished run of the campaign in ``out``."""
    rows: list[dict[str, Any]] = []
    for path in sorted((out / "rows").glob("*.json")):
        rows += json.loads(path.read_text(encoding="utf-8"))
    return rows


@contextlib.contextmanager
def _client(scheduler: str | None, workers: int) -> Iterator[Any]:
    import dask
    from dask.distributed import Client, LocalCluster

    if scheduler is not None:
        with Client(scheduler, timeout="20s") as client:
            yield client
        return
    # Processes, one thread each: a run is NumPy and Python, which threads would serialize on the GIL. The scheduler's
    # HTTP server on a free local port: None would still take 8787, and a second campaign would find it in use.
    with dask.config.set(_quiet_workers()), \
            LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address="127.0.0.1:0") as cluster, \
            Client(cluster) as client:
        yield client


def _quiet_workers() -> dict[str, Any]:
    """Dask settings that leave a worker's CPU to its run (measured on a 200 s ``short`` run in a worker: the other threads
    of the process took 12 to 13 % of the run's CPU time by default, 1 % with these).

    - Dask's default ``MALLOC_TRIM_THRESHOLD_`` for its workers turns every mid-sized NumPy array into an mmap and page
      faults (a run took 1.5 times as long as in-process): the workers keep glibc's adaptive default.
    - The statistical profiler walks the running task's stack every 10 ms, under the GIL: off (a campaign's runs are
      profiled in-process, not through Dask's dashboard).
    - The event loop's health tick every 20 ms, the memory monitor every 100 ms and the system monitor every 500 ms wake
      the worker's main thread and take the GIL from the run: every second or two instead.
    """
    import dask

    environ = {k: v for k, v in dask.config.get("distributed.nanny.pre-spawn-environ").items() if k != "MALLOC_TRIM_THRESHOLD_"}
    return {"distributed.nanny.pre-spawn-environ": environ, "distributed.worker.profile.enabled": False,
            "distributed.admin.tick.interval": "1s", "distributed.worker.memory.monitor-interval": "1s",
            "distributed.admin.system-monitor.interval": "2s"}


def run_campaign(spec: CampaignSpec, out: Path, *, scheduler: str | None = None, workers: int = 2,
                 progress: Callable | None = None, task: Callable[[RunTask], list[dict]] = run_task) -> dict[str, Any]:
    """Run every run of ``spec`` that has no row file in ``out`` yet; return the campaign's summary.

    ``task`` is the function each worker runs (the campaign's own :func:`run_task`; a test may pass another).
    """
    out = Path(out).absolute()
    parent = writable_parent(out)
    with folder_lock(parent, out):
        _claim(out, spec)
        tasks = spec.tasks()
        done = {path.stem for path in (out / "rows").glob("*.json")}
        todo = [t for t in tasks if t.run_id not in done]
        if todo:
            _execute(todo, out, scheduler, workers, progress, task)
        return _finish(spec, out, len(tasks), len(todo))


def _execute(todo: list[RunTask], out: Path, scheduler: str | None, workers: int, progress: Callable | None,
             task: Callable[[RunTask], list[dict]]) -> None:
    from dask.distributed import as_completed

    by_key = {}
    with _client(scheduler, workers) as client:
        futures = client.map(task, todo, key=[f"lost-run-{t.run_id}" for t in todo], pure=False)
        by_key = {f.key: t for f, t in zip(futures, todo)}
        finished = as_completed(futures)
        for future in (progress(finished) if progress else finished):
            run = by_key[future.key]
            try:
                rows = future.result()
            except Exception as error:  # the worker died under it every time it was tried (KilledWorker), or it could not be sent
                rows = [{"run_id": run.run_id, "system": run.system, "case": run.case, "scenario": run.scenario, "seed": run.seed, "estimator": None,
                         "error": f"{type(error).__name__}: {error}", **{f"param.{k}": v for k, v in run.values.items()}}]
            atomic_write(out / "rows" / f"{run.run_id}.json", lambda handle, rows=rows: handle.write(json.dumps(rows, default=str) + "\n"))


def _finish(spec: CampaignSpec, out: Path, runs: int, ran: int) -> dict[str, Any]:
    import pandas as pd

    from ..plotting import draw_plots
    from .plots import campaign_plots

    rows = read_rows(out)
    table = pd.DataFrame(rows)
    fd, tmp = tempfile.mkstemp(dir=out, prefix=".results.parquet.", suffix=".partial")
    os.close(fd)
    try:
        table.to_parquet(tmp, index=False)
        os.replace(tmp, out / "results.parquet")
    finally:
        Path(tmp).unlink(missing_ok=True)
    failed = table[table["error"].notna()] if "error" in table else table.iloc[0:0]
    warnings: list[str] = []
    draw_plots(out, campaign_plots(table), warnings)
    summary = {"campaign": spec.name, "runs": runs, "ran_now": ran, "finished": int(table["run_id"].nunique()) if len(table) else 0,
               "failed_runs": int(failed["run_id"].nunique()) if len(failed) else 0,
               "errors": sorted(set(failed["error"].astype(str)))[:20] if len(failed) else [],
               "system": spec.system, "distributions": _distributions(table), "warnings": warnings}
    write_summary(out / "summary.json", summary)
    text = markdown_table(table, tuple(case.name for case in spec.all_cases()))
    atomic_write(out / "summary.md", lambda handle: handle.write(text))
    return summary


def _distributions(table) -> list[dict[str, Any]]:
    """Median and 90th percentile of each of the system's figures per case and estimator, over seeds and values."""
    if table.empty or "estimator" not in table:
        return []
    from .systems import FIGURES, system_of

    ok = table[table["error"].isna() & table["estimator"].notna()]
    system = system_of(table)
    figures = FIGURES[system] + (("rms_nodes", "usable_rms_nodes") if system == "nav" else ())
    result = []
    for (case, estimator), group in ok.groupby(["case", "estimator"]):
        entry: dict[str, Any] = {"case": case, "estimator": estimator, "runs": int(len(group))}
        for figure in figures:
            values = group[figure].dropna().astype(float) if figure in group else []
            entry[figure] = None if not len(values) else {"median": float(values.median()), "p90": float(values.quantile(0.9))}
        result.append(entry)
    return result
