"""The planner against Monte Carlo: the predicted error along a tow's track against the point-mass filter's RMS over seeds.

python benchmarks/plan_check.py [--seeds 10] [--segment-s 120] [--scenarios short shelf_canyon ...] [--workers 2]
                                [--cache DIR] [--evidence-scale C] [--acquisitions-per-patch K]

For each scenario the floor and the map are fixed (the scenario's own seed draws them) and the sensors change with
the seed: the question is how well the navigation does on *this* map along *this* route. The planner sees only the
map (`lost plan`'s model: the bound of one correlation with the map's own error per node, the look-alikes, the lock
acquired, lost and regained, the dead reckoning's growth, the filters' floor), the scenario's sensors, the true track
and the start's error (the first record's of that track's seed: the lay-back model's). The whole track is
cut into segments of ``segment_s``; per segment, the Monte Carlo RMS (all seeds, all records of the segment) against
the RMS of the predicted errors. Prints per scenario the share of segments within a factor 1.5 (the goal: >= 80 %),
also of those after the seeds' median convergence, the median ratio, and steep features against smooth shelves (the
third of the segments on the map with the smallest median bound against the third with the largest: median predicted
and Monte Carlo RMS, and their shelf/steep ratios); writes build/bench/plan_check.json. ``--cache`` keeps each seed's
run (``NAME-SEED.npz``: the error, the filter's own sigma and usable flag) and reads it back the next time, so the
prediction can be scored again without the filters. ``prepare`` and ``score`` are also ``benchmarks/plan_fit.py``'s.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import subprocess
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from lost.host.campaign import scenario_with
from lost.host.cli.plan import scenario_motion, scenario_sonar
from lost.host.grid import Grid
from lost.host.nav import NavParameters, navigate
from lost.host.plan import Lookalike, RouteModel, SonarModel, accuracy_grid, held_grid, held_sigma, lookalike_grid, map_sigma, predict_along
from lost.host.report import ConvergenceRule, convergence_index, horizontal_error
from lost.host.scenario import builtin_scenario_path, load_scenario, scenario_grid, simulate


def _scenario(name: str, seed: int):
    base = load_scenario(builtin_scenario_path(name))
    fixed = {"terrain.seed": base.terrain.seed if base.terrain.seed is not None else base.seed,
             "map.seed": base.map.seed if base.map.seed is not None else base.seed}
    return scenario_with(base, {**fixed, "seed": 1000 + seed})


def one_seed(name: str, seed: int, cache: Path | None = None) -> dict:
    """One seed's point-mass run on the scenario's fixed floor and map: times, errors, convergence, truth.

    With ``cache`` the run is kept in ``cache/NAME-SEED.npz`` and read from there the next time (the prediction
    can then be re-scored without the Monte Carlo)."""
    path = None if cache is None else cache / f"{name}-{seed}.npz"
    if path is not None and path.is_file():
        data = np.load(path)
        start = int(data["start"])
        run = {"t_s": data["t_s"], "error": data["error"], "start": None if start < 0 else start, "truth": data["truth"]}
        return {**run, **{key: data[key] for key in ("sigma", "usable") if key in data}}
    scenario = _scenario(name, seed)
    grid, records = simulate(scenario)
    result = navigate(records, grid, NavParameters(**scenario.navigation), estimators=("pmf",))
    error = horizontal_error(result.tracks["pmf"].position, result.truth)
    start = convergence_index(result.t_s, error, ConvergenceRule())
    track = result.tracks["pmf"]
    run = {"t_s": np.asarray(result.t_s), "error": np.asarray(error), "start": start, "truth": np.asarray(result.truth),
           "sigma": np.sqrt(np.trace(np.asarray(track.covariance), axis1=-2, axis2=-1)), "usable": np.asarray(track.usable)}
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(path.with_suffix(".partial.npz"), **{**run, "start": -1 if start is None else start})
        path.with_suffix(".partial.npz").replace(path)
    return run


@dataclasses.dataclass
class Floor:
    """One scenario's Monte Carlo runs and what the planner sees of it: the map's bound, its look-alikes' inputs, the route model."""

    name: str
    runs: list[dict]
    grid: Grid
    sonar: SonarModel
    sigma: np.ndarray
    radius_m: float
    accuracy: Grid
    held: Grid
    model: RouteModel
    sonar_times: np.ndarray
    sonar_xy: np.ndarray

    def lookalike(self, evidence_scale: float | None = None) -> Lookalike:
        return lookalike_grid(self.grid, self.sonar, self.sigma, radius_m=self.radius_m,
                              **({} if evidence_scale is None else {"evidence_scale": evidence_scale}))


