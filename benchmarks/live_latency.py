"""`lost serve`'s latency on localhost: `lost replay` of the tow ``short_exact_map`` at ``--speed`` into `lost serve`.

Latency is the serve's own: from the completion of the ping that closes a record (its last datagram decoded) to
the record's estimates sent and logged, every estimator of the bank; the served summary's p50, p90, p99, max.

    python benchmarks/live_latency.py [--speed 20] [--out build/bench/live_latency]
"""

from __future__ import annotations

import argparse
import json
import socket
import threading
import time
from pathlib import Path

from lost.host.cli import main as lost
from lost.host.io import write_npz
from lost.host.io.kmall_write import write_kmall_pings
from lost.host.io.simulated import simulated_pings
from lost.host.scenario import builtin_scenario_path, load_scenario


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--speed", type=float, default=20.0)
    parser.add_argument("--out", type=Path, default=Path("build/bench/live_latency"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    grid, _, pings = simulated_pings(load_scenario(builtin_scenario_path("short_exact_map")))
    tow = write_kmall_pings(pings, args.out / "tow.kmall")
    map_path = write_npz(grid, args.out / "map.npz")
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    config = args.out / "live.toml"
    config.write_text(f'[serve]\nlisten = "127.0.0.1:{port}"\nbathy = "{map_path.resolve()}"\nrecord_s = 2.0\nwindow_s = 60.0\n'
                      'patch_centre = "soundings"\nstart_offset_m = [30.0, -20.0]\ndr_bias_mps = [0.1, 0.05]\nidle_stop_s = 3.0\nstatus_s = 10.0\n')
    served = threading.Thread(target=lost, args=(["serve", "--config", str(config), "--out", str(args.out / "serve"), "--replace"],))
    served.start()
    time.sleep(3.0)  # the map read and the port bound
    lost(["replay", str(tow), "--to", f"127.0.0.1:{port}", "--speed", f"{args.speed:g}"])
    served.join()
    summary = json.loads((args.out / "serve" / "summary.json").read_text())
    print(json.dumps({"speed": args.speed, "records": summary["records"], "latency_ms": summary["latency_ms"],
                      "methods": summary["methods"]}, indent=1))


if __name__ == "__main__":
    main()
