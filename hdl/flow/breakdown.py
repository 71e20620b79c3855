"""Where a core's LUTs go: ``synth_ecp5 -noflatten`` and the cells of each component, for the lane's diet.

The gateware is made of components (:mod:`lost.hdl.blocks`, the window lane's parts), each its own
module in the netlist when Yosys does not flatten, so ``stat`` counts the cells of each. A LUT4
equivalent is a ``LUT4`` or half a ``CCU2C`` (a carry-chain cell holds two LUT4s; nextpnr counts both
in ``TRELLIS_COMB``). The figures are before placement (no packing, no cross-module optimisation), so
their sum runs a little above a flattened build's; they say where the cost is, not the final count.

``python -m lost.hdl.flow.breakdown --part lane`` synthesizes one window lane at the paper's sizes
(501 x 501 / 10 x 10) and prints its components, largest first; ``--part core --lanes 1`` the whole core.
``--part increment`` measures what the flow's figures count instead: the window core in its measurement
harness with 1 and 2 lanes (``--lanes 1 2``, any two counts), synthesized as ``make synth`` does and packed by
nextpnr (:func:`lost.hdl.flow.pnr.pack`, seconds), and the difference per lane (a few minutes).
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from collections.abc import Sequence
from pathlib import Path

from amaranth.back import rtlil

from lost.hdl.interface import CorrelatorParameters
from lost.hdl.variants import build_core
from lost.model.paper import PAPER_MAP_SHAPE, PAPER_PATCH_SHAPE
from lost.model.variants import window_variant

from .pnr import ALU_MAP, _yosys, pack, synthesize
from .synth import Configuration

__all__ = ["cell_counts", "lane_increment", "lut4_equivalent", "main"]

#: The flow's classic-``abc`` script (:data:`lost.hdl.flow.pnr._CLASSIC_ABC_SCRIPT`, with its adder map
#: :data:`~lost.hdl.flow.pnr.ALU_MAP`), without flattening.
_SCRIPT = ("read_rtlil {il}; synth_ecp5 -noflatten -top top -run begin:map_gates; techmap -map +/techmap.v -map "
           + ALU_MAP.name + "; synth_ecp5 -noflatten -top top -run map_gates:map_luts; techmap -map +/lattice/latches_map.v; "
           "abc -lut 4; clean; synth_ecp5 -noflatten -top top -run map_cells:; tee -q -o {stat} stat -json")


def lut4_equivalent(cells: dict[str, int]) -> int:
    """LUT4s of a module's cell counts: each ``LUT4`` one, each ``CCU2C`` two."""
    return int(cells.get("LUT4", 0)) + 2 * int(cells.get("CCU2C", 0))


def cell_counts(design, name: str, out_dir: Path) -> dict[str, dict[str, int]]:
    """The cells of each module of ``design`` after ``synth_ecp5 -noflatten``, by module name.

    Writes ``NAME.il``, ``NAME-stat.json`` and ``NAME-yosys.log`` under ``out_dir``.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    il, stat = out_dir / f"{name}.il", out_dir / f"{name}-stat.json"
    il.write_text(rtlil.convert(design, name="top"))
    shutil.copyfile(ALU_MAP, out_dir / ALU_MAP.name)
    _yosys(_SCRIPT.format(il=il.name, stat=stat.name), out_dir / f"{name}-yosys.log")
    modules = json.loads(stat.read_text())["modules"]
    return {module.lstrip("\\"): {cell: int(n) for cell, n in figures.get("num_cells_by_type", {}).items()}
            for module, figures in modules.items()}


def _design(part: str, lanes: int):
    if part == "core":
        return build_core(window_variant(lanes), map_shape=PAPER_MAP_SHAPE, patch_shape=PAPER_PATCH_SHAPE, memory="external")
    from lost.hdl.window_lane import WindowLane

    return WindowLane(parameters=CorrelatorParameters(map_shape=PAPER_MAP_SHAPE, patch_shape=PAPER_PATCH_SHAPE,
                                                      lanes=lanes))


#: The packed cells ``--part increment`` reports, by nextpnr's names.
PACKED_CELLS = {"LUT4": "TRELLIS_COMB", "FF": "TRELLIS_FF", "DSP": "MULT18X18D", "EBR": "DP16KD"}


def lane_increment(lanes: Sequence[int], out_dir: Path) -> dict[int, dict[str, int]]:
    """The packed cells of the window core (paper's sizes, in its harness) at each lane count, by :data:`PACKED_CELLS`."""
    packed = {}
    for count in lanes:
        config = Configuration("window", lanes=count)
        utilization = pack(synthesize(config.design(), config.name, out_dir), config.name)
        packed[count] = {label: utilization.get(cell, {}).get("used", 0) for label, cell in PACKED_CELLS.items()}
    return packed


def _print_increment(lanes: Sequence[int], out_dir: Path) -> None:
    if len(lanes) != 2 or lanes[0] >= lanes[1]:
        raise SystemExit(f"--part increment needs two lane counts, fewer first, got {list(lanes)}")
    packed = lane_increment(lanes, out_dir)
    labels = list(PACKED_CELLS)
    print("| window core, packed | " + " | ".join(labels) + " |\n|---|" + "---:|" * len(labels))
    for count in lanes:
        print(f"| {count} lane{'s' if count > 1 else ''} | " + " | ".join(str(packed[count][k]) for k in labels) + " |")
    low, high = lanes
    print("| per lane | " + " | ".join(f"{(packed[high][k] - packed[low][k]) / (high - low):g}" for k in labels) + " |")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m lost.hdl.flow.breakdown", description=__doc__.splitlines()[0])
    parser.add_argument("--part", choices=["lane", "core", "increment"], default="lane",
                        help="one window lane, the whole core, or the packed cost of a lane (2 builds, minutes)")
    parser.add_argument("--lanes", type=int, nargs="+", default=None,
                        help="the core's lanes (--part core: one count, default 1; --part increment: two, default 1 2)")
    parser.add_argument("--out", type=Path, default=Path("build/fpga/breakdown"))
    args = parser.parse_args(argv)
    if args.part == "increment":
        _print_increment(args.lanes or [1, 2], args.out)
        return 0
    lanes = (args.lanes or [1])[0]
    counts = cell_counts(_design(args.part, lanes), f"{args.part}_l{lanes}", args.out)
    rows = sorted(((lut4_equivalent(c), int(c.get("TRELLIS_FF", 0)), int(c.get("MULT18X18D", 0)), name)
                   for name, c in counts.items()), reverse=True)
    print("| module | LUT4 (LUT4 + 2 x CCU2C) | FF | DSP |\n|---|---:|---:|---:|")
    for lut4, ff, dsp, name in rows:
        print(f"| {name} | {lut4} | {ff} | {dsp} |")
    total = [sum(row[k] for row in rows) for k in range(3)]
    print(f"| total | {total[0]} | {total[1]} | {total[2]} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
