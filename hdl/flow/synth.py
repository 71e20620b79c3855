"""The measured configurations of the correlator on the open ECP5 flow, and their report.

``python -m lost.hdl.flow.synth`` builds every :data:`CONFIGURATIONS` entry inside a
:class:`~lost.hdl.flow.harness.MeasurementHarness`, synthesizes each once, places and routes it with a few
seeds (the steps of :mod:`lost.hdl.flow.pnr`), keeps the best, and writes ``build/fpga/report.json`` and
``build/fpga/report.md``: per variant and lane count the post-route Fmax, LUT4/FF/EBR/DSP, the cycles of one
501 x 501 / 10 x 10 correlation from the cycle models, the time at that Fmax, the map bandwidth an external
memory must deliver, and what nextpnr's critical path runs through. Results are cached per netlist and seed,
so a rerun after an unchanged HDL only rewrites the report.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from lost.model.paper import PAPER_MAP_SHAPE, PAPER_PATCH_SHAPE, PAPER_SECONDS
from lost.model.variants import Variant, of_kind

from . import figures
from .pnr import FlowError, ToolStopped, lut_mapper, pack, route, synthesize

__all__ = [
    "CONFIGURATIONS",
    "Configuration",
    "critical_path_summary",
    "largest_square_map",
    "main",
    "markdown_table",
]


# ---- the configurations measured --------------------------------------------------------------------

#: The goals: the recursive variant at least matches the paper, the window one is 1000 times faster.
GOAL_SECONDS = {"recursive": PAPER_SECONDS, "window": PAPER_SECONDS / 1000}
#: The DP16KD block RAM of the ECP5: 18 kbit, of which 1024 words of 16 bits serve a depth word.
EBR_DEPTH_WORDS = 1024


@dataclass(frozen=True)
class Configuration:
    """One build: a correlator variant, its lane count, its map size and where its map lives.

    Parameters
    ----------
    variant : {"recursive", "window"}
        :class:`~lost.hdl.recursive.RecursiveCore` or :class:`~lost.hdl.window.WindowCore`.
    lanes : int
        Placements per clock (the recursive variant has one).
    memory : {"external", "on-chip"}
        ``external``: the core alone, its ``map_read`` port on pins (the map in an external memory);
        ``on-chip``: the whole correlator with its map in block RAM.
    map_shape, patch_shape : (int, int)
        The sizes the gateware is built for.
    """

    variant: str
    lanes: int = 1
    memory: str = "external"
    map_shape: tuple[int, int] = PAPER_MAP_SHAPE
    patch_shape: tuple[int, int] = PAPER_PATCH_SHAPE

    def __post_init__(self):
        of_kind(self.variant, self.lanes)  # a ValueError names a wrong kind or lane count
        if self.memory not in ("external", "on-chip"):
            raise ValueError(f"memory must be 'external' or 'on-chip', got {self.memory!r}")
        object.__setattr__(self, "map_shape", tuple(self.map_shape))
        object.__setattr__(self, "patch_shape", tuple(self.patch_shape))

    @property
    def name(self) -> str:
        (H, W), (h, w) = self.map_shape, self.patch_shape
        lanes = f"_l{self.lanes}" if self.variant == "window" else ""
        return f"{self.variant}{lanes}_{self.memory.replace('-', '')}_{H}x{W}_{h}x{w}"

    def core(self):
        """The gateware: the core alone (external) or the correlator with its map memory (on-chip)."""
        from .harness import ECP5RegisteredProduct, ecp5_global_buffer

        # The step enable reaches every step-synchronous register: on the ECP5, a global net; the lanes'
        # products keep their operands' registers inside the multipliers.
        options = {"enable_buffer": ecp5_global_buffer, "product": ECP5RegisteredProduct} if self.variant == "window" else {}
        from lost.hdl.variants import build_core

        return build_core(self.registered, map_shape=self.map_shape, patch_shape=self.patch_shape,
                          memory=self.memory, **options)

    @property
    def registered(self) -> Variant:
        """The variant table's entry of this kind and lane count (:mod:`lost.model.variants`)."""
        return of_kind(self.variant, self.lanes)

    def design(self):
        """The core inside its :class:`~lost.hdl.flow.harness.MeasurementHarness`."""
        from .harness import MeasurementHarness

        return MeasurementHarness(core=self.core(), global_reset=True)

    def cycles(self) -> int:
        """Cycles from the start beat to the best beat of one full-patch correlation at the built sizes."""
        return self.registered.schedule(self.map_shape, self.patch_shape).total


