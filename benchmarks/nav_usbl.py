"""LOST and the terrain filters with a ship's USBL: `make bench-nav-usbl` (python benchmarks/nav_usbl.py).

The shipped scenario ``usbl_nav`` (or ``--scenario``) simulated once per seed, then navigated four ways on the
same records:

- ``none``: no USBL at all (no slant range, no fix);
- ``straight``: the slant range of a constant sound speed, the profile's speed at the transducer times the
  travel time (the paper's Table 1 range S1: what a range without ray tracing gives);
- ``ray``: the slant range ray-traced from the travel time through the cast (``navigate(profile=...)``);
- ``fix``: the ray-traced range and the USBL fixes with their covariance.

For each: LOST, PMF and PF RMS / p95 / max error after each one's convergence (``lost.host.report``: within
20 m for 60 s) and the RMS over the whole run after its first minute; the filters' NEES in band (two-sided 95 %)
over their terrain updates after convergence (the summary's ``nees_in_band``) and over every record after the
first minute (off the map the fixes alone carry them), and false fixes; and the horizontal-range error of the
ranges themselves against the truth. Prints markdown tables and writes build/bench/nav_usbl.json.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from lost.host.nav import NavParameters, navigate
from lost.host.records import USBL_FIELDS
from lost.host.report import NEES_BAND, horizontal_error, summarize, track_nees
from lost.host.scenario import builtin_scenario_path, load_scenario, simulate, usbl_profile
from lost.host.usbl.rays import slant_range_from_travel_time

VARIANTS = ("none", "straight", "ray", "fix")
#: Records before this are the start's transient (the lay-back start is some 200 m off): left out of the whole-run figures.
SETTLE_S = 60.0
METHODS = ("lost", "pmf", "pf")


def variant_records(records, profile, reference_depth_m: float, variant: str):
    """The same tow with only what the variant's navigation may see."""
    travel = records.usbl_travel_time_s
    no_usbl = {name: None for name in USBL_FIELDS}
    if variant == "none":
        return replace(records, slant_range_m=np.full(len(records), np.nan), **no_usbl)
    if variant == "straight":
        surface = float(profile.speed_at(reference_depth_m))
        return replace(records, slant_range_m=surface * travel, **no_usbl)
    if variant == "ray":
        return replace(records, slant_range_m=np.full(len(records), np.nan), usbl_x_m=None, usbl_y_m=None, usbl_sxx=None,
                       usbl_syy=None, usbl_sxy=None)
    return replace(records, slant_range_m=np.full(len(records), np.nan))


def range_errors(records, profile, reference_depth_m: float) -> dict:
    """Horizontal range to the vehicle from each range source, minus the true one (metres): RMS and mean."""
    pinged = np.flatnonzero(np.isfinite(records.usbl_travel_time_s) & np.isfinite(records.vehicle_depth_m))
    true = np.hypot(records.truth_x_m - records.ship_x_m, records.truth_y_m - records.ship_y_m)[pinged]
    vertical = records.vehicle_depth_m[pinged] - reference_depth_m
    straight = float(profile.speed_at(reference_depth_m)) * records.usbl_travel_time_s[pinged]
    straight_h = np.sqrt(np.maximum(straight**2 - vertical**2, 0.0))
    begin = time.perf_counter()
    ray_h = np.array([_ray(profile, t, reference_depth_m, d) for t, d in zip(records.usbl_travel_time_s[pinged], records.vehicle_depth_m[pinged])])
    ray_ms = (time.perf_counter() - begin) * 1e3 / max(len(pinged), 1)
    out = {"ray_trace_ms_per_ping": round(ray_ms, 3)}
    for name, horizontal in (("straight", straight_h), ("ray", ray_h)):
        error = horizontal - true
        error = error[np.isfinite(error)]  # a GPS dropout leaves no true range to compare with
        out[name] = {"mean_m": round(float(np.mean(error)), 2), "median_abs_m": round(float(np.median(np.abs(error))), 2)}
    fixed = np.isfinite(records.usbl_x_m)
    fix_error = np.hypot(records.usbl_x_m - records.truth_x_m, records.usbl_y_m - records.truth_y_m)[fixed]
    out["fix"] = {"rms_m": round(float(np.sqrt(np.mean(fix_error**2))), 2), "median_m": round(float(np.median(fix_error)), 2),
                  "fixes": int(fixed.sum()), "pings": int(np.isfinite(records.usbl_travel_time_s).sum())}
    return out


def _ray(profile, travel: float, top: float, depth: float) -> float:
    try:
        return slant_range_from_travel_time(profile, travel, top, depth)[1]
    except ValueError:
        return float("nan")