def prepare(name: str, seeds: int, workers: int, cache: Path | None = None) -> Floor:
    """The scenario's Monte Carlo (run, or read from ``cache``) and the planner's inputs on its map."""
    with ProcessPoolExecutor(workers) as pool:
        runs = list(pool.map(one_seed, [name] * seeds, range(seeds), [cache] * seeds))
    scenario = _scenario(name, 0)
    grid = scenario_grid(scenario)
    params = NavParameters(**scenario.navigation)
    spec = scenario.sensors["sonar"]
    sonar = scenario_sonar(scenario, grid.node_m)
    sigma = map_sigma(grid, params.survey_sigma_m)
    t = np.asarray(runs[0]["t_s"])
    model = RouteModel.from_navigation(params, grid.node_m, patch_nodes=float(np.sqrt(np.prod(sonar.shape))), patch_lag_m=sonar.lag_m(grid.node_m),
                                       initial_error_m=float(runs[0]["error"][0]), **scenario_motion(scenario, grid.node_m))
    sonar_times = t[::max(int(round(spec.interval_s / max(np.median(np.diff(t)), 1e-9))), 1)]
    sonar_xy = np.asarray(runs[0]["truth"])[np.searchsorted(t, sonar_times)]
    return Floor(name, runs, grid, sonar, sigma, params.lookalike_radius_m, accuracy_grid(grid, sonar, sigma),
                 held_grid(grid, sonar, sigma, held_sigma(grid, sonar, params.survey_sigma_m)), model, sonar_times, sonar_xy)


def score(floor: Floor, lookalike: Lookalike, model: RouteModel, segment_s: float = 120.0) -> dict:
    """The prediction along the true track against the Monte Carlo, per segment of ``segment_s``, and the scores."""
    runs, t = floor.runs, np.asarray(floor.runs[0]["t_s"])
    route = predict_along(floor.accuracy, floor.sonar_times, floor.sonar_xy, model, lookalike, floor.held)
    predicted = np.interp(t, floor.sonar_times, route["predicted_m"])
    unlocked = np.interp(t, floor.sonar_times, route["unlocked"])
    bound = np.interp(t, floor.sonar_times, np.where(np.isfinite(route["bound_m"]), route["bound_m"], 1e9))
    starts = [r["start"] for r in runs if r["start"] is not None]
    converged = t[int(np.median(starts))] if starts else np.inf
    errors = np.array([r["error"] for r in runs])
    segments = []
    for lo in np.arange(t[0], t[-1], segment_s):
        inside = (t >= lo) & (t < lo + segment_s)
        measured = errors[:, inside]
        if inside.sum() < segment_s / 4 or not np.isfinite(measured).any():
            continue
        mc = float(np.sqrt(np.nanmean(measured**2)))
        pred = float(np.sqrt(np.mean(predicted[inside] ** 2)))
        segments.append({"t0_s": float(lo), "mc_rms_m": mc, "predicted_m": pred, "ratio": pred / mc, "bound_m": float(np.median(bound[inside])),
                         "mc_unlocked": float(np.mean(np.nanmax(measured, axis=1) > LOST_M)), "predicted_unlocked": float(np.mean(unlocked[inside])),
                         "after_convergence": bool(lo >= converged)})
    return {"scenario": floor.name, "seeds": len(runs), "converged_seeds": len(starts), "median_convergence_s": float(converged), **_scores(segments),
            "bound_median_m": float(np.median(floor.accuracy.depth_m[np.isfinite(floor.accuracy.depth_m)])), "segment_list": segments}


