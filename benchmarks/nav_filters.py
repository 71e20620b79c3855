"""The Bayesian navigation's goals, measured: `make bench-nav-goals` (python benchmarks/nav_filters.py).

For every shipped scenario, the three estimators on the same records: error after each one's
convergence, NEES in band, false fixes, usable share, time per update. Then the issue's specific
goals: convergence from a 500 m start error, recovery from the injected 500 m jump, the time per
update over a 600 m x 600 m area at 10 m nodes (PMF) and with 10,000 particles (PF), the two-hour tow,
and eq. 5.2 by Monte Carlo. Prints markdown tables and writes build/bench/nav_filters.json.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from lost.host.nav import NavParameters, navigate
from lost.host.nav.estimator import Motion, Observation
from lost.host.nav.likelihood import TerrainLikelihood, map_error_estimate
from lost.host.nav.mapprep import PreparedMap
from lost.host.nav.pf import ParticleFilter
from lost.host.nav.pmf import PointMassFilter
from lost.host.nav.theory import ml_offset_variance, nygren_ml_variance
from lost.host.report import ConvergenceRule, convergence_index, horizontal_error, summarize
from lost.host.scenario import builtin_scenario_path, builtin_scenarios, load_scenario, simulate

FILTERS = ("pmf", "pf")


def run(name: str, **overrides) -> tuple[dict, object, object]:
    scenario = load_scenario(builtin_scenario_path(name))
    grid, records = simulate(scenario)
    params = NavParameters(**{**scenario.navigation, **overrides})
    start = time.perf_counter()
    result = navigate(records, grid, params)
    summary = summarize(result, name=name, parameters={}, run_time_s=time.perf_counter() - start)
    return summary, result, grid


def same_span_rms(result) -> dict:
    """RMS of each estimator over the same records: from the later of LOST's and the PMF's convergence to the end.

    Each estimator's own-convergence RMS starts where it converged; a filter that starts within the
    convergence radius has "converged" at once and carries its acquisition in its figure, while LOST's
    starts minutes later. Over the same records the two are compared like for like.
    """
    rule = ConvergenceRule()
    errors = {"lost": horizontal_error(result.estimate, result.truth),
              **{f: horizontal_error(result.tracks[f].position, result.truth) for f in FILTERS}}
    starts = [convergence_index(result.t_s, errors[m], rule) for m in ("lost", "pmf")]
    if any(k is None for k in starts):
        return {}
    start = max(starts)
    return {m: round(float(np.sqrt(np.nanmean(e[start:] ** 2))), 3) for m, e in errors.items()}


def scenario_table(names: list[str]) -> list[dict]:
    rows = []
    for name in names:
        summary, result, grid = run(name)
        methods = summary["methods"]
        row = {"scenario": name, "node_m": grid.node_m}
        for method in ("lost", *FILTERS):
            m = methods.get(method, {})
            row[method] = {k: m.get(k) for k in ("rms_m", "p95_m", "max_m", "nees_in_band", "false_fixes", "usable_fraction",
                                                 "ms_per_update", "convergence_time_s")}
        row["lost"]["convergence_time_s"] = summary["convergence"].get("time_s")
        lost = row["lost"]["rms_m"]
        row["pmf_over_lost"] = None if not (lost and row["pmf"]["rms_m"]) else round(row["pmf"]["rms_m"] / lost, 3)
        row["pmf_rms_nodes"] = None if row["pmf"]["rms_m"] is None else round(row["pmf"]["rms_m"] / grid.node_m, 3)
        row["same_span_rms_m"] = same = same_span_rms(result)
        row["pmf_over_lost_same_span"] = round(same["pmf"] / same["lost"], 3) if same else None
        rows.append(row)
        print(f"  {name}: done", flush=True)
    return rows


#: Terrain (and noise) seeds of ``offset`` the recovery is measured on: the shipped one and five more.
#: Which way a re-initialized search goes turns on small differences, so one run says little.
RECOVERY_TERRAIN_SEEDS = (2003, 11, 12, 13, 14, 15)
#: The particle filter's own seeds on each.
RECOVERY_PF_SEEDS = (0, 1, 2)


def recovery_time(t_s: np.ndarray, error_m: np.ndarray, at_s: float) -> float | None:
    """Seconds from ``at_s`` until the error stays under 20 m for 30 s; None if it never does."""
    for k in np.flatnonzero(t_s >= at_s):
        window = (t_s >= t_s[k]) & (t_s <= t_s[k] + 30.0)
        if np.all(error_m[window] < 20.0):
            return float(t_s[k] - at_s)
    return None


def recovery(name: str = "offset") -> dict:
    """Recovery from the injected jump on each terrain seed (the PF on each of its seeds): times, and how many recovered."""
    base = load_scenario(builtin_scenario_path(name))
    times: dict[str, list] = {"lost": [], "pmf": [], "pf": []}
    for terrain_seed in RECOVERY_TERRAIN_SEEDS:
        scenario = replace(base, seed=terrain_seed)
        grid, records = simulate(scenario)
        for pf_seed in RECOVERY_PF_SEEDS:
            params = NavParameters(**{**scenario.navigation, "seed": pf_seed})
            first = pf_seed == RECOVERY_PF_SEEDS[0]
            result = navigate(records, grid, params, estimators=("lost", *FILTERS) if first else ("pf",))
            tracks = {"pf": result.tracks["pf"].position}
            if first:
                tracks.update(lost=result.estimate, pmf=result.tracks["pmf"].position)
            for method, track in tracks.items():
                times[method].append(recovery_time(result.t_s, horizontal_error(track, result.truth), scenario.fault.at_s))
    out = {"terrain_seeds": list(RECOVERY_TERRAIN_SEEDS), "pf_seeds": list(RECOVERY_PF_SEEDS)}
    for method, values in times.items():
        done = [v for v in values if v is not None]
        out[method] = {"seconds": values, "recovered": f"{len(done)} of {len(values)}",
                       "within_120_s": sum(v <= 120.0 for v in done), "median_s": float(np.median(done)) if done else None,
                       "worst_s": max(done) if len(done) == len(values) else None}
    return out


def point_form(name: str = "demo") -> dict:
    """The single-depth form (one ocean depth a record, the depth-bias state) on a patch scenario's records."""
    summary, _, _ = run(name, matching="point")
    return {m: {k: summary["methods"][m].get(k) for k in ("rms_m", "false_fixes", "nees_in_band", "convergence_time_s")}
            for m in ("lost", *FILTERS)}


