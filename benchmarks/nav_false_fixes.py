"""Each false fix of one campaign run, with what made it: the run of a case and seed of a campaign file, navigated again.

python benchmarks/nav_false_fixes.py CASE SEED [--campaign benchmarks/campaigns/nav.toml] [--estimators pmf,pf]

A false fix is a record flagged usable whose error lies beyond 3 sigma (NEES above 11.83, as ``lost.host.report``
counts it). For each one: the record, its time, the error and its NEES, the largest 1-sigma, the stage, what was
refused there, since when the flag was up, and a class:

- ``range outlier``: the record's slant range differs from the true one (the truth's, as the simulator knows it) by
  more than three ``slant_range_sigma_m``, and the false fix lasts at most three records: one range took the density;
- ``trailing``: the false fix lasts longer than ten records (a density that lags the truth, or a lock beside it);
- ``spike``: the rest (a false fix of a few records without a range outlier).

The runs are the campaign's own (``lost.host.campaign``: the same scenario, seed and values), so a campaign's count
can be examined run by run. Nothing here is asserted.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from lost.host.campaign.run import scenario_with
from lost.host.campaign.spec import load_campaign
from lost.host.campaign.systems import load_system_scenario
from lost.host.nav import NavParameters, navigate
from lost.host.report import NEES_3_SIGMA, track_nees
from lost.host.scenario import simulate

SHORT_RECORDS = 3
TRAILING_RECORDS = 10


def true_slant_m(records, reference_depth_m: float) -> np.ndarray:
    """The slant range from the ship to the true vehicle, as a perfect range would read it."""
    horizontal = np.hypot(records.truth_x_m - records.ship_x_m, records.truth_y_m - records.ship_y_m)
    return np.hypot(horizontal, records.vehicle_depth_m - reference_depth_m)


def runs_of(flags: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) record of each unbroken run of True."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], flags.astype(int), [0]])))
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2])]


def false_fixes(case: str, seed: int, campaign: str, estimators: tuple[str, ...]) -> list[dict]:
    spec = load_campaign(campaign)
    tasks = [t for t in spec.tasks() if t.case == case and t.seed == seed]
    if not tasks:
        raise SystemExit(f"{campaign} has no run of case {case!r} with seed {seed}")
    task = tasks[0]
    scenario = scenario_with(load_system_scenario(task.system, Path(task.base_dir) / task.scenario), {"seed": task.seed, **task.values})
    grid, records = simulate(scenario)
    params = NavParameters(**scenario.navigation)
    result = navigate(records, grid, params, estimators=estimators)
    range_error = records.slant_range_m - true_slant_m(records, params.reference_depth_m)
    outlier = np.abs(np.nan_to_num(range_error)) > 3.0 * params.slant_range_sigma_m
    rows = []
    for name in estimators:
        track = result.tracks[name]
        nees = track_nees(track, result.truth)
        bad = track.usable & (nees > NEES_3_SIGMA)
        for first, last in runs_of(bad):
            length = last - first + 1
            near_outlier = bool(outlier[max(first - 1, 0):last + 1].any())
            kind = ("range outlier" if near_outlier and length <= SHORT_RECORDS else "trailing" if length > TRAILING_RECORDS else "spike")
            since = first
            while since > 0 and track.usable[since - 1]:
                since -= 1
            for n in range(first, last + 1):
                error = track.position[n] - result.truth[n]
                rows.append({"estimator": name, "record": n, "t_s": float(result.t_s[n]), "error_m": float(np.hypot(*error)),
                             "nees": float(nees[n]), "sigma_max_m": float(math.sqrt(max(np.linalg.eigvalsh(track.covariance[n])))),
                             "stage": str(track.stage[n]), "rejected": str(track.rejected[n]), "usable_since_s": float(result.t_s[since]),
                             "range_error_m": float(range_error[n]), "class": kind})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("case")
    parser.add_argument("seed", type=int)
    parser.add_argument("--campaign", default="benchmarks/campaigns/nav.toml")
    parser.add_argument("--estimators", default="pmf,pf")
    args = parser.parse_args()
    rows = false_fixes(args.case, args.seed, args.campaign, tuple(args.estimators.split(",")))
    print(f"{args.case} seed {args.seed}: {len(rows)} false fixes")
    for r in rows:
        print(f"{r['estimator']:4s} record {r['record']:5d} t {r['t_s']:7.0f} s  error {r['error_m']:6.1f} m  NEES {r['nees']:6.1f}  "
              f"sigma {r['sigma_max_m']:5.1f} m  {r['stage']:14s} {r['rejected'] or '-':12s} usable since {r['usable_since_s']:.0f} s  "
              f"range error {r['range_error_m']:+7.1f} m  {r['class']}")


if __name__ == "__main__":
    main()
