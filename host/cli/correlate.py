"""``lost correlate MAP PATCH``: the best fit and runner-up of a sonar patch on a map, with any correlator backend."""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

from ..correlator import BACKENDS, correlation
from ..nav import PreparedMap
from .common import BACKEND_HELP, configure_hardware, hardware_options, node_count, positive_metres

__all__ = ["register"]


def _cmd_correlate(args: argparse.Namespace) -> int:
    from ..io import read_grid
    from ..io.patch import read_patch

    grid = read_grid(args.map)
    prepared = PreparedMap(grid=replace(grid, sigma_m=None), lsb_m=args.lsb_m)  # a correlation takes no map uncertainty
    words, mask, dropped = prepared.quantize_patch(read_patch(args.patch))
    if not mask.any():
        raise ValueError(f"{args.patch} has no finite depth inside the map's word range")
    configure_hardware(args)
    start = time.perf_counter()
    result = correlation(prepared.words, words, mask=mask, mean_compensation=not args.no_mean_compensation,
                         backend=args.backend, holes=prepared.holes, exclusion_radius=args.exclusion_radius)
    elapsed_ms = (time.perf_counter() - start) * 1e3
    h, w = words.shape

    def where(i: int, j: int) -> str:
        x, y = grid.xy(i + (h - 1) / 2, j + (w - 1) / 2)
        return f"(i, j) = ({i}, {j})   centre x = {float(x):.1f} m, y = {float(y):.1f} m"

    def placement(p) -> dict | None:
        return None if p is None else {"i": p.i, "j": p.j, "value": int(p.value)}

    summary = {
        "map": str(args.map), "patch": str(args.patch), "backend": args.backend, "lsb_m": prepared.lsb_m,
        "valid_nodes": int(mask.sum()), "dropped_out_of_range": dropped,
        "excluded_placements": int((~result.valid).sum()), "valid_placements": int(result.valid.sum()),
        "best": placement(result.best), "runner_up": placement(result.runner_up), "best_from": result.best_from,
        "device_cycles": result.cycles,
    }
    if args.json:
        print(json.dumps(summary))
        return 0
    print(f"map {grid.shape[0]} x {grid.shape[1]} at {grid.node_m:g} m nodes, patch {h} x {w} ({int(mask.sum())} valid), "
          f"{prepared.lsb_m:g} m depth step, backend {args.backend!r}: {elapsed_ms:.2f} ms"
          + ("" if result.cycles is None else f", {result.cycles} device cycles"))
    if result.best is None:
        print(f"no valid placement: every one of the {result.valid.size} placements touches a hole of the map")
        return 0
    best, ru = result.best, result.runner_up
    print(f"best fit   {where(best.i, best.j)}   V = {best.value}"
          + (f"   ({summary['excluded_placements']} placements touching holes excluded)" if summary["excluded_placements"] else ""))
    if ru is None:
        print(f"runner-up  none farther than {result.exclusion_radius} nodes")
    else:
        # The ratio says how distinct the best fit is; against an exact fit (V = 0) any runner-up is infinitely worse.
        ratio = f"{ru.value / best.value:.2f}" if best.value else "- (the best fit is exact, V = 0)"
        print(f"runner-up  {where(ru.i, ru.j)}   V = {ru.value}   ratio {ratio}")
    return 0


def register(commands, parents: list[argparse.ArgumentParser]) -> None:
    """Add ``lost correlate``."""
    corr = commands.add_parser("correlate", parents=parents, help="correlate a sonar patch against a map file")
    corr.add_argument("map", type=Path, help="map: .npz (write_npz) or any grid read_grid reads")
    corr.add_argument("patch", type=Path, help="patch of depths in metres: .npy, .npz or .csv (empty cell = no beam)")
    corr.add_argument("--backend", choices=sorted(BACKENDS), default="software", help=f"{BACKEND_HELP} (default software)")
    hardware_options(corr)
    corr.add_argument("--no-mean-compensation", action="store_true", help="plain SAD instead of Nygren's eq. 8.1")
    corr.add_argument("--exclusion-radius", type=node_count, default=None, metavar="NODES",
                      help="the runner-up is the best placement farther than this from the best fit, nodes (default half the patch)")
    corr.add_argument("--lsb-m", type=positive_metres, default=None, metavar="METRES",
                      help="depth of one step of the int16 words, metres (default: chosen from the map)")
    corr.add_argument("--json", action="store_true", help="print one JSON object")
    corr.set_defaults(handler=_cmd_correlate)
