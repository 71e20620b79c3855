"""A simulated tow exported as Kongsberg .all (or GSF) and navigated as a recorded survey, against the scenario's own run, over seeds.

    python benchmarks/read_survey_nav.py [--scenario short_exact_map] [--seeds 10] [--format all|gsf] [--full-window] [--out FILE.json]
    python benchmarks/read_survey_nav.py --table build/bench/read_survey_nav.json      the table of a run again

Per seed (the scenario's ``seed`` set to 1..N) the tow's pings (``lost.host.io.simulated``) are written as ``.all``
(or GSF, ``--format gsf``), read back through ``open_survey``, and navigated six ways, each one step from the survey
run toward the scenario's own run, so that each step's change of the error is one factor's share:

1. ``survey``: the records ``lost run --survey`` makes (``lost.host.io.survey_records``: 2 s records, patches of the
   last 60 s of pings centred on the soundings, none in the first 60 s with ``--full-window``, a start 30 m east and
   20 m south of the truth, a dead-reckoning bias of 0.1 m/s east and 0.05 m/s north), the default navigation parameters;
2. ``survey_params``: the same records, the scenario's ``[navigation]`` (``lost run --survey --config SCENARIO.toml``);
3. ``survey_dr``: the survey's records made with the scenario run's dead reckoning (its lay-back start and its
   integrated measured velocity, less the truth, as the recorder's ``dead_reckoning_error``): the same start and
   dead-reckoning errors, the survey's records otherwise (2 s, no cable: the reckoned track is the re-initialization
   anchor);
4. ``patch_only``: the scenario's own records, each of its patches replaced by the survey route's patch at that
   record (1 s records of the recorder, the same 60 s window and centre, beams placed by the scenario's dead
   reckoning): only the patch differs from the scenario run;
5. ``patch_true_placed``: as 4 with the beams placed by the true track (no dead-reckoning error inside a patch, and
   the patch's age 0, so that no velocity-bias estimate moves it);
6. ``scenario``: ``lost run SCENARIO`` with that seed (its lay-back start, its sensors, its ``[navigation]``, its
   patches: the floor sampled at the map's nodes around the true position);

and, beside them, 7. ``scenario_swath``: the scenario's own run with its sonar a multibeam swath (``[sensors.sonar]``
``mode = "swath"``, ``realtime = true``: its own pings binned by its own dead reckoning, as the shipped swath
scenarios make their patches): what the scenario itself gives with patches gridded from pings.

Reported: each filter's RMS and 95th percentile error after its convergence, the share of seeds that converged and
the dead reckoning's RMS, as medians and 90th percentiles over the seeds.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
ESTIMATORS = ("pmf", "pf")
VARIANTS = ("survey", "survey_params", "survey_dr", "patch_only", "patch_true_placed", "scenario", "scenario_swath")
#: The survey route's settings (what the docs' `lost run --survey` example gives).
RECORD_S, WINDOW_S, START_OFFSET_M, DR_BIAS_MPS = 2.0, 60.0, (30.0, -20.0), (0.1, 0.05)


def scripted_error(t_s: np.ndarray, reckoned: np.ndarray, truth: np.ndarray):
    """The dead-reckoned track less the truth as a function of time (linear between records; held before the start)."""
    error = reckoned - truth
    finite = np.all(np.isfinite(error), axis=1)
    t, error = t_s[finite], error[finite]
    return lambda at: np.array([np.interp(at, t, error[:, 0]), np.interp(at, t, error[:, 1])])


def patches_at(records, pings: list, node_m: float, error, full_window: bool = False) -> tuple:
    """The survey route's patch at each record of ``records`` that has one (one recorder record per ping: the tow's rate)."""
    from lost.host.io.survey_records import SurveyRecorder

    recorder = SurveyRecorder(node_m=node_m, patch_shape=(10, 10), interval_s=1.0, window_s=WINDOW_S, dead_reckoning_error=error,
                              patch_centre="soundings", full_window=full_window)
    rows = [row for ping in pings for row in recorder.add(ping)] + recorder.finish()
    by_time = {round(row.t_s, 3): row.sonar for row in rows}
    t0 = float(records.t_s[0])
    return tuple(None if patch is None else by_time.get(round(float(t) - t0, 3)) for t, patch in zip(records.t_s, records.sonar))


def one_seed(scenario, folder: Path, file_format: str = "all", full_window: bool = False) -> dict:
    from lost.host.io.gsf_write import write_gsf_pings
    from lost.host.io.kongsberg_all import write_all_pings
    from lost.host.io.simulated import simulated_pings
    from lost.host.io.survey import open_survey
    from lost.host.io.survey_records import SurveyRecorder, survey_records
    from lost.host.nav import NavParameters, navigate, navigation_parameters
    from lost.host.report import summarize
    from lost.host.scenario import simulate

    grid, crs, pings = simulated_pings(scenario)
    write = write_gsf_pings if file_format == "gsf" else write_all_pings
    path = write(pings, folder / f"{scenario.name}_{scenario.seed}.{file_format}")
    pings = list(open_survey(path, crs=crs))
    path.unlink()
    own_grid, own_records = simulate(scenario)
    defaults, own_params = NavParameters(), navigation_parameters(scenario.navigation)
    results = {"scenario": (navigate(own_records, own_grid, own_params, estimators=ESTIMATORS), own_params)}
    own_dead = results["scenario"][0].dead_reckoning
    truth = np.column_stack([own_records.truth_x_m, own_records.truth_y_m])
    own_error = scripted_error(own_records.t_s - own_records.t_s[0], own_dead, truth)

    def recorded(**kw):
        recorder = SurveyRecorder(node_m=grid.node_m, patch_shape=(10, 10), interval_s=RECORD_S, window_s=WINDOW_S, patch_centre="soundings",
                                  full_window=full_window, **kw)
        return survey_records(iter(pings), recorder)

    survey = recorded(dr_bias_mps=DR_BIAS_MPS, start_offset_m=START_OFFSET_M)
    results["survey"] = (navigate(survey, grid, defaults, estimators=ESTIMATORS), defaults)
    results["survey_params"] = (navigate(survey, grid, own_params, estimators=ESTIMATORS), own_params)
    results["survey_dr"] = (navigate(recorded(dead_reckoning_error=own_error), grid, own_params, estimators=ESTIMATORS), own_params)
    for label, error in (("patch_only", own_error), ("patch_true_placed", lambda t: (0.0, 0.0))):
        patches = patches_at(own_records, pings, grid.node_m, error, full_window)
        if label == "patch_true_placed":  # beams placed by the truth: no velocity bias to move them by, whatever their age
            patches = tuple(None if p is None else replace(p, age_s=0.0) for p in patches)
        mixed = replace(own_records, sonar=patches)
        results[label] = (navigate(mixed, own_grid, own_params, estimators=ESTIMATORS), own_params)
    swath = replace(scenario, sensors={**scenario.sensors, "sonar": replace(scenario.sensors["sonar"], mode="swath", realtime=True)})
    swath_grid, swath_records = simulate(swath)
    results["scenario_swath"] = (navigate(swath_records, swath_grid, own_params, estimators=ESTIMATORS), own_params)
    row = {"seed": scenario.seed}
    for label in VARIANTS:
        result, params = results[label]
        summary = summarize(result, name=label, parameters=params.as_dict())
        for name in ESTIMATORS:
            stats = summary["methods"][name]
            row[f"{label}_{name}_rms_m"] = stats.get("rms_m")
            row[f"{label}_{name}_p95_m"] = stats.get("p95_m")
        row[f"{label}_converged"] = summary["convergence"]["converged"]
        row[f"{label}_dead_reckoning_rms_m"] = summary["methods"]["dead_reckoning"].get("rms_m")
    return row


def table(rows: list[dict], node_m: float) -> list[str]:
    """Median and 90th percentile over the seeds of each figure of each variant (metres, and map nodes for the RMS)."""
    figures = [f"{name}_{kind}" for name in ESTIMATORS for kind in ("rms_m", "p95_m")] + ["dead_reckoning_rms_m"]
    variants = [label for label in VARIANTS if f"{label}_converged" in rows[0]]  # an earlier run's table may lack some
    lines = [f"{'variant':18s} " + " ".join(f"{f:>22s}" for f in figures) + "  converged",
             f"{'':18s} " + " ".join(f"{'median':>10s} {'p90':>11s}" for _ in figures)]
    for label in variants:
        cells = []
        for figure in figures:
            values = np.array([np.nan if r[f"{label}_{figure}"] is None else r[f"{label}_{figure}"] for r in rows], dtype=float)
            finite = values[np.isfinite(values)]
            cells += [f"{np.median(finite):10.2f}", f"{np.percentile(finite, 90):11.2f}"] if finite.size else ["-".rjust(10), "-".rjust(11)]
        converged = sum(bool(r[f"{label}_converged"]) for r in rows)
        lines.append(f"{label:18s} " + " ".join(cells) + f"  {converged}/{len(rows)}")
    lines.append(f"in map nodes ({node_m:g} m), RMS median / p90 over the seeds on which that filter converged:")
    for label in variants:
        parts = []
        for name in ESTIMATORS:
            values = np.array([r[f"{label}_{name}_rms_m"] for r in rows if r[f"{label}_{name}_rms_m"] is not None], dtype=float)
            if values.size:
                parts.append(f"{name} {np.median(values) / node_m:.3f} / {np.percentile(values, 90) / node_m:.3f} ({values.size}/{len(rows)})")
        lines.append(f"  {label:18s} " + ", ".join(parts))
    return lines


def _map_node_m(scenario) -> float:
    return scenario.terrain.node_m if scenario.map.node_m is None else scenario.map.node_m


def main() -> None:
    from lost.host.scenario import builtin_scenario_path, load_scenario

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="short_exact_map")
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--format", choices=("all", "gsf"), default="all", help="the file the tow is exported as")
    parser.add_argument("--full-window", action="store_true", help="the survey route's patches only once 60 s of pings are in")
    parser.add_argument("--out", type=Path, default=ROOT / "build" / "bench" / "read_survey_nav.json")
    parser.add_argument("--table", type=Path, default=None, metavar="JSON", help="print the table of an earlier run's --out, and stop")
    args = parser.parse_args()
    if args.table is not None:
        saved = json.loads(args.table.read_text())
        scenario = load_scenario(builtin_scenario_path(saved["scenario"]))
        print("\n".join(table(saved["rows"], _map_node_m(scenario))))
        return
    base = load_scenario(builtin_scenario_path(args.scenario))
    if base.rate_hz != 1.0:
        raise SystemExit(f"{args.scenario}: the patch-only variants take one recorder record per ping of a 1 Hz tow; this one is {base.rate_hz:g} Hz")
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for seed in range(1, args.seeds + 1):
            rows.append(one_seed(replace(base, seed=seed), Path(folder), args.format, args.full_window))
            print(json.dumps(rows[-1]), flush=True)
    lines = table(rows, _map_node_m(base))
    print("\n".join(lines))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"scenario": args.scenario, "format": args.format, "full_window": args.full_window, "rows": rows, "table": lines},
                                   indent=1))


if __name__ == "__main__":
    main()
