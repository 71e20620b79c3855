"""CPU time per record of the navigation on ``short``: the point-mass filter alone, the particle filter alone, all three.

python benchmarks/nav_speed.py [--repeats 7] [--scenario short] [--likelihood-phases K] [--out build/bench/nav_speed.json]
(make bench-nav-speed)

Each configuration navigates the same simulated records ``--repeats`` times, in turn (PMF, PF, all three, PMF,
...), so that a change of the machine's load falls on every one alike; the CPU time of the process
(``time.process_time``, not the wall clock) over the records is divided by their number. Reported: the
median and the least of the repeats, and the load average before and after (a shared machine's load moves
CPU figures too, by cache and memory contention). The goal: all three estimators together at
most 4 ms per record, one correlation per record. Nothing is asserted: the figures go to docs/nav.md with
the command, the commit and the load.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import time
from pathlib import Path

import numpy as np

from lost.host.nav import NavParameters, navigate
from lost.host.scenario import builtin_scenario_path, load_scenario, simulate

CONFIGURATIONS = {"pmf_alone": ("pmf",), "pf_alone": ("pf",), "all_three": ("lost", "pmf", "pf")}
GOAL_MS = 4.0


def measure(scenario_name: str, repeats: int, phases: int | None = None) -> dict:
    scenario = load_scenario(builtin_scenario_path(scenario_name))
    grid, records = simulate(scenario)
    params = NavParameters(**scenario.navigation, **({} if phases is None else {"likelihood_phases": phases}))
    navigate(records, grid, params, estimators=CONFIGURATIONS["all_three"])  # warm: imports, caches, first allocations
    samples: dict[str, list[float]] = {name: [] for name in CONFIGURATIONS}
    for _ in range(repeats):
        for name, estimators in CONFIGURATIONS.items():
            begin = time.process_time()
            navigate(records, grid, params, estimators=estimators)
            samples[name].append(1e3 * (time.process_time() - begin) / len(records))
    return {name: {"median_ms": float(np.median(v)), "least_ms": float(min(v)), "samples_ms": v} for name, v in samples.items()} | {
        "records": len(records)}


def _commit() -> str:
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--scenario", default="short")
    parser.add_argument("--likelihood-phases", type=int, default=None, help="the likelihood's phases (default: the scenario's)")
    parser.add_argument("--out", type=Path, default=Path("build/bench/nav_speed.json"))
    args = parser.parse_args()
    if args.repeats < 1:
        parser.error("--repeats must be at least 1")
    load_before = os.getloadavg()
    figures = measure(args.scenario, args.repeats, args.likelihood_phases)
    load_after = os.getloadavg()
    report = {"scenario": args.scenario, "repeats": args.repeats, "likelihood_phases": args.likelihood_phases, "commit": _commit(), "cpu_count": os.cpu_count(),
              "load_before": load_before, "load_after": load_after, "goal_all_three_ms": GOAL_MS, **figures}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=2))
    phases = "" if args.likelihood_phases is None else f", likelihood_phases {args.likelihood_phases}"
    print(f"{args.scenario}{phases}, {figures['records']} records, {args.repeats} repeats, commit {report['commit']}, "
          f"load {load_before[0]:.1f} before / {load_after[0]:.1f} after on {os.cpu_count()} cores")
    print("| estimators | CPU ms per record, median | least |")
    print("|---|---|---|")
    for name in CONFIGURATIONS:
        print(f"| {name.replace('_', ' ')} | {figures[name]['median_ms']:.2f} | {figures[name]['least_ms']:.2f} |")
    met = figures["all_three"]["median_ms"] <= GOAL_MS
    print(f"all three <= {GOAL_MS:g} ms per record: {'met' if met else 'not met'} (median)")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