def convergence_from(initial_error_m: float = 500.0, name: str = "demo") -> dict:
    """Start about ``initial_error_m`` off (the lay-back error plus an offset) and time each estimator's convergence."""
    scenario = load_scenario(builtin_scenario_path(name))
    grid, records = simulate(scenario)
    params = NavParameters(**scenario.navigation)
    probe = navigate(records, grid, params, estimators=("lost",))
    first = np.flatnonzero(np.isfinite(probe.estimate[:, 0]))[0]
    layback_error = probe.truth[first] - probe.estimate[first]
    # Push the start further along the lay-back's own error until it is initial_error_m off.
    direction = -layback_error / np.linalg.norm(layback_error)
    offset = direction * (initial_error_m - np.linalg.norm(layback_error))
    result = navigate(records, grid, replace(params, initial_offset_m=tuple(offset)))
    summary = summarize(result, name=name, parameters={})
    return {"initial_error_m": summary["convergence"]["initial_error_m"], "lost_s": summary["convergence"]["time_s"],
            **{f"{f}_s": summary["methods"][f]["convergence_time_s"] for f in FILTERS}}


def update_speed(rounds: int = 300) -> dict:
    """Median ms per predict + update: the PMF held at 600 m x 600 m over 10 m nodes, the PF at 10,000 particles."""
    scenario = load_scenario(builtin_scenario_path("demo"))
    grid, records = simulate(scenario)
    params = NavParameters(**scenario.navigation)
    prepared = PreparedMap.for_navigation(grid, params)
    sigma = float(np.hypot(params.depth_noise_m, map_error_estimate(grid.depth_m)))
    likelihood = TerrainLikelihood(prepared, sigma_m=sigma)
    truth = np.column_stack([records.truth_x_m, records.truth_y_m])
    out = {}
    for name in FILTERS:
        f = PointMassFilter(likelihood, params, grid=grid) if name == "pmf" else ParticleFilter(likelihood, params, grid=grid)
        observation = Observation(0.0, None, None, np.nan, 0.0, np.nan)
        f.start(0.0, truth[100], observation)
        if name == "pmf":
            f._lay(truth[100], 300.0, None)  # 600 m square: 96 x 96 cells of 6.25 m
            f._follow = lambda: None  # held there, whatever the density does
        times = []
        velocity = np.zeros(2)
        for n in range(101, 101 + rounds):
            patch = records.sonar[n]
            observation = Observation(float(records.t_s[n]), None, patch, np.nan, 0.0, np.nan)
            measured = np.array([records.vel_x_mps[n], records.vel_y_mps[n]])
            velocity = measured if np.isfinite(measured).all() else velocity  # a dropped reading held, as the loop does
            begin = time.perf_counter()
            f.predict(Motion(1.0, velocity))
            f.update(observation)
            times.append((time.perf_counter() - begin) * 1e3)
        out[name] = round(float(np.median(times)), 3)
    return out


