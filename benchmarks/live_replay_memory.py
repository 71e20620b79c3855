"""`lost serve`'s memory over a long replay: a real `lost serve` process fed by a real `lost replay --speed S` over UDP.

The tow is a scenario made long (default ``two_hour``'s racetrack, its ``duration_s`` set to ``--hours``: the ship
goes round its four waypoints again and again, so the tow stays on its map for as long as asked), written as a
benchmark scenario file in ``--out``; its map (the same for any duration: the survey of the same floor) is written
as ``map.npz`` from a one-minute copy of it. `lost replay` makes the pings one at a time
(:func:`lost.host.io.simulated.simulated_pings` is a generator; only the scenario's small per-second records are
simulated whole) and sends them, with the vehicle's DVL and depth as PD6, at ``--speed`` times real time to
127.0.0.1. `lost serve` navigates them with every estimator of the bank (2 s records, a 240 s window: 300 m of tow,
the 10 x 10 patch of 30 m nodes; the patch on the soundings) and stops ``idle_stop_s`` after the replay ends.

Every ``--sample-s`` seconds of wall time the server's ``VmRSS`` and ``VmHWM`` (``/proc/PID/status``), the tow time of
the last record in its log and the load average are sampled. Reported: the RSS at the start (the first sample with a
record), after ``--warm-up-h`` hours of tow, at the end; the least-squares slope of RSS against tow time (MB per hour of
tow) after the warm-up and over the second half; the records served; the drops, latency and navigation time of the
server's summary; the load average (median, largest) over the run.

    python benchmarks/live_replay_memory.py [--scenario two_hour] [--hours 12] [--speed 20] [--sample-s 60] [--out build/bench/live_12h]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

from lost.host.io import write_npz
from lost.host.io.simulated import simulated_pings
from lost.host.scenario import builtin_scenario_path, load_scenario


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def _status_mb(pid: int) -> tuple[float, float]:
    """VmRSS and VmHWM of process ``pid``, MB."""
    fields = dict(line.split(":", 1) for line in Path(f"/proc/{pid}/status").read_text().splitlines() if ":" in line)
    return int(fields["VmRSS"].split()[0]) / 1024.0, int(fields["VmHWM"].split()[0]) / 1024.0


class _LogTail:
    """The tow time (``t_s``) of the last record line of a growing ``log.jsonl``, read from where the last call ended."""

    def __init__(self, path: Path) -> None:
        self.path, self.offset, self.t_s, self.records = path, 0, float("nan"), 0

    def update(self) -> None:
        if not self.path.exists():
            return
        with self.path.open("rb") as log:
            log.seek(self.offset)
            chunk = log.read()
        whole = chunk[: chunk.rfind(b"\n") + 1]
        self.offset += len(whole)
        for line in whole.splitlines():
            value = json.loads(line)
            if "record" in value:
                self.t_s, self.records = float(value["t_s"]), self.records + 1


def _scenario(args: argparse.Namespace) -> tuple[Path, Path]:
    """The long scenario file and the map file, in ``args.out``."""
    text = builtin_scenario_path(args.scenario).read_text()
    duration = re.search(r"^duration_s = .*$", text, flags=re.MULTILINE)
    if duration is None:
        raise SystemExit(f"scenario {args.scenario!r} has no duration_s line to lengthen")
    long_text = text.replace(duration.group(0), f"duration_s = {round(args.hours * 3600)}", 1)
    long_text = re.sub(r'^name = ".*"$', f'name = "{args.scenario}_{args.hours:g}h"', long_text, count=1, flags=re.MULTILINE)
    scenario = args.out / f"{args.scenario}_{args.hours:g}h.toml"
    scenario.write_text(f"# {args.scenario} lengthened to {args.hours:g} h of tow by benchmarks/live_replay_memory.py\n{long_text}")
    minute = args.out / "map_source.toml"
    minute.write_text(text.replace(duration.group(0), "duration_s = 60", 1))
    grid, _, _ = simulated_pings(load_scenario(minute))  # the map only; its pings are never made
    return scenario, write_npz(grid, args.out / "map.npz")


def _slope(tow_h: np.ndarray, rss: np.ndarray, keep: np.ndarray) -> float:
    return float(np.polyfit(tow_h[keep], rss[keep], 1)[0]) if keep.sum() >= 3 else float("nan")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="two_hour")
    parser.add_argument("--hours", type=float, default=12.0, help="hours of tow")
    parser.add_argument("--speed", type=float, default=20.0, help="lost replay --speed")
    parser.add_argument("--sample-s", type=float, default=60.0, help="wall-clock seconds between samples")
    parser.add_argument("--warm-up-h", type=float, default=1.5, help="hours of tow left out of the slope (the receiver's memories filling)")
    parser.add_argument("--out", type=Path, default=Path("build/bench/live_12h"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    scenario, map_path = _scenario(args)
    port = _free_port()
    config = args.out / "live.toml"
    config.write_text(f'[serve]\nlisten = "127.0.0.1:{port}"\nbathy = "{map_path.resolve()}"\nrecord_s = 2.0\nwindow_s = 240.0\n'
                      'patch_centre = "soundings"\nstart_offset_m = [30.0, -20.0]\ndr_bias_mps = [0.1, 0.05]\nidle_stop_s = 10.0\nstatus_s = 60.0\n')
    lost = [sys.executable, "-m", "lost.host.cli"]
    serve_err = (args.out / "serve.stderr").open("w")
    server = subprocess.Popen([*lost, "serve", "--config", str(config), "--out", str(args.out / "serve"), "--replace"],
                              stdout=subprocess.PIPE, stderr=serve_err, text=True)
    first = server.stdout.readline()
    found = re.search(r"; log (.*)$", first.strip())
    if found is None:
        server.kill()
        raise SystemExit(f"lost serve did not start: {first!r} (see {args.out / 'serve.stderr'})")
    serve_out: list[str] = [first]
    threading.Thread(target=lambda: serve_out.extend(server.stdout), daemon=True).start()
    tail = _LogTail(Path(found.group(1)))
    replay_out = (args.out / "replay.stdout").open("w")
    started = time.monotonic()
    replay = subprocess.Popen([*lost, "replay", str(scenario), "--to", f"127.0.0.1:{port}", "--speed", f"{args.speed:g}"],
                              stdout=replay_out, stderr=subprocess.STDOUT)
    samples: list[dict] = []
    while server.poll() is None:
        time.sleep(min(args.sample_s, 5.0) if not samples else args.sample_s)
        try:
            rss, hwm = _status_mb(server.pid)
        except (FileNotFoundError, KeyError):
            break  # the server ended between the poll and the read
        tail.update()
        samples.append({"wall_s": time.monotonic() - started, "tow_s": tail.t_s, "records": tail.records, "rss_mb": rss, "hwm_mb": hwm,
                        "load_1min": os.getloadavg()[0]})
        print(f"{samples[-1]['wall_s']:7.0f} s: {tail.records} records, tow {tail.t_s / 3600:.2f} h, RSS {rss:.1f} MB (HWM {hwm:.1f}), "
              f"load {samples[-1]['load_1min']:.2f}", flush=True)
    replay_code, serve_code = replay.wait(), server.wait()
    serve_err.close()
    replay_out.close()
    summary = json.loads((args.out / "serve" / "summary.json").read_text())
    status = [line for line in (args.out / "serve.stderr").read_text().splitlines() if line.startswith("lost serve:")]
    rows = [s for s in samples if s["records"] > 0]
    tow_h = np.array([s["tow_s"] for s in rows]) / 3600.0
    rss = np.array([s["rss_mb"] for s in rows])
    loads = np.array([s["load_1min"] for s in samples])
    warm = tow_h >= args.warm_up_h
    report = {"scenario": scenario.name, "speed": args.speed, "hours": args.hours, "replay_exit": replay_code, "serve_exit": serve_code,
              "wall_s": time.monotonic() - started, "tow_h_served": float(tow_h[-1]) if rows else 0.0, "records": summary["records"],
              "rss_mb_start": float(rss[0]) if rows else None, "rss_mb_after_warm_up": float(rss[warm][0]) if warm.any() else None,
              "rss_mb_end": float(rss[-1]) if rows else None, "hwm_mb_end": samples[-1]["hwm_mb"] if samples else None,
              "slope_after_warm_up_mb_per_tow_h": _slope(tow_h, rss, warm),
              "slope_second_half_mb_per_tow_h": _slope(tow_h, rss, tow_h >= tow_h[-1] / 2) if rows else float("nan"),
              "load_1min_median": float(np.median(loads)), "load_1min_max": float(loads.max()),
              "latency_ms": summary["latency_ms"], "navigation_ms": summary["navigation_ms"], "ended": summary["ended"],
              "last_status": status[-1] if status else None, "replay": (args.out / "replay.stdout").read_text().splitlines(),
              "received": summary["received"], "server": summary["server"], "navigation": summary["navigation"], "samples": samples}
    (args.out / "memory.json").write_text(json.dumps(report, indent=1))
    print("\n".join(report["replay"]))
    print(report["last_status"])
    print(f"{scenario.name} at {args.speed:g}x: {summary['records']} records, {report['tow_h_served']:.2f} h of tow served in "
          f"{report['wall_s'] / 60:.1f} min; RSS {report['rss_mb_start']:.1f} MB at the start, {report['rss_mb_after_warm_up'] or float('nan'):.1f} "
          f"after {args.warm_up_h:g} h of tow, {report['rss_mb_end']:.1f} at the end (VmHWM {report['hwm_mb_end']:.1f}); slope "
          f"{report['slope_after_warm_up_mb_per_tow_h']:+.3f} MB per hour of tow after the warm-up, "
          f"{report['slope_second_half_mb_per_tow_h']:+.3f} over the second half; latency p50 {summary['latency_ms'].get('p50', float('nan')):.1f} "
          f"p99 {summary['latency_ms'].get('p99', float('nan')):.1f} max {summary['latency_ms']['max'] or float('nan'):.1f} ms; "
          f"load average {report['load_1min_median']:.2f} median, {report['load_1min_max']:.2f} max")


if __name__ == "__main__":
    main()
