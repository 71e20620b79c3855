# amaranth: UnusedElaboratable=no
"""The synthesis harness's clock and reset: each pin on a primary clock input, the reset straight into its DCCA."""

import re

from amaranth import Module
from amaranth.back import rtlil
from amaranth.lib import wiring
from amaranth.lib.wiring import Out

from lost.hdl.flow.harness import CLOCK_SITE, RESET_SITE, MeasurementHarness


class Counter(wiring.Component):
    count: Out(8)

    def elaborate(self, platform):
        m = Module()
        m.d.sync += self.count.eq(self.count + 1)
        return m


def _top(harness) -> str:
    text = rtlil.convert(harness, name="top")
    top = text[text.index("module \\top"):]
    return top[: top.index("\nend\n")]


def test_the_reset_pin_is_placed_on_a_clock_input_and_drives_the_buffer_directly():
    top = _top(MeasurementHarness(core=Counter(), global_reset=True))
    # The port carries its site, so nextpnr places it where a dedicated wire reaches a clock buffer.
    assert re.search(r'attribute \\LOC "' + RESET_SITE + r'"\n\s*wire width 1 input \d+ +\\reset\n', top)
    # The buffer's input is the pin itself: no register (whose fabric route may be blocked) between them.
    dcca = top[top.index("cell \\DCCA"):]
    dcca = dcca[: dcca.index("\n  end\n")]
    assert re.search(r"connect \\CLKI \\reset \[0\]\n", dcca)
    # Nothing else reads the pin: the core's reset is the buffer's output.
    assert len(re.findall(r"\\reset\b(?!_)", top)) == 2  # its declaration and the buffer's input
    assert re.search(r"connect \\reset_global \\rst", top)


def test_the_clock_pin_is_placed_on_the_other_clock_input():
    top = _top(MeasurementHarness(core=Counter(), global_reset=True))
    # nextpnr routes a clock from this pad to a global buffer on dedicated wires (JINCK to LDCC0).
    assert re.search(r'attribute \\LOC "' + CLOCK_SITE + r'"\n\s*wire width 1 input \d+ +\\clk\n', top)
    assert CLOCK_SITE != RESET_SITE


def test_the_simulation_harness_has_no_site_and_no_buffer():
    harness = MeasurementHarness(core=Counter())
    top = _top(harness)
    assert "LOC" not in top and "DCCA" not in top
    assert "reset" not in harness.signature.members
