"""`lost serve`'s memory over a long tow: the resident set size while a whole simulated tow is served, as fast as possible.

The tow is a scenario's (default ``two_hour``: 7,200 pings at 1 Hz, 64 beams), its pings made one at a time by
:func:`lost.host.io.simulated.simulated_pings` (the scenario's records, small, are simulated whole; the pings are
not held), turned into the live datagrams of ``lost replay`` (:func:`lost.host.live.stream.live_datagrams`), decoded
by the receiver's :class:`~lost.host.live.receiver.LiveDecoder` and served by :class:`~lost.host.live.server.LiveServer`
(the navigator with every estimator, the UDP outputs, the run log, the summary's statistics) in one process, without
the socket and its queue (they hold only what the navigation has not yet taken: nothing at real time). The RSS
(``VmRSS`` of /proc/self/status) is sampled every ``--every`` records; the slope is a least-squares line through the
samples after ``--warm-up-s`` of tow, in MB per hour of tow, and through those of the tow's second half (after the
receiver's memories of the last 4,096 datagrams and ping counters have filled, at 1 Hz after 68 min).

    python benchmarks/live_memory.py [--scenario two_hour] [--every 50] [--out build/bench/live_memory.json]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from lost.host.cli.common import map_uncertainty
from lost.host.io.simulated import simulated_pings
from lost.host.io.survey import Ping
from lost.host.io.survey_records import SurveyRecorder
from lost.host.live.navigator import LiveNavigator
from lost.host.live.outputs import RunLog, UdpSender
from lost.host.live.receiver import LiveDecoder
from lost.host.live.server import LiveServer
from lost.host.live.stream import live_datagrams
from lost.host.nav import ESTIMATORS, NavParameters
from lost.host.scenario import builtin_scenario_path, load_scenario


def rss_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    raise RuntimeError("no VmRSS in /proc/self/status (not Linux?)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="two_hour")
    parser.add_argument("--record-s", type=float, default=2.0)
    parser.add_argument("--every", type=int, default=50, help="records between RSS samples")
    parser.add_argument("--warm-up-s", type=float, default=900.0, help="tow seconds left out of the slope (the first records' allocations)")
    parser.add_argument("--out", type=Path, default=Path("build/bench/live_memory.json"))
    args = parser.parse_args()
    scenario = load_scenario(builtin_scenario_path(args.scenario))
    grid, _, pings = simulated_pings(scenario)
    params = NavParameters()
    grid, _ = map_uncertainty(grid, params)
    recorder = SurveyRecorder(node_m=grid.node_m, patch_shape=(10, 10), interval_s=args.record_s, window_s=60.0, patch_centre="soundings")
    decoder = LiveDecoder()
    with tempfile.TemporaryDirectory() as folder:
        log = RunLog(Path(folder) / "log.jsonl")
        sender = UdpSender([("127.0.0.1", 9)])  # the discard port: sent, or refused and counted
        server = LiveServer(SimpleNamespace(decoder=decoder), LiveNavigator(grid, params, ESTIMATORS, recorder), sender, log,
                            status_stream=sys.stderr)
        samples: list[tuple[float, int, float]] = []  # tow seconds, records, RSS MB
        started, next_sample = time.monotonic(), 0
        for datagram in live_datagrams(pings):
            for value in decoder.feed(datagram.payload):
                server.take(time.monotonic(), value)
                records = server.navigator.counts["records stepped"]
                if isinstance(value, Ping) and records >= next_sample:
                    samples.append((value.time_s - (recorder.epoch_s or value.time_s), records, rss_mb()))
                    next_sample = records + args.every
        for value in decoder.finish():
            server.take(time.monotonic(), value)
        summary = server.summary()
        log.close()
        sender.close()
    wall_s = time.monotonic() - started
    tow_s, _, rss = (np.array(column) for column in zip(*samples, strict=True))
    late = tow_s >= args.warm_up_s
    slope = float(np.polyfit(tow_s[late] / 3600.0, rss[late], 1)[0]) if late.sum() >= 3 else float("nan")
    half = tow_s >= tow_s[-1] / 2
    slope_half = float(np.polyfit(tow_s[half] / 3600.0, rss[half], 1)[0]) if half.sum() >= 3 else float("nan")
    report = {"scenario": args.scenario, "tow_h": float(tow_s[-1] / 3600.0), "records": summary["records"], "wall_s": wall_s,
              "rss_mb_first": float(rss[0]), "rss_mb_after_warm_up": float(rss[late][0]) if late.any() else None,
              "rss_mb_last": float(rss[-1]), "rss_mb_max": float(rss.max()), "slope_mb_per_tow_hour": slope,
              "slope_second_half_mb_per_tow_hour": slope_half,
              "samples": [list(s) for s in samples], "latency_ms": summary["latency_ms"], "methods": summary["methods"]}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=1))
    print(f"{args.scenario}: {report['tow_h']:.2f} h of tow, {summary['records']} records of {args.record_s:g} s served in {wall_s:.0f} s; "
          f"RSS {report['rss_mb_first']:.0f} MB at the first record, {report['rss_mb_after_warm_up'] or float('nan'):.0f} MB after "
          f"{args.warm_up_s:g} s of tow, {report['rss_mb_last']:.0f} MB at the end (max {report['rss_mb_max']:.0f}); "
          f"slope after the warm-up {slope:+.2f} MB per hour of tow, over the second half {slope_half:+.2f}")


if __name__ == "__main__":
    main()
