"""Every goal of the contact tracker over seeded simulated runs, beside Stone Soup's GM-PHD and JPDA: `make bench-track`.

    python benchmarks/track_goals.py [--seeds 10] [--hours 1.0] [--separations 15 20 30 40] [--out build/track]
                                     [--set NAME=VALUE ...]   # our tracker's TrackerParameters, e.g. permutation_pruning=false

Cases, each over ``--seeds`` seeds (0, 1, ...); every figure is a distribution over the seeds (median and
90th percentile, or the 10th where less is worse):

- ``diver_free``: the shipped ``clutter_hour`` (no target) at the shipped clutter (5 a ping) and twice it, for
  ``--hours`` each; every confirmed identity is a false track. The baselines run ``--baseline-minutes`` of it.
- ``separation``: two divers side by side at 350 m, ``S`` metres apart, swimming the same course at 0.5 m/s for
  ``--separation-s`` seconds, the platform swinging on its chain; all three trackers.
- ``split``: two divers from one point on courses 11.5 degrees apart (they part at 0.1 m/s), for 300 s: the
  pings from when they are 20 m apart until both are held.
- ``pd06``: the shipped ``one_diver`` with pd 0.6, for ``--pd-s`` seconds; all three trackers.
- ``paper``: the paper's filter as stated (no clutter floor) on the shipped ``one_diver``.

Every tracker is told the scenario's own sonar model (pd, clutter rate, noise); our tracker also its strengths'
Gaussian fit (``strength_moments``), which the baselines do not weigh.

Metrics, the same code for every tracker (``lost.host.track.evaluate``): coverage, first lock, identity
switches and the all-held share from the one-to-one holding within 25 m; false tracks per hour; Stone Soup's
GOSPA (c = 50 m, p = 1, alpha = 2) per ping on the pings with a target in the sector, mean and 95th
percentile per run. Our tracker's step time per ping (10,000 particles) over every run, as wall time and as
its thread's CPU time (the cost of a step on a machine shared with other work; the goal is judged on it). Prints Markdown
tables and the goals; writes ``goals.json``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import time
from pathlib import Path

import numpy as np

from lost.host.cli.common import setting_argument
from lost.host.config import ConfigError, build
from lost.host.track.baseline import run_gm_phd, run_jpda
from lost.host.track.evaluate import contact_metrics, holding, score
from lost.host.track.particle import DiverParticleFilter, PaperParameters
from lost.host.track.run import run_tracker
from lost.host.track.simulate import PlatformSpec, TargetSpec, TrackScenario, builtin_scenario_path, load_scenario, simulate, tracker_model
from lost.host.track.tracker import TrackerParameters

TRACKERS = ("ours", "gm_phd", "jpda")
#: ``--set`` overrides of our tracker's parameters (the baselines keep theirs).
OURS_SETTINGS: dict = {}


def params_for(sim) -> TrackerParameters:
    """The sonar model the trackers assume: the scenario's own (its strengths as our tracker's Gaussian fit of them)."""
    return TrackerParameters(**tracker_model(sim.scenario.sonar))


def run(tracker: str, sim, seed: int, step_ms: list) -> tuple[list, float]:
    """One tracker over one simulated run: its confirmed contacts per ping and its wall time per ping (ms)."""
    params, sonar = params_for(sim), sim.scenario.sonar.sonar
    start = time.perf_counter()
    if tracker == "ours":
        result = run_tracker(sim.pings, sonar=sonar, parameters=dataclasses.replace(params, **OURS_SETTINGS), seed=seed, cloud_points=0)
        step_ms.append(np.column_stack((result.step_ms, result.step_cpu_ms)))
        history = result.estimates
    elif tracker == "gm_phd":
        history = run_gm_phd(sim.pings, sonar=sonar, tracker=params)
    else:
        history = run_jpda(sim.pings, sonar=sonar, tracker=params)
    return history, (time.perf_counter() - start) / len(sim.pings) * 1e3


def figures(history, sim, after: int = 0) -> dict:
    """Every metric of one run (module docstring)."""
    s = score(history, sim.truth, siap=False)
    bearing = sim.truth.in_sector.any(axis=1)
    gospa = np.asarray(s.gospa_per_ping)[bearing]
    hours = len(sim.pings) * sim.scenario.sonar.ping_interval_s / 3600.0
    out = {"false_tracks": s.false_tracks, "false_per_hour": s.false_tracks / hours, "confirmed_ids": s.confirmed_tracks,
           "gospa_mean": float(gospa.mean()) if gospa.size else None, "gospa_p95": float(np.percentile(gospa, 95)) if gospa.size else None}
    if sim.truth.xy.shape[1]:
        out.update(contact_metrics(history, sim.truth, after=after))
    return out


def separated(separation_m: float, seed: int, duration_s: float) -> TrackScenario:
    half = math.degrees(separation_m / 2 / 350.0)
    divers = tuple(TargetSpec(start_range_m=350.0, start_bearing_deg=b, speed_mps=0.5, course_deg=180.0) for b in (-half, half))
    return TrackScenario(name=f"separation_{separation_m:g}", seed=seed, duration_s=duration_s, targets=divers,
                         platform=PlatformSpec(yaw_amplitude_deg=8.0, yaw_period_s=90.0))


def splitting(seed: int) -> TrackScenario:
    divers = tuple(TargetSpec(start_range_m=350.0, speed_mps=0.5, course_deg=180.0 + c) for c in (-5.74, 5.74))
    return TrackScenario(name="split", seed=seed, duration_s=300.0, targets=divers, platform=PlatformSpec(yaw_amplitude_deg=8.0, yaw_period_s=90.0))


def shipped(name: str, seed: int, duration_s: float | None = None, **sonar) -> TrackScenario:
    base = load_scenario(builtin_scenario_path(name))
    base = dataclasses.replace(base, seed=seed, sonar=dataclasses.replace(base.sonar, **sonar))
    return base if duration_s is None else dataclasses.replace(base, duration_s=duration_s)


def case_diver_free(args, results: dict, step_ms: list) -> None:
    for factor in (1, 2):
        rows = results["diver_free"][f"{factor}x"] = {t: [] for t in TRACKERS}
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            for tracker in args.trackers:
                minutes = args.hours * 60 if tracker == "ours" else args.baseline_minutes
                sim = simulate(shipped("clutter_hour", seed, minutes * 60.0, clutter_per_ping=5.0 * factor))
                history, ms = run(tracker, sim, seed, step_ms)
                rows[tracker].append({"seed": seed, "hours": minutes / 60, "ms_per_ping": ms, **figures(history, sim)})
            progress(f"diver-free {factor}x seed {seed}")


def case_separation(args, results: dict, step_ms: list) -> None:
    for separation in args.separations:
        rows = results["separation"][f"{separation:g}"] = {t: [] for t in TRACKERS}
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            sim = simulate(separated(separation, seed, args.separation_s))
            for tracker in args.trackers:
                history, ms = run(tracker, sim, seed, step_ms)
                rows[tracker].append({"seed": seed, "ms_per_ping": ms, **figures(history, sim, after=20)})
            progress(f"separation {separation:g} m seed {seed}")


def case_split(args, results: dict, step_ms: list) -> None:
    rows = results["split"] = []
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        sim = simulate(splitting(seed))
        history, _ = run("ours", sim, seed, step_ms)
        held = holding(history, sim.truth)
        apart = np.hypot(*(sim.truth.xy[:, 0] - sim.truth.xy[:, 1]).T)
        both = (held >= 0).all(axis=1) & sim.truth.in_sector.all(axis=1)
        at20 = int(np.argmax(apart >= 20.0))
        later = np.flatnonzero(both[at20:])
        rows.append({"seed": seed, "pings_after_20m": int(later[0]) if later.size else None,
                     "separation_when_both_first_held_m": float(apart[np.argmax(both)]) if both.any() else None,
                     "all_held_after_20m": float(both[at20:].mean()), **figures(history, sim)})
        progress(f"split seed {seed}")


def case_pd06(args, results: dict, step_ms: list) -> None:
    rows = results["pd06"] = {t: [] for t in TRACKERS}
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        sim = simulate(shipped("one_diver", seed, args.pd_s, pd=0.6))
        for tracker in args.trackers:
            history, ms = run(tracker, sim, seed, step_ms)
            rows[tracker].append({"seed": seed, "ms_per_ping": ms, **figures(history, sim)})
        progress(f"pd 0.6 seed {seed}")


def case_paper(args, results: dict, step_ms: list) -> None:
    """The paper's filter as stated (no clutter floor) on the shipped one_diver: how soon and how often its mean is within 25 m."""
    rows = results["paper"] = []
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        sim = simulate(shipped("one_diver", seed))
        pf = DiverParticleFilter(sonar=sim.scenario.sonar.sonar, parameters=PaperParameters(), rng=np.random.default_rng(seed))
        errors = np.hypot(*(np.array([e.mean_xy for e in pf.run(sim.pings)]) - sim.truth.xy[:, 0]).T)
        valid = sim.truth.in_sector[:, 0]
        within = np.flatnonzero(valid & (errors <= 25.0))
        rows.append({"seed": seed, "first_within_25m": int(within[0]) + 1 if within.size else None,
                     "share_within_25m": float(np.mean(errors[valid] <= 25.0))})
    progress("paper's filter")


