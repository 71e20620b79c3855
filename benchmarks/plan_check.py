"""The planner against Monte Carlo: the predicted error along a tow's track against the point-mass filter's RMS over seeds.

python benchmarks/plan_check.py [--seeds 10] [--segment-s 120] [--scenarios short shelf_canyon ...] [--workers 2]

For each scenario the floor and the map are fixed (the scenario's own seed draws them) and the sensors change with
the seed: the question is how well the navigation does on *this* map along *this* route. The planner sees only the
map (`lost plan`'s model: the bound of one correlation with the map's own error per node, the dead reckoning's
growth between fixes, the filters' floor) and the true track. The track is cut into segments of ``segment_s``
after the filter's convergence; per segment, the Monte Carlo RMS (all seeds, all records of the segment) against
the RMS of the predicted 1-sigma errors. Prints per scenario the share of segments within a factor 1.5 (the goal:
>= 80 %), the median ratio, and the predicted and measured errors on the most and least informative segments; writes
build/bench/plan_check.json.
"""

from __future__ import annotations

import argparse
import json
import subprocess
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from lost.host.campaign import scenario_with
from lost.host.nav import NavParameters, navigate
from lost.host.plan import RouteModel, SonarModel, accuracy_grid, map_sigma, predict_along
from lost.host.report import ConvergenceRule, convergence_index, horizontal_error
from lost.host.scenario import builtin_scenario_path, load_scenario, simulate


def _scenario(name: str, seed: int):
    base = load_scenario(builtin_scenario_path(name))
    fixed = {"terrain.seed": base.terrain.seed if base.terrain.seed is not None else base.seed,
             "map.seed": base.map.seed if base.map.seed is not None else base.seed}
    return scenario_with(base, {**fixed, "seed": 1000 + seed})


def one_seed(name: str, seed: int) -> dict:
    scenario = _scenario(name, seed)
    grid, records = simulate(scenario)
    result = navigate(records, grid, NavParameters(**scenario.navigation), estimators=("pmf",))
    error = horizontal_error(result.tracks["pmf"].position, result.truth)
    start = convergence_index(result.t_s, error, ConvergenceRule())
    return {"t_s": result.t_s.tolist(), "error": error.tolist(), "start": start,
            "truth": result.truth.tolist(), "grid": grid if seed == 0 else None, "scenario": scenario if seed == 0 else None}


def check(name: str, seeds: int, segment_s: float, workers: int) -> dict:
    with ProcessPoolExecutor(workers) as pool:
        runs = list(pool.map(one_seed, [name] * seeds, range(seeds)))
    grid, scenario = runs[0]["grid"], runs[0]["scenario"]
    params = NavParameters(**scenario.navigation)
    spec = scenario.sensors["sonar"]
    sonar = SonarModel(shape=tuple(spec.shape), noise_m=max(spec.noise, 1e-3))
    accuracy = accuracy_grid(grid, sonar, map_sigma(grid, params.survey_sigma_m))
    t = np.asarray(runs[0]["t_s"])
    truth = np.asarray(runs[0]["truth"])
    model = RouteModel.from_navigation(params, grid.node_m, speed_mps=scenario.ship.speed_kn * 1852 / 3600, interval_s=spec.interval_s,
                                       initial_sigma_m=params.initial_sigma_m)
    sonar_times = t[::max(int(round(spec.interval_s / max(np.median(np.diff(t)), 1e-9))), 1)]
    sonar_xy = truth[np.searchsorted(t, sonar_times)]
    predicted = np.interp(t, sonar_times, predict_along(accuracy, sonar_times, sonar_xy, model)["predicted_m"])
    starts = [r["start"] for r in runs if r["start"] is not None]
    begin = int(np.median(starts)) if starts else len(t)
    errors = np.array([r["error"] for r in runs])
    segments = []
    for lo in np.arange(t[begin] if begin < len(t) else t[-1], t[-1], segment_s):
        inside = (t >= lo) & (t < lo + segment_s)
        measured = errors[:, inside]
        measured = measured[np.isfinite(measured)]
        if inside.sum() < segment_s / 4 or measured.size == 0:
            continue
        mc = float(np.sqrt(np.mean(measured**2)))
        pred = float(np.sqrt(np.mean(predicted[inside] ** 2)))
        segments.append({"t0_s": float(lo), "mc_rms_m": mc, "predicted_m": pred, "ratio": pred / mc})
    ratios = np.array([s["ratio"] for s in segments])
    within = float(np.mean((ratios >= 1 / 1.5) & (ratios <= 1.5))) if ratios.size else None
    by_prediction = sorted(segments, key=lambda s: s["predicted_m"])
    return {"scenario": name, "seeds": seeds, "converged_seeds": len(starts), "segments": len(segments), "within_1_5": within,
            "median_ratio": float(np.median(ratios)) if ratios.size else None,
            "most_informative": by_prediction[0] if segments else None, "least_informative": by_prediction[-1] if segments else None,
            "bound_median_m": float(np.median(accuracy.depth_m[np.isfinite(accuracy.depth_m)])), "segment_list": segments}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--segment-s", type=float, default=120.0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--scenarios", nargs="+", default=["short", "coarse_map", "shelf_canyon", "seamount_ridges"])
    parser.add_argument("--out", type=Path, default=Path("build/bench/plan_check.json"))
    args = parser.parse_args()
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    results = [check(name, args.seeds, args.segment_s, args.workers) for name in args.scenarios]
    print(f"planner against Monte Carlo (point-mass filter, {args.seeds} seeds a scenario, {args.segment_s:g} s segments, commit {commit})")
    print("| scenario | segments | within 1.5x | median predicted/MC | most informative: predicted / MC m | least: predicted / MC m |")
    print("|---|---|---|---|---|---|")
    for r in results:
        if not r["segments"]:
            print(f"| {r['scenario']} | 0 | - | - | - | - |")
            continue
        hi, lo = r["most_informative"], r["least_informative"]
        print(f"| {r['scenario']} | {r['segments']} | {r['within_1_5']:.0%} | {r['median_ratio']:.2f} | "
              f"{hi['predicted_m']:.2f} / {hi['mc_rms_m']:.2f} | {lo['predicted_m']:.2f} / {lo['mc_rms_m']:.2f} |")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"commit": commit, "results": results}, indent=1) + "\n")


if __name__ == "__main__":
    main()