def run(name: str, seed: int | None) -> dict:
    scenario = load_scenario(builtin_scenario_path(name))
    if seed is not None:
        scenario = replace(scenario, seed=seed)
    grid, records = simulate(scenario)
    profile = usbl_profile(scenario)
    params = NavParameters(**scenario.navigation)
    out = {"scenario": name, "seed": scenario.seed, "ranges": range_errors(records, profile, params.reference_depth_m), "variants": {}}
    for variant in VARIANTS:
        begin = time.perf_counter()
        result = navigate(variant_records(records, profile, params.reference_depth_m, variant), grid, params,
                          profile=profile if variant in ("ray", "fix") else None)
        summary = summarize(result, name=name, parameters={}, run_time_s=time.perf_counter() - begin)
        row = {"run_time_s": round(summary["run_time_s"], 1), "counts": {k: v for k, v in result.counts.items() if "usbl" in k or "slant" in k}}
        settled = result.t_s - result.t_s[0] >= SETTLE_S
        for method in METHODS:
            stats = summary["methods"][method]
            row[method] = {k: stats.get(k) for k in ("rms_m", "p95_m", "max_m", "nees_in_band", "false_fixes", "usable_fraction")}
            error = horizontal_error(result.tracks[method].position, result.truth)[settled]
            row[method]["whole_rms_m"] = round(float(np.sqrt(np.nanmean(error**2))), 2)
            if method != "lost":
                value = track_nees(result.tracks[method], result.truth)[settled]
                value = value[np.isfinite(value)]
                row[method]["nees_in_band_all"] = round(float(np.mean((value >= NEES_BAND[0]) & (value <= NEES_BAND[1]))), 3)
            row[method]["counts"] = {k: v for k, v in result.tracks[method].counts.items() if "fix" in k or "range" in k}
        out["variants"][variant] = row
        print(f"  seed {scenario.seed} {variant}: {row['run_time_s']} s", flush=True)
    return out


def _cell(value, digits=2) -> str:
    return "-" if value is None else f"{value:.{digits}f}" if isinstance(value, float) else str(value)


def print_tables(runs: list[dict]) -> None:
    for run_ in runs:
        ranges = run_["ranges"]
        times = ", ".join(f"{variant} {row['run_time_s']} s" for variant, row in run_["variants"].items())
        print(f"\n### {run_['scenario']}, seed {run_['seed']}\n")
        print(f"Horizontal range minus the true one: straight (constant transducer-depth speed) mean {ranges['straight']['mean_m']} m, "
              f"median |error| {ranges['straight']['median_abs_m']} m; ray-traced mean {ranges['ray']['mean_m']} m, median |error| "
              f"{ranges['ray']['median_abs_m']} m. USBL fixes: {ranges['fix']['fixes']} of {ranges['fix']['pings']} replies, RMS "
              f"{ranges['fix']['rms_m']} m, median {ranges['fix']['median_m']} m. Ray trace: {ranges['ray_trace_ms_per_ping']} ms per ping "
              f"(the navigation runs: {times}).\n")
        print("RMS / p95 / max after convergence (\"never\": not within 20 m for 60 s), [RMS over the whole run after 60 s]; "
              "NEES in band over the terrain updates after convergence / over every record after 60 s.\n")
        print("| USBL use | LOST (m) | PMF (m) | PMF NEES in band | PMF false fixes | PF (m) | PF NEES in band | PF false fixes |")
        print("|---|---|---|---|---|---|---|---|")
        for variant, row in run_["variants"].items():
            cells = [variant]
            for method in METHODS:
                m = row[method]
                after = "never" if m["rms_m"] is None else " / ".join(_cell(m[k], 1) for k in ("rms_m", "p95_m", "max_m"))
                cells.append(f"{after} [{_cell(m['whole_rms_m'], 1)}]")
                if method != "lost":
                    cells += [f"{_cell(m['nees_in_band'])} / {_cell(m['nees_in_band_all'])}", _cell(m["false_fixes"])]
            print("| " + " | ".join(cells) + " |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="usbl_nav")
    parser.add_argument("--seeds", type=int, nargs="*", default=None, help="scenario seeds (default: the scenario's own)")
    parser.add_argument("--out", type=Path, default=Path("build/bench/nav_usbl.json"))
    args = parser.parse_args()
    runs = [run(args.scenario, seed) for seed in (args.seeds or [None])]
    print_tables(runs)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(runs, indent=2))
    print(f"\nwrote {args.out}")


if __name__ == "__main__":
    main()