def two_hour_times() -> dict:
    scenario = load_scenario(builtin_scenario_path("two_hour"))
    grid, records = simulate(scenario)
    params = NavParameters(**scenario.navigation)
    out = {}
    for name in ("lost", *FILTERS):
        begin = time.perf_counter()
        navigate(records, grid, params, estimators=(name,))
        out[name] = round(time.perf_counter() - begin, 2)
    return out


def eq_5_2() -> list[dict]:
    rows = []
    for a in (0.0, 0.3, 0.5):
        for n in (25, 50, 100):
            mc = ml_offset_variance(a, n, 0.1, trials=2000, seed=n)
            formula = nygren_ml_variance(a, n, 0.1)
            rows.append({"a": a, "beams": n, "monte_carlo": mc, "eq_5_2": formula, "ratio": round(mc / formula, 3)})
    return rows


def _cell(value, fmt="{:.2f}") -> str:
    return "-" if value is None else fmt.format(value)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", nargs="*", default=builtin_scenarios())
    parser.add_argument("--out", type=Path, default=Path("build/bench/nav_filters.json"))
    args = parser.parse_args()
    results = {"scenarios": scenario_table(args.scenarios), "recovery_s": recovery(), "convergence_from_500m": convergence_from(),
               "ms_per_update_fixed_area": update_speed(), "two_hour_s": two_hour_times(), "eq_5_2": eq_5_2(),
               "point_form_demo": point_form()}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=2))
    print("\n| scenario | LOST rms / p95 m | PMF rms / p95 m | PF rms / p95 m | PMF / LOST | same span | PMF NEES in band "
          "| PF NEES in band | false fixes PMF / PF | PMF ms | PF ms |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for row in results["scenarios"]:
        lost, pmf, pf = row["lost"], row["pmf"], row["pf"]
        print(f"| {row['scenario']} | {_cell(lost['rms_m'])} / {_cell(lost['p95_m'])} | {_cell(pmf['rms_m'])} / {_cell(pmf['p95_m'])} "
              f"| {_cell(pf['rms_m'])} / {_cell(pf['p95_m'])} | {_cell(row['pmf_over_lost'])} | {_cell(row['pmf_over_lost_same_span'])} "
              f"| {_cell(pmf['nees_in_band'])} "
              f"| {_cell(pf['nees_in_band'])} | {pmf['false_fixes']} / {pf['false_fixes']} | {_cell(pmf['ms_per_update'])} "
              f"| {_cell(pf['ms_per_update'])} |")
    recovery_runs = results["recovery_s"]
    print(f"\nrecovery after the 500 m jump on offset's terrain seeds {recovery_runs['terrain_seeds']} "
          f"(PF seeds {recovery_runs['pf_seeds']} on each):")
    for method in ("lost", *FILTERS):
        r = recovery_runs[method]
        print(f"  {method}: recovered {r['recovered']}, {r['within_120_s']} within 120 s, median {_cell(r['median_s'], '{:.0f}')} s, "
              f"worst {_cell(r['worst_s'], '{:.0f}')} s; {r['seconds']}")
    print(f"convergence from a 500 m start: {results['convergence_from_500m']}")
    print(f"ms per update, fixed area: {results['ms_per_update_fixed_area']}")
    print(f"two-hour tow, s per estimator: {results['two_hour_s']}")
    print(f"single-depth form on demo: {results['point_form_demo']}")
    print("\n| a | beams | Monte Carlo | eq. 5.2 | ratio |\n|---|---|---|---|---|")
    for row in results["eq_5_2"]:
        print(f"| {row['a']} | {row['beams']} | {row['monte_carlo']:.3g} | {row['eq_5_2']:.3g} | {row['ratio']} |")
    print(f"\nwrote {args.out}")


if __name__ == "__main__":
    main()
