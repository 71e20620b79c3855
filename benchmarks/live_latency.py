"""`lost serve`'s latency on localhost: `lost replay` of the tow ``short_exact_map`` at ``--speed`` into `lost serve`, per seed.

Each seed is the scenario with that seed (its own floor, sonar noise and track), its first ``--pings`` pings written
as a ``.kmall`` file and replayed at ``--speed`` (1: real time) into `lost serve` with every estimator of the bank,
2 s records, the default reorder buffer (0.5 s of ping time, 0.05 s of wall-clock hold). Two latencies per record,
from the served summary:

- end to end: from the completion of the ping that closes a record (its last datagram decoded) to the record's
  estimates sent and logged; it includes the reorder buffer's hold (up to its wall-clock hold, at real time);
- navigation: from that ping's release by the reorder buffer to the estimates sent and logged.

Per seed p50, p90, p99, max of each; over the seeds the median and the largest of the per-seed p99.

    python benchmarks/live_latency.py [--speed 1] [--seeds 1 2 3] [--pings 150] [--out build/bench/live_latency]
"""

from __future__ import annotations

import argparse
import json
import socket
import threading
import time
from itertools import islice
from pathlib import Path

import numpy as np

from lost.host.cli import main as lost
from lost.host.io import write_npz
from lost.host.io.kmall_write import write_kmall_pings
from lost.host.io.simulated import simulated_pings
from lost.host.scenario import builtin_scenario_path, load_scenario


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def one_seed(seed: int, args: argparse.Namespace) -> dict:
    folder = args.out / f"seed{seed}"
    folder.mkdir(parents=True, exist_ok=True)
    text = builtin_scenario_path("short_exact_map").read_text()
    scenario = folder / "tow.toml"
    scenario.write_text(text.replace("seed = 5\n", f"seed = {seed}\n", 1))
    grid, _, pings = simulated_pings(load_scenario(scenario))
    tow = write_kmall_pings(islice(pings, args.pings), folder / "tow.kmall")
    map_path = write_npz(grid, folder / "map.npz")
    port = _free_port()
    config = folder / "live.toml"
    config.write_text(f'[serve]\nlisten = "127.0.0.1:{port}"\nbathy = "{map_path.resolve()}"\nrecord_s = 2.0\nwindow_s = 60.0\n'
                      'patch_centre = "soundings"\nstart_offset_m = [30.0, -20.0]\ndr_bias_mps = [0.1, 0.05]\nidle_stop_s = 3.0\nstatus_s = 60.0\n')
    served = threading.Thread(target=lost, args=(["serve", "--config", str(config), "--out", str(folder / "serve"), "--replace"],))
    served.start()
    time.sleep(3.0)  # the map read and the port bound
    lost(["replay", str(tow), "--to", f"127.0.0.1:{port}", "--speed", f"{args.speed:g}"])
    served.join()
    summary = json.loads((folder / "serve" / "summary.json").read_text())
    return {"records": summary["records"], "latency_ms": summary["latency_ms"], "navigation_ms": summary["navigation_ms"],
            "reorder_lag_s": summary["reorder_lag_s"], "reorder_hold_s": summary["reorder_hold_s"], "received": summary["received"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--speed", type=float, default=1.0)
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument("--pings", type=int, default=150, help="pings of each seed's tow replayed (1 Hz: seconds of tow)")
    parser.add_argument("--out", type=Path, default=Path("build/bench/live_latency"))
    args = parser.parse_args()
    runs = {seed: one_seed(seed, args) for seed in args.seeds}
    report = {"speed": args.speed, "pings": args.pings, "seeds": runs}
    for kind in ("latency_ms", "navigation_ms"):
        p99 = np.array([runs[s][kind]["p99"] for s in args.seeds])
        report[f"{kind}_p99_median"], report[f"{kind}_p99_max"] = float(np.median(p99)), float(p99.max())
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "latency.json").write_text(json.dumps(report, indent=1))
    print(f"lost replay at {args.speed:g}x into lost serve, {args.pings} pings per seed, every estimator, 2 s records, reorder lag "
          f"{runs[args.seeds[0]]['reorder_lag_s']:g} s, hold {runs[args.seeds[0]]['reorder_hold_s']:g} s")
    print(f"{'seed':>5s} {'records':>8s} | end to end ms: {'p50':>7s} {'p90':>7s} {'p99':>7s} {'max':>7s} | navigation ms: "
          f"{'p50':>6s} {'p90':>6s} {'p99':>6s} {'max':>6s}")
    for seed, run in runs.items():
        e, n = run["latency_ms"], run["navigation_ms"]
        print(f"{seed:5d} {run['records']:8d} | {'':14s} {e['p50']:7.1f} {e['p90']:7.1f} {e['p99']:7.1f} {e['max']:7.1f} | {'':14s} "
              f"{n['p50']:6.1f} {n['p90']:6.1f} {n['p99']:6.1f} {n['max']:6.1f}")
    print(f"p99 over seeds: end to end median {report['latency_ms_p99_median']:.1f} ms, largest {report['latency_ms_p99_max']:.1f}; "
          f"navigation median {report['navigation_ms_p99_median']:.1f} ms, largest {report['navigation_ms_p99_max']:.1f}")


if __name__ == "__main__":
    main()
