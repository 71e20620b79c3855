"""The navigation over seeds: every estimator on map = floor and on realistic maps, medians and 90th percentiles.

python benchmarks/nav_campaign.py --seeds 10 [--cases ...] [--out build/bench/nav_campaign.json]

A case is a shipped scenario, optionally with its map made as a survey makes one: block means 3 times
coarser than the floor, 0.7 m survey noise per node, a 2.5 m datum offset (``[map]`` of
:mod:`lost.host.scenario`), and optionally a shortened tow or a smooth shelf. Each seed changes the floor,
the map's noise and every sensor (the scenario's seed; terrain and map seeds follow it). Per estimator and
case: the RMS after convergence (metres and map nodes), NEES in band, false fixes (usable records beyond
3 sigma), the usable share, the median time per update, each as median and 90th percentile over the seeds.
Also the time of one update of all three estimators together against the point-mass filter alone, CPU
time per record on ``short``. Nothing here is asserted: the figures go to docs/nav.md with the command
and commit.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from lost.host.nav import NavParameters, navigate
from lost.host.report import summarize
from lost.host.scenario import builtin_scenario_path, load_scenario, simulate

ESTIMATORS = ("lost", "pmf", "pf")
REALISTIC_MAP = {"node_factor": 3, "noise_m": 0.7, "offset_m": 2.5}

#: name: (shipped scenario, realistic map?, duration_s or None, terrain changes)
CASES = {
    "short": ("short", False, None, {}),
    "demo_900s": ("demo", False, 900.0, {}),
    "short_survey_map": ("short", True, None, {}),
    "demo_survey_map_shelf": ("demo", True, 1200.0, {"smooth_fraction": 0.75}),
    "coarse_map_900s": ("coarse_map", False, 900.0, {}),
}


def case_scenario(case: str, seed_index: int):
    base, realistic, duration, terrain = CASES[case]
    scenario = load_scenario(builtin_scenario_path(base))
    seed = scenario.seed + seed_index
    changes: dict = {"seed": seed, "terrain": replace(scenario.terrain, seed=None, **terrain)}
    if realistic:
        changes["map"] = replace(scenario.map, node_m=REALISTIC_MAP["node_factor"] * scenario.terrain.node_m, noise_m=REALISTIC_MAP["noise_m"],
                                 offset_m=REALISTIC_MAP["offset_m"], seed=None)
    else:
        changes["map"] = replace(scenario.map, seed=None)
    if duration is not None:
        changes["duration_s"] = duration
    return replace(scenario, **changes)


def one_run(case: str, seed_index: int) -> dict:
    scenario = case_scenario(case, seed_index)
    grid, records = simulate(scenario)
    params = NavParameters(**scenario.navigation)
    begin = time.process_time()
    result = navigate(records, grid, params, estimators=ESTIMATORS)
    cpu_s = time.process_time() - begin
    summary = summarize(result, name=case, parameters={}, run_time_s=cpu_s)
    row = {"case": case, "seed": scenario.seed, "node_m": grid.node_m, "records": len(records), "cpu_ms_per_record": 1e3 * cpu_s / len(records)}
    for name in ESTIMATORS:
        m = summary["methods"].get(name, {})
        row[name] = {k: m.get(k) for k in ("rms_m", "p95_m", "nees_in_band", "false_fixes", "usable_fraction", "ms_per_update")}
        row[name]["rms_nodes"] = None if m.get("rms_m") is None else m["rms_m"] / grid.node_m
    return row


def distribution(values: list) -> dict:
    finite = [float(v) for v in values if v is not None and np.isfinite(v)]
    if not finite:
        return {"median": None, "p90": None, "n": 0}
    return {"median": float(np.median(finite)), "p90": float(np.percentile(finite, 90)), "n": len(finite)}


def table(rows: list[dict]) -> list[dict]:
    out = []
    for case in dict.fromkeys(r["case"] for r in rows):
        mine = [r for r in rows if r["case"] == case]
        for name in ESTIMATORS:
            entry = {"case": case, "estimator": name, "seeds": len(mine), "node_m": mine[0]["node_m"]}
            for key in ("rms_m", "rms_nodes", "nees_in_band", "false_fixes", "usable_fraction", "ms_per_update"):
                entry[key] = distribution([r[name][key] for r in mine])
            entry["false_fixes_total"] = int(sum(r[name]["false_fixes"] or 0 for r in mine))
            out.append(entry)
    return out


def update_speed(repeats: int = 3) -> dict:
    """CPU ms per record on ``short``: all three estimators together, and the point-mass filter alone (best of ``repeats``)."""
    scenario = load_scenario(builtin_scenario_path("short"))
    grid, records = simulate(scenario)
    params = NavParameters(**scenario.navigation)
    figures = {}
    for label, names in (("all_three", ESTIMATORS), ("pmf_alone", ("pmf",))):
        best = float("inf")
        for _ in range(repeats):
            begin = time.process_time()
            navigate(records, grid, params, estimators=names)
            best = min(best, 1e3 * (time.process_time() - begin) / len(records))
        figures[label] = best
    return figures


def _fmt(d: dict, spec: str = "{:.2f}") -> str:
    if d["median"] is None:
        return "-"
    return f"{spec.format(d['median'])} / {spec.format(d['p90'])}"


def markdown(summary: list[dict]) -> str:
    lines = ["| case | estimator | RMS m (median / p90) | RMS nodes | NEES in band | false fixes (median / p90; total) | usable | ms/update |",
             "|---|---|---|---|---|---|---|---|"]
    for e in summary:
        lines.append(f"| {e['case']} | {e['estimator']} | {_fmt(e['rms_m'])} | {_fmt(e['rms_nodes'], '{:.3f}')} | {_fmt(e['nees_in_band'])} | "
                     f"{_fmt(e['false_fixes'], '{:.0f}')}; {e['false_fixes_total']} | {_fmt(e['usable_fraction'])} | {_fmt(e['ms_per_update'])} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--cases", nargs="*", default=list(CASES))
    parser.add_argument("--no-speed", action="store_true")
    parser.add_argument("--out", type=Path, default=Path("build/bench/nav_campaign.json"))
    args = parser.parse_args()
    rows = []
    for case in args.cases:
        for k in range(args.seeds):
            rows.append(one_run(case, k))
            print(f"  {case} seed {rows[-1]['seed']}: " + ", ".join(f"{n} {rows[-1][n]['rms_m']}" for n in ESTIMATORS), flush=True)
    summary = table(rows)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    speed = None if args.no_speed else update_speed()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"commit": commit, "seeds": args.seeds, "runs": rows, "summary": summary, "speed": speed}, indent=1))
    print(markdown(summary))
    if speed:
        print(f"\nCPU ms per record on short: all three {speed['all_three']:.2f}, PMF alone {speed['pmf_alone']:.2f}")


if __name__ == "__main__":
    main()