#: The window lane counts tried, in order, until one packs into more than :data:`MAX_LUT_PERCENT` of the LUT4s.
WINDOW_LANES = (1, 2, 3, 4, 6, 8)

#: The external-memory builds at the paper's sizes, smallest first (the window's LUT use grows with lanes).
CONFIGURATIONS: tuple[Configuration, ...] = (
    Configuration("recursive"),
    *(Configuration("window", lanes=lanes) for lanes in WINDOW_LANES),
)


def largest_square_map(*, core_ebr: int, ebr_available: int, lanes: int, depth_bits: int = 16) -> int:
    """The side of the largest square map whose memory fits the block RAM the core leaves free.

    The map memory holds ``ceil(N / lanes)`` rows of ``lanes`` words per map row; each DP16KD holds
    1024 rows of up to 18 bits (:data:`EBR_DEPTH_WORDS`), so a row of ``lanes * depth_bits`` bits takes
    ``ceil(lanes * depth_bits / 18)`` blocks side by side. ``core_ebr`` is the block RAM the core uses
    at the paper's width, an upper bound for any narrower map (its line buffers and row store shrink
    with the width).
    """
    free = ebr_available - core_ebr
    if free <= 0:
        raise ValueError(f"The core alone uses {core_ebr} of {ebr_available} block RAMs; no map fits beside it.")
    blocks_per_row = -(-lanes * depth_bits // 18)
    rows = (free // blocks_per_row) * EBR_DEPTH_WORDS
    side = math.isqrt(rows * lanes)
    while side * -(-side // lanes) > rows:
        side -= 1
    return side


def critical_path_summary(report: dict, *, sources_under: str = "hdl") -> dict:
    """What the longest path of a nextpnr report runs through.

    Returns its start and end cells, total, logic and routing delay (ns), the number of logic cells on
    it, and the Amaranth source lines (``file:line`` under ``sources_under``) of its nets, in path order.
    """
    paths = report.get("critical_paths", [])
    if not paths:
        raise FlowError("the nextpnr report has no critical path")
    path = max(paths, key=lambda p: sum(step["delay"] for step in p["path"]))["path"]
    logic = [step for step in path if step["type"] == "logic"]
    sources = []
    for step in path:
        for source in step.get("sources", []):
            marker = f"/{sources_under}/"
            if marker in source:
                short = sources_under + "/" + source.split(marker, 1)[1]
                if short not in sources:
                    sources.append(short)
    # A path of few cells can still be long: one net (a high-fanout enable) may carry most of it.
    longest = max((step for step in path if step["type"] == "routing"), key=lambda step: step["delay"], default=None)
    return {
        "longest_net": None if longest is None else {"net": longest.get("net", ""), "ns": round(longest["delay"], 3)},
        "from": path[0]["from"]["cell"],
        "to": path[-1]["to"]["cell"],
        "delay_ns": round(sum(step["delay"] for step in path), 3),
        "logic_ns": round(sum(step["delay"] for step in logic), 3),
        "routing_ns": round(sum(step["delay"] for step in path if step["type"] == "routing"), 3),
        "logic_cells": len(logic),
        "sources": sources,
    }


#: The placer struggles above about this LUT4 use; configurations beyond it are packed, not placed.
MAX_LUT_PERCENT = 60.0

#: Iterations router2 may go without fewer overused wires (while more than a hundred remain) before its seed is
#: given up (:class:`RouterStall`).
ROUTER_PATIENCE = 30


def _build(config: Configuration, out_dir: Path, *, seeds: Sequence[int], target_mhz: float,
           max_lut_percent: float = MAX_LUT_PERCENT, router: str = "router2", place: bool = True,
           router_patience: int | None = ROUTER_PATIENCE, log=print) -> dict:
    """Synthesize once, pack, route each seed (cached per netlist and seed), and return the best seed's entry.

    A configuration whose packed LUT4 use exceeds ``max_lut_percent`` is not placed; its entry carries
    the packed cell counts and ``routed: False``.
    """
    name = config.name
    log(f"{name}: synthesizing")
    netlist = synthesize(config.design(), name, out_dir)
    fingerprint = (out_dir / f"{name}.il.sha256").read_text()
    cycles = int(config.cycles())
    entry = {
        "name": name,
        "variant": config.variant,
        "lanes": config.lanes,
        "memory": config.memory,
        "map_shape": list(config.map_shape),
        "patch_shape": list(config.patch_shape),
        "cycles": cycles,
        "goal_seconds": GOAL_SECONDS[config.variant],
        "lut_mapper": lut_mapper(name, out_dir),
    }
    # What an entry that is not placed (or whose every seed failed) reports instead of post-route figures.
    unplaced = _packed_figures(netlist, name, out_dir, fingerprint, log) | {"max_lut_percent": max_lut_percent}
    if unplaced["lut4_percent"] > max_lut_percent or not place:
        return entry | {
            "routed": False,
            "reason": (f"LUT4 use over {max_lut_percent:g} %" if unplaced["lut4_percent"] > max_lut_percent
                       else "no time in this run"),
            **unplaced,
        }
    tries = _route_seeds(netlist, name, out_dir, fingerprint, seeds=seeds, target_mhz=target_mhz, router=router,
                         router_patience=router_patience, log=log)
    seed_figures = {str(_seed_of(t)): (None if "failed" in t else round(t["result"]["fmax_mhz"], 2)) for t in tries}
    routed = [t for t in tries if "failed" not in t]
    if not routed:
        return entry | {
            "routed": False,
            "reason": "nextpnr failed on every seed (" + ", ".join(seed_figures) + "; see the -nextpnr.log files)",
            "seeds": seed_figures,
            **unplaced,
        }
    best = max(routed, key=lambda tried: tried["result"]["fmax_mhz"])
    return entry | {"routed": True, "router": router, "seeds": seed_figures} | _routed_figures(config, cycles, best)


def _packed_figures(netlist: Path, name: str, out_dir: Path, fingerprint: str, log) -> dict:
    """nextpnr's packed cell counts of the netlist (cached per netlist fingerprint) and its LUT4 share."""
    packed_path = out_dir / f"{name}-packed.json"
    packed = json.loads(packed_path.read_text()) if packed_path.exists() else None
    if packed is None or packed["il_sha256"] != fingerprint:
        log(f"{name}: packing")
        packed = {"il_sha256": fingerprint, "utilization": pack(netlist, name)}
        packed_path.write_text(json.dumps(packed, indent=1))
    util = packed["utilization"]
    lut4, lut4_available = util["TRELLIS_COMB"]["used"], util["TRELLIS_COMB"]["available"]
    lut4_percent = round(100 * lut4 / lut4_available, 1)
    log(f"{name}: packed into {lut4} LUT4 ({lut4_percent} %)")
    return {
        "packed": {"lut4": lut4, "ff": util["TRELLIS_FF"]["used"], "ebr": util.get("DP16KD", {}).get("used", 0),
                   "dsp": util.get("MULT18X18D", {}).get("used", 0), "lut4_available": lut4_available},
        "lut4_percent": lut4_percent,
    }


def _route_seeds(netlist: Path, name: str, out_dir: Path, fingerprint: str, *, seeds: Sequence[int],
                 target_mhz: float, router: str, router_patience: int | None, log) -> list[dict]:
    """Every seed's try of this netlist, router and target, in seed order: the asked seeds (routed unless cached,
    a router failure kept as that seed's result) and those earlier runs cached."""

    def current(tried: dict) -> bool:
        """A cached try of this netlist, router and target (a failed one keeps its seed and target at the top)."""
        target = tried.get("target_mhz", tried.get("result", {}).get("target_mhz"))
        # A stall is a result of the patience it was given: more patience tries that seed again.
        stalled_sooner = tried.get("stopped", False) and tried.get("router_patience") != router_patience
        return (tried["il_sha256"] == fingerprint and tried.get("router") == router and target == target_mhz
                and not stalled_sooner)

    def with_current_summary(tried: dict) -> dict:
        """Summaries of cached runs follow this module's reading of the report."""
        report_path = out_dir / f"{name}-seed{_seed_of(tried)}-report.json"
        if "failed" not in tried and report_path.exists():
            tried["critical_path"] = critical_path_summary(json.loads(report_path.read_text()))
        return tried

    tries = []
    for seed in seeds:
        cached = out_dir / f"{name}-seed{seed}.json"
        tried = json.loads(cached.read_text()) if cached.exists() else None
        if tried is None or not current(tried):
            log(f"{name}: routing with seed {seed} at {target_mhz:g} MHz ({router})")
            tried = _route_seed(netlist, f"{name}-seed{seed}", fingerprint, seed=seed, target_mhz=target_mhz,
                                router=router, router_patience=router_patience)
            cached.write_text(json.dumps(tried, indent=1))
        tried = with_current_summary(tried)
        log(f"{name}: seed {seed}: " + (f"failed: {tried['failed']}" if "failed" in tried else f"{tried['result']['fmax_mhz']:.1f} MHz"))
        tries.append(tried)
    for cached in sorted(out_dir.glob(f"{name}-seed*.json")):
        if cached.name.endswith("-report.json"):
            continue
        tried = json.loads(cached.read_text())
        if _seed_of(tried) not in seeds and current(tried):
            tries.append(with_current_summary(tried))
    return sorted(tries, key=_seed_of)


def _route_seed(netlist: Path, name: str, fingerprint: str, *, seed: int, target_mhz: float, router: str,
                router_patience: int | None) -> dict:
    """One seed's place and route, as cached: its result and critical path, or its failure."""
    try:
        result, report = route(netlist, name, target_mhz=target_mhz, seed=seed, router=router,
                               router_patience=router_patience)
    except FlowError as error:
        # One seed's router failure (seen: the clock pin's route to its global buffer, router2's stall) is a
        # result of that seed, not of the configuration: report it and try the others.
        return {"il_sha256": fingerprint, "router": router, "target_mhz": target_mhz, "seed": seed,
                "router_patience": router_patience, "stopped": isinstance(error, ToolStopped),
                "failed": str(error).splitlines()[0]}
    return {"il_sha256": fingerprint, "router": router, "result": result.as_dict(),
            "critical_path": critical_path_summary(report)}


def _routed_figures(config: Configuration, cycles: int, best: dict) -> dict:
    """The post-route figures of the best seed: its result, shares of the device, time (``cycles`` of one
    correlation) and map bandwidth."""
    result = best["result"]
    seconds = cycles / (result["fmax_mhz"] * 1e6)
    return {
        "result": result,
        "lut4_percent": round(100 * result["lut4"] / result["lut4_available"], 1),
        "ebr_percent": round(100 * result["ebr"] / result["ebr_available"], 1),
        "seconds": seconds,
        # Every step reads one map word per lane (the recursive core one per term), whatever the access order.
        "map_bandwidth_gbit_s": (config.lanes * 16 * result["fmax_mhz"] * 1e6 / 1e9
                                 if config.memory == "external" else None),
        "goal_met": (seconds <= GOAL_SECONDS[config.variant]) if tuple(config.map_shape) == PAPER_MAP_SHAPE else None,
        "critical_path": best["critical_path"],
    }


def _seed_of(tried: dict) -> int:
    return tried["seed"] if "failed" in tried else tried["result"]["seed"]


def _time(seconds: float) -> str:
    return f"{seconds * 1e3:.3f} ms" if seconds < 1 else f"{seconds:.2f} s"


def markdown_table(entries: Sequence[dict]) -> str:
    """The report's table: one row per configuration, figures as measured."""
    lines = [
        "| variant | lanes | map | memory | Fmax (MHz) | seeds (MHz) | LUT4 | FF | EBR | DSP | cycles | time | map bandwidth | goal |",
        "|---|---:|---|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for entry in entries:
        H, W = entry["map_shape"]
        if not entry["routed"]:
            p = entry["packed"]
            lines.append(
                f"| {entry['variant']} | {entry['lanes']} | {H}x{W} | {entry['memory']} | not placed: {entry['reason']} | - | {p['lut4']} ({entry['lut4_percent']:.0f} %, packed) | {p['ff']} "
                f"| {p['ebr']} | {p['dsp']} | {entry['cycles']:,} | - | - | - |")
            continue
        r = entry["result"]
        bandwidth = ("-" if entry["map_bandwidth_gbit_s"] is None
                     else f"{entry['map_bandwidth_gbit_s']:.2f} Gbit/s")
        if entry["goal_met"] is None:
            goal = f"- ({H}x{W} map)"
        else:
            goal = ("met" if entry["goal_met"] else "not reached") + f" (<= {_time(entry['goal_seconds'])})"
        seeds = ", ".join(f"{seed}: " + ("failed" if fmax is None else f"{fmax:.1f}") for seed, fmax in entry["seeds"].items())
        lines.append(
            f"| {entry['variant']} | {entry['lanes']} | {H}x{W} | {entry['memory']} | {r['fmax_mhz']:.1f} | {seeds} "
            f"| {r['lut4']} ({entry['lut4_percent']:.0f} %) | {r['ff']} | {r['ebr']} | {r['dsp']} "
            f"| {entry['cycles']:,} | {_time(entry['seconds'])} | {bandwidth} | {goal} |")
    return "\n".join(lines) + "\n"


def mapper_note(entries: Sequence[dict]) -> str:
    """A line naming the configurations mapped with the classic ``abc`` because ABC9 failed (empty if none)."""
    fallback = [entry["name"] for entry in entries if entry.get("lut_mapper") == "abc"]
    if not fallback:
        return ""
    return ("\nMapped to LUTs with Yosys's classic `abc -lut 4` (not timing-driven), ABC9 having failed on them: "
            + ", ".join(f"`{name}`" for name in fallback) + ".\n")


def critical_path_lines(entries: Sequence[dict]) -> str:
    """One line per configuration: the delay of its critical path and the source lines it runs through."""
    lines = []
    for entry in entries:
        if not entry["routed"]:
            continue
        path = entry["critical_path"]
        lines.append(f"- {entry['name']}: {path['delay_ns']:.2f} ns ({path['logic_cells']} logic cells, "
                     f"{path['logic_ns']:.2f} ns logic, {path['routing_ns']:.2f} ns routing) from `{path['from']}` "
                     f"to `{path['to']}`; longest net `{path['longest_net']['net']}` ({path['longest_net']['ns']:.2f} ns); "
                     "sources " + (", ".join(f"`{s}`" for s in path["sources"]) or "none named in hdl/"))
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m lost.hdl.flow.synth``: build the configurations and write the report."""
    parser = _argument_parser()
    args = parser.parse_args(argv)
    if args.target_mhz <= 0:
        parser.error(f"--target-mhz must be positive, got {args.target_mhz}")
    if args.router_patience < 0:
        parser.error(f"--router-patience must be 0 (never stop) or a positive number of iterations, got {args.router_patience}")
    out_dir = args.out
    out_dir.mkdir(parents=True, exist_ok=True)
    report_path = out_dir / "report.json"
    previous = {entry["name"]: entry for entry in
                (json.loads(report_path.read_text())["configurations"] if report_path.exists() else [])}

    entries: dict[str, dict] = {}
    command = "python -m lost.hdl.flow.synth " + " ".join(sys.argv[1:] if argv is None else argv)

    def write() -> str:
        # After every configuration, so an interrupted run keeps what it measured.
        ordered = list(entries.values())
        report = {
            "device": "LFE5U-85F-CABGA381",
            "paper_seconds": PAPER_SECONDS,
            "paper_sizes": {"map": list(PAPER_MAP_SHAPE), "patch": list(PAPER_PATCH_SHAPE)},
            "target_mhz": args.target_mhz,
            "command": command.strip(),
            "configurations": ordered,
        }
        report_path.write_text(json.dumps(report, indent=1))
        markdown = markdown_table(ordered) + mapper_note(ordered) + "\nCritical paths (best seed):\n\n" + critical_path_lines(ordered)
        (out_dir / "report.md").write_text(markdown)
        return markdown

    wanted = set(args.only) if args.only else None

    commit = figures.gateware_commit()

    def take(config: Configuration) -> None:
        if wanted is None or config.name in wanted:
            entries[config.name] = entry = _build(config, out_dir, seeds=args.seeds, target_mhz=args.target_mhz,
                                                  router=args.router, router_patience=args.router_patience or None,
                                                  place=not any(config.name.startswith(name) for name in args.no_place or ()))
            write()
            if entry["routed"] and args.figures is not None:
                row = figures.row_of(entry, commit=commit)
                if not figures.recorded(figures.read(args.figures), row):
                    figures.append(row, args.figures)
        elif config.name in previous:
            entries[config.name] = previous[config.name]

    if any(lanes < 1 for lanes in args.lanes):
        parser.error(f"--lanes must be positive, got {args.lanes}")
    for config in [Configuration("recursive"), *(Configuration("window", lanes=lanes) for lanes in args.lanes)]:
        take(config)
        entry = entries.get(config.name)
        if config.variant == "window" and entry is not None and not entry["routed"]:
            print(f"{config.name} was not placed ({entry['reason']}): no more lanes")
            break
    for lanes in args.on_chip:
        _take_on_chip(take, entries, lanes)
    print(write())
    return 0


def _argument_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m lost.hdl.flow.synth``."""
    parser = argparse.ArgumentParser(prog="python -m lost.hdl.flow.synth", description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("build/fpga"), help="output folder (build/fpga)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2], help="placer seeds per configuration")
    parser.add_argument("--target-mhz", type=float, default=250.0,
                        help="the clock nextpnr is asked for; ambitious on purpose (250)")
    parser.add_argument("--only", nargs="+", metavar="NAME",
                        help="configurations to build, by name (default: all); the report keeps the others' cached entries")
    parser.add_argument("--router", choices=["router1", "router2"], default="router2",
                        help="nextpnr's router (router2: router1 did not converge on the window core in 25 min)")
    parser.add_argument("--router-patience", type=int, default=ROUTER_PATIENCE, metavar="N",
                        help="give a seed up when router2 has found no fewer overused wires for N iterations while "
                             f"over a hundred remain (default {ROUTER_PATIENCE}; 0: never)")
    parser.add_argument("--no-place", nargs="+", metavar="NAME",
                        help="configurations only synthesized and packed (their cell counts), not placed; a name or its "
                             "beginning (window_l1_onchip: the on-chip build whatever its map size)")
    parser.add_argument("--lanes", type=int, nargs="+", default=list(WINDOW_LANES), metavar="L",
                        help=f"window lane counts, built in order until one is over the LUT budget (default: {' '.join(map(str, WINDOW_LANES))})")
    parser.add_argument("--figures", type=Path, metavar="CSV",
                        help="append each placed build's figures to this versioned CSV (make synth: docs/fpga_figures.csv)")
    parser.add_argument("--on-chip", type=int, nargs="*", metavar="LANES", default=[1],
                        help="window lane counts also built with the map on chip, at the largest map that fits (default: 1)")
    return parser


def _take_on_chip(take, entries: dict[str, dict], lanes: int) -> None:
    """The on-chip build of ``lanes`` lanes at the largest square map that fits beside the whole correlator."""
    external = entries.get(Configuration("window", lanes=lanes).name)
    if external is None or not external["routed"]:
        print(f"on-chip build with {lanes} lanes skipped: its external-memory build is not in the report")
        return
    available = external["result"]["ebr_available"]
    core_ebr = external["result"]["ebr"]
    while True:
        side = largest_square_map(core_ebr=core_ebr, ebr_available=available, lanes=lanes)
        config = Configuration("window", lanes=lanes, memory="on-chip", map_shape=(side, side))
        take(config)
        entry = entries.get(config.name)
        used = None if entry is None else (entry["result"] if entry["routed"] else entry["packed"])["ebr"]
        if used is None or used <= available:
            return
        # The whole correlator needs more blocks beside its map than the core alone (its loader's
        # memory ports): count them and take the next smaller map.
        print(f"{config.name} needs {used} of {available} EBR: one size smaller")
        del entries[config.name]
        core_ebr += used - available


if __name__ == "__main__":
    sys.exit(main())
