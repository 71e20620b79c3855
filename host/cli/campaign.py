"""``lost campaign SPEC.toml --out DIR [--scheduler ADDRESS] [--workers N]``: many tows on Dask, one row per run and estimator.

Writes ``DIR/rows/RUN_ID.json`` as each run finishes (so the campaign resumes where it stopped), then
``results.parquet``, ``summary.json`` (medians and 90th percentiles per scenario and estimator) and
``distributions.png``. The file's layout: :mod:`lost.host.campaign.spec`.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ..errors import UsageError
from .common import progress_bar

__all__ = ["register", "run_campaign_command"]


def run_campaign_command(args: argparse.Namespace) -> int:
    """The handler of ``lost campaign``."""
    from ..campaign import load_campaign, run_campaign

    if args.workers < 1:
        raise UsageError(f"--workers must be at least 1, got {args.workers}")
    spec = load_campaign(args.spec)
    tasks = spec.tasks()
    cases = len(spec.all_cases())
    print(f"{spec.name} ({spec.system}): {len(tasks)} runs ({cases} cases x {len(spec.seed_list())} seeds x "
          f"{len(tasks) // max(cases * len(spec.seed_list()), 1)} parameter combinations), estimators {', '.join(spec.estimators)}")
    out = args.out = args.out or Path("runs") / "campaign" / spec.name
    progress = progress_bar(len(tasks), "runs", minimum=0)  # a campaign is long even with few runs
    summary = run_campaign(spec, out, scheduler=args.scheduler, workers=args.workers, progress=progress)
    print(f"ran {summary['ran_now']} now; {summary['finished']} of {summary['runs']} runs finished, {summary['failed_runs']} failed")
    shown = {"nav": ("rms_nodes", "nees_in_band"), "track": ("coverage", "gospa_mean"), "usbl": ("rms_m", "nees_in_band")}[spec.system]
    for entry in summary["distributions"]:
        figures = ", ".join(f"{name} " + ("-" if entry.get(name) is None else f"median {entry[name]['median']:.3g} / p90 {entry[name]['p90']:.3g}")
                            for name in shown)
        print(f"  {entry['case']:>24s} {entry['estimator']:>6s}: {entry['runs']} runs, {figures}")
    for error in summary["errors"]:
        print(f"  failed: {error}")
    print(f"wrote {out}/results.parquet, summary.json" + (", distributions.png" if (out / "distributions.png").is_file() else ""))
    return 0


def register(commands, parents: list[argparse.ArgumentParser]) -> None:
    """Add ``lost campaign``."""
    sub = commands.add_parser("campaign", parents=parents, help="many simulated tows over scenarios, seeds and parameters, on Dask")
    sub.add_argument("spec", type=Path, help="campaign TOML file (scenarios, seeds, estimators, [parameters])")
    sub.add_argument("--out", type=Path, default=None, help="campaign folder (default runs/campaign/NAME); started again, it runs only what is missing")
    sub.add_argument("--scheduler", default=None, metavar="ADDRESS", help="a running Dask scheduler (tcp://host:8786); default a local cluster")
    sub.add_argument("--workers", type=int, default=2, help="worker processes of the local cluster (default 2)")
    sub.set_defaults(handler=run_campaign_command)
