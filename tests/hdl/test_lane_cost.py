# amaranth: UnusedElaboratable=no
"""What a window lane costs after packing: the flow's netlist passes and the lane's reciprocal quotient."""

import json

import pytest
from amaranth import Module, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from lost.hdl.flow.synth import drop_unused_carry_outs, pack, synthesize


def carry_cell(cin, cout):
    return {"type": "CCU2C", "port_directions": {"CIN": "input", "A0": "input", "S0": "output", "COUT": "output"},
            "connections": {"CIN": [cin], "A0": [2], "S0": [3], "COUT": [cout]}}


def test_only_unread_carry_outs_are_dropped(tmp_path):
    # Chain a -> b: a's carry out is b's carry in and stays; b's goes nowhere; c's leaves the module.
    cells = {"a": carry_cell("0", 10), "b": carry_cell(10, 11), "c": carry_cell("0", 12)}
    netlist = tmp_path / "n.json"
    netlist.write_text(json.dumps({"modules": {"top": {
        "ports": {"o": {"direction": "output", "bits": [12]}, "i": {"direction": "input", "bits": [2]}},
        "cells": cells}}}))
    assert drop_unused_carry_outs(netlist) == 1
    cells = json.loads(netlist.read_text())["modules"]["top"]["cells"]
    assert [cells[name]["connections"]["COUT"] for name in "abc"] == [[10], ["x"], [12]]
    assert drop_unused_carry_outs(netlist) == 0


class Adders(wiring.Component):
    """``count`` independent registered 18-bit sums: ``count`` carry chains."""

    def __init__(self, count):
        self.count = count
        super().__init__({"i": In(34 * count), "o": Out(18 * count)})

    def elaborate(self, platform):
        m = Module()
        for k in range(self.count):
            a, b = self.i[34 * k:34 * k + 17], self.i[34 * k + 17:34 * (k + 1)]
            total = Signal(18, name=f"sum{k}")
            m.d.sync += total.eq(a + b)
            m.d.comb += self.o[18 * k:18 * (k + 1)].eq(total)
        return m


@pytest.mark.fpga
def test_a_chain_packs_with_its_feed_in_only(tmp_path):
    count = 3
    netlist = synthesize(Adders(count), "adders", tmp_path)
    cells = json.loads(netlist.read_text())["modules"]["top"]["cells"].values()
    carries = sum(cell["type"] == "CCU2C" for cell in cells)
    luts = sum(cell["type"] == "LUT4" for cell in cells)
    assert carries == 9 * count
    # Each chain's carry in is a constant, which nextpnr feeds in through one more CCU2C; nothing feeds out
    # (a feed-out would be one more per chain). The packer adds a driver for each of 0 and 1.
    assert pack(netlist, "adders")["TRELLIS_COMB"]["used"] == 2 * (carries + count) + luts + 2
