"""The tow simulator's speed: `make bench-sim` (python benchmarks/simulate_speed.py).

For every shipped scenario, the time of ``simulate()`` (floor, map and tow with its sensors) and of its
first two parts alone, ``scenario_floor()`` and ``survey_map()``, over ``--repeats`` runs: median and 90th
percentile of the process's CPU time (on a machine shared with other jobs the wall time measures them too;
it is in the JSON beside). Then a 10 km x 10 km floor at 5 m (a shelf, its slope, von Karman relief, a winding canyon, a
ridge, a seamount) and its 25 m survey map. Prints a markdown table and writes build/bench/simulate_speed.json.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from lost.host.scenario import (
    CableSpec,
    MapSpec,
    Scenario,
    TerrainSpec,
    builtin_scenario_path,
    builtin_scenarios,
    load_scenario,
    scenario_floor,
    simulate,
    survey_map,
)
from lost.host.terrain import Feature

LARGE_FLOOR = TerrainSpec(
    shape=(2000, 2000), node_m=5.0, mean_depth_m=300.0, relief_m=3.0, roughness_m=0.5, corner_m=500.0, gradient=0.01, downslope_deg=135.0,
    break_m=2000.0, slope_gradient=0.08,
    features=(Feature(kind="canyon", height_m=80.0, width_m=120.0, path_m=((1000.0, 9000.0), (6000.0, 4000.0), (9500.0, 500.0)), meander_m=300.0,
                      meander_wavelength_m=1800.0),
              Feature(kind="ridge", height_m=40.0, width_m=150.0, path_m=((1000.0, 1000.0), (4000.0, 2500.0))),
              Feature(kind="seamount", height_m=150.0, width_m=600.0, at_m=(7500.0, 7500.0))),
)
LARGE_MAP = MapSpec(node_m=25.0, gridding="median", line_spacing_m=600.0, swath_width_m=620.0, line_azimuth_deg=20.0, line_offset_m=0.4,
                    line_drift_m=0.3, along_m=800.0, refraction_m=0.6, sounding_noise_m=0.3, hole_fraction=0.03, hole_size_m=400.0, offset_m=2.0)


def timed(call, repeats: int) -> tuple[tuple[list[float], list[float]], object]:
    """(CPU seconds, wall seconds) of each of ``repeats`` calls, and the last call's result."""
    cpu, wall, result = [], [], None
    for _ in range(repeats):
        start_cpu, start_wall = time.process_time(), time.perf_counter()
        result = call()
        cpu.append(time.process_time() - start_cpu)
        wall.append(time.perf_counter() - start_wall)
    return (cpu, wall), result


def stats(times: tuple[list[float], list[float]]) -> dict[str, float]:
    cpu, wall = times
    return {"median_s": float(np.median(cpu)), "p90_s": float(np.percentile(cpu, 90)),
            "wall_median_s": float(np.median(wall)), "wall_p90_s": float(np.percentile(wall, 90))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", type=Path, default=Path("build/bench/simulate_speed.json"))
    args = parser.parse_args()
    rows = {}
    for name in builtin_scenarios():
        scenario = load_scenario(builtin_scenario_path(name))
        floor_times, floor = timed(lambda s=scenario: scenario_floor(s), args.repeats)
        seed = scenario.seed + 1 if scenario.map.seed is None else scenario.map.seed
        map_times, grid = timed(lambda s=scenario, f=floor, k=seed: survey_map(f, s.map, k), args.repeats)
        total_times, (_, records) = timed(lambda s=scenario: simulate(s), args.repeats)
        rows[name] = {"records": int(records.t_s.size), "floor_nodes": int(floor.depth_m.size), "map_shape": list(grid.shape),
                      "simulate": stats(total_times), "floor": stats(floor_times), "map": stats(map_times)}
    large = Scenario(terrain=LARGE_FLOOR, cable=CableSpec(out_m=3000.0))
    floor_times, floor = timed(lambda: scenario_floor(large), args.repeats)
    map_times, _ = timed(lambda: survey_map(floor, LARGE_MAP, 1), args.repeats)
    rows["10 km x 10 km at 5 m"] = {"records": 0, "floor_nodes": int(floor.depth_m.size), "map_shape": [400, 400],
                                   "floor": stats(floor_times), "map": stats(map_times)}
    print(f"simulate() and its parts, {args.repeats} runs each: median / 90th percentile of the CPU time, seconds\n")
    print("| scenario | records | floor nodes | map | simulate() | floor | map |")
    print("|---|---|---|---|---|---|---|")
    for name, row in rows.items():
        whole = f"{row['simulate']['median_s']:.2f} / {row['simulate']['p90_s']:.2f}" if "simulate" in row else "-"
        print(f"| {name} | {row['records']} | {row['floor_nodes']:,} | {row['map_shape'][0]} x {row['map_shape'][1]} | {whole} | "
              f"{row['floor']['median_s']:.2f} / {row['floor']['p90_s']:.2f} | {row['map']['median_s']:.2f} / {row['map']['p90_s']:.2f} |")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(rows, indent=2))


if __name__ == "__main__":
    main()