_START = time.perf_counter()


def progress(what: str) -> None:
    print(f"  [{time.perf_counter() - _START:7.0f} s] {what}", flush=True)


def spread(values, low: bool = False) -> str:
    """Median and 90th percentile (10th with ``low``) of the values that exist, as 'median (p90)'; '-' when none."""
    v = np.array([x for x in values if x is not None], float)
    if not v.size:
        return "-"
    return f"{np.median(v):.3g} ({'p10' if low else 'p90'} {np.percentile(v, 10 if low else 90):.3g})"


def tables(results: dict, trackers: tuple[str, ...]) -> list[str]:
    lines = ["### Diver-free clutter: false tracks", "", "| clutter | tracker | hours | false tracks | per hour: median (p90) | ms/ping |",
             "|---|---|---|---|---|---|"]
    for level, rows in results["diver_free"].items():
        for t in trackers:
            r = rows.get(t)
            if r:
                lines.append(f"| {level} | {t} | {sum(x['hours'] for x in r):.3g} | {sum(x['false_tracks'] for x in r)} | "
                             f"{spread([x['false_per_hour'] for x in r])} | {spread([x['ms_per_ping'] for x in r])} |")
    lines += ["", "### Two divers side by side", "",
              "| apart (m) | tracker | both held after ping 20: median (p10) | coverage (p10) | first lock | identity switches | "
              "false tracks | GOSPA mean (p90) | GOSPA p95 (p90) |", "|---|---|---|---|---|---|---|---|---|"]
    for separation, rows in results["separation"].items():
        for t in trackers:
            r = rows.get(t)
            if r:
                lines.append(
                    f"| {separation} | {t} | {spread([x['all_held'] for x in r], low=True)} | "
                    f"{spread([c for x in r for c in x['coverage']], low=True)} | {spread([c for x in r for c in x['first_lock']])} | "
                    f"{spread([sum(x['identity_switches']) for x in r])} | {spread([x['false_tracks'] for x in r])} | "
                    f"{spread([x['gospa_mean'] for x in r])} | {spread([x['gospa_p95'] for x in r])} |")
    r = results["split"]
    if r:
        lines += ["", "### Two divers parting (ours)", "", "| pings from 20 m apart to both held | separation when both first held (m) | "
                  "both held after 20 m | identity switches |", "|---|---|---|---|",
                  f"| {spread([x['pings_after_20m'] for x in r])} | {spread([x['separation_when_both_first_held_m'] for x in r])} | "
                  f"{spread([x['all_held_after_20m'] for x in r], low=True)} | {spread([sum(x['identity_switches']) for x in r])} |"]
    lines += ["", "### One diver at pd 0.6", "", "| tracker | coverage: median (p10) | first lock | identity switches | false tracks | "
              "GOSPA mean (p90) | GOSPA p95 (p90) |", "|---|---|---|---|---|---|---|"]
    for t in trackers:
        r = results["pd06"].get(t)
        if r:
            lines.append(f"| {t} | {spread([x['coverage'][0] for x in r], low=True)} | {spread([x['first_lock'][0] for x in r])} | "
                         f"{spread([x['identity_switches'][0] for x in r])} | {spread([x['false_tracks'] for x in r])} | "
                         f"{spread([x['gospa_mean'] for x in r])} | {spread([x['gospa_p95'] for x in r])} |")
    r = results.get("paper", [])
    if r:
        lines += ["", "### The paper's filter as stated (one_diver)", "", "| first within 25 m (pings) | share of pings within 25 m |",
                  "|---|---|", f"| {spread([x['first_within_25m'] for x in r])} | {spread([x['share_within_25m'] for x in r], low=True)} |"]
    return lines


