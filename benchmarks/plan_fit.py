"""The planner's fitted constants, fitted on some floors and scored on the others (hold-out).

python benchmarks/plan_fit.py [--seeds 12] [--cache build/bench/plan_mc] [--evidence-scales 2 4 8 16 32 64]
                              [--acquisitions 3 10 30 100] [--held-out demo lookalike]

The route model has two constants fitted to the Monte Carlo: the look-alikes' ``evidence_scale`` and the route model's
``acquisitions_per_patch``. Scoring them on the floors they were fitted on flatters the planner. Here each pair of the
four floors fits them (the pair's mean share of segments within a factor 1.5, over the grid of values) and the other two
are scored with that fit; then each floor is scored with the constants fitted on the other three (leave one out): the
held-out share is the planner's honest figure on a floor it has not seen. ``--held-out`` floors are never fitted on:
they are scored with the constants fitted on all four. The Monte Carlo comes from
``benchmarks/plan_check.py``'s cache (run that first; without a cache this runs the filters). Writes
build/bench/plan_fit.json.
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
import subprocess
from pathlib import Path

import numpy as np
from plan_check import prepare, score

FLOORS = ("short", "coarse_map", "shelf_canyon", "seamount_ridges")


def table(floors: dict, scales: list[float], acquisitions: list[float]) -> dict:
    """The share within 1.5x of every floor at every pair of constants."""
    shares = {}
    for scale in scales:
        lookalikes = {name: floor.lookalike(scale) for name, floor in floors.items()}
        for acquisition in acquisitions:
            shares[scale, acquisition] = {name: score(floor, lookalikes[name], _with(floor.model, acquisition))["within_1_5"] for name, floor in floors.items()}
    return shares


def _with(model, acquisition: float | None):
    """The route model with ``acquisitions_per_patch`` set, where the model has that constant."""
    fields = {field.name for field in dataclasses.fields(model)}
    return dataclasses.replace(model, acquisitions_per_patch=acquisition) if "acquisitions_per_patch" in fields else model


def fit(shares: dict, names: tuple[str, ...]) -> tuple[float, float]:
    """The constants with the best mean share on ``names`` (ties: the first in the grid)."""
    return max(shares, key=lambda key: np.mean([shares[key][name] for name in names]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=12)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--cache", type=Path, default=Path("build/bench/plan_mc"))
    parser.add_argument("--evidence-scales", type=float, nargs="+", default=[2.0, 4.0, 8.0, 16.0, 32.0, 64.0])
    parser.add_argument("--acquisitions", type=float, nargs="+", default=[3.0, 10.0, 30.0, 100.0])
    parser.add_argument("--held-out", nargs="*", default=[], help="scenarios scored with the fit on the four floors, never fitted on")
    parser.add_argument("--out", type=Path, default=Path("build/bench/plan_fit.json"))
    args = parser.parse_args()
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    floors = {name: prepare(name, args.seeds, args.workers, args.cache) for name in (*FLOORS, *args.held_out)}
    shares = table(floors, args.evidence_scales, args.acquisitions)
    print(f"the planner's constants fitted on some floors, scored on the others ({args.seeds} seeds, commit {commit})")
    print("| fitted on | evidence scale, acquisitions | share within 1.5x where fitted | scored on | share within 1.5x there |")
    print("|---|---|---|---|---|")
    splits = []
    for train in itertools.combinations(FLOORS, 2):
        test = tuple(name for name in FLOORS if name not in train)
        best = fit(shares, train)
        fitted = ", ".join(f"{shares[best][name]:.0%}" for name in train)
        held = ", ".join(f"{shares[best][name]:.0%}" for name in test)
        print(f"| {', '.join(train)} | {best[0]:g}, {best[1]:g} | {fitted} | {', '.join(test)} | {held} |")
        splits.append({"train": train, "test": test, "constants": best, "train_shares": [shares[best][n] for n in train],
                       "test_shares": [shares[best][n] for n in test]})
    print("\nleave one out: each floor scored with the constants fitted on the other three")
    print("| floor | constants fitted on the others | share within 1.5x held out | with the constants fitted on all four |")
    print("|---|---|---|---|")
    everywhere = fit(shares, FLOORS)
    held_out = {}
    for name in FLOORS:
        best = fit(shares, tuple(other for other in FLOORS if other != name))
        held_out[name] = {"constants": best, "share": shares[best][name]}
        print(f"| {name} | {best[0]:g}, {best[1]:g} | {shares[best][name]:.0%} | {shares[everywhere][name]:.0%} |")
    print(f"all four: {everywhere[0]:g}, {everywhere[1]:g}")
    for name in args.held_out:
        spread = [shares[key][name] for key in shares]
        print(f"held out of every fit: {name} {shares[everywhere][name]:.0%} with the fit on all four ({min(spread):.0%}-{max(spread):.0%} over the grid)")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"commit": commit, "splits": splits, "leave_one_out": held_out, "all_four": everywhere,
                                    "never_fitted": {name: shares[everywhere][name] for name in args.held_out},
                                    "grid": [{"evidence_scale": k[0], "acquisitions_per_patch": k[1], **v} for k, v in shares.items()]},
                                   indent=1, default=list) + "\n")


if __name__ == "__main__":
    main()
