"""Truth against processing over many seeds: replies traced through the truth ocean, processed with the logged cast.

Cases (the tow of usbl_turns, 30 min at 1000 m, 700 m layback):
  fresh            usbl_turns: the truth is the cast itself at 5 m (the processing thins it to 0.05 m/s); default settings
  stale, no state  usbl_stale_cast (4 h old cast, surface warming 0.25 degC/h, 10 m internal waves), the filter without
                   the sound-speed state (sound_speed_sigma_m_s = 0, surface_speed_drift_m_s_per_h = 0): the model before it
  stale, age unknown  the same log, default settings (the cast's age not given)
  stale, age given    the same log, the scenario's [processing] (cast_age_h = 4, sound_speed_sigma_m_s = 0.5)

Run: .venv/bin/python benchmarks/usbl_truth.py --seeds 20 [--jobs 2]   (about 1 min a seed on one core)
Writes build/bench/usbl_truth.json and prints the table (median and 90th percentile over seeds; for the share of
epochs with NEES in its band, the median and the 10th percentile, its bad tail).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import subprocess
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from lost.host.usbl.ins import ImuSamples
from lost.host.usbl.ocean import TruthOcean
from lost.host.usbl.pipeline import UsblConfig, process
from lost.host.usbl.report import summarize
from lost.host.usbl.scenario import load_usbl_scenario
from lost.host.usbl.simulate import simulate_tow
from lost.host.usbl.sound import SoundSpeedProfile

CASES = ("fresh", "stale, no state", "stale, age unknown", "stale, age given")
METRICS = ("fused_rms_m", "usbl_good_rms_m", "nees_inside", "nees_mean", "good_rejected_pct", "bad_caught_pct", "failed_fixes")


def _row(summary: dict) -> dict[str, float]:
    methods, gating, nees = summary["methods"], summary["gating"], summary["nees"]
    return {"fused_rms_m": methods["fused"]["rms_m"], "usbl_good_rms_m": methods["usbl_good_fixes"]["rms_m"],
            "nees_inside": nees["fraction_inside"], "nees_mean": nees["mean"], "good_rejected_pct": 100.0 * gating["good_rejected_fraction"],
            "bad_caught_pct": 100.0 * gating["injected_bad_caught_fraction"], "failed_fixes": gating["failed"]}


def _process(sim, config: UsblConfig) -> dict[str, float]:
    imu = ImuSamples(sim.imu.time_s.to_numpy(), sim.imu[["fx_m_s2", "fy_m_s2", "fz_m_s2"]].to_numpy(),
                     sim.imu[["wx_rad_s", "wy_rad_s", "wz_rad_s"]].to_numpy())
    return _row(summarize(process(sim.log, imu, sim.cast, config), name="bench", run_time_s=0.0))


def _path_mean_offset(scenario, sim) -> list[float]:
    """Truth minus cast in the harmonic-mean speed from 5 m to the tow's depth, its least and greatest over the tow (m/s)."""
    ocean = TruthOcean.build(sim.cast, scenario.ocean, scenario.tow.depth_m + 50.0)
    depth = scenario.tow.depth_m
    cast = SoundSpeedProfile.from_cast(sim.cast).harmonic_mean_m_s(5.0, depth)
    offsets = [ocean.profile_at(t).harmonic_mean_m_s(5.0, depth) - cast for t in np.arange(0.0, scenario.duration_s + 1.0, 60.0)]
    return [float(min(offsets)), float(max(offsets))]


def one_seed(seed: int) -> dict[str, object]:
    fresh = dataclasses.replace(load_usbl_scenario("usbl_turns"), seed=seed)
    stale = dataclasses.replace(load_usbl_scenario("usbl_stale_cast"), seed=seed)
    fresh_sim, stale_sim = simulate_tow(fresh), simulate_tow(stale)
    default = UsblConfig(array=stale.usbl, imu=stale.imu, gate_probability=stale.gate_probability)
    rows = {
        "fresh": _process(fresh_sim, fresh.processing_config()),
        "stale, no state": _process(stale_sim, dataclasses.replace(default, sound_speed_sigma_m_s=0.0, surface_speed_drift_m_s_per_h=0.0)),
        "stale, age unknown": _process(stale_sim, default),
        "stale, age given": _process(stale_sim, stale.processing_config()),
    }
    return {"seed": seed, "rows": rows, "stale_path_mean_offset_m_s": _path_mean_offset(stale, stale_sim)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--first-seed", type=int, default=100)
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--out", type=Path, default=Path("build/bench/usbl_truth.json"))
    args = parser.parse_args()
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    with ProcessPoolExecutor(args.jobs) as pool:
        results = []
        for result in pool.map(one_seed, seeds):
            results.append(result)
            print(f"seed {result['seed']}: " + "; ".join(f"{case} fused {row['fused_rms_m']:.2f} m, NEES in band {row['nees_inside']:.3f}"
                                                          for case, row in result["rows"].items()), flush=True)
    table = {case: {metric: np.array([r["rows"][case][metric] for r in results], dtype=float) for metric in METRICS} for case in CASES}
    offsets = np.array([r["stale_path_mean_offset_m_s"] for r in results])
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    print(f"\n{len(seeds)} seeds ({seeds[0]}-{seeds[-1]}), commit {commit}; stale truth minus cast, harmonic-mean speed 5-1000 m: "
          f"{np.median(offsets[:, 0]):+.2f} to {np.median(offsets[:, 1]):+.2f} m/s over the tow (the same ocean for every seed)")
    print("| case | fused RMS (m) | good-fix USBL RMS (m) | NEES in band (median / p10) | NEES mean | good fixes rejected (%) "
          "| bad fixes caught (%) | failed fixes |")
    print("|---|---|---|---|---|---|---|---|")
    for case in CASES:
        t = table[case]

        def cell(metric: str, digits: int = 2, t: dict = t) -> str:
            return f"{np.median(t[metric]):.{digits}f} / {np.percentile(t[metric], 90):.{digits}f}"

        inside = f"{np.median(t['nees_inside']):.3f} / {np.percentile(t['nees_inside'], 10):.3f}"
        print(f"| {case} | {cell('fused_rms_m')} | {cell('usbl_good_rms_m')} | {inside} | {cell('nees_mean')} | {cell('good_rejected_pct')} "
              f"| {np.median(t['bad_caught_pct']):.1f} / {np.percentile(t['bad_caught_pct'], 10):.1f} | {cell('failed_fixes', 0)} |")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"commit": commit, "seeds": seeds, "results": results}, indent=1) + "\n")


if __name__ == "__main__":
    main()
