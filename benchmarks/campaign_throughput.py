"""The campaign engine's throughput against the same runs one after another in one process.

python benchmarks/campaign_throughput.py [--runs 40] [--workers 2] [--scenario short]: N ten-minute tows (the
scenario over seeds 0..N-1, the point-mass and particle filters) run serially with ``run_task``, then as a campaign on
a local Dask cluster; prints runs per minute of each and their ratio (the goal: >= 1.8 on this 2-core machine). Run
it on a quiet machine: another job on either core moves the ratio. Also prints what the workers' other threads (Dask's
event loop and monitors) took beside the runs: their process's CPU time over the run's own thread's, which other jobs
on the machine do not move.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import pandas as pd

from lost.host.campaign import CampaignSpec, run_campaign, run_task
from lost.host.campaign.spec import RunTask


def timed_task(task: RunTask) -> list[dict]:
    """``run_task`` with the CPU time of its own thread and of its whole process (defined here: sent to the workers whole)."""
    thread, process = time.thread_time(), time.process_time()
    rows = run_task(task)
    thread, process = time.thread_time() - thread, time.process_time() - process
    return [{**row, "thread_cpu_s": thread, "process_cpu_s": process} for row in rows]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=40)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--scenario", default="short")
    args = parser.parse_args()
    spec = CampaignSpec(name="throughput", scenarios=(args.scenario,), seeds=args.runs, estimators=("pmf", "pf"))
    tasks = spec.tasks()
    start = time.perf_counter()
    failed = sum(any(row["error"] for row in run_task(task)) for task in tasks)
    serial = time.perf_counter() - start
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        summary = run_campaign(spec, Path(folder) / "out", workers=args.workers, task=timed_task)
        parallel = time.perf_counter() - start
        runs = pd.read_parquet(Path(folder) / "out" / "results.parquet").drop_duplicates("run_id")
    rate = lambda seconds: 60.0 * len(tasks) / seconds  # noqa: E731
    print(f"{len(tasks)} runs of {args.scenario}: serial {serial:.1f} s ({rate(serial):.1f}/min, {failed} failed); "
          f"campaign on {args.workers} workers {parallel:.1f} s ({rate(parallel):.1f}/min, {summary['failed_runs']} failed, cluster start included); "
          f"ratio {serial / parallel:.2f}")
    print(f"in the workers, beside the runs' own threads: {runs.process_cpu_s.sum() / runs.thread_cpu_s.sum() - 1:.1%} more CPU time "
          f"(the runs' thread: {runs.thread_cpu_s.median():.2f} s median)")


if __name__ == "__main__":
    main()
