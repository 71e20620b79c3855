"""The ULX3S build: its clock constraint names the net the PLL drives, and the summary reads that clock."""

import re

import pytest

from lost.hdl.flow.bitstream import CLOCK_HZ, CLOCK_NET, NAME, UlX3SDevice, _summary, build_plan
from lost.hdl.flow.pnr import FlowError

SMALL = {"tile_shape": (16, 16), "area_shape": (8, 8), "patch_shape": (3, 3), "exclusion_radius": 1}


# hdl/flow/bitstream.py still requests the UART and LED pins without dir="-" (Amaranth 0.5 deprecates it).
@pytest.mark.filterwarnings("ignore:Using platform.request without:DeprecationWarning")
def test_the_constraint_names_the_net_the_pll_drives():
    pytest.importorskip("amaranth_boards", reason="make bitstream installs amaranth-boards")
    plan = build_plan(UlX3SDevice(**SMALL))
    lpf, rtlil = plan.files[f"{NAME}.lpf"], plan.files[f"{NAME}.il"]
    assert re.findall(r'FREQUENCY NET "([^"]+)" ([0-9.]+) HZ;', lpf) == [(CLOCK_NET, str(CLOCK_HZ))]
    top = rtlil[rtlil.index(f"module \\{NAME}\n"):]
    top = top[:top.index("\nend\n")]
    # A top-level wire of that name is the PLL's output and the device's clock (Yosys keeps such a wire's name;
    # a synth_ecp5 of this build lists it among the clock net's names, where a deeper name was merged away).
    assert re.search(rf"^  wire width 1 \\{CLOCK_NET}$", top, re.MULTILINE)
    pll = top[top.index("cell \\EHXPLLL"):]
    pll = pll[:pll.index("\n  end\n")]
    assert f"connect \\CLKOP \\{CLOCK_NET}\n" in pll
    device = top[top.index(f"cell \\{NAME}.device \\device"):]
    device = device[:device.index("\n  end\n")]
    assert f"connect \\clk \\{CLOCK_NET} [0]" in device


def _report(*clocks):
    return {"fmax": {name: {"achieved": mhz, "constraint": 60.0} for name, mhz in clocks},
            "utilization": {"TRELLIS_COMB": {"used": 10, "available": 83640}, "DP16KD": {"used": 2, "available": 208}}}


def test_the_summary_reads_the_pll_clock_among_others():
    summary = _summary(_report(("$glbnet$clk25_0__io", 400.0), (f"$glbnet${CLOCK_NET}", 76.3)))
    assert (summary["clock"], summary["fmax_mhz"], summary["clock_constraint_mhz"]) == (f"$glbnet${CLOCK_NET}", 76.3, 60.0)
    assert (summary["lut4"], summary["ebr"], summary["dsp"]) == (10, 2, 0)
    assert _summary(_report((CLOCK_NET, 61.0)))["fmax_mhz"] == 61.0


def test_a_report_without_the_pll_clock_is_an_error():
    with pytest.raises(FlowError, match="no clock 'clk'.*clk25_0__io"):
        _summary(_report(("clk25_0__io", 400.0)))
