"""INS+USBL speed: one ray inversion (eqs. 4-5), one USBL fix, one filter step, and the shipped usbl_turns scenario.

Run: .venv/bin/python benchmarks/usbl_speed.py   (best of a few repeats; seconds, per call)
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np

from lost.host.usbl.filter import ImuNoise, InsUsblFilter
from lost.host.usbl.fix import UsblArray, reply_from_geometry, usbl_fix
from lost.host.usbl.ins import EarthModel, ImuSamples, NavState
from lost.host.usbl.pipeline import UsblConfig, process
from lost.host.usbl.rays import solve_ray, trace_to_depth
from lost.host.usbl.scenario import load_usbl_scenario
from lost.host.usbl.simulate import simulate_tow
from lost.host.usbl.sound import SoundSpeedProfile, read_cast


def best(call: Callable[[], object], repeats: int = 5, number: int = 1) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(number):
            call()
        times.append((time.perf_counter() - start) / number)
    return min(times)


def main() -> None:
    scenario = load_usbl_scenario("usbl_turns")
    cast = read_cast(scenario.cast_path())
    full = SoundSpeedProfile.from_cast(cast)
    thin = SoundSpeedProfile.from_cast(cast, tolerance_m_s=0.05)
    print(f"profile: {full.depth_m.size} samples, {thin.depth_m.size} after thinning to 0.05 m/s")
    for label, profile in (("full", full), ("thinned", thin)):
        ray = trace_to_depth(profile, np.radians(35.0), 5.0, 1000.0)
        print(f"solve_ray ({label}, 1000 m, 35 deg): {best(lambda p=profile, t=ray.time_s: solve_ray(p, 5.0, 1000.0, t), number=20) * 1e3:.2f} ms")
    array = UsblArray()
    ship = dict(roll_rad=0.02, pitch_rad=-0.01, heading_rad=0.5, antenna_north_m=0.0, antenna_east_m=0.0)
    reply = reply_from_geometry(thin, array, **ship, target_north_m=-600.0, target_east_m=-300.0, target_depth_m=1000.0)
    fix_time = best(lambda: usbl_fix(thin, array, travel_time_s=reply[0], phase_x_rad=reply[1], phase_y_rad=reply[2], **ship,
                                     target_depth_m=1000.0), number=20)
    print(f"usbl_fix (1000 m, thinned profile, with covariance): {fix_time * 1e3:.2f} ms")
    filt = InsUsblFilter(NavState(np.zeros(3), np.zeros(3), np.eye(3)), np.eye(15) * 1e-4, ImuNoise(), EarthModel.at(18.0))
    force, rate = np.array([0.0, 0.0, -9.785]), np.zeros(3)
    print(f"filter predict (strapdown + 16x16 covariance): {best(lambda: filt.predict(force, rate, 0.1), number=2000) * 1e6:.1f} us")
    sim_time = best(lambda: simulate_tow(scenario), repeats=2)
    sim = simulate_tow(scenario)
    imu = ImuSamples(sim.imu.time_s.to_numpy(), sim.imu[["fx_m_s2", "fy_m_s2", "fz_m_s2"]].to_numpy(), sim.imu[["wx_rad_s", "wy_rad_s", "wz_rad_s"]].to_numpy())
    config = UsblConfig(array=scenario.usbl, imu=scenario.imu, gate_probability=scenario.gate_probability)
    run_time = best(lambda: process(sim.log, imu, sim.cast, config), repeats=2)
    print(f"usbl_turns ({scenario.duration_s:.0f} s, {len(sim.log)} pings, {len(sim.imu)} IMU samples): simulate {sim_time:.2f} s, "
          f"process {run_time:.2f} s ({scenario.duration_s / run_time:.0f}x real time)")


if __name__ == "__main__":
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()  # --help, and no stray options
    main()