def check(name: str, seeds: int, segment_s: float, workers: int, cache: Path | None = None, evidence_scale: float | None = None,
          acquisitions_per_patch: float | None = None) -> dict:
    floor = prepare(name, seeds, workers, cache)
    model = floor.model if acquisitions_per_patch is None else dataclasses.replace(floor.model, acquisitions_per_patch=acquisitions_per_patch)
    return score(floor, floor.lookalike(evidence_scale), model, segment_s)


#: A seed whose error exceeds this within a segment has not held the true position there (the "unlocked" share).
LOST_M = 30.0


def _within(segments: list[dict]) -> float | None:
    ratios = np.array([s["ratio"] for s in segments])
    return float(np.mean((ratios >= 1 / 1.5) & (ratios <= 1.5))) if ratios.size else None


def _scores(segments: list[dict]) -> dict:
    """The share within 1.5x (all segments, and after the median convergence), and steep features against smooth shelves:
    the third of the segments on the map with the smallest median bound against the third with the largest, median predicted and
    MC RMS."""
    informative = sorted((s for s in segments if s["bound_m"] < 1e8), key=lambda s: s["bound_m"])  # where the map gives a bound
    third = max(len(informative) // 3, 1)
    steep, shelf = informative[:third], informative[-third:]
    median = lambda group, key: float(np.median([s[key] for s in group])) if group else None  # noqa: E731
    return {"segments": len(segments), "within_1_5": _within(segments), "median_ratio": median(segments, "ratio"),
            "after_convergence": {"segments": sum(s["after_convergence"] for s in segments),
                                  "within_1_5": _within([s for s in segments if s["after_convergence"]])},
            "steep": {"bound_m": median(steep, "bound_m"), "predicted_m": median(steep, "predicted_m"), "mc_rms_m": median(steep, "mc_rms_m")},
            "shelf": {"bound_m": median(shelf, "bound_m"), "predicted_m": median(shelf, "predicted_m"), "mc_rms_m": median(shelf, "mc_rms_m")}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--segment-s", type=float, default=120.0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--scenarios", nargs="+", default=["short", "coarse_map", "shelf_canyon", "seamount_ridges"])
    parser.add_argument("--out", type=Path, default=Path("build/bench/plan_check.json"))
    parser.add_argument("--evidence-scale", type=float, default=None, help="the look-alikes' evidence_scale (default: lookalike_grid's)")
    parser.add_argument("--acquisitions-per-patch", type=float, default=None, help="the route model's acquisitions_per_patch (default: RouteModel's)")
    parser.add_argument("--cache", type=Path, default=None,
                        help="keep each seed's Monte Carlo run here and reuse it (re-scoring the prediction without re-running the filters)")
    args = parser.parse_args()
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    results = [check(name, args.seeds, args.segment_s, args.workers, args.cache, args.evidence_scale, args.acquisitions_per_patch) for name in args.scenarios]
    print(f"planner against Monte Carlo (point-mass filter, {args.seeds} seeds a scenario, {args.segment_s:g} s segments, commit {commit})")
    print("| scenario | segments | within 1.5x | after convergence: within 1.5x | median predicted/MC | steep third: bound, predicted / MC m "
          "| shelf third: bound, predicted / MC m | shelf/steep predicted, MC |")
    print("|---|---|---|---|---|---|---|---|")
    for r in results:
        if not r["segments"]:
            print(f"| {r['scenario']} | 0 | - | - | - | - | - | - |")
            continue
        st, sh, after = r["steep"], r["shelf"], r["after_convergence"]
        late = "-" if after["within_1_5"] is None else f"{after['within_1_5']:.0%} of {after['segments']}"
        print(f"| {r['scenario']} | {r['segments']} | {r['within_1_5']:.0%} | {late} | {r['median_ratio']:.2f} | "
              f"{st['bound_m']:.1f}, {st['predicted_m']:.1f} / {st['mc_rms_m']:.1f} | {sh['bound_m']:.1f}, {sh['predicted_m']:.1f} / {sh['mc_rms_m']:.1f} | "
              f"{sh['predicted_m'] / st['predicted_m']:.1f}, {sh['mc_rms_m'] / st['mc_rms_m']:.1f} |")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"commit": commit, "results": results}, indent=1) + "\n")


if __name__ == "__main__":
    main()
