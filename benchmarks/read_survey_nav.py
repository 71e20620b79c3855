"""A simulated tow exported as Kongsberg .all (or GSF) and navigated as a recorded survey, against the scenario's own run, over seeds.

    python benchmarks/read_survey_nav.py [--scenario short_exact_map] [--seeds 10] [--duration-s S] [--format all|gsf] [--full-window] [--out FILE.json]
    python benchmarks/read_survey_nav.py --table build/bench/read_survey_nav.json      the table of a run again

Per seed (the scenario's ``seed`` set to 1..N) the tow's pings (``lost.host.io.simulated``) are written as ``.all``
(or GSF, ``--format gsf``), read back through ``open_survey``, and navigated several ways.

A scenario whose sonar is a ``"swath"`` (``--scenario demo``): the file holds the scenario's own soundings, and the
survey route's recorder takes the scenario's real-time rule (``patch_rule="behind"``, 1 s records, ``window_s`` the
sonar's ``max_window_s``), all with the scenario's ``[navigation]``:

1. ``scenario``: ``lost run SCENARIO`` with that seed;
2. ``file_patches``: the scenario's records, each patch replaced by the one the recorder grids from the file with the
   dead reckoning the scenario placed its pings by (``swath_dead_reckoning_error``): the round trip;
3. ``scenario_no_slant``: 1 without its slant ranges (a hull-mounted survey has no cable to range along);
4. ``survey_offset``: ``lost run --survey FILE --patch-rule behind --record-s 1 --window-s MAX_WINDOW --config SCENARIO``
   with ``--start-offset 30,-20``: the file's positions differenced, no velocity bias;
5. ``survey_bias``: 4 with ``--dr-bias 0.1,0.05`` as well.

A scenario whose sonar is ``"gridded"`` (``short_exact_map``, the default: patches of map nodes, no pings to agree with), six steps,
each one from the survey run toward the scenario's own run, so that each step's change of the error is one factor's share:

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
SWATH_VARIANTS = ("scenario", "file_patches", "scenario_no_slant", "survey_offset", "survey_bias")
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
    """The seven runs of a gridded-sonar scenario's seed (see the module), as one row."""
    from lost.host.io.survey_records import SurveyRecorder, survey_records
    from lost.host.nav import NavParameters, navigate, navigation_parameters
    from lost.host.scenario import simulate

    grid, crs, pings = _exported(scenario, folder, file_format)
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
    return _row(scenario.seed, results, VARIANTS)


def one_swath_seed(scenario, folder: Path, file_format: str = "all") -> dict:
    """The five runs of a swath scenario's seed (see the module), as one row."""
    from lost.host.io.simulated import swath_dead_reckoning_error
    from lost.host.io.survey_records import SurveyRecorder, survey_records
    from lost.host.nav import navigate, navigation_parameters
    from lost.host.scenario.tow import simulate_with_swath

    grid, crs, pings = _exported(scenario, folder, file_format)
    own_grid, own_records, swath = simulate_with_swath(scenario)
    params, spec = navigation_parameters(scenario.navigation), scenario.sensors["sonar"]

    def recorded(**kw):
        recorder = SurveyRecorder(node_m=grid.node_m, patch_shape=spec.shape, interval_s=spec.interval_s, window_s=spec.max_window_s,
                                  patch_rule="behind", **kw)
        return survey_records(iter(pings), recorder)

    file_patches = recorded(dead_reckoning_error=swath_dead_reckoning_error(own_records, swath)).sonar
    runs = {"scenario": own_records, "file_patches": replace(own_records, sonar=file_patches),
            "scenario_no_slant": replace(own_records, slant_range_m=np.full(len(own_records), np.nan)),
            "survey_offset": recorded(start_offset_m=START_OFFSET_M), "survey_bias": recorded(start_offset_m=START_OFFSET_M, dr_bias_mps=DR_BIAS_MPS)}
    results = {label: (navigate(records, grid if label.startswith("survey") else own_grid, params, estimators=ESTIMATORS), params)
               for label, records in runs.items()}
    return _row(scenario.seed, results, SWATH_VARIANTS)


def _exported(scenario, folder: Path, file_format: str) -> tuple:
    """The scenario's map, CRS and pings, the pings written as ``file_format`` and read back."""
    from lost.host.io.gsf_write import write_gsf_pings
    from lost.host.io.kongsberg_all import write_all_pings
    from lost.host.io.simulated import simulated_pings
    from lost.host.io.survey import open_survey

    grid, crs, pings = simulated_pings(scenario)
    write = write_gsf_pings if file_format == "gsf" else write_all_pings
    path = write(pings, folder / f"{scenario.name}_{scenario.seed}.{file_format}")
    pings = list(open_survey(path, crs=crs))
    path.unlink()
    return grid, crs, pings


def _row(seed: int, results: dict, variants: tuple) -> dict:
    """Each variant's figures (its summary's RMS, 95th percentile, convergence, dead reckoning) as one row."""
    from lost.host.report import summarize

    row = {"seed": seed}
    for label in variants:
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
    variants = [label for label in dict.fromkeys(VARIANTS + SWATH_VARIANTS) if f"{label}_converged" in rows[0]]  # what the run made
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
    parser.add_argument("--full-window", action="store_true", help="a gridded-sonar scenario's survey route: patches only once 60 s of pings are in")
    parser.add_argument("--duration-s", type=float, default=None, help="the tow's seconds (default the scenario's)")
    parser.add_argument("--out", type=Path, default=ROOT / "build" / "bench" / "read_survey_nav.json")
    parser.add_argument("--table", type=Path, default=None, metavar="JSON", help="print the table of an earlier run's --out, and stop")
    args = parser.parse_args()
    if args.table is not None:
        saved = json.loads(args.table.read_text())
        scenario = load_scenario(builtin_scenario_path(saved["scenario"]))
        print("\n".join(table(saved["rows"], _map_node_m(scenario))))
        return
    base = load_scenario(builtin_scenario_path(args.scenario))
    base = base if args.duration_s is None else replace(base, duration_s=args.duration_s)
    swath = base.sensors["sonar"].mode == "swath"
    if not swath and base.rate_hz != 1.0:
        raise SystemExit(f"{args.scenario}: the patch-only variants take one recorder record per ping of a 1 Hz tow; this one is {base.rate_hz:g} Hz")
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for seed in range(1, args.seeds + 1):
            scenario = replace(base, seed=seed)
            rows.append(one_swath_seed(scenario, Path(folder), args.format) if swath else one_seed(scenario, Path(folder), args.format, args.full_window))
            print(json.dumps(rows[-1]), flush=True)
    lines = table(rows, _map_node_m(base))
    print("\n".join(lines))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"scenario": args.scenario, "format": args.format, "full_window": args.full_window, "rows": rows, "table": lines},
                                   indent=1))


if __name__ == "__main__":
    main()
