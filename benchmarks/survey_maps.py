"""How wrong the realistic maps are, measured: `make bench-sim` (python benchmarks/survey_maps.py).

For each shipped scenario whose map is a survey (``[map] node_m`` given), over ``--seeds`` seeds of the
scenario (floor and survey both drawn anew): the map's error against the true floor's mean over each map
cell, the datum offset removed (RMS and 90th percentile of |error|, metres), the map's own per-node
standard deviation (``Grid.sigma_m``, median), the relief inside a cell that the map cannot show (the
true floor's spread in the cell, median), the share of nodes with |error| within 2 sigma_m, and the share
of holes. Prints, per figure, the median and 90th percentile over the seeds; writes build/bench/survey_maps.json.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from lost.host.scenario import builtin_scenario_path, builtin_scenarios, load_scenario, scenario_floor, survey_map
from lost.host.scenario.map import grid_soundings

FIGURES = ("rms_error_m", "p90_error_m", "sigma_median_m", "cell_relief_median_m", "within_2_sigma", "holes")


def one_seed(name: str, seed: int) -> dict[str, float]:
    scenario = replace(load_scenario(builtin_scenario_path(name)), seed=seed)
    floor = scenario_floor(scenario)
    grid = survey_map(floor, replace(scenario.map, extent_m=None), seed + 1)  # the whole survey: a cut map's errors are the same
    factor = int(round(scenario.map.node_m / floor.node_m))
    truth, relief = grid_soundings(floor.depth_m, factor)
    error = grid.depth_m - truth - scenario.map.offset_m
    finite = np.isfinite(error)
    return {
        "rms_error_m": float(np.sqrt(np.mean(error[finite] ** 2))),
        "p90_error_m": float(np.percentile(np.abs(error[finite]), 90)),
        "sigma_median_m": float(np.nanmedian(grid.sigma_m)),
        "cell_relief_median_m": float(np.median(relief)),
        "within_2_sigma": float(np.mean(np.abs(error[finite]) <= 2 * grid.sigma_m[finite])),
        "holes": float(np.mean(~finite)),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--out", type=Path, default=Path("build/bench/survey_maps.json"))
    args = parser.parse_args()
    surveyed = [name for name in builtin_scenarios() if load_scenario(builtin_scenario_path(name)).map.node_m is not None]
    table = {}
    for name in surveyed:
        runs = [one_seed(name, seed) for seed in range(1, args.seeds + 1)]
        table[name] = {figure: {"median": float(np.median([r[figure] for r in runs])), "p90": float(np.percentile([r[figure] for r in runs], 90))}
                       for figure in FIGURES}
    print(f"The shipped survey maps against their floors, {args.seeds} seeds each: median / 90th percentile over the seeds\n")
    print("| scenario | map error RMS, m | map error p90, m | sigma_m median, m | relief in a cell, m | error within 2 sigma_m | holes |")
    print("|---|---|---|---|---|---|---|")
    for name, row in table.items():
        cells = [f"{row[f]['median']:.2f} / {row[f]['p90']:.2f}" for f in FIGURES[:4]]
        cells += [f"{100 * row[f]['median']:.0f} / {100 * row[f]['p90']:.0f} %" for f in FIGURES[4:]]
        print(f"| {name} | " + " | ".join(cells) + " |")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(table, indent=2))


if __name__ == "__main__":
    main()
