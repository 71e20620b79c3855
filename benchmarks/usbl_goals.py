"""The issue's goals on usbl_turns over many seeds (the shipped scenario is one seed; this shows the spread).

Run: .venv/bin/python benchmarks/usbl_goals.py --seeds 20   (about 8 s a seed on this machine)
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from lost.host.usbl.ins import ImuSamples
from lost.host.usbl.pipeline import UsblConfig, process
from lost.host.usbl.report import summarize
from lost.host.usbl.scenario import load_usbl_scenario
from lost.host.usbl.simulate import simulate_tow


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--first-seed", type=int, default=100)
    parser.add_argument("--gate-probability", type=float, default=None, help="override the scenario's chi-square gate")
    args = parser.parse_args()
    base = load_usbl_scenario("usbl_turns")
    rows = []
    print(f"{'seed':>5s} {'fused_rms':>9s} {'usbl_rms':>9s} {'good_rms':>9s} {'bad_caught':>10s} {'good_rej':>8s} {'nees_in':>7s} {'gaps':>4s}")
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        scenario = dataclasses.replace(base, seed=seed)
        if args.gate_probability is not None:
            scenario = dataclasses.replace(scenario, gate_probability=args.gate_probability)
        sim = simulate_tow(scenario)
        imu = ImuSamples(sim.imu.time_s.to_numpy(), sim.imu[["fx_m_s2", "fy_m_s2", "fz_m_s2"]].to_numpy(),
                         sim.imu[["wx_rad_s", "wy_rad_s", "wz_rad_s"]].to_numpy())
        run = process(sim.log, imu, sim.cast, UsblConfig(array=scenario.usbl, imu=scenario.imu, gate_probability=scenario.gate_probability))
        s = summarize(run, name=scenario.name, run_time_s=0.0)
        m, g = s["methods"], s["gating"]
        row = (seed, m["fused"]["rms_m"], m["usbl"]["rms_m"], m["usbl_good_fixes"]["rms_m"], g["injected_bad_caught_fraction"],
               g["good_rejected_fraction"], s["nees"]["fraction_inside"], s["epochs_without_fused_position"])
        rows.append(row)
        print(f"{row[0]:5d} {row[1]:9.2f} {row[2]:9.2f} {row[3]:9.2f} {row[4]:10.3f} {row[5]:8.4f} {row[6]:7.3f} {row[7]:4d}", flush=True)
    data = np.array(rows, dtype=float)
    met = {
        "fused position at every epoch": np.all(data[:, 7] == 0),
        "fused RMS <= half raw USBL": np.mean(data[:, 1] <= 0.5 * data[:, 2]),
        "fused RMS <= half good-fix USBL": np.mean(data[:, 1] <= 0.5 * data[:, 3]),
        "bad fixes caught >= 95 %": np.mean(data[:, 4] >= 0.95),
        "good fixes rejected <= 1 %": np.mean(data[:, 5] <= 0.01),
        "NEES inside band >= 90 % of epochs": np.mean(data[:, 6] >= 0.90),
    }
    print(f"median fused RMS {np.median(data[:, 1]):.2f} m, raw USBL {np.median(data[:, 2]):.2f} m, good fixes {np.median(data[:, 3]):.2f} m; "
          f"bad caught median {np.median(data[:, 4]):.3f} (min {data[:, 4].min():.3f}); good rejected median {np.median(data[:, 5]):.4f} "
          f"(max {data[:, 5].max():.4f}); NEES inside median {np.median(data[:, 6]):.3f} (min {data[:, 6].min():.3f})")
    for goal, share in met.items():
        print(f"{goal}: met in {float(share):.0%} of {len(rows)} seeds")


if __name__ == "__main__":
    main()
