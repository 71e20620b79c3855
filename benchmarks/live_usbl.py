"""`lost serve`'s navigation with the USBL's fixes and without them, over seeds: error on and off the map, and NEES.

The tow ``usbl_nav`` (30 min at 1,100 m, the survey map ending after about 15 min, the USBL pinging every 2 s
through the ``scs_june`` cast) with its seed set to each of ``--seeds``: its pings
(:func:`lost.host.io.simulated.simulated_pings`) and its USBL fixes as the JSON lines `lost replay` sends
(:func:`lost.host.live.stream.vehicle_datagrams`, decoded by the receiver's
:class:`~lost.host.live.inputs.JsonInputDecoder`), each fix before the ping of its time, through the live navigator
(:class:`lost.host.live.navigator.LiveNavigator`) in one process; once with the fixes, once without. The settings:
5 s records, 200 s window (the 10 x 10 patch of the 30 m map is 300 m, 200 s of tow), patch on the soundings, start
30,-20 m off, dead reckoning (the pings' differenced positions) biased 0.1,0.05 m/s. Per estimator and run: RMS of
the horizontal error against the pings' positions over the records after ``--after-s``, on the map and off it; for
the PMF and the PF the mean NEES of the estimate (its 2 x 2 covariance against that error; 2 for a consistent
filter). Medians and 90th percentiles over seeds.

    python benchmarks/live_usbl.py [--seeds 1 2 3 4 5] [--duration-s 1800] [--out build/bench/live_usbl.json]
"""

from __future__ import annotations

import argparse
import json
import tempfile
from collections import Counter
from pathlib import Path

import numpy as np

from lost.host.cli.common import map_uncertainty
from lost.host.io.simulated import EPOCH_S, simulated_pings
from lost.host.io.survey_records import SurveyRecorder
from lost.host.live.inputs import JsonInputDecoder
from lost.host.live.navigator import LiveNavigator
from lost.host.live.stream import vehicle_datagrams
from lost.host.nav import ESTIMATORS, NavParameters
from lost.host.scenario import builtin_scenario_path, load_scenario, simulate

#: Seconds of pings in a record's patch: the 300 m patch of 30 m nodes needs about 200 s of tow at 3 knots along it.
WINDOW_S = 200.0


def _tow(seed: int, duration_s: float, folder: Path):
    text = builtin_scenario_path("usbl_nav").read_text().replace("seed = 1414", f"seed = {seed}")
    path = folder / f"usbl_nav_{seed}.toml"
    path.write_text(text.replace("duration_s = 1800", f"duration_s = {duration_s:g}"))
    scenario = load_scenario(path)
    grid, crs, pings = simulated_pings(scenario)
    decoder = JsonInputDecoder(Counter())
    fixes = [fix for d in vehicle_datagrams(simulate(scenario)[1], crs, dvl_format="none", epoch_s=EPOCH_S)
             for fix in decoder.feed(d.payload.decode())]
    return grid, list(pings), fixes


def _run(grid, pings, fixes, after_s: float) -> dict:
    params = NavParameters()
    grid, _ = map_uncertainty(grid, params)
    recorder = SurveyRecorder(node_m=grid.node_m, patch_shape=(10, 10), interval_s=5.0, window_s=WINDOW_S, dr_bias_mps=(0.1, 0.05),
                              start_offset_m=(30.0, -20.0), patch_centre="soundings")
    navigator = LiveNavigator(grid, params, ESTIMATORS, recorder)
    served, waiting = [], list(fixes)
    for ping in pings:
        while waiting and waiting[0].time_s <= ping.time_s:
            navigator.add_sensor(waiting.pop(0))
        served += navigator.add(ping)
    served += navigator.finish()
    out = {"fixes_used": navigator.counts["USBL fixes used"]}
    for name in ESTIMATORS:
        mine = [e for e in served if e.estimator == name and e.t_s >= after_s]
        error = np.array([(e.east_m - e.truth_east_m, e.north_m - e.truth_north_m) for e in mine])
        on_map = grid.contains(np.array([e.truth_east_m for e in mine]), np.array([e.truth_north_m for e in mine]))
        row = {"rms_on_map_m": float(np.sqrt(np.mean(np.sum(error[on_map] ** 2, axis=1)))) if on_map.any() else None,
               "rms_off_map_m": float(np.sqrt(np.mean(np.sum(error[~on_map] ** 2, axis=1)))) if (~on_map).any() else None}
        if name != "lost":
            cov = np.array([[[e.covariance_m2[0], e.covariance_m2[2]], [e.covariance_m2[2], e.covariance_m2[1]]] for e in mine])
            row["nees_mean"] = float(np.mean(np.einsum("ni,nij,nj->n", error, np.linalg.inv(cov), error)))
        out[name] = row
    return out


def _spread(values) -> str:
    values = [v for v in values if v is not None]
    return f"{np.median(values):8.2f} {np.percentile(values, 90):8.2f}" if values else f"{'-':>8} {'-':>8}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    parser.add_argument("--duration-s", type=float, default=1800.0)
    parser.add_argument("--after-s", type=float, default=100.0)
    parser.add_argument("--out", type=Path, default=Path("build/bench/live_usbl.json"))
    args = parser.parse_args()
    runs = []
    with tempfile.TemporaryDirectory() as folder:
        for seed in args.seeds:
            grid, pings, fixes = _tow(seed, args.duration_s, Path(folder))
            run = {"seed": seed, "fixes_sent": len(fixes), "with": _run(grid, pings, fixes, args.after_s),
                   "without": _run(grid, pings, [], args.after_s)}
            runs.append(run)
            print(json.dumps(run), flush=True)
    print(f"\n{len(runs)} seeds; median and 90th percentile over seeds")
    print(f"{'estimator':10} {'USBL':8} {'RMS on map m':>17} {'RMS off map m':>17} {'NEES mean':>17}")
    for name in ESTIMATORS:
        for case in ("without", "with"):
            rows = [run[case][name] for run in runs]
            print(f"{name:10} {case:8} {_spread([r['rms_on_map_m'] for r in rows])} {_spread([r['rms_off_map_m'] for r in rows])} "
                  f"{_spread([r.get('nees_mean') for r in rows])}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(runs, indent=1))


if __name__ == "__main__":
    main()
