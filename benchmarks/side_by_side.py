"""The correlator side by side at the paper's sizes (501 x 501 map, 10 x 10 patch): FPGA, software, OpenCV.

``python benchmarks/side_by_side.py [build/fpga/report.json]`` (run by ``make synth`` after the FPGA
flow) prints one markdown table:

* each FPGA configuration of the report: cycles of one correlation (cycle model) over the post-route
  Fmax (nextpnr), as ``python -m lost.hdl.flow.synth`` measured them;
* the project's exact software correlator (``lost.host.correlate``, backend ``software``) and OpenCV's
  ``matchTemplate`` (``TM_SQDIFF`` on float32, not exact, not mean-compensated), both timed here on
  this machine: the best of several rounds, after a warm-up;
* the 2002 hardware correlator (FOI-R--0764--SE, section 8.3), for scale.

No figure is typed in: the FPGA rows come from the report, the others from the clock.
"""

from __future__ import annotations

import argparse
import json
import sys
import timeit
from pathlib import Path

import cv2
import numpy as np

from lost import model
from lost.host import correlate
from lost.host.terrain import synthetic_terrain
from lost.model.paper import PAPER_SECONDS


def best_time(function, *, rounds: int = 20) -> float:
    """The fastest of ``rounds`` calls (seconds), after one warm-up call."""
    function()
    return min(timeit.repeat(function, number=1, repeat=rounds))


def paper_case() -> tuple[np.ndarray, np.ndarray]:
    """A quantized synthetic 501 x 501 map and a 10 x 10 patch cut from it at (200, 300)."""
    terrain = model.quantize(synthetic_terrain((501, 501), seed=1), 0.1, offset_m=1000.0)
    return terrain, terrain[200:210, 300:310].copy()


def rows(report: dict, *, rounds: int) -> list[tuple[str, str, float, str]]:
    """``(what, where, seconds, exact)`` for every row of the table."""
    table = []
    for entry in report["configurations"]:
        if not entry["routed"]:
            continue  # packed only: no Fmax, so no time
        H, W = entry["map_shape"]
        lanes = f", {entry['lanes']} lane{'s' if entry['lanes'] > 1 else ''}" if entry["variant"] == "window" else ""
        where = (f"LFE5U-85F post-route, {entry['result']['fmax_mhz']:.1f} MHz, map {entry['memory']}"
                 + ("" if [H, W] == [501, 501] else f" ({H}x{W} map)"))
        table.append((f"FPGA {entry['variant']}{lanes}", where, entry["seconds"], "yes (simulated bit for bit against lost.model)"))

    terrain, patch = paper_case()
    surface = correlate(terrain, patch, backend="software")
    if model.best_fit(surface).best != model.Placement(200, 300, 0):
        raise RuntimeError("the software correlator did not find the patch where it was cut: not timing a wrong answer")
    table.append(("software correlator (lost.host, exact)", "this machine",
                  best_time(lambda: correlate(terrain, patch, backend="software"), rounds=rounds), "yes"))
    terrain32, patch32 = terrain.astype(np.float32), patch.astype(np.float32)
    table.append(("OpenCV matchTemplate TM_SQDIFF float32", "this machine",
                  best_time(lambda: cv2.matchTemplate(terrain32, patch32, cv2.TM_SQDIFF), rounds=rounds),
                  "no (float, squared, no mean compensation)"))
    table.append(("2002 hardware correlator", "FOI-R--0764--SE, section 8.3", PAPER_SECONDS, "-"))
    return table


def markdown(table: list[tuple[str, str, float, str]]) -> str:
    lines = ["| correlator, 501x501 map / 10x10 patch | where | time | vs 2002 | exact |", "|---|---|---:|---:|---|"]
    for what, where, seconds, exact in table:
        lines.append(f"| {what} | {where} | {seconds * 1e3:.3f} ms | {PAPER_SECONDS / seconds:,.1f}x | {exact} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("report", nargs="?", type=Path, default=Path("build/fpga/report.json"),
                        help="the FPGA report of `python -m lost.hdl.flow.synth` (build/fpga/report.json)")
    parser.add_argument("--rounds", type=int, default=20, help="timed rounds of each software correlator (20)")
    args = parser.parse_args(argv)
    if not args.report.exists():
        parser.error(f"{args.report} does not exist: run `python -m lost.hdl.flow.synth` (or `make synth`) first")
    if args.rounds < 1:
        parser.error(f"--rounds must be at least 1, got {args.rounds}")
    print(markdown(rows(json.loads(args.report.read_text()), rounds=args.rounds)), end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