def goals(results: dict, ms: np.ndarray) -> list[tuple[str, str, bool | None]]:
    """Each goal, its figure and whether it is met (None where not measured)."""
    out = []
    for level, limit in (("1x", 0), ("2x", 1)):
        r = results["diver_free"].get(level, {}).get("ours", [])
        hours = sum(x["hours"] for x in r)
        false = sum(x["false_tracks"] for x in r)
        out.append((f"<= {limit} false tracks in 10 diver-free hours at {level} clutter",
                    f"{false} in {hours:.3g} h ({len(r)} seeds)", (false * 10 / hours <= limit) if hours else None))
    sep = results["separation"].get("20", {}).get("ours", [])
    held = [x["all_held"] for x in sep if x["all_held"] is not None]
    out.append(("two divers 20 m apart: both held >= 90 % of in-sector pings after the first 20 (every seed)",
                f"median {np.median(held):.3f}, worst {min(held):.3f} ({len(held)} seeds)" if held else "-", min(held) >= 0.9 if held else None))
    verdicts, figures_ = [], []
    for separation, rows in results["separation"].items():
        if float(separation) < 15 or not rows["ours"]:
            continue
        medians = {t: float(np.median([x["gospa_mean"] for x in rows[t]])) for t in TRACKERS if rows[t]}
        figures_.append(f"{separation} m: " + ", ".join(f"{t} {v:.2f}" for t, v in medians.items()))
        # Judged only beside both baselines: a run of ours alone (an ablation) says nothing of this goal.
        verdicts.append(all(medians["ours"] <= v for v in medians.values()) if len(medians) == len(TRACKERS) else None)
    judged = verdicts and None not in verdicts
    out.append(("median GOSPA <= GM-PHD's and JPDA's at every separation from 15 m", "; ".join(figures_) or "-", all(verdicts) if judged else None))
    cov = [x["coverage"][0] for x in results["pd06"].get("ours", [])]
    out.append(("pd 0.6: coverage >= 0.9 (every seed)", f"median {np.median(cov):.3f}, worst {min(cov):.3f}" if cov else "-", min(cov) >= 0.9 if cov else None))
    if len(ms):
        wall, cpu = np.percentile(ms, 95, axis=0)
        out.append(("<= 20 ms per ping at the 95th percentile with 10,000 particles (judged on CPU time)",
                    f"CPU p95 {cpu:.1f} ms (median {np.median(ms[:, 1]):.1f}); wall p95 {wall:.1f} ms (median {np.median(ms[:, 0]):.1f}) "
                    f"over {len(ms)} pings, load average {os.getloadavg()[0]:.1f} at the end", cpu <= 20.0))
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--first-seed", type=int, default=0, help="seeds run from this one (to add runs to earlier ones)")
    parser.add_argument("--hours", type=float, default=1.0, help="diver-free hours per seed and clutter level, our tracker")
    parser.add_argument("--baseline-minutes", type=float, default=5.0, help="diver-free minutes per seed and clutter level, the baselines")
    parser.add_argument("--separations", type=float, nargs="+", default=[15.0, 20.0, 30.0, 40.0])
    parser.add_argument("--separation-s", type=float, default=100.0, help="length of each side-by-side run, s")
    parser.add_argument("--pd-s", type=float, default=None, help="length of each pd 0.6 run, s (default one_diver's 400)")
    parser.add_argument("--trackers", nargs="+", default=list(TRACKERS), choices=TRACKERS)
    parser.add_argument("--cases", nargs="+", default=["diver_free", "separation", "split", "pd06"],
                        choices=["diver_free", "separation", "split", "pd06", "paper"])
    parser.add_argument("--out", type=Path, default=Path("build/track"))
    parser.add_argument("--report", type=Path, nargs="+", default=None,
                        help="run nothing: merge these goals.json files (cases run apart) and print their tables and goals")
    parser.add_argument("--set", dest="settings", type=setting_argument, action="append", default=[], metavar="NAME=VALUE",
                        help="a TrackerParameters field of our tracker; repeatable; VALUE is TOML (e.g. permutation_pruning=false)")
    args = parser.parse_args(argv)
    try:  # the settings layer's strict checks: unknown names and wrong types refused by name
        build(TrackerParameters, dict(args.settings), "--set")
    except (ConfigError, ValueError) as error:
        parser.error(str(error))
    OURS_SETTINGS.update(dict(args.settings))
    if args.report:
        return report(args.report)
    results: dict = {"arguments": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()},
                     "diver_free": {}, "separation": {}, "split": [], "pd06": {}, "paper": []}
    step_ms: list[np.ndarray] = []
    for case in args.cases:
        globals()[f"case_{case}"](args, results, step_ms)
    ms = np.concatenate(step_ms) if step_ms else np.empty((0, 2))
    results["step_ms"] = ms.round(3).tolist()
    judged = goals(results, ms)
    results["goals"] = [{"goal": g, "figure": f, "met": None if m is None else bool(m)} for g, f, m in judged]
    results["ms_per_ping"] = {"wall_median": float(np.median(ms[:, 0])), "wall_p95": float(np.percentile(ms[:, 0], 95)),
                              "cpu_median": float(np.median(ms[:, 1])), "cpu_p95": float(np.percentile(ms[:, 1], 95)),
                              "pings": len(ms)} if len(ms) else {}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "goals.json").write_text(json.dumps(results, indent=1))
    print("\n".join(tables(results, tuple(args.trackers))))
    print("\n| goal | figure | met |\n|---|---|---|")
    for g, f, m in judged:
        print(f"| {g} | {f} | {'-' if m is None else 'yes' if m else 'NO'} |")
    print(f"\nwrote {args.out / 'goals.json'}")
    return 0


def _merge(a, b):
    """Runs of one case from several files together: lists of runs joined, tables merged key by key."""
    if isinstance(a, list):
        return a + b
    return {k: _merge(a[k], b[k]) if k in a and k in b else a.get(k, b.get(k)) for k in {**a, **b}}


def report(paths: list[Path]) -> int:
    """Tables and goals of several runs' goals.json files taken together."""
    merged: dict = {"diver_free": {}, "separation": {}, "split": [], "pd06": {}, "paper": []}
    ms = []
    for path in paths:
        part = json.loads(path.read_text())
        for key in ("diver_free", "separation", "pd06", "split", "paper"):
            merged[key] = _merge(merged[key], part.get(key, type(merged[key])()))
        ms += part.get("step_ms", [])
    print("\n".join(tables(merged, TRACKERS)))
    print("\n| goal | figure | met |\n|---|---|---|")
    for g, f, m in goals(merged, np.array(ms, float).reshape(-1, 2)):
        print(f"| {g} | {f} | {'-' if m is None else 'yes' if m else 'NO'} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
