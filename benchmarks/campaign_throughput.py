"""The campaign engine's throughput against the same runs one after another in one process.

python benchmarks/campaign_throughput.py [--runs 40] [--workers 2] [--scenario short]: N ten-minute tows (the
scenario over seeds 0..N-1, the point-mass and particle filters) run serially with ``run_task``, then as a campaign on
a local Dask cluster; prints runs per minute of each and their ratio (the goal: >= 1.8 on this 2-core machine). Run
it on a quiet machine: another job on either core moves the ratio.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from lost.host.campaign import CampaignSpec, run_campaign, run_task


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
        summary = run_campaign(spec, Path(folder) / "out", workers=args.workers)
        parallel = time.perf_counter() - start
    rate = lambda seconds: 60.0 * len(tasks) / seconds  # noqa: E731
    print(f"{len(tasks)} runs of {args.scenario}: serial {serial:.1f} s ({rate(serial):.1f}/min, {failed} failed); "
          f"campaign on {args.workers} workers {parallel:.1f} s ({rate(parallel):.1f}/min, {summary['failed_runs']} failed, cluster start included); "
          f"ratio {serial / parallel:.2f}")


if __name__ == "__main__":
    main()
