"""A simulated tow exported as Kongsberg .all (or GSF) and navigated as a recorded survey, against the scenario's own run, over seeds.

    python benchmarks/read_survey_nav.py [--scenario short_exact_map] [--seeds 10] [--format all|gsf] [--out build/bench/read_survey_nav.json]

Per seed (the scenario's ``seed`` set to 1..N): the tow's pings (``lost.host.io.simulated``) are written as
``.all`` (or GSF, ``--format gsf``) and read back through ``open_survey``; their records (``lost.host.io.survey_records``, what
``lost run --survey`` makes: 2 s records, patches of the last 60 s of pings centred on the soundings, a start
30 m east and 20 m south of the truth, a dead-reckoning bias of 0.1 m/s east and 0.05 m/s north, the default
navigation parameters) are navigated on the scenario's map; beside it the scenario's own run (``lost run
SCENARIO``: its lay-back start, its sensors, its ``[navigation]``). Reported: each filter's RMS and 95th
percentile error after its convergence, the share of seeds that converged and the dead reckoning's RMS,
as medians and 90th percentiles over the seeds.
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


def one_seed(scenario, folder: Path, file_format: str = "all") -> dict:
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
    recorder = SurveyRecorder(node_m=grid.node_m, patch_shape=(10, 10), interval_s=2.0, window_s=60.0, dr_bias_mps=(0.1, 0.05),
                              start_offset_m=(30.0, -20.0), patch_centre="soundings")
    records = survey_records(open_survey(path, crs=crs), recorder)
    params = NavParameters()
    survey = summarize(navigate(records, grid, params, estimators=ESTIMATORS), name="survey", parameters=params.as_dict())
    path.unlink()
    own_grid, own_records = simulate(scenario)
    own_params = navigation_parameters(scenario.navigation)
    own = summarize(navigate(own_records, own_grid, own_params, estimators=ESTIMATORS), name="scenario", parameters=own_params.as_dict())
    row = {"seed": scenario.seed}
    for label, summary in (("survey", survey), ("scenario", own)):
        for name in ESTIMATORS:
            stats = summary["methods"][name]
            row[f"{label}_{name}_rms_m"] = stats.get("rms_m")
            row[f"{label}_{name}_p95_m"] = stats.get("p95_m")
        row[f"{label}_converged"] = summary["convergence"]["converged"]
        row[f"{label}_dead_reckoning_rms_m"] = summary["methods"]["dead_reckoning"].get("rms_m")
    return row


def table(rows: list[dict], file_format: str = "all") -> list[str]:
    lines = [f"{'figure':34s} {f'survey (.{file_format})':>22s} {'scenario run':>22s}", f"{'':34s} {'median':>10s} {'p90':>11s} {'median':>10s} {'p90':>11s}"]
    figures = [f"{name}_{kind}" for name in ESTIMATORS for kind in ("rms_m", "p95_m")] + ["dead_reckoning_rms_m"]
    for figure in figures:
        cells = []
        for label in ("survey", "scenario"):
            values = np.array([np.nan if r[f"{label}_{figure}"] is None else r[f"{label}_{figure}"] for r in rows], dtype=float)
            finite = values[np.isfinite(values)]
            cells += [f"{np.median(finite):10.2f}", f"{np.percentile(finite, 90):11.2f}"] if finite.size else ["-".rjust(10), "-".rjust(11)]
        lines.append(f"{figure:34s} " + " ".join(cells))
    for label in ("survey", "scenario"):
        lines.append(f"{label}: converged on {sum(bool(r[f'{label}_converged']) for r in rows)} of {len(rows)} seeds")
    return lines


def main() -> None:
    from lost.host.scenario import builtin_scenario_path, load_scenario

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="short_exact_map")
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--format", choices=("all", "gsf"), default="all", help="the file the tow is exported as")
    parser.add_argument("--out", type=Path, default=ROOT / "build" / "bench" / "read_survey_nav.json")
    args = parser.parse_args()
    base = load_scenario(builtin_scenario_path(args.scenario))
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for seed in range(1, args.seeds + 1):
            rows.append(one_seed(replace(base, seed=seed), Path(folder), args.format))
            print(json.dumps(rows[-1]), flush=True)
    lines = table(rows, args.format)
    print("\n".join(lines))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"scenario": args.scenario, "format": args.format, "rows": rows, "table": lines}, indent=1))


if __name__ == "__main__":
    main()
