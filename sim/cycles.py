"""Cycles of one correlation on each correlator variant, from the cycle models the simulations check.

``python -m lost.sim.cycles`` (``make cycles``) prints, for the paper's 501 x 501 map and 10 x 10 patch
(or ``--map``/``--patch``), the clock edge of the first and last surface beat and of the best beat of
each variant, counted from the edge on which the ``start`` beat transfers, with ``surface.ready`` and
``best.ready`` held high and a full mask. The numbers come from :mod:`lost.model.cycles_recursive` and
:mod:`lost.model.cycles_window`; the Verilator benches (``tests/sim``, ``lost.sim.cocotb.correlator``)
compare every beat of the generated Verilog with them, so they are the simulated counts too.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

import numpy as np

from lost.model.shapes import shape_argument
from lost.model.variants import of_kind, window_variant

__all__ = ["cycle_table", "main"]


def cycle_table(
    map_shape: tuple[int, int], patch_shape: tuple[int, int], *, lanes: Sequence[int] = (1, 4), exclusion_radius: int = 1
) -> list[dict]:
    """One row per variant and mode: first and last surface beat, best beat, and throughput."""
    (H, W), (h, w) = map_shape, patch_shape
    placements = (H - h + 1) * (W - w + 1)
    mask = np.ones(patch_shape, dtype=bool)
    registered = [of_kind("recursive"), *(window_variant(L) for L in lanes)]
    runs = [("recursive" if v.kind == "recursive" else f"window, {v.lanes} lane{'s' if v.lanes > 1 else ''}", v.lanes,
             lambda mc, v=v: v.schedule(map_shape, patch_shape, mask, mc, exclusion_radius=exclusion_radius))
            for v in registered]
    rows = []
    for name, _, schedule in runs:
        for mean_compensation in (True, False):
            result = schedule(mean_compensation)
            rows.append({
                "variant": name,
                "mean_compensation": mean_compensation,
                "first_beat": int(result.surface[0]),
                "last_beat": int(result.surface[-1]),
                "best_beat": int(result.best),
                "cycles_per_placement": int(result.best) / placements,
            })
    return rows




def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m lost.sim.cycles", description=__doc__.splitlines()[0])
    parser.add_argument("--map", type=shape_argument, default=(501, 501), help="map shape, ROWSxCOLS")
    parser.add_argument("--patch", type=shape_argument, default=(10, 10), help="patch shape, ROWSxCOLS")
    parser.add_argument("--exclusion-radius", type=int, default=1)
    args = parser.parse_args(argv)
    try:
        rows = cycle_table(args.map, args.patch, exclusion_radius=args.exclusion_radius)
    except ValueError as error:
        parser.error(str(error))
    (H, W), (h, w) = args.map, args.patch
    print(f"One correlation, {H} x {W} map, {h} x {w} patch, full mask, ready held high; cycle 0 = the start beat.")
    print("Every surface beat and the best beat of the generated Verilog are checked against these")
    print("cycle models on Verilator (tests/sim, lost.sim.cocotb.correlator). The recursive core spends")
    print("a clock per valid patch node and placement, so a sparser mask takes fewer cycles; the window")
    print("core's timing depends on neither mask nor mode.")
    print()
    header = f"{'variant':<20} {'mode':<10} {'first beat':>11} {'last beat':>11} {'best beat':>11} {'cycles/placement':>17}"
    print(header)
    print("-" * len(header))
    for row in rows:
        mode = "mean-comp" if row["mean_compensation"] else "plain"
        print(f"{row['variant']:<20} {mode:<10} {row['first_beat']:>11} {row['last_beat']:>11} "
              f"{row['best_beat']:>11} {row['cycles_per_placement']:>17.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
