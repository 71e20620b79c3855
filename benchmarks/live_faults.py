"""`lost serve`'s navigation on a faulty stream against the clean one, over seeds; and its time per record.

The tow ``short_exact_map`` (600 pings) as the live datagrams of ``lost replay`` (:mod:`lost.host.live.stream`), with
5 % loss, 5 % reordering and 5 % duplication drawn per seed, through the receiver's decoder and the live navigator
(:class:`lost.host.live.navigator.LiveNavigator`) in one process (no socket: the faults are the stream's own). The
settings are `lost run --survey`'s of tests/host/io/test_simulated_export.py (5 s records, 20 s window, patch on the
soundings, start 30,-20 m off, dead reckoning biased 0.1,0.05 m/s). Per estimator: RMS of the horizontal error over
the records after ``--after-s`` seconds, usable fraction; the faulty runs' RMS over the clean run's, median and 90th
percentile over seeds. And the time from the ping that closes a record to its estimates (navigation only, the
socket and decoding excluded), median, p90, p99 over every record of every run.

    python benchmarks/live_faults.py [--seeds 1 2 3 4 5] [--out build/bench/live_faults.json]
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections import Counter
from pathlib import Path

import numpy as np

from lost.host.io.simulated import simulated_pings
from lost.host.io.survey_records import SurveyRecorder
from lost.host.live.navigator import LiveNavigator
from lost.host.live.receiver import LiveDecoder
from lost.host.live.stream import Faults, live_datagrams, with_faults
from lost.host.nav import ESTIMATORS, NavParameters
from lost.host.scenario import builtin_scenario_path, load_scenario

RECORD_S = 2.0


def _run(grid, pings, faults: Faults | None, after_s: float) -> tuple[dict, list[float]]:
    params = NavParameters()
    recorder = SurveyRecorder(node_m=grid.node_m, patch_shape=(10, 10), interval_s=RECORD_S, window_s=60.0, dr_bias_mps=(0.1, 0.05),
                              start_offset_m=(30.0, -20.0), patch_centre="soundings")
    navigator = LiveNavigator(grid, params, ESTIMATORS, recorder)
    decoder, served, latency_ms = LiveDecoder(), [], []
    datagrams = live_datagrams(pings)
    if faults is not None:
        datagrams = with_faults(datagrams, faults, Counter())
    for datagram in datagrams:
        for value in decoder.feed(datagram.payload):
            if hasattr(value, "beams"):
                start = time.perf_counter()
                out = navigator.add(value)
                if out:
                    latency_ms.append((time.perf_counter() - start) * 1e3)
                served += out
    for value in decoder.finish():
        served += navigator.add(value) if hasattr(value, "beams") else []
    served += navigator.finish()
    methods = {}
    for name in ESTIMATORS:
        mine = [e for e in served if e.estimator == name and e.t_s >= after_s]
        error = np.array([math.hypot(e.east_m - e.truth_east_m, e.north_m - e.truth_north_m) for e in mine])
        methods[name] = {"rms_m": float(np.sqrt(np.nanmean(error**2))), "usable_fraction": float(np.mean([e.usable for e in mine])),
                         "records": len(mine)}
    return {"methods": methods, "received": dict(decoder.counts), "navigation": dict(navigator.counts)}, latency_ms


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    parser.add_argument("--after-s", type=float, default=100.0, help="RMS over the records after this (the start's acquisition left out)")
    parser.add_argument("--out", type=Path, default=Path("build/bench/live_faults.json"))
    args = parser.parse_args()
    grid, crs, pings = simulated_pings(load_scenario(builtin_scenario_path("short_exact_map")))
    pings = list(pings)
    clean, latency = _run(grid, pings, None, args.after_s)
    runs = {}
    for seed in args.seeds:
        runs[seed], more = _run(grid, pings, Faults(loss=0.05, reorder=0.05, duplicate=0.05, seed=seed), args.after_s)
        latency += more
    table = {}
    for name in ESTIMATORS:
        ratios = np.array([runs[s]["methods"][name]["rms_m"] / clean["methods"][name]["rms_m"] for s in args.seeds])
        usable = np.array([runs[s]["methods"][name]["usable_fraction"] for s in args.seeds])
        table[name] = {"clean_rms_m": clean["methods"][name]["rms_m"], "clean_usable": clean["methods"][name]["usable_fraction"],
                       "faulty_rms_m_median": float(np.median([runs[s]["methods"][name]["rms_m"] for s in args.seeds])),
                       "ratio_median": float(np.median(ratios)), "ratio_p90": float(np.percentile(ratios, 90)),
                       "faulty_usable_median": float(np.median(usable))}
    lat = np.array(latency)
    report = {"seeds": args.seeds, "after_s": args.after_s, "table": table, "clean": clean, "faulty": runs,
              "navigation_ms_per_record": {"count": int(lat.size), "p50": float(np.percentile(lat, 50)), "p90": float(np.percentile(lat, 90)),
                                           "p99": float(np.percentile(lat, 99)), "max": float(lat.max())}}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=1))
    print(f"{'estimator':10s} {'clean RMS m':>12s} {'faulty RMS m (median)':>22s} {'ratio median':>13s} {'ratio p90':>10s} "
          f"{'usable clean':>13s} {'usable faulty':>14s}")
    for name, row in table.items():
        print(f"{name:10s} {row['clean_rms_m']:12.2f} {row['faulty_rms_m_median']:22.2f} {row['ratio_median']:13.3f} {row['ratio_p90']:10.3f} "
              f"{row['clean_usable']:13.2f} {row['faulty_usable_median']:14.2f}")
    nav = report["navigation_ms_per_record"]
    print(f"navigation per record (all estimators, {nav['count']} records): median {nav['p50']:.1f} ms, p90 {nav['p90']:.1f}, "
          f"p99 {nav['p99']:.1f}, max {nav['max']:.1f}")


if __name__ == "__main__":
    main()
